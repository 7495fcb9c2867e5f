#version 460
// The ray-tracing-pipeline peer's miss stage (raygen.rgen says how the stages share the
// payload): the miss record, t = +inf, id = MISS_ID, u = v = 0.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_tracing : require

#include "types.glsl"

layout(location = 0) rayPayloadInEXT Hit payload;

void main() {
    payload.t = uintBitsToFloat(0x7f800000u);
    payload.id = MISS_ID;
    payload.u = 0.0;
    payload.v = 0.0;
}
