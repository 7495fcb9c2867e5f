// Stack-based "while-if" BVH traversal (Shumskiy & Parshin, appendix 8.3; after Aila & Laine
// 2009): one node per loop iteration, both children's boxes tested, the nearer child visited
// first and the farther pushed with its box's entry distance; a popped node whose entry distance
// is beyond the closest hit so far is skipped without being visited (as the wide layouts do;
// measured 1.04-1.09x on the bunny, results/lavapipe/traversals/bvh2-cull-ab.md); and the leaf
// loop, written once for every intersector.
//
// The intersector, included before this file, provides the primitive test only:
// - PRIM_TRIANGLES: triangle slots per primitive, 1 or 4 (a plain integer literal);
// - with PRIM_TRIANGLES 1: bool intersect_triangle(TraceRay r, uint slot, float tmax,
//   out float t, out float u, out float v): whether the triangle in `slot` is hit at
//   r.tmin <= t <= tmax (u, v: barycentric weights of vertices 1 and 2); the intersector
//   decides where in its arithmetic to compare t, so it can reject early (early returns are
//   fine: on lavapipe this form measured within 1.5 % of the per-intersector loops it replaced,
//   and faster than single-exit or `inout` variants, results/lavapipe/refactor-ab.md);
// - with PRIM_TRIANGLES 4: bvec4 intersect_quad(TraceRay r, uint quad, out vec4 t, out vec4 u,
//   out vec4 v): per lane (slot 4 quad + lane), whether it is hit at t >= r.tmin; the leaf loop
//   compares each lane with the closest hit so far, in lane order;
// - optionally INTERSECTOR_RAY_SETUP(r, h): run once per ray at the start of trace(), before any
//   leaf (watertight.glsl: its shear; f64.glsl: its bound in double), and
//   CONSERVATIVE_TRAVERSAL: the conservative box test below (watertight.glsl, pluecker.glsl).
#ifndef TRILAB_TRAVERSE
#define TRILAB_TRAVERSE

#include "types.glsl"

// |dir| components below this are replaced by it (with the component's sign) before 1/dir,
// so axis-parallel rays give large finite slopes instead of inf * 0 = NaN in the slab test.
// It is the smallest normal f32 (2^-126), whose reciprocal 2^126 ~ 8.5e37 is still finite: a
// zero component's slab then ends at |b - o| * 2^126 (inf past |b - o| = 4), not at
// |b - o| * 1e30, which lost the hits of an axis-parallel ray beyond t ~ 1e30 on a small box
// (issue 24: a triangle at x = 2^100). Rust's twins: traversal.rs, bvh/wide.rs.
const float TINY_DIR = 1.17549435e-38;
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
//              too; equal to `triangles` for the one-triangle intersectors);
//   boxes:     slab tests: the root's and both children's per inner iteration here; in a wide
//              layout, each occupied child slot of a visited node (glsl/layout/).
// A ray that misses the root box does no other work (boxes 1, the rest zero).
// With a wide layout, `inner` counts wide nodes visited.
struct TraversalCounts {
    uint inner;
    uint leaves;
    uint triangles;
    uint slots;
    uint boxes;
};
TraversalCounts trav_counts = TraversalCounts(0u, 0u, 0u, 0u, 0u);
#define COUNT_INNER() trav_counts.inner += 1u
#define COUNT_BOXES(n) trav_counts.boxes += (n)
#define COUNT_LEAF(count)                                                                      \
    trav_counts.leaves += 1u;                                                                  \
    trav_counts.triangles += (count);                                                          \
    trav_counts.slots += ((count) + uint(PRIM_TRIANGLES) - 1u) / uint(PRIM_TRIANGLES) * uint(PRIM_TRIANGLES)
#else
#define COUNT_INNER()
#define COUNT_LEAF(count)
#define COUNT_BOXES(n)
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

#ifdef CONSERVATIVE_TRAVERSAL
// Conservative traversal for an intersector that accepts triangles the exact ray misses by a
// rounding error (watertight.glsl and pluecker.glsl define CONSERVATIVE_TRAVERSAL; every other
// kernel compiles the plain slab test above, unchanged). After Woop, Benthin & Wald, "Watertight Ray/Triangle
// Intersection", JCGT 2(1), 2013, sec. 5, with the rounding of the slab test itself as in Ize,
// "Robust BVH Ray Traversal", JCGT 2(2), 2013.
//
// Two errors are covered, both with per-ray constants, so the per-box test costs what the plain
// one does (two subtractions and two multiplications per axis, min/max), minus the far scaling:
// 1. The triangle test rounds the sheared vertex coordinates: with u = 2^-24, |Sx|, |Sy| <= 1
//    and a division within 2.5 ulp (Vulkan's precision for x / y; the paper assumes 0.5), a
//    sheared coordinate is off by at most about 2u |V - O|[kx] + 8u |V - O|[kz]. That is as if
//    the vertex moved along the world axes kx and ky, so the test can hit a triangle whose box
//    the exact ray misses by that much. The paper grows the box by this error in kx and ky,
//    bounding |V - O| by the scene box once per ray; here each axis k is grown by
//    err_k = CONS_EPS (d_k + max_j d_j), d_j = the largest |V - O|[j] over the root box, which
//    bounds the paper's term (max_j d_j >= d_kz) without knowing the intersector's kz, and uses
//    CONS_EPS = 16u, twice the bound above. Growing [bmin, bmax] to [bmin - err, bmax + err] is
//    the same as measuring bmin from O + err and bmax from O - err, whatever the direction's
//    sign, so the growth goes into two shifted origins (rounded outwards: `pad` below).
// 2. The slab distances (b - o) * (1/d) are rounded: the subtraction and the product within
//    0.5 ulp each, 1/d within 2.5 ulp (Vulkan), 1/d scaled below within 0.5 ulp: at most 8u
//    relative in all. The entry distance of an axis uses 1/d scaled down by (1 - 2^-20), its
//    exit distance 1/d scaled up by (1 + 2^-20) (2^-20 = 16u), chosen per axis by the sign of d
//    (bmin is the entry plane where d > 0, the exit plane where d < 0). Like the paper (and like
//    the plain test's far scaling) this is conservative for distances >= 0: rays start at
//    tmin >= 0, and a box behind the origin is not needed.
// Both only grow boxes, by about 1e-6 of the scene's extent: no result changes, a grazing box is
// visited now and then.
const float CONS_EPS = 9.5367431640625e-7; // 2^-20 = 16 * 2^-24
const float CONS_DOWN = 0.99999904632568359375; // 1 - 2^-20 (exact in f32)
const float CONS_UP = 1.00000095367431640625;   // 1 + 2^-20 (exact in f32)

struct ConservativeRay {
    vec3 org_lo;  // origin that box minima are measured from (O + err, rounded up)
    vec3 org_hi;  // origin that box maxima are measured from (O - err, rounded down)
    vec3 rdir_lo; // 1/d for the bmin planes: scaled down where bmin is the entry (d > 0)
    vec3 rdir_hi; // 1/d for the bmax planes: scaled down where bmax is the entry (d < 0)
    float tmin;
};

// Once per ray, from the root box (every vertex lies in it).
ConservativeRay make_conservative_ray(TraceRay r, vec3 root_min, vec3 root_max) {
    ConservativeRay c;
    precise vec3 dist = max(abs(r.origin - root_min), abs(r.origin - root_max));
    precise float dmax = max(max(dist.x, dist.y), dist.z);
    precise vec3 err = CONS_EPS * (dist + dmax);
    // O + pad rounds to at least O + err: the sum's rounding is below 2^-24 (|O| + pad).
    precise vec3 pad = err + (abs(r.origin) + err) * 2.384185791015625e-7; // 2^-22
    c.org_lo = r.origin + pad;
    c.org_hi = r.origin - pad;
    bvec3 pos = greaterThanEqual(r.inv_dir, vec3(0.0));
    precise vec3 down = r.inv_dir * CONS_DOWN;
    precise vec3 up = r.inv_dir * CONS_UP;
    c.rdir_lo = mix(up, down, pos);
    c.rdir_hi = mix(down, up, pos);
    c.tmin = r.tmin;
    return c;
}

bool hit_box_conservative(ConservativeRay c, vec3 bmin, vec3 bmax, float tfar, out float tnear) {
    precise vec3 t0 = (bmin - c.org_lo) * c.rdir_lo;
    precise vec3 t1 = (bmax - c.org_hi) * c.rdir_hi;
    vec3 lo = min(t0, t1);
    vec3 hi = max(t0, t1);
    tnear = max(max(lo.x, lo.y), max(lo.z, c.tmin));
    float tf = min(min(hi.x, hi.y), min(hi.z, tfar));
    return tnear <= tf;
}
#define HIT_BOX(bmin, bmax, tfar, tnear) hit_box_conservative(cons, bmin, bmax, tfar, tnear)
#else
#define HIT_BOX(bmin, bmax, tfar, tnear) hit_box(r, bmin, bmax, tfar, tnear)
#endif

// What traversal keeps of a node once its box has been tested: LEAF_ENTRY(left_or_first, count).
// The stack holds these, so popping a node costs no memory access (the paper's stack holds node
// indices and re-reads the node). count <= 16 (MAX_LEAF_SIZE) fits in 5 bits; the host checks
// that every left_or_first fits in 27 (EncodedScene::check_limits).
uint pack_node(BvhNode n) {
    return LEAF_ENTRY(n.left_or_first, n.count);
}

// Every stack loop's leaf step (trace() below, glsl/layout/bvh4.glsl, bvh8.glsl): the leaf
// (first, count) of `current` through the leaf loop; with `any_hit`, trace() returns at a hit.
#define TEST_LEAF_OR_RETURN()                                                                  \
    COUNT_LEAF(count);                                                                         \
    bool found = intersect_leaf(r, first, count, h, any_hit);                                  \
    if (any_hit && found) {                                                                    \
        return;                                                                                \
    }

// Every stack loop's pop (trace() below, glsl/layout/bvh4.glsl, bvh8.glsl): the nearest pushed
// entry whose box entry distance (stack_t) is not beyond the closest hit so far becomes
// `current`, the others are dropped unvisited; with none left, trace() returns.
#define POP_NEAREST_OR_RETURN()                                                                \
    while (true) {                                                                             \
        if (sp == 0u) {                                                                        \
            return;                                                                            \
        }                                                                                      \
        sp -= 1u;                                                                              \
        if (stack_t[sp] <= h.t) {                                                              \
            current = stack[sp];                                                               \
            break;                                                                             \
        }                                                                                      \
    }

#if PRIM_TRIANGLES == 1
// The leaf loop: tests the leaf's `count` triangle slots from `first` in order; a hit at
// tmin <= t <= h.t becomes the closest so far (so of two hits at the same t the later slot is
// kept). With `any_hit` it returns at the first. Returns whether anything was hit.
bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h, bool any_hit) {
    bool found = false;
    for (uint s = first; s < first + count; ++s) {
        float t, u, v;
        if (intersect_triangle(r, s, h.t, t, u, v)) {
            h.t = t;
            h.slot = s;
            h.u = u;
            h.v = v;
            found = true;
            if (any_hit) {
                return true;
            }
        }
    }
    return found;
}
#elif PRIM_TRIANGLES == 4
// Lane `c` (x, y, z or w; slot 4 p + k) of a quad's results becomes the closest hit so far if it
// is a hit at t <= h.t.
#define ACCEPT_LANE(c, k)                                                                      \
    if (hit.c && t.c <= h.t) {                                                                 \
        h.t = t.c;                                                                             \
        h.slot = 4u * p + k;                                                                   \
        h.u = u.c;                                                                             \
        h.v = v.c;                                                                             \
        found = true;                                                                          \
    }

// The leaf loop for four-triangle primitives: `first` and the primitives count quads (a leaf of
// `count` triangles has ceil(count / 4) quads, padding lanes never hit); lanes are accepted in
// order within a quad, and with `any_hit` it returns after the first quad with a hit.
bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h, bool any_hit) {
    bool found = false;
    uint end = first + (count + 3u) / 4u;
    for (uint p = first; p < end; ++p) {
        vec4 t, u, v;
        bvec4 hit = intersect_quad(r, p, t, u, v);
        ACCEPT_LANE(x, 0u)
        ACCEPT_LANE(y, 1u)
        ACCEPT_LANE(z, 2u)
        ACCEPT_LANE(w, 3u)
        if (any_hit && found) {
            return true;
        }
    }
    return found;
}
#else
#error "PRIM_TRIANGLES must be 1 or 4"
#endif

#ifdef WIDE_LAYOUT
// A wide layout's traversal (glsl/layout/<layout>.glsl) replaces the binary one below: the
// variants compiled per layout (`// trilab:layouts` in the kernel).
#include "layout.glsl"
#elif defined(WHILE_WHILE)
// While-while with leaf postponing (the `*_ww` variants; binary nodes only).
#include "while_while.glsl"
#else
// Traces `r` through the BVH, updating `h` (h.t must start at the ray's tmax).
// With `any_hit` it returns at the first accepted intersection (occlusion). Pass a constant:
// every call site is inlined and specialised by the compiler.
void trace(TraceRay r, inout HitState h, bool any_hit) {
#ifdef INTERSECTOR_RAY_SETUP
    // The intersector's per-ray precomputation (watertight.glsl: axes and shear), once per ray.
    INTERSECTOR_RAY_SETUP(r, h);
#endif
    float troot;
    BvhNode root = load_node(0u);
#ifdef CONSERVATIVE_TRAVERSAL
    ConservativeRay cons = make_conservative_ray(r, root.bmin, root.bmax);
#endif
    COUNT_BOXES(1u);
    if (!HIT_BOX(root.bmin, root.bmax, h.t, troot)) {
        return;
    }
    uint current = pack_node(root);
    uint stack[STACK_SIZE];
    float stack_t[STACK_SIZE];
    uint sp = 0u;
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        bool pop = true;
        if (count > 0u) {
            TEST_LEAF_OR_RETURN();
        } else {
            COUNT_INNER();
            COUNT_BOXES(2u);
            BvhNode l = load_node(first);
            BvhNode rr = load_node(first + 1u);
            float tl, tr;
            bool want_l = HIT_BOX(l.bmin, l.bmax, h.t, tl);
            bool want_r = HIT_BOX(rr.bmin, rr.bmax, h.t, tr);
            if (want_l && want_r) {
                bool left_first = tl <= tr;
                stack[sp] = pack_node(left_first ? rr : l);
                stack_t[sp] = left_first ? tr : tl;
                sp += 1u;
                current = pack_node(left_first ? l : rr);
                pop = false;
            } else if (want_l || want_r) {
                current = pack_node(want_l ? l : rr);
                pop = false;
            }
        }
        if (pop) {
            POP_NEAREST_OR_RETURN();
        }
    }
}

#endif // WIDE_LAYOUT

#endif
