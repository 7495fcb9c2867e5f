#version 460
// trilab:intersector none
// Writes draws of rng.glsl for the host to compare bit for bit with render::rng (tests/render.rs):
// invocation i takes pixel i, sample 7 i + 3, and writes draws 0..3 as bits and as floats.
#extension GL_GOOGLE_include_directive : require

#include "shared.glsl"
#include "rng.glsl"

struct RngProbeOut {
    uvec4 bits;     // rand_u32(key, 0..3)
    vec4 uniforms;  // rand01(key, 0..3)
};

layout(std430, set = 0, binding = BINDING_RNG_PROBE_OUT) writeonly buffer Out { RngProbeOut outs[]; };

layout(push_constant) uniform Push {
    uint seed;
    uint count;
} pc;

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    uint key = path_key(pc.seed, i, 7u * i + 3u);
    RngProbeOut o;
    for (uint d = 0u; d < 4u; ++d) {
        o.bits[d] = rand_u32(key, d);
        o.uniforms[d] = rand01(key, d);
    }
    outs[i] = o;
}
