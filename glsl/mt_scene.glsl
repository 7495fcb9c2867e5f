// Möller–Trumbore's scene buffers (src/encoding/mt.rs), read by every intersector that works on
// the plain triangle list: mt, watertight and f64 (so comparing them measures the arithmetic
// only). The vertex list is one rgba32f texel per vertex (w unused); each triangle slot is one
// rgba32ui texel (vertex indices, material index), slots in BVH leaf order.
#ifndef TRILAB_MT_SCENE
#define TRILAB_MT_SCENE

#include "types.glsl"

struct MtTriangle {
    uvec3 v;
    uint material;
};

SCENE_BUFFER(BINDING_PRIMS, rgba32f, F4, mt_vertices);
SCENE_BUFFER(BINDING_INDICES, rgba32ui, U4, mt_triangles);

#define PRIM_STRUCT MtTriangle
// Triangle slots one primitive holds (one triangle per slot).
#define PRIM_TRIANGLES 1
MtTriangle load_prim(uint slot) {
    uvec4 t = SCENE_TEXEL(mt_triangles, slot);
    MtTriangle r;
    r.v = t.xyz;
    r.material = t.w;
    return r;
}

vec3 load_vertex(uint i) {
    return SCENE_TEXEL(mt_vertices, i).xyz;
}

#endif
