#version 460
// trilab:intersector none
// Lane probe: what raycast_coop.comp relies on in every lane of a subgroup, each on values whose
// answer the host knows from the lane numbers alone (tests/subgroup_probe.rs checks every
// invocation, at every width the driver offers): the subgroup operations, and loads whose
// coordinate is the same in every lane (the cooperative traversal's root node). Self-contained
// on purpose: a driver developer can compile this one file with glslc
// (`-DWORKGROUP_SIZE=64 -DBINDING_SUBGROUP_PROBE_OUT=0 -DBINDING_SUBGROUP_PROBE_TEXELS=1
// -DBINDING_SUBGROUP_PROBE_WORDS=2`) and dispatch it without trilab.
//
// Input: eight 16-byte words, word t = (100 t + 1, 100 t + 2, 100 t + 3, 100 t + 4), bound both
// as an rgba32ui storage texel buffer and as a storage buffer. Invocation i writes outs[i]:
//   id       (gl_SubgroupSize, gl_SubgroupInvocationID, gl_SubgroupID, gl_LocalInvocationIndex)
//   ballot   subgroupBallot(valid): one bit per lane whose invocation is below pc.count
//   counts   (subgroupBallotBitCount(ballot), subgroupBallotFindLSB(ballot),
//             subgroupBallotFindMSB(ballot), subgroupBallotBitCount(subgroupBallot(lane odd)))
//   reduce   (subgroupAdd(lane), subgroupMax(lane), subgroupMin(lane + 1),
//             subgroupOr(lane == size - 1 ? 1000 + lane : 0))
//   floats   (subgroupMax(float(lane)), subgroupMin(-float(lane)), subgroupShuffle(100 + lane,
//             (lane + 1) % size), subgroupAll(lane < size) + 2 subgroupAny(lane == size - 1))
//   loop     raycast_coop.comp's ray loop: take the lowest set bit of a ballot, clear it, broadcast
//            the owner's value (subgroupOr), until no bit is left: (iterations, times this lane
//            owned, the value it was given when it did, the sum of all values seen)
//   texel_const   imageLoad(texels, 1): a constant coordinate, the same in every lane
//   texel_push    imageLoad(texels, pc.index): a push-constant coordinate, the same in every lane
//   texel_lane    imageLoad(texels, lane % 8): a coordinate that differs between lanes
//   word_push     words[pc.index]: the storage buffer at a push-constant index
//   texel_lane0   imageLoad(texels, pc.index) in lane 0 alone, then subgroupOr to every lane
//                 (one lane fetching for all, as a uniform-fetch traversal would)
//
// Run at 16 lanes on lavapipe 25.0.7 with a shader cache an 8-lane run filled, every imageLoad
// reads zeros in lanes 8-15 (docs/driver-defects.md): the cached image functions are 8-lane code.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require

#ifndef WORKGROUP_SIZE
#include "shared.glsl"
#endif

struct SubgroupProbeOut {
    uvec4 id;
    uvec4 ballot;
    uvec4 counts;
    uvec4 reduce;
    uvec4 floats;
    uvec4 loop;
    uvec4 texel_const;
    uvec4 texel_push;
    uvec4 texel_lane;
    uvec4 word_push;
    uvec4 texel_lane0;
};

layout(std430, set = 0, binding = BINDING_SUBGROUP_PROBE_OUT) writeonly buffer Out { SubgroupProbeOut outs[]; };
layout(set = 0, binding = BINDING_SUBGROUP_PROBE_TEXELS, rgba32ui) uniform readonly uimageBuffer texels;
layout(std430, set = 0, binding = BINDING_SUBGROUP_PROBE_WORDS) readonly buffer Words { uvec4 words[]; };

layout(push_constant) uniform Push {
    uint count; // invocations that count as valid (the rest still run every subgroup operation)
    uint index; // the word the uniform loads read (0..7)
} pc;

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint s = gl_SubgroupSize;
    uint k = gl_SubgroupInvocationID;
    bool valid = i < pc.count;
    SubgroupProbeOut o;
    o.id = uvec4(s, k, gl_SubgroupID, gl_LocalInvocationIndex);
    uvec4 ballot = subgroupBallot(valid);
    o.ballot = ballot;
    o.counts = uvec4(subgroupBallotBitCount(ballot), subgroupBallotFindLSB(ballot), subgroupBallotFindMSB(ballot),
                     subgroupBallotBitCount(subgroupBallot((k & 1u) == 1u)));
    o.reduce = uvec4(subgroupAdd(k), subgroupMax(k), subgroupMin(k + 1u), subgroupOr(k == s - 1u ? 1000u + k : 0u));
    o.floats = uvec4(floatBitsToUint(subgroupMax(float(k))), floatBitsToUint(subgroupMin(-float(k))),
                     subgroupShuffle(100u + k, (k + 1u) % s),
                     (subgroupAll(k < s) ? 1u : 0u) + (subgroupAny(k == s - 1u) ? 2u : 0u));
    uvec4 todo = ballot;
    uint iterations = 0u;
    uint owned = 0u;
    uint given = 0u;
    uint seen = 0u;
    while (subgroupBallotBitCount(todo) > 0u) {
        uint j = subgroupBallotFindLSB(todo);
        todo[j / 32u] &= ~(1u << (j % 32u));
        bool owner = k == j;
        uint v = subgroupOr(owner ? 1000u + k : 0u);
        iterations += 1u;
        seen += v;
        if (owner) {
            owned += 1u;
            given = v;
        }
    }
    o.loop = uvec4(iterations, owned, given, seen);
    o.texel_const = imageLoad(texels, 1);
    o.texel_push = imageLoad(texels, int(pc.index));
    o.texel_lane = imageLoad(texels, int(k % 8u));
    o.word_push = words[pc.index];
    uvec4 first = uvec4(0u);
    if (k == 0u) {
        first = imageLoad(texels, int(pc.index));
    }
    o.texel_lane0 = subgroupOr(first);
    outs[i] = o;
}
