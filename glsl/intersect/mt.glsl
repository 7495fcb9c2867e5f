// Möller–Trumbore ray-triangle test, one triangle at a time (T. Möller, B. Trumbore, "Fast,
// minimum storage ray-triangle intersection", JGT 2(1), 1997): solves
//   [t u v]^T = 1/(P.E1) [Q.E2, P.T, Q.D]^T,  E1 = V1-V0, E2 = V2-V0, T = O-V0, P = D x E2, Q = T x E1,
// rejecting as early as the algorithm allows.
// Data: mt_scene.glsl (the vertex list and one index/material texel per slot). The leaf loop
// that calls it is leaf.glsl's.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

#include "mt_scene.glsl"

bool intersect_triangle(TraceRay r, uint s, float tmax, out float t, out float u, out float v) {
    uvec3 idx = SCENE_TEXEL(mt_triangles, s).xyz;
    vec3 v0 = load_vertex(idx.x);
    vec3 e1 = load_vertex(idx.y) - v0;
    vec3 e2 = load_vertex(idx.z) - v0;
    vec3 p = cross(r.dir, e2);
    float det = dot(e1, p);
    if (det == 0.0) {
        return false; // ray parallel to the plane (or a zero-area triangle)
    }
    float inv_det = 1.0 / det;
    vec3 tv = r.origin - v0;
    u = dot(tv, p) * inv_det;
    if (!(u >= 0.0 && u <= 1.0)) {
        return false;
    }
    vec3 q = cross(tv, e1);
    v = dot(r.dir, q) * inv_det;
    if (!(v >= 0.0 && u + v <= 1.0)) {
        return false;
    }
    t = dot(e2, q) * inv_det;
    return t >= r.tmin && t <= tmax;
}

#endif
