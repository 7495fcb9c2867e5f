// Baldwin and Weber's ray-triangle test (D. Baldwin, M. Weber, "Fast Ray-Triangle Intersections
// by Coordinate Transformation", JCGT 5(3), 2016): each triangle stores the affine map from world
// space to its barycentric space, whose third basis vector is the world axis k on which the
// normal is largest. That column of the map is (0, 0, 1) for world coordinate k, so it is not
// stored: nine coefficients and k (the "fixed column") remain.
// In the cyclically permuted coordinates p' = (p[k], p[k+1], p[k+2]):
//   w(p) = p'0 + plane.x p'1 + plane.y p'2 + plane.z     (zero on the triangle's plane)
//   t = -w(O) / (D'0 + plane.x D'1 + plane.y D'2),  P = O + t D (only P'1, P'2 are needed)
//   u = u_row.x P'1 + u_row.y P'2 + u_row.z,  v = v_row.x P'1 + v_row.y P'2 + v_row.z
// 48 bytes per triangle (three rgba32f texels); plane.w holds k as the float 0, 1 or 2, and 3 for
// a slot that is never hit (padding, unrepresentable triangles), skipped before any arithmetic.
// No vertex list is needed to intersect. Data and derivation: src/encoding/baldwin_weber.rs.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

struct BwTriangle {
    vec4 plane; // xy: coefficients of p'1, p'2; z: constant; w: k (the fixed column)
    vec4 u_row; // xy: coefficients of p'1, p'2; z: constant; w: 0
    vec4 v_row; // likewise for v
};

SCENE_BUFFER(BINDING_PRIMS, rgba32f, F4, bw_triangles);

vec4 load_bw_row(uint slot, uint row) {
    return SCENE_TEXEL(bw_triangles, 3u * slot + row);
}

#define PRIM_STRUCT BwTriangle
// Triangle slots one primitive holds (one triangle per slot).
#define PRIM_TRIANGLES 1
BwTriangle load_prim(uint slot) {
    BwTriangle t;
    t.plane = load_bw_row(slot, 0u);
    t.u_row = load_bw_row(slot, 1u);
    t.v_row = load_bw_row(slot, 2u);
    return t;
}

// p' for fixed column k: a cyclic permutation (selects, not a branch, so lanes whose triangles
// have different k stay together).
vec3 bw_permute(vec3 p, float k) {
    return k == 0.0 ? p : (k == 1.0 ? p.yzx : p.zxy);
}

bool intersect_triangle(TraceRay r, uint s, float tmax, out float t, out float u, out float v) {
    vec4 pl = load_bw_row(s, 0u);
    if (pl.w > 2.0) {
        return false; // never hit
    }
    vec3 o = bw_permute(r.origin, pl.w);
    vec3 d = bw_permute(r.dir, pl.w);
    float wd = d.x + pl.x * d.y + pl.y * d.z;
    if (wd == 0.0) {
        return false; // ray parallel to the plane
    }
    t = -(o.x + pl.x * o.y + pl.y * o.z + pl.z) / wd;
    if (!(t >= r.tmin && t <= tmax)) {
        return false;
    }
    vec2 p = o.yz + t * d.yz;
    vec4 ur = load_bw_row(s, 1u);
    u = ur.x * p.x + ur.y * p.y + ur.z;
    if (!(u >= 0.0 && u <= 1.0)) {
        return false;
    }
    vec4 vr = load_bw_row(s, 2u);
    v = vr.x * p.x + vr.y * p.y + vr.z;
    return v >= 0.0 && u + v <= 1.0;
}

#endif
