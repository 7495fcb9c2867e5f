// Möller–Trumbore's scene layout (src/encoding/mt.rs), read by every intersector that works on
// the plain triangle list: mt, watertight and f64 (so comparing them measures the arithmetic
// only). The vertex list is one rgba32f texel per vertex (w unused); each triangle slot is one
// rgba32ui texel (vertex indices, material index), slots in BVH leaf order.
#ifndef TRILAB_MT_LAYOUT
#define TRILAB_MT_LAYOUT

#include "types.glsl"

struct MtTriangle {
    uvec3 v;
    uint material;
};

layout(set = 0, binding = BINDING_PRIMS, rgba32f) uniform readonly restrict imageBuffer mt_vertices;
layout(set = 0, binding = BINDING_INDICES, rgba32ui) uniform readonly restrict uimageBuffer mt_triangles;

#define PRIM_STRUCT MtTriangle
// Triangle slots one primitive holds (one triangle per slot).
#define PRIM_TRIANGLES 1u
MtTriangle load_prim(uint slot) {
    uvec4 t = imageLoad(mt_triangles, int(slot));
    MtTriangle r;
    r.v = t.xyz;
    r.material = t.w;
    return r;
}

vec3 load_vertex(uint i) {
    return imageLoad(mt_vertices, int(i)).xyz;
}

#endif
