// The qbvh4 layout (the `*_qbvh4` variants): bvh4's tree with each node's four child boxes
// quantized to 8 bits per plane on a per-node power-of-two grid (cwbvh's quantization at width
// 4), and bvh4's step. Host side: src/encoding/layout/qbvh4.rs, src/bvh/qbvh4.rs (the format,
// the CPU model: bvh4's walk over the decoded boxes).
//
// Nodes are `QNode4` (64 bytes, one cache line), bound at BINDING_NODES: 4 texels per node, so
// node i is texels 4i .. 4i + 3:
//   texel 0: p.x, p.y, p.z (the grid's origin, f32 bits), e.x | e.y << 8 | e.z << 16 (biased
//            exponents: the scale per axis is uintBitsToFloat(e << 23));
//   texel 1: q_lo_x, q_lo_y, q_lo_z, q_hi_x; texel 2: q_hi_y, q_hi_z, 0, 0 (per plane one word of
//            the four children's bytes, child 0 in the lowest byte);
//   texel 3: the four children's packed entries, LEAF_ENTRY(first, count) (count 0: an inner
//            node's index), EMPTY_CHILD for an empty slot (empty slots come last).
// Child k's box on axis a decodes as p[a] + float(q) * scale[a] in f32: the only arithmetic the
// host checked its outward rounding in (bvh::quantize), so the decoded box contains the child's
// true box and a ray visits what it visits on bvh4 (and perhaps more). Node 0 is the root; its
// box is not stored.
//
// Per step (layout_visit): the four texels are loaded, the four boxes decoded, the occupied
// children slab-tested, and bvh4's end of step (wide_step.glsl: far to near, all but the nearest
// pushed). For the cooperative kernel, lane k decodes child k (layout_child).
//
// Stack: BVH4_STACK_SIZE entries (the tree is bvh4's; Qbvh4::stack_bound).
#ifndef TRILAB_LAYOUT_QBVH4
#define TRILAB_LAYOUT_QBVH4

#include "layout_interface.glsl"
#include "wide_step.glsl"

#define LAYOUT_STACK_SIZE BVH4_STACK_SIZE
#define LAYOUT_WIDTH 4u
#define QBVH4_NODE_TEXELS 4u

#include "stack.glsl"

// A node's four decoded boxes and entries.
struct QNode4 {
    vec4 mnx, mny, mnz, mxx, mxy, mxz;
    uvec4 entry;
};

// The four children's planes of one byte-plane word, as floats.
vec4 q4_bytes(uint w) {
    return vec4((uvec4(w) >> uvec4(0u, 8u, 16u, 24u)) & 0xFFu);
}

QNode4 q4_load(uint node) {
    uint base = QBVH4_NODE_TEXELS * node;
    uvec4 g = SCENE_TEXEL(scene_nodes, base);
    uvec4 lo = SCENE_TEXEL(scene_nodes, base + 1u);
    uvec4 hi = SCENE_TEXEL(scene_nodes, base + 2u);
    QNode4 n;
    n.entry = SCENE_TEXEL(scene_nodes, base + 3u);
    vec3 p = uintBitsToFloat(g.xyz);
    vec3 scale = uintBitsToFloat(((uvec3(g.w) >> uvec3(0u, 8u, 16u)) & 0xFFu) << 23u);
    n.mnx = p.x + q4_bytes(lo.x) * scale.x;
    n.mny = p.y + q4_bytes(lo.y) * scale.y;
    n.mnz = p.z + q4_bytes(lo.z) * scale.z;
    n.mxx = p.x + q4_bytes(lo.w) * scale.x;
    n.mxy = p.y + q4_bytes(hi.x) * scale.y;
    n.mxz = p.z + q4_bytes(hi.y) * scale.z;
    return n;
}

// Child `k` (0..3) against [tmin, tmax]: its entry distance and its entry in `entry` (`hits`
// counted up) when hit, else `miss` and 0. Empty slots are never tested (their planes are 0).
float q4_test(BoxRay b, QNode4 n, uint k, float tmax, float miss, inout uint hits, out uint entry) {
    WIDE_TEST_CHILD(n.entry[k] != EMPTY_CHILD, vec3(n.mnx[k], n.mny[k], n.mnz[k]), vec3(n.mxx[k], n.mxy[k], n.mxz[k]),
                    n.entry[k])
}

// Node 0, an inner node; the tree's box (only for the conservative test) is the union of its
// occupied children's decoded boxes.
LayoutRoot layout_root() {
    LayoutRoot root;
    root.entry = 0u;
    root.bmin = vec3(3.40282347e38);
    root.bmax = vec3(-3.40282347e38);
#ifdef CONSERVATIVE_TRAVERSAL
    QNode4 n = q4_load(0u);
    for (uint k = 0u; k < 4u; ++k) {
        if (n.entry[k] != EMPTY_CHILD) {
            root.bmin = min(root.bmin, vec3(n.mnx[k], n.mny[k], n.mnz[k]));
            root.bmax = max(root.bmax, vec3(n.mxx[k], n.mxy[k], n.mxz[k]));
        }
    }
#endif
    return root;
}

bool layout_visit(BoxRay b, float tmax, uint node, out uint next) {
    QNode4 n = q4_load(node);
    uint hits = 0u;
    uint e0, e1, e2, e3;
    float t0 = q4_test(b, n, 0u, tmax, NO_HIT, hits, e0);
    float t1 = q4_test(b, n, 1u, tmax, NO_HIT, hits, e1);
    float t2 = q4_test(b, n, 2u, tmax, NO_HIT, hits, e2);
    float t3 = q4_test(b, n, 3u, tmax, NO_HIT, hits, e3);
    WIDE4_ORDER_AND_PUSH(next)
    return hits > 0u;
}

// Child `ch` of node `node` for raycast_coop.comp's lane `ch` (ch >= 4: a copy of child 3,
// marked unoccupied).
NodeChild layout_child(uint node, uint ch) {
    QNode4 n = q4_load(node);
    uint k = min(ch, 3u);
    uint e = n.entry[k];
    return NodeChild(vec3(n.mnx[k], n.mny[k], n.mnz[k]), vec3(n.mxx[k], n.mxy[k], n.mxz[k]), e,
                     ch < 4u && e != EMPTY_CHILD);
}

#endif
