// The bvh4 layout's traversal (the `*_bvh4` variants: `// trilab:layouts` in raycast.comp and
// pathtrace.comp). Included by traverse.glsl in place of the binary trace(); the leaf loop
// (intersect_leaf), the box test (HIT_BOX, conservative for watertight and Plücker) and the packed stack
// entries (LEAF_ENTRY, shared.glsl) are traverse.glsl's. Host side: src/encoding/layout/bvh4.rs.
//
// Nodes are src/bvh/wide.rs's `Bvh4Node` (128 bytes, structure of arrays), bound at
// BINDING_NODES in place of the binary nodes: 8 texels per node, one per field, so node i is
// texels 8i .. 8i + 7: min_x, min_y, min_z, max_x, max_y, max_z (the four children's box planes,
// f32 bits), child, count. A child with count 0 is a node index; count > 0 is a leaf of `count`
// units from `child` (the encoding's units, as in the binary tree); child == 0xFFFFFFFF marks an
// empty slot, and empty slots come last. Node 0 is the root; the root box is not stored, so the
// traversal starts at node 0 and tests its children (the union of the root's child boxes is the
// root box; the conservative test takes it from there).
//
// Per step (one wide node): the four texels of box planes are loaded, the occupied children's
// boxes are slab-tested with the entry distance of each, the hit children are sorted far to near
// (a 5-comparator network over four (t, entry) pairs, misses at -FLT_MAX), all but the nearest are
// pushed with their entry distance, and the nearest is visited next. A popped entry whose entry
// distance is beyond the closest hit so far is skipped (as WideBvh::trace, the CPU model).
//
// hit_box swaps min and max per axis, so an empty slot's inverted box (+inf, -inf) would be hit:
// the slot's child word is checked instead (empty slots are never tested).
//
// Stack: BVH4_STACK_SIZE entries (shared.glsl). The host refuses a tree whose
// WideBvh::stack_bound exceeds it before anything is uploaded (pipeline), so the kernel needs no
// check per push.
#ifndef TRILAB_LAYOUT_BVH4
#define TRILAB_LAYOUT_BVH4

#include "wide.glsl"

// -FLT_MAX: below every entry distance (tnear >= the ray's tmin), so misses sort after every hit.
const float NO_HIT = -3.40282347e38;

// Sorting-network comparator: larger entry distance first (the far child is pushed first).
#define BVH4_SORT(a, b)                                                                        \
    if (t##a < t##b) {                                                                         \
        float ts = t##a;                                                                       \
        t##a = t##b;                                                                           \
        t##b = ts;                                                                             \
        uint es = e##a;                                                                        \
        e##a = e##b;                                                                           \
        e##b = es;                                                                             \
    }

// Slot `k` (x, y, z, w) of the node: its entry distance in t<i> (NO_HIT when missed or empty)
// and its packed entry in e<i>.
#define BVH4_TEST(i, k)                                                                        \
    t##i = NO_HIT;                                                                             \
    e##i = 0u;                                                                                 \
    if (kid.k != EMPTY_CHILD) {                                                              \
        COUNT_BOXES(1u);                                                                       \
        float tn;                                                                              \
        if (HIT_BOX(vec3(mnx.k, mny.k, mnz.k), vec3(mxx.k, mxy.k, mxz.k), h.t, tn)) {          \
            t##i = tn;                                                                         \
            e##i = LEAF_ENTRY(kid.k, cnt.k);                                                   \
            hits += 1u;                                                                        \
        }                                                                                      \
    }

// Traces `r` through the 4-wide BVH, updating `h` (h.t must start at the ray's tmax).
void trace(TraceRay r, inout HitState h, bool any_hit) {
#ifdef INTERSECTOR_RAY_SETUP
    INTERSECTOR_RAY_SETUP(r, h);
#endif
#ifdef CONSERVATIVE_TRAVERSAL
    // The root box: the union of the root's child boxes (an empty slot's +inf/-inf changes
    // nothing in a min/max union).
    vec4 rmnx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 0u));
    vec4 rmny = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 1u));
    vec4 rmnz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 2u));
    vec4 rmxx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 3u));
    vec4 rmxy = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 4u));
    vec4 rmxz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 5u));
    vec3 root_min = vec3(min(min(rmnx.x, rmnx.y), min(rmnx.z, rmnx.w)), min(min(rmny.x, rmny.y), min(rmny.z, rmny.w)),
                         min(min(rmnz.x, rmnz.y), min(rmnz.z, rmnz.w)));
    vec3 root_max = vec3(max(max(rmxx.x, rmxx.y), max(rmxx.z, rmxx.w)), max(max(rmxy.x, rmxy.y), max(rmxy.z, rmxy.w)),
                         max(max(rmxz.x, rmxz.y), max(rmxz.z, rmxz.w)));
    ConservativeRay cons = make_conservative_ray(r, root_min, root_max);
#endif
    uint stack[BVH4_STACK_SIZE];
    float stack_t[BVH4_STACK_SIZE];
    uint sp = 0u;
    uint current = 0u; // node 0, an inner node
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        if (count > 0u) {
            TEST_LEAF_OR_RETURN();
        } else {
            COUNT_INNER();
            uint base = 8u * first;
            vec4 mnx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base));
            vec4 mny = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 1u));
            vec4 mnz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 2u));
            vec4 mxx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 3u));
            vec4 mxy = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 4u));
            vec4 mxz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 5u));
            uvec4 kid = SCENE_TEXEL(scene_nodes, base + 6u);
            uvec4 cnt = SCENE_TEXEL(scene_nodes, base + 7u);
            uint hits = 0u;
            float t0, t1, t2, t3;
            uint e0, e1, e2, e3;
            BVH4_TEST(0, x)
            BVH4_TEST(1, y)
            BVH4_TEST(2, z)
            BVH4_TEST(3, w)
            if (hits > 0u) {
                // Far to near; the misses (NO_HIT) end up last.
                BVH4_SORT(0, 1)
                BVH4_SORT(2, 3)
                BVH4_SORT(0, 2)
                BVH4_SORT(1, 3)
                BVH4_SORT(1, 2)
                if (hits == 1u) {
                    current = e0;
                } else {
                    stack[sp] = e0;
                    stack_t[sp] = t0;
                    sp += 1u;
                    if (hits == 2u) {
                        current = e1;
                    } else {
                        stack[sp] = e1;
                        stack_t[sp] = t1;
                        sp += 1u;
                        if (hits == 3u) {
                            current = e2;
                        } else {
                            stack[sp] = e2;
                            stack_t[sp] = t2;
                            sp += 1u;
                            current = e3;
                        }
                    }
                }
                continue;
            }
        }
        POP_NEAREST_OR_RETURN();
    }
}

#endif
