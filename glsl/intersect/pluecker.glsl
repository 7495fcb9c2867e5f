// Ray-triangle test in Plücker coordinates, in the form Embree uses for its robust mode (I. Wald,
// S. Woop, C. Benthin, G. S. Johnson, M. Ernst, "Embree: A Kernel Framework for Efficient CPU Ray
// Tracing", ACM TOG 33(4), 2014; the Plücker side test itself: K. Shoemake, "Plücker coordinate
// tutorial", Ray Tracing News 11(1), 1998, and R. Jones, "Intersecting a ray and a triangle with
// Plücker coordinates", Ray Tracing News 13(1), 2000). Embree documents the shifted form in its
// kernels/geometry/triangle_intersector_pluecker.h ("modified Pluecker ray/triangle intersector");
// this is our own derivation of it, below.
//
// A line through points P and Q has Plücker coordinates (Q - P, P x Q); two lines (d1, m1) and
// (d2, m2) pass each other clockwise or counter-clockwise as the sign of d1.m2 + d2.m1 says. The
// ray crosses a triangle when it passes all three edges on the same side. Shifting the vertices by
// -O puts the ray through the origin, so its moment is zero and the side product with the edge
// from A to B reduces to D.(A x B). It is computed as D.((B - A) x (B + A)) / 2, that is for the
// shifted vertices v0, v1, v2 and edges e0 = v2 - v0, e1 = v0 - v1, e2 = v1 - v2:
//   U = D.(e0 x (v2 + v0)),  V = D.(e1 x (v0 + v1)),  W = D.(e2 x (v1 + v2))
// (twice the signed areas seen along D: U is opposite v1, V opposite v2, W opposite v0, so
// u = U / (U + V + W) and v = V / (U + V + W) are the barycentric weights of v1 and v2).
// Accept when U, V and W do not have mixed signs, with a tolerance of one ulp of |U + V + W|
// (two-sided); t = (v0.N) / (D.N) with the normal N taken per component from whichever of
// e0 x e1 and e1 x e2 (equal in exact arithmetic) cancels less.
//
// Where it does not leak: a shifted vertex is computed by the same instruction in every
// triangle that shares it; a shared edge is walked in opposite directions by the two triangles,
// so one computes e x s and the other (-e) x s from the same bits, and with no fused multiply-add
// (`precise`) every product and sum of the second is exactly the negation of the first. A ray
// therefore sees exactly opposite values for a shared edge in its two triangles and cannot pass
// between them; a value of 0 is accepted on both sides. The shift rounds the vertices relative to
// O, so the test can accept a triangle that the exact ray misses by that rounding, like Woop et
// al.'s watertight test: traversal uses the conservative box test (CONSERVATIVE_TRAVERSAL,
// box.glsl).
// Where it can: at a shared vertex. The spokes (edges meeting there) are separate sums of
// rounded products, each of whose signs can be wrong when the ray passes within rounding of the
// vertex (unlike the watertight test's 2D edge functions, whose signs are never wrong, only 0),
// so around a vertex every spoke can come out on the same side and no triangle of the fan
// accepts. Embree claims watertightness "along the edge" only; `trilab accuracy` measures 0.2 %
// of rays aimed exactly at vertices leaking, none at edges or in random directions, and the
// tolerance of one ulp of |U + V + W| does not cover it (the spokes' error grows with the
// distance from the ray origin, |U + V + W| with the triangle's size).
//
// Data: Möller–Trumbore's scene buffers (glsl/mt_scene.glsl), like watertight and f64.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

// Ask box.glsl for the conservative box test this test needs.
#define CONSERVATIVE_TRAVERSAL

#include "mt_scene.glsl"

// The acceptance tolerance, relative to |U + V + W|: one f32 ulp (2^-23).
const float PLUECKER_ULP = 1.1920928955078125e-7;

// a x b, every product rounded on its own (precise: no FMA), in a fixed order.
vec3 plk_cross(vec3 a, vec3 b) {
    precise float x = a.y * b.z - a.z * b.y;
    precise float y = a.z * b.x - a.x * b.z;
    precise float z = a.x * b.y - a.y * b.x;
    return vec3(x, y, z);
}

// a.b in a fixed order (precise).
float plk_dot(vec3 a, vec3 b) {
    precise float d = a.x * b.x + a.y * b.y + a.z * b.z;
    return d;
}

// The normal from the edges (a + b + c = 0, so a x b = b x c): per component, the cross product
// whose subtracted product is the smaller, so the one that cancels less.
vec3 plk_stable_normal(vec3 a, vec3 b, vec3 c) {
    precise vec3 ab_sub = vec3(a.z * b.y, a.x * b.z, a.y * b.x);
    precise vec3 bc_sub = vec3(b.z * c.y, b.x * c.z, b.y * c.x);
    precise vec3 ab = vec3(a.y * b.z, a.z * b.x, a.x * b.y) - ab_sub;
    precise vec3 bc = vec3(b.y * c.z, b.z * c.x, b.x * c.y) - bc_sub;
    return mix(bc, ab, lessThan(abs(ab_sub), abs(bc_sub)));
}

bool intersect_triangle(TraceRay r, uint s, float tmax, out float t, out float u, out float v) {
    uvec3 idx = SCENE_TEXEL(mt_triangles, s).xyz;
    // Vertices relative to the ray origin: the same instructions for every triangle sharing one.
    precise vec3 v0 = load_vertex(idx.x) - r.origin;
    precise vec3 v1 = load_vertex(idx.y) - r.origin;
    precise vec3 v2 = load_vertex(idx.z) - r.origin;
    precise vec3 e0 = v2 - v0;
    precise vec3 e1 = v0 - v1;
    precise vec3 e2 = v1 - v2;
    precise vec3 s0 = v2 + v0;
    precise vec3 s1 = v0 + v1;
    precise vec3 s2 = v1 + v2;
    // Side products with the three edges: a shared edge's two triangles get exact negations.
    precise float eu = plk_dot(plk_cross(e0, s0), r.dir);
    precise float ev = plk_dot(plk_cross(e1, s1), r.dir);
    precise float ew = plk_dot(plk_cross(e2, s2), r.dir);
    precise float uvw = eu + ev + ew;
    float eps = PLUECKER_ULP * abs(uvw);
    if (!(min(eu, min(ev, ew)) >= -eps || max(eu, max(ev, ew)) <= eps)) {
        return false; // the ray passes the edges on mixed sides
    }
    vec3 n = plk_stable_normal(e0, e1, e2);
    float den = plk_dot(n, r.dir);
    if (den == 0.0) {
        return false; // parallel to the plane, or a zero-area triangle
    }
    t = plk_dot(v0, n) / den;
    if (!(t >= r.tmin && t <= tmax)) {
        return false;
    }
    // 1/uvw where it is a normal float (a denormal's reciprocal overflows).
    float inv = abs(uvw) < 1.17549435e-38 ? 0.0 : 1.0 / uvw;
    u = min(eu * inv, 1.0);
    v = min(ev * inv, 1.0);
    return true;
}

#endif
