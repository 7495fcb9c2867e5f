#version 460
// trilab:intersector none
// trilab:variants texel storage=ROOFLINE_STORAGE address=ROOFLINE_ADDRESS address32=ROOFLINE_ADDRESS,ROOFLINE_WORDS32
// The traversal roofline (`trilab roofline`, issue 27): what vkpeak is to arithmetic, for the
// gathers of a traversal. Each invocation walks `steps` dependent steps through a buffer of
// 32-byte nodes (bvh2's size: two 16-byte texels, box min + a word, box max + a word), each step
// loading one node, testing the invocation's box against it with the slab test and taking the
// next node's index from the loaded words: (hit ? the second word : the first) & mask. The host
// makes the first words one random cycle through every node and the second words random
// indices (gpu::roofline::nodes), so the loads are dependent and, past the caches, miss them.
// Ray state kept live over the walk: 12 floats (origin, inverse direction, tmin, tmax, and the
// nearest entry / farthest exit of the hit and of the missed boxes). One checksum per
// invocation; gpu::roofline::reference computes the same chain on the CPU bit for bit (only
// exact float operations: a difference of values on a 2^-17 grid, one product, min, max).
// Variants, the three ways a kernel can read its nodes:
//   texel    a storage texel buffer (rgba32ui) read with imageLoad: trilab's texel path
//   storage  a readonly storage buffer of uvec4
//   address  GL_EXT_buffer_reference: a uniform block at the binding holds the buffer's device
//            address, as the raycast kernels' `*_address` variants (types.glsl, SCENE_ADDRESS); a
//            16-byte texel loaded as two 64-bit words, as they load it
//   address32  the same, a texel loaded as one uvec4 (four 32-bit words): the `*_address` kernels'
//            form before issue 27, which llvmpipe gathers once per component
// Rust twin: trilab::gpu::roofline (RooflinePush, nodes, reference).
#extension GL_GOOGLE_include_directive : require
#ifdef ROOFLINE_ADDRESS
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#endif

#include "shared.glsl"

#if defined(ROOFLINE_ADDRESS) && defined(ROOFLINE_WORDS32)
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer RooflineTexels { uvec4 texels[]; };
layout(std140, set = 0, binding = BINDING_NODES) uniform NodesAddress { RooflineTexels nodes; };
#define NODE_TEXEL(i_) nodes.texels[i_]
#elif defined(ROOFLINE_ADDRESS)
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer RooflineTexels { u64vec2 texels[]; };
layout(std140, set = 0, binding = BINDING_NODES) uniform NodesAddress { RooflineTexels nodes; };
uvec4 roofline_texel(uint i) {
    u64vec2 w = nodes.texels[i];
    return uvec4(unpackUint2x32(w.x), unpackUint2x32(w.y));
}
#define NODE_TEXEL(i_) roofline_texel(i_)
#elif defined(ROOFLINE_STORAGE)
layout(std430, set = 0, binding = BINDING_NODES) readonly restrict buffer Nodes { uvec4 texels[]; } nodes;
#define NODE_TEXEL(i_) nodes.texels[i_]
#else
layout(set = 0, binding = BINDING_NODES, rgba32ui) uniform readonly restrict uimageBuffer nodes;
#define NODE_TEXEL(i_) imageLoad(nodes, int(i_))
#endif

layout(std430, set = 0, binding = BINDING_ROOFLINE_OUT) writeonly buffer Out { uint checksums[]; };

layout(push_constant) uniform Push {
    uint mask;   // nodes - 1 (a power of two nodes)
    uint steps;  // dependent steps per invocation
    uint count;  // invocations
    uint seed;   // start indices and ray state
} pc;

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

// lowbias32 (C. Wellons, "Prospecting for hash functions", 2018).
uint roofline_hash(uint x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) {
        return;
    }
    uint base = roofline_hash(i ^ roofline_hash(pc.seed));
    uint h[7];
    for (uint j = 0u; j < 7u; ++j) {
        h[j] = roofline_hash(base + j * 0x9E3779B9u);
    }
    // Origin in the unit cube on the half-step of a 2^-16 grid (never equal to a box plane,
    // which lie on the grid); inverse direction of magnitude 0.25 to 4.25, either sign.
    vec3 o = (vec3(uvec3(h[1], h[2], h[3]) >> 16u) + 0.5) * (1.0 / 65536.0);
    vec3 mag = vec3(uvec3(h[4], h[5], h[6]) & 0xFFFu) + 256.0;
    vec3 inv = mix(mag, -mag, notEqual(uvec3(h[4], h[5], h[6]) >> 31u, uvec3(0u))) * (1.0 / 1024.0);
    float tmin = 0.0;
    float tmax = 64.0;
    float FLT_MAX = uintBitsToFloat(0x7f7fffffu);
    float hit_near = FLT_MAX, hit_far = -FLT_MAX, miss_near = FLT_MAX, miss_far = -FLT_MAX;
    uint node = h[0] & pc.mask;
    uint acc = base;
    for (uint s = 0u; s < pc.steps; ++s) {
        uvec4 lo = NODE_TEXEL(2u * node);
        uvec4 hi = NODE_TEXEL(2u * node + 1u);
        vec3 t0 = (uintBitsToFloat(lo.xyz) - o) * inv;
        vec3 t1 = (uintBitsToFloat(hi.xyz) - o) * inv;
        vec3 near3 = min(t0, t1);
        vec3 far3 = max(t0, t1);
        float tn = max(max(near3.x, near3.y), max(near3.z, tmin));
        float tf = min(min(far3.x, far3.y), min(far3.z, tmax));
        bool hit = tn <= tf;
        hit_near = hit ? min(hit_near, tn) : hit_near;
        hit_far = hit ? max(hit_far, tf) : hit_far;
        miss_near = hit ? miss_near : min(miss_near, tn);
        miss_far = hit ? miss_far : max(miss_far, tf);
        node = (hit ? hi.w : lo.w) & pc.mask;
        acc = (acc ^ node) * 0x01000193u;
    }
    acc = roofline_hash(acc ^ floatBitsToUint(hit_near));
    acc = roofline_hash(acc ^ floatBitsToUint(hit_far));
    acc = roofline_hash(acc ^ floatBitsToUint(miss_near));
    acc = roofline_hash(acc ^ floatBitsToUint(miss_far));
    checksums[i] = acc;
}
