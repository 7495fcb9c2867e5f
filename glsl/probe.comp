#version 460
// Layout probe: loads every node, primitive and slot id through the same load_* functions the
// ray-casting kernels use and writes them to std430 storage buffers. tests/reflection.rs checks
// those buffers' Offset/ArrayStride decorations against the Rust structs; tests/probe.rs checks
// that what comes back is byte for byte what the encoder wrote.
#extension GL_GOOGLE_include_directive : require

#include "types.glsl"
// Only the intersector's data layout (PRIM_STRUCT, load_prim) is used here.
#define LAYOUT_ONLY
#include "intersector.glsl"

layout(std430, set = 0, binding = BINDING_PROBE_NODES) writeonly buffer ProbeNodes { BvhNode probe_nodes[]; };
layout(std430, set = 0, binding = BINDING_PROBE_PRIMS) writeonly buffer ProbePrims { PRIM_STRUCT probe_prims[]; };
layout(std430, set = 0, binding = BINDING_PROBE_SLOT_IDS) writeonly buffer ProbeSlotIds { uint probe_slot_ids[]; };

layout(push_constant) uniform Push {
    uint nodes; // how many of each to copy
    uint prims;
    uint slots;
} pc;

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i < pc.nodes) {
        probe_nodes[i] = load_node(i);
    }
    if (i < pc.prims) {
        probe_prims[i] = load_prim(i);
    }
    if (i < pc.slots) {
        probe_slot_ids[i] = load_slot_id(i);
    }
}
