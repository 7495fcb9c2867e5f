#version 460
// The ray-tracing-pipeline peer's closest-hit stage (raygen.rgen says how the stages share
// the payload): the hit's t, OBJ triangle id and barycentrics, as rayquery.comp reports them.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_tracing : require

#include "types.glsl"
// scene_slot_ids (types.glsl, BINDING_SLOT_IDS) maps the BLAS's primitive index to the OBJ
// triangle id: zero-area triangles are left out of the BLAS, so the two can differ.

layout(location = 0) rayPayloadInEXT Hit payload;
hitAttributeEXT vec2 barycentrics;

void main() {
    payload.t = gl_HitTEXT;
    payload.id = load_slot_id(uint(gl_PrimitiveID));
    payload.u = barycentrics.x;
    payload.v = barycentrics.y;
}
