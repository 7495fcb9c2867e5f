// The bvh4 layout (the `*_bvh4` variants: `// trilab:layouts` in the kernels): its node format and
// its step, as every layout gives them to the traversals (layout_interface.glsl). Host side:
// src/encoding/layout/bvh4.rs.
//
// Nodes are src/bvh/wide/'s `Bvh4Node` (128 bytes, structure of arrays), bound at
// BINDING_NODES in place of the binary nodes: 8 texels per node, one per field, so node i is
// texels 8i .. 8i + 7: min_x, min_y, min_z, max_x, max_y, max_z (the four children's box planes,
// f32 bits), child, count. A child with count 0 is a node index; count > 0 is a leaf of `count`
// units from `child` (the encoding's units, as in the binary tree); child == 0xFFFFFFFF marks an
// empty slot, and empty slots come last. Node 0 is the root; the root box is not stored, so the
// traversal starts at node 0 and tests its children (the union of the root's child boxes is the
// root box; the conservative test takes it from there).
//
// Per step (one wide node, layout_visit): the eight texels are loaded, the occupied children's
// boxes are slab-tested with the entry distance of each, the hit children are sorted far to near
// (a 5-comparator network over four (t, entry) pairs, misses at -FLT_MAX), all but the nearest are
// pushed with their entry distance, and the nearest is visited next. A popped entry whose entry
// distance is beyond the closest hit so far is skipped (as WideBvh::trace, the CPU model).
//
// Stack: BVH4_STACK_SIZE entries (shared.glsl; WideBvh::stack_bound).
#ifndef TRILAB_LAYOUT_BVH4
#define TRILAB_LAYOUT_BVH4

#define LAYOUT_STACK_SIZE BVH4_STACK_SIZE
#define LAYOUT_WIDTH 4u
#define LAYOUT_NODE_TEXELS 8u

// Field f (0..7) of child `ch`: texel f, component ch & 3.
uint layout_field_texel(uint f, uint ch) {
    return f;
}

#include "wide.glsl"
#include "stack.glsl"

bool layout_visit(BoxRay b, float tmax, uint node, out uint next) {
    WideQuad q = wide_load(node, 0u);
    uint hits = 0u;
    uint e0, e1, e2, e3;
    float t0 = wide_test(b, q, 0u, tmax, NO_HIT, hits, e0);
    float t1 = wide_test(b, q, 1u, tmax, NO_HIT, hits, e1);
    float t2 = wide_test(b, q, 2u, tmax, NO_HIT, hits, e2);
    float t3 = wide_test(b, q, 3u, tmax, NO_HIT, hits, e3);
    WIDE4_ORDER_AND_PUSH(next)
    return hits > 0u;
}

#endif
