// The bvh8 layout's traversal (the `*_bvh8` variants: `// trilab:layouts` in raycast.comp and
// pathtrace.comp). Included by traverse.glsl in place of the binary trace(); the leaf loop
// (intersect_leaf), the box test (HIT_BOX, conservative for watertight) and the packed entries
// (LEAF_ENTRY, shared.glsl) are traverse.glsl's. Host side: src/encoding/layout/bvh8.rs.
//
// Nodes are src/bvh/wide.rs's `Bvh8Node` (256 bytes, structure of arrays), bound at
// BINDING_NODES in place of the binary nodes: 16 texels per node, two per field (children 0-3,
// then 4-7), so node i's field f is texels 16i + 2f and 16i + 2f + 1, fields in the order
// min_x, min_y, min_z, max_x, max_y, max_z (f32 bits), child, count. A child with count 0 is a
// node index; count > 0 is a leaf of `count` units from `child`; child == EMPTY_CHILD marks an
// empty slot, and empty slots come last (so a node of at most four children never loads the
// second texel of a field). Node 0 is the root; its box is the union of its children's.
//
// Per step (one wide node): the occupied children's boxes are slab-tested, each with its entry
// distance (+FLT_MAX when missed); when more than one is hit, the eight (t, entry) pairs are
// sorted near to far by a 19-comparator network (optimal for 8 inputs: Knuth, TAOCP vol. 3,
// 5.3.4), all hit children but the nearest are pushed farthest first with their entry
// distance, and the nearest is visited next. A popped entry beyond the closest hit so far is
// skipped (as WideBvh::trace, the CPU model).
//
// Stack: BVH8_STACK_SIZE entries (shared.glsl). The host refuses a tree whose stack bound
// exceeds it before anything is uploaded (pipeline), so the kernel needs no check per push.
#ifndef TRILAB_LAYOUT_BVH8
#define TRILAB_LAYOUT_BVH8

#include "wide.glsl"

// +FLT_MAX: beyond every entry distance, so misses sort after every hit.
const float BVH8_MISS = 3.40282347e38;

// Comparator: smaller entry distance first.
#define BVH8_SORT(a, b)                                                                        \
    if (t##b < t##a) {                                                                         \
        float ts = t##a;                                                                       \
        t##a = t##b;                                                                           \
        t##b = ts;                                                                             \
        uint es = e##a;                                                                        \
        e##a = e##b;                                                                           \
        e##b = es;                                                                             \
    }

// Child `i`, lane `k` (x, y, z, w) of the half loaded into mnx .. cnt.
#define BVH8_TEST(i, k)                                                                        \
    t##i = BVH8_MISS;                                                                          \
    e##i = 0u;                                                                                 \
    if (kid.k != EMPTY_CHILD) {                                                                \
        COUNT_BOXES(1u);                                                                       \
        float tn;                                                                              \
        if (HIT_BOX(vec3(mnx.k, mny.k, mnz.k), vec3(mxx.k, mxy.k, mxz.k), h.t, tn)) {          \
            t##i = tn;                                                                         \
            e##i = LEAF_ENTRY(kid.k, cnt.k);                                                       \
            hits += 1u;                                                                        \
        }                                                                                      \
    }

// Loads half `half_` (0: children 0-3, 1: 4-7) of node texels from `base`.
#define BVH8_LOAD(half_)                                                                       \
    mnx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + half_));                             \
    mny = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 2u + half_));                        \
    mnz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 4u + half_));                        \
    mxx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 6u + half_));                        \
    mxy = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 8u + half_));                        \
    mxz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 10u + half_));                       \
    kid = SCENE_TEXEL(scene_nodes, base + 12u + half_);                                        \
    cnt = SCENE_TEXEL(scene_nodes, base + 14u + half_)

#define BVH8_PUSH(i)                                                                           \
    if (hits > uint(i)) {                                                                      \
        stack[sp] = e##i;                                                                      \
        stack_t[sp] = t##i;                                                                    \
        sp += 1u;                                                                              \
    }

// Traces `r` through the 8-wide BVH, updating `h` (h.t must start at the ray's tmax).
void trace(TraceRay r, inout HitState h, bool any_hit) {
#ifdef INTERSECTOR_RAY_SETUP
    INTERSECTOR_RAY_SETUP(r, h);
#endif
#ifdef CONSERVATIVE_TRAVERSAL
    // The root box: the union of the root's child boxes (an empty slot's +inf/-inf changes
    // nothing in a min/max union).
    vec3 root_min = vec3(3.40282347e38);
    vec3 root_max = vec3(-3.40282347e38);
    for (uint q = 0u; q < 2u; ++q) {
        vec4 a = uintBitsToFloat(SCENE_TEXEL(scene_nodes, q));
        vec4 b = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 2u + q));
        vec4 c = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 4u + q));
        vec4 d = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 6u + q));
        vec4 e = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 8u + q));
        vec4 f = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 10u + q));
        root_min = min(root_min, vec3(min(min(a.x, a.y), min(a.z, a.w)), min(min(b.x, b.y), min(b.z, b.w)),
                                      min(min(c.x, c.y), min(c.z, c.w))));
        root_max = max(root_max, vec3(max(max(d.x, d.y), max(d.z, d.w)), max(max(e.x, e.y), max(e.z, e.w)),
                                      max(max(f.x, f.y), max(f.z, f.w))));
    }
    ConservativeRay cons = make_conservative_ray(r, root_min, root_max);
#endif
    uint stack[BVH8_STACK_SIZE];
    float stack_t[BVH8_STACK_SIZE];
    uint sp = 0u;
    uint current = 0u; // node 0, an inner node
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        if (count > 0u) {
            TEST_LEAF_OR_RETURN();
        } else {
            COUNT_INNER();
            uint base = 16u * first;
            vec4 mnx, mny, mnz, mxx, mxy, mxz;
            uvec4 kid, cnt;
            uint hits = 0u;
            float t0, t1, t2, t3, t4, t5, t6, t7;
            uint e0, e1, e2, e3, e4, e5, e6, e7;
            BVH8_LOAD(0u);
            bool more = kid.w != EMPTY_CHILD;
            BVH8_TEST(0, x)
            BVH8_TEST(1, y)
            BVH8_TEST(2, z)
            BVH8_TEST(3, w)
            t4 = BVH8_MISS;
            t5 = BVH8_MISS;
            t6 = BVH8_MISS;
            t7 = BVH8_MISS;
            e4 = 0u;
            e5 = 0u;
            e6 = 0u;
            e7 = 0u;
            if (more) {
                BVH8_LOAD(1u);
                BVH8_TEST(4, x)
                BVH8_TEST(5, y)
                BVH8_TEST(6, z)
                BVH8_TEST(7, w)
            }
            if (hits > 0u) {
                if (hits > 1u) {
                    BVH8_SORT(0, 2) BVH8_SORT(1, 3) BVH8_SORT(4, 6) BVH8_SORT(5, 7)
                    BVH8_SORT(0, 4) BVH8_SORT(1, 5) BVH8_SORT(2, 6) BVH8_SORT(3, 7)
                    BVH8_SORT(0, 1) BVH8_SORT(2, 3) BVH8_SORT(4, 5) BVH8_SORT(6, 7)
                    BVH8_SORT(2, 4) BVH8_SORT(3, 5)
                    BVH8_SORT(1, 4) BVH8_SORT(3, 6)
                    BVH8_SORT(1, 2) BVH8_SORT(3, 4) BVH8_SORT(5, 6)
                    BVH8_PUSH(7) BVH8_PUSH(6) BVH8_PUSH(5) BVH8_PUSH(4)
                    BVH8_PUSH(3) BVH8_PUSH(2) BVH8_PUSH(1)
                } else {
                    // One hit: bring it to slot 0 (a scan, no sort needed for one).
                    BVH8_SORT(0, 1) BVH8_SORT(0, 2) BVH8_SORT(0, 3) BVH8_SORT(0, 4)
                    BVH8_SORT(0, 5) BVH8_SORT(0, 6) BVH8_SORT(0, 7)
                }
                current = e0;
                continue;
            }
        }
        POP_NEAREST_OR_RETURN();
    }
}

#endif
