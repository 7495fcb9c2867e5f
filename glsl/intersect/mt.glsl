// Möller–Trumbore ray-triangle test, one triangle at a time (T. Möller, B. Trumbore, "Fast,
// minimum storage ray-triangle intersection", JGT 2(1), 1997): solves
//   [t u v]^T = 1/(P.E1) [Q.E2, P.T, Q.D]^T,  E1 = V1-V0, E2 = V2-V0, T = O-V0, P = D x E2, Q = T x E1,
// rejecting as early as the algorithm allows.
// Data: mt_layout.glsl (the vertex list and one index/material texel per slot).
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

#include "mt_layout.glsl"

bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h, bool any_hit) {
    bool found = false;
    for (uint s = first; s < first + count; ++s) {
        uvec3 idx = SCENE_TEXEL(mt_triangles, s).xyz;
        vec3 v0 = load_vertex(idx.x);
        vec3 e1 = load_vertex(idx.y) - v0;
        vec3 e2 = load_vertex(idx.z) - v0;
        vec3 p = cross(r.dir, e2);
        float det = dot(e1, p);
        if (det == 0.0) {
            continue; // ray parallel to the plane (or a zero-area triangle)
        }
        float inv_det = 1.0 / det;
        vec3 tv = r.origin - v0;
        float u = dot(tv, p) * inv_det;
        if (!(u >= 0.0 && u <= 1.0)) {
            continue;
        }
        vec3 q = cross(tv, e1);
        float v = dot(r.dir, q) * inv_det;
        if (!(v >= 0.0 && u + v <= 1.0)) {
            continue;
        }
        float t = dot(e2, q) * inv_det;
        if (t >= r.tmin && t <= h.t) {
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

#endif
