// Watertight ray-triangle test (S. Woop, C. Benthin, I. Wald, "Watertight Ray/Triangle
// Intersection", JCGT 2(1), 2013, sec. 3-4): translate the vertices so the ray starts at the
// origin, shear and scale so that it runs along +z with unit length, and test the 2D edge
// functions of the projected vertices against the point (0, 0):
//   kz = axis of largest |dir|, kx = (kz + 1) % 3, ky = (kx + 1) % 3, kx <-> ky if dir[kz] < 0
//        (the swap keeps the winding, so U, V, W keep their signs' meaning);
//   Sx = dir[kx] / dir[kz], Sy = dir[ky] / dir[kz], Sz = 1 / dir[kz]         (once per ray);
//   A = V0 - O, Ax = A[kx] - Sx A[kz], Ay = A[ky] - Sy A[kz] (likewise B = V1 - O, C = V2 - O);
//   U = Cx By - Cy Bx, V = Ax Cy - Ay Cx, W = Bx Ay - By Ax   (twice the signed areas of the
//        sub-triangles opposite A, B, C: the unnormalised barycentric weights of V0, V1, V2);
//   hit iff U, V, W do not have mixed signs and det = U + V + W != 0;
//   T = U Sz A[kz] + V Sz B[kz] + W Sz C[kz], range-tested against tmin det and t det with det's
//        sign, without dividing; then t = T / det, u = V / det (weight of V1), v = W / det (V2).
// Two-sided (no back-face culling).
//
// Why it is watertight: a vertex's sheared (Ax, Ay) is a function of the vertex and the ray only,
// computed by the same instructions in every triangle, so triangles sharing a vertex see the same
// bits; an edge function of a shared edge is computed from the same two projected vertices in
// both triangles, in opposite order, and fl(a*b) - fl(c*d) = -(fl(c*d) - fl(a*b)) exactly, so the
// two triangles get exactly opposite values. Rounding is monotonic, so a computed edge function
// never has the wrong sign, it can only round to 0; a zero is accepted on both sides (the test
// rejects only mixed signs), so a ray exactly on a shared edge or vertex hits every triangle
// around it and none of them can let it through. All of this needs the arithmetic of the
// projection and of the edge functions rounded exactly as written: a fused multiply-add would
// round one product of `Cx By - Cy Bx` but not the other, and which one depends on the operand
// order, so the neighbour would no longer get the exact negation. Those computations are
// therefore `precise` (SPIR-V NoContraction: no FMA, no reassociation).
//
// The paper's double-precision fallback (recompute U, V, W in f64 when one is 0) is left out:
// f64 is optional on Vulkan devices, and it does not change watertightness. Without it an edge
// function that rounds to 0 counts as "on the edge", so a ray within a rounding error of an edge
// is accepted by the triangles on both sides of it (hits at nearly the same t; the closest-hit
// search keeps one of them). Triangles whose three edge functions all round to 0 give det = 0 and
// are rejected, as in the paper.
//
// The hit is reported only for tmin <= t <= h.t after the division too: the scaled test decides
// with T and det, and rounding the quotient must not move t outside the ray's interval.
//
// Because the sheared vertices are rounded, the test accepts triangles that the exact ray misses
// by up to a few ulps of their distance from the origin. BVH traversal must not cull the boxes of
// those triangles, so this intersector turns on CONSERVATIVE_TRAVERSAL (box.glsl, after
// the paper's sec. 5).
//
// Data: Möller–Trumbore's scene buffers (glsl/mt_scene.glsl, src/encoding/mt.rs), so a comparison
// with MT measures the arithmetic only.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

// Ask box.glsl for the conservative box test this test needs.
#define CONSERVATIVE_TRAVERSAL

#include "mt_scene.glsl"

// v[k] for the per-ray axes. Written as selects rather than `v[k]`: glslang lowers a dynamic
// index into a vector to a store into a function-local variable and an indexed load (scratch
// memory on a GPU); selects keep the vertex in registers. Exact either way (no arithmetic).
float wt_pick(vec3 v, uint k) {
    return mix(mix(v.z, v.y, k == 1u), v.x, k == 0u); // mix with a bool: OpSelect, no branch
}

// The per-ray part of the test (paper, sec. 3, first half).
struct WatertightRay {
    uint kx;
    uint ky;
    uint kz;
    vec3 shear; // (Sx, Sy, Sz)
};

// Set by trace() once per ray, through INTERSECTOR_RAY_SETUP (leaf.glsl), before any leaf is
// tested; intersect_triangle reads it. One traced ray at a time per invocation, so one variable.
WatertightRay wt_ray;

WatertightRay watertight_setup(TraceRay r) {
    vec3 ad = abs(r.dir);
    WatertightRay w;
    // Axis of the largest |dir| (ties: the lower axis): dir[kz] != 0, as a direction is nonzero.
    w.kz = ad.x >= ad.y ? (ad.x >= ad.z ? 0u : 2u) : (ad.y >= ad.z ? 1u : 2u);
    uint kx = w.kz == 2u ? 0u : w.kz + 1u;
    uint ky = kx == 2u ? 0u : kx + 1u;
    bool flip = wt_pick(r.dir, w.kz) < 0.0;
    w.kx = flip ? ky : kx;
    w.ky = flip ? kx : ky;
    float dz = wt_pick(r.dir, w.kz);
    w.shear = vec3(wt_pick(r.dir, w.kx) / dz, wt_pick(r.dir, w.ky) / dz, 1.0 / dz);
    return w;
}

#define INTERSECTOR_RAY_SETUP(r, h) wt_ray = watertight_setup(r)

bool intersect_triangle(TraceRay r, uint s, float tmax, out float t, out float u, out float v) {
    uint kx = wt_ray.kx;
    uint ky = wt_ray.ky;
    uint kz = wt_ray.kz;
    float sx = wt_ray.shear.x;
    float sy = wt_ray.shear.y;
    float sz = wt_ray.shear.z;
    uvec3 idx = SCENE_TEXEL(mt_triangles, s).xyz;
    // Vertices relative to the ray origin, then sheared: the same instructions for every
    // vertex slot, so a shared vertex gets the same bits in every triangle (precise: no FMA).
    precise vec3 a = load_vertex(idx.x) - r.origin;
    precise vec3 b = load_vertex(idx.y) - r.origin;
    precise vec3 c = load_vertex(idx.z) - r.origin;
    float az = wt_pick(a, kz);
    float bz = wt_pick(b, kz);
    float cz = wt_pick(c, kz);
    precise float ax = wt_pick(a, kx) - sx * az;
    precise float ay = wt_pick(a, ky) - sy * az;
    precise float bx = wt_pick(b, kx) - sx * bz;
    precise float by = wt_pick(b, ky) - sy * bz;
    precise float cx = wt_pick(c, kx) - sx * cz;
    precise float cy = wt_pick(c, ky) - sy * cz;
    // Edge functions: a shared edge's two triangles must get exactly opposite values (precise).
    precise float eu = cx * by - cy * bx;
    precise float ev = ax * cy - ay * cx;
    precise float ew = bx * ay - by * ax;
    if ((eu < 0.0 || ev < 0.0 || ew < 0.0) && (eu > 0.0 || ev > 0.0 || ew > 0.0)) {
        return false; // the point (0, 0) is outside: mixed signs (zeros are on the edge)
    }
    float det = eu + ev + ew;
    if (det == 0.0) {
        return false; // ray parallel to the plane, or a degenerate projection
    }
    // Scaled distance, compared with the interval scaled by |det| (no division yet).
    float tt = eu * (sz * az) + ev * (sz * bz) + ew * (sz * cz);
    float adet = abs(det);
    float st = det < 0.0 ? -tt : tt;
    if (!(st >= r.tmin * adet && st <= tmax * adet)) {
        return false;
    }
    float inv_det = 1.0 / det;
    t = tt * inv_det;
    if (!(t >= r.tmin && t <= tmax)) {
        return false; // the quotient rounded out of the interval
    }
    u = ev * inv_det;
    v = ew * inv_det;
    return true;
}

#endif
