// The box test every traversal uses: the ray as traversal sees it (make_trace_ray) and the
// slab test (hit_box), plain or, where the intersector asks for it (CONSERVATIVE_TRAVERSAL),
// conservative. Traversals hold a `BoxRay` (the TraceRay itself, or its ConservativeRay) made
// once per ray by box_ray() from the tree's root box, and call hit_box(b, ...) on it; the
// intersector still gets the TraceRay. Rust twins: traversal.rs (the slab tests step for step),
// bvh/slab.rs.
#ifndef TRILAB_BOX
#define TRILAB_BOX

#include "types.glsl"

// |dir| components below this are replaced by it (with the component's sign) before 1/dir,
// so axis-parallel rays give large finite slopes instead of inf * 0 = NaN in the slab test.
// It is the smallest normal f32 (2^-126), whose reciprocal 2^126 ~ 8.5e37 is still finite: a
// zero component's slab then ends at |b - o| * 2^126 (inf past |b - o| = 4), not at
// |b - o| * 1e30, which lost the hits of an axis-parallel ray beyond t ~ 1e30 on a small box
// (issue 24: a triangle at x = 2^100). Rust's twins: traversal.rs, bvh/slab.rs.
const float TINY_DIR = 1.17549435e-38;
// pbrt-v3/v4's conservative slab test: scale the far distance up by 1 + 2*gamma(3) so that
// rounding never culls a box the ray grazes (Pharr, Jakob & Humphreys, PBR 3rd ed., 3.9.2).
const float SLAB_FAR_SCALE = 1.0000003576;

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

bool hit_box(ConservativeRay c, vec3 bmin, vec3 bmax, float tfar, out float tnear) {
    precise vec3 t0 = (bmin - c.org_lo) * c.rdir_lo;
    precise vec3 t1 = (bmax - c.org_hi) * c.rdir_hi;
    vec3 lo = min(t0, t1);
    vec3 hi = max(t0, t1);
    tnear = max(max(lo.x, lo.y), max(lo.z, c.tmin));
    float tf = min(min(hi.x, hi.y), min(hi.z, tfar));
    return tnear <= tf;
}

// What traversal tests boxes with: the conservative ray, made once per ray from the root box.
#define BoxRay ConservativeRay
BoxRay box_ray(TraceRay r, vec3 root_min, vec3 root_max) {
    return make_conservative_ray(r, root_min, root_max);
}
#else
// What traversal tests boxes with: the ray itself (the root box is not needed).
#define BoxRay TraceRay
BoxRay box_ray(TraceRay r, vec3 root_min, vec3 root_max) {
    return r;
}
#endif

#endif
