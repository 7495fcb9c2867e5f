// Möller–Trumbore ray-triangle test, one triangle at a time (T. Möller, B. Trumbore, "Fast,
// minimum storage ray-triangle intersection", JGT 2(1), 1997): solves
//   [t u v]^T = 1/(P.E1) [Q.E2, P.T, Q.D]^T,  E1 = V1-V0, E2 = V2-V0, T = O-V0, P = D x E2, Q = T x E1,
// rejecting as early as the algorithm allows.
// Data (src/encoding/mt.rs): the vertex list (vec4, w unused) and one uvec4 per triangle slot
// (vertex indices, material index), slots in BVH leaf order.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

struct MtTriangle {
    uvec3 v;
    uint material;
};

layout(std430, set = 0, binding = BINDING_PRIMS) readonly buffer MtVertices { vec4 mt_vertices[]; };
layout(std430, set = 0, binding = BINDING_INDICES) readonly buffer MtTriangles { MtTriangle mt_triangles[]; };

bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h) {
    bool found = false;
    for (uint s = first; s < first + count; ++s) {
        uvec3 idx = mt_triangles[s].v;
        vec3 v0 = mt_vertices[idx.x].xyz;
        vec3 e1 = mt_vertices[idx.y].xyz - v0;
        vec3 e2 = mt_vertices[idx.z].xyz - v0;
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
#ifdef ANY_HIT
            return true;
#endif
        }
    }
    return found;
}

#endif
