// Woop's unit-triangle test (S. Woop, J. Schmittler, P. Slusallek, "RPU: A Programmable Ray
// Processing Unit for Realtime Ray Tracing", SIGGRAPH 2005; S. Woop's thesis 2004, sec. 4.4):
// each triangle stores the affine map T(x) = M x + N that takes it to the unit triangle
// (0,0,0), (1,0,0), (0,1,0) in the z = 0 plane. The ray is mapped into that space
// (O' = M O + N, D' = M D); then t = -O'z / D'z, u = O'x + t D'x, v = O'y + t D'y.
// 48 bytes per triangle (three rgba32f texels, the rows [M_i | N_i]); no vertex list is needed
// to intersect. Data: src/encoding/unit.rs.
#ifndef TRILAB_INTERSECTOR
#define TRILAB_INTERSECTOR

#include "types.glsl"

struct UnitTriangle {
    vec4 row0; // maps to u
    vec4 row1; // maps to v
    vec4 row2; // maps to the distance from the plane
};

SCENE_BUFFER(BINDING_PRIMS, rgba32f, F4, unit_triangles);

vec4 load_unit_row(uint slot, uint row) {
    return SCENE_TEXEL(unit_triangles, 3u * slot + row);
}

#define PRIM_STRUCT UnitTriangle
// Triangle slots one primitive holds (one triangle per slot).
#define PRIM_TRIANGLES 1
UnitTriangle load_prim(uint slot) {
    UnitTriangle t;
    t.row0 = load_unit_row(slot, 0u);
    t.row1 = load_unit_row(slot, 1u);
    t.row2 = load_unit_row(slot, 2u);
    return t;
}

bool intersect_triangle(TraceRay r, uint s, float tmax, out float t, out float u, out float v) {
    vec4 r2 = load_unit_row(s, 2u);
    float oz = dot(r2.xyz, r.origin) + r2.w;
    float dz = dot(r2.xyz, r.dir);
    if (dz == 0.0) {
        return false; // ray parallel to the plane
    }
    t = -oz / dz;
    if (!(t >= r.tmin && t <= tmax)) {
        return false;
    }
    vec4 r0 = load_unit_row(s, 0u);
    u = dot(r0.xyz, r.origin) + r0.w + t * dot(r0.xyz, r.dir);
    if (!(u >= 0.0 && u <= 1.0)) {
        return false;
    }
    vec4 r1 = load_unit_row(s, 1u);
    v = dot(r1.xyz, r.origin) + r1.w + t * dot(r1.xyz, r.dir);
    return v >= 0.0 && u + v <= 1.0;
}

#endif
