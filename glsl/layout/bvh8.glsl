// The bvh8 layout (the `*_bvh8` variants: `// trilab:layouts` in the kernels): its node format and
// its step, as every layout gives them to the traversals (layout_interface.glsl). Host side:
// src/encoding/layout/bvh8.rs.
//
// Nodes are src/bvh/wide/'s `Bvh8Node` (256 bytes, structure of arrays), bound at
// BINDING_NODES in place of the binary nodes: 16 texels per node, two per field (children 0-3,
// then 4-7), so node i's field f is texels 16i + 2f and 16i + 2f + 1, fields in the order
// min_x, min_y, min_z, max_x, max_y, max_z (f32 bits), child, count. A child with count 0 is a
// node index; count > 0 is a leaf of `count` units from `child`; child == EMPTY_CHILD marks an
// empty slot, and empty slots come last (so a node of at most four children never loads the
// second texel of a field). Node 0 is the root; its box is the union of its children's.
//
// Per step (one wide node, layout_visit): the occupied children's boxes are slab-tested, each with its entry
// distance (+FLT_MAX when missed); when more than one is hit, the eight (t, entry) pairs are
// sorted near to far by a 19-comparator network (optimal for 8 inputs: Knuth, TAOCP vol. 3,
// 5.3.4), all hit children but the nearest are pushed farthest first with their entry
// distance, and the nearest is visited next. A popped entry beyond the closest hit so far is
// skipped (as WideBvh::trace, the CPU model).
//
// Stack: BVH8_STACK_SIZE entries (shared.glsl; WideBvh::stack_bound).
#ifndef TRILAB_LAYOUT_BVH8
#define TRILAB_LAYOUT_BVH8

#define LAYOUT_STACK_SIZE BVH8_STACK_SIZE
#define LAYOUT_WIDTH 8u
#define LAYOUT_NODE_TEXELS 16u

// Field f (0..7) of child `ch`: texel 2f for children 0-3, 2f + 1 for 4-7 (component ch & 3;
// ch >= 8 stays inside the node).
uint layout_field_texel(uint f, uint ch) {
    return 2u * f + ((ch >> 2u) & 1u);
}

#include "wide.glsl"
#include "stack.glsl"

// +FLT_MAX: beyond every entry distance, so misses sort after every hit.
const float BVH8_MISS = 3.40282347e38;

// Comparator: smaller entry distance first.
#define BVH8_SORT(a, b) WIDE_SWAP_IF_LESS(b, a)

// Pushes hit child `i` of the sorted eight (hits beyond the nearest, farthest first).
#define BVH8_PUSH(i)                                                                           \
    if (hits > uint(i)) {                                                                      \
        stack_push(e##i, t##i);                                                                \
    }

bool layout_visit(BoxRay b, float tmax, uint node, out uint next) {
    WideQuad q = wide_load(node, 0u);
    bool more = q.kid.w != EMPTY_CHILD;
    uint hits = 0u;
    uint e0, e1, e2, e3, e4, e5, e6, e7;
    float t0 = wide_test(b, q, 0u, tmax, BVH8_MISS, hits, e0);
    float t1 = wide_test(b, q, 1u, tmax, BVH8_MISS, hits, e1);
    float t2 = wide_test(b, q, 2u, tmax, BVH8_MISS, hits, e2);
    float t3 = wide_test(b, q, 3u, tmax, BVH8_MISS, hits, e3);
    float t4 = BVH8_MISS;
    float t5 = BVH8_MISS;
    float t6 = BVH8_MISS;
    float t7 = BVH8_MISS;
    e4 = 0u;
    e5 = 0u;
    e6 = 0u;
    e7 = 0u;
    if (more) {
        // The second texel of each field only for a node of more than four children.
        q = wide_load(node, 1u);
        t4 = wide_test(b, q, 0u, tmax, BVH8_MISS, hits, e4);
        t5 = wide_test(b, q, 1u, tmax, BVH8_MISS, hits, e5);
        t6 = wide_test(b, q, 2u, tmax, BVH8_MISS, hits, e6);
        t7 = wide_test(b, q, 3u, tmax, BVH8_MISS, hits, e7);
    }
    next = 0u;
    if (hits > 1u) {
        BVH8_SORT(0, 2) BVH8_SORT(1, 3) BVH8_SORT(4, 6) BVH8_SORT(5, 7)
        BVH8_SORT(0, 4) BVH8_SORT(1, 5) BVH8_SORT(2, 6) BVH8_SORT(3, 7)
        BVH8_SORT(0, 1) BVH8_SORT(2, 3) BVH8_SORT(4, 5) BVH8_SORT(6, 7)
        BVH8_SORT(2, 4) BVH8_SORT(3, 5)
        BVH8_SORT(1, 4) BVH8_SORT(3, 6)
        BVH8_SORT(1, 2) BVH8_SORT(3, 4) BVH8_SORT(5, 6)
        BVH8_PUSH(7) BVH8_PUSH(6) BVH8_PUSH(5) BVH8_PUSH(4)
        BVH8_PUSH(3) BVH8_PUSH(2) BVH8_PUSH(1)
        next = e0;
    } else if (hits == 1u) {
        // One hit: bring it to slot 0 (a scan, no sort needed for one).
        BVH8_SORT(0, 1) BVH8_SORT(0, 2) BVH8_SORT(0, 3) BVH8_SORT(0, 4)
        BVH8_SORT(0, 5) BVH8_SORT(0, 6) BVH8_SORT(0, 7)
        next = e0;
    }
    return hits > 0u;
}

#endif
