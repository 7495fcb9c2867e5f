// Stack-based "while-if" BVH traversal (Shumskiy & Parshin, appendix 8.3; after Aila & Laine
// 2009): one node per loop iteration, both children's boxes tested, the nearer child visited
// first and the farther pushed. Needs `intersect_leaf` from the intersector, included before.
#ifndef TRILAB_TRAVERSE
#define TRILAB_TRAVERSE

#include "types.glsl"

// |dir| components below this are replaced by it (with the component's sign) before 1/dir,
// so axis-parallel rays give large finite slopes instead of inf * 0 = NaN in the slab test.
const float TINY_DIR = 1.0e-30;
// pbrt-v3/v4's conservative slab test: scale the far distance up by 1 + 2*gamma(3) so that
// rounding never culls a box the ray grazes (Pharr, Jakob & Humphreys, PBR 3rd ed., 3.9.2).
const float SLAB_FAR_SCALE = 1.0000003576;

#ifdef TRAVERSAL_STATS
#ifdef ANY_HIT
#error "TRAVERSAL_STATS counts closest-hit traversal; an any-hit leaf stops at its first hit"
#endif
#ifndef PRIM_TRIANGLES
#error "TRAVERSAL_STATS needs the intersector's PRIM_TRIANGLES"
#endif
// The work trace() did for this invocation's ray (16 bytes; Rust twin gpu::TraversalCounts).
// A leaf's `count` is its triangles (padding slots are not counted in it), and the closest-hit
// intersectors test every one, so:
//   inner:     loop iterations at an inner node (each loads and slab-tests both children);
//   leaves:    loop iterations at a leaf (each calls intersect_leaf once);
//   triangles: sum of `count` over the leaves visited: real triangles tested;
//   slots:     triangle slots evaluated: `count` rounded up to a whole primitive
//              (PRIM_TRIANGLES: 4 for the Quad intersectors, whose padding lanes are computed
//              too; equal to `triangles` for the one-triangle intersectors).
// A ray that misses the root box does no work (all zero).
struct TraversalCounts {
    uint inner;
    uint leaves;
    uint triangles;
    uint slots;
};
TraversalCounts trav_counts = TraversalCounts(0u, 0u, 0u, 0u);
#define COUNT_INNER() trav_counts.inner += 1u
#define COUNT_LEAF(count)                                                                      \
    trav_counts.leaves += 1u;                                                                  \
    trav_counts.triangles += (count);                                                          \
    trav_counts.slots += ((count) + PRIM_TRIANGLES - 1u) / PRIM_TRIANGLES * PRIM_TRIANGLES
#else
#define COUNT_INNER()
#define COUNT_LEAF(count)
#endif

TraceRay make_trace_ray(Ray r) {
    TraceRay tr;
    tr.origin = r.origin;
    tr.dir = r.dir;
    vec3 s = mix(vec3(1.0), vec3(-1.0), lessThan(r.dir, vec3(0.0)));
    vec3 safe = s * max(abs(r.dir), vec3(TINY_DIR));
    tr.inv_dir = 1.0 / safe;
    tr.tmin = r.tmin;
    return tr;
}

// Slab test against [tmin, tfar]; returns the entry distance in `tnear`.
bool hit_box(TraceRay r, vec3 bmin, vec3 bmax, float tfar, out float tnear) {
    vec3 t0 = (bmin - r.origin) * r.inv_dir;
    vec3 t1 = (bmax - r.origin) * r.inv_dir;
    vec3 lo = min(t0, t1);
    vec3 hi = max(t0, t1);
    tnear = max(max(lo.x, lo.y), max(lo.z, r.tmin));
    float tf = min(min(hi.x, hi.y), min(hi.z, tfar)) * SLAB_FAR_SCALE;
    return tnear <= tf;
}

// What traversal keeps of a node once its box has been tested: (left_or_first << 5) | count.
// The stack holds these, so popping a node costs no memory access (the paper's stack holds node
// indices and re-reads the node). count <= 16 (MAX_LEAF_SIZE) fits in 5 bits; the host checks
// that every left_or_first fits in 27 (EncodedScene::check_limits).
uint pack_node(BvhNode n) {
    return (n.left_or_first << 5u) | n.count;
}

// Traces `r` through the BVH, updating `h` (h.t must start at the ray's tmax).
// With `any_hit` it returns at the first accepted intersection (occlusion). Pass a constant:
// every call site is inlined and specialised by the compiler.
void trace(TraceRay r, inout HitState h, bool any_hit) {
    float troot;
    BvhNode root = load_node(0u);
    if (!hit_box(r, root.bmin, root.bmax, h.t, troot)) {
        return;
    }
    uint current = pack_node(root);
    uint stack[STACK_SIZE];
    uint sp = 0u;
    while (true) {
        uint count = current & 31u;
        uint first = current >> 5u;
        if (count > 0u) {
            // Leaf.
            COUNT_LEAF(count);
            bool found = intersect_leaf(r, first, count, h, any_hit);
            if (any_hit && found) {
                return;
            }
            if (sp == 0u) {
                return;
            }
            current = stack[--sp];
        } else {
            COUNT_INNER();
            BvhNode l = load_node(first);
            BvhNode rr = load_node(first + 1u);
            float tl, tr;
            bool want_l = hit_box(r, l.bmin, l.bmax, h.t, tl);
            bool want_r = hit_box(r, rr.bmin, rr.bmax, h.t, tr);
            if (want_l && want_r) {
                bool left_first = tl <= tr;
                stack[sp++] = pack_node(left_first ? rr : l);
                current = pack_node(left_first ? l : rr);
            } else if (want_l || want_r) {
                current = pack_node(want_l ? l : rr);
            } else {
                if (sp == 0u) {
                    return;
                }
                current = stack[--sp];
            }
        }
    }
}

#endif
