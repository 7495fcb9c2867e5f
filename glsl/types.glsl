// Data layouts shared by every kernel. Each struct has a #[repr(C)] twin in Rust with the same
// bytes; tests/reflection.rs checks the std430 offsets, and tests/probe.rs checks that the
// load_* functions below return exactly the bytes the encoders wrote.
//
// The scene is read from storage texel buffers (imageLoad of 16-byte texels), not storage
// buffers: on lavapipe (Mesa 25.0) a storage-buffer load at lane-varying addresses is done lane
// by lane, with a branch and a bounds check per lane and per 32-bit word, while an imageLoad is
// one branch-free 16-byte load per lane (measured: about 1.8x faster traversal on random rays);
// on GPUs it goes through the texture path. Every scene struct is a whole number of texels.
#ifndef TRILAB_TYPES
#define TRILAB_TYPES

#include "shared.glsl"

// One ray, 32 bytes: exactly a record of the .rays file format.
struct Ray {
    vec3 origin;
    float tmin;
    vec3 dir;
    float tmax;
};

// One hit, 16 bytes: exactly a record of the .hits file format.
struct Hit {
    float t;   // +inf on a miss
    uint id;   // OBJ triangle id; MISS_ID on a miss
    float u;   // barycentric weight of vertex 1
    float v;   // barycentric weight of vertex 2
};

// The paper's 32-byte BVH node (two texels). Inner node: count == 0, children at left_or_first
// and left_or_first + 1. Leaf: count > 0 triangles starting at left_or_first (in the encoding's
// own units: triangle slots, or quads for the Quad encodings).
struct BvhNode {
    vec3 bmin;
    uint left_or_first;
    vec3 bmax;
    uint count;
};

// How the kernels reach a scene buffer: every declaration is SCENE_BUFFER and every load
// SCENE_TEXEL (16-byte texels) or SCENE_TEXEL_R32 (4-byte), so an intersector is written once
// for both paths.
// - Default (texel path): a storage texel buffer, read with imageLoad (the reasons above).
//   One binding holds at most maxTexelBufferElements texels (2^27 on lavapipe and NVIDIA).
// - SCENE_ADDRESS (the raycast kernels' `*_address` variants; src/encoding/placement.rs picks
//   them when a buffer exceeds that limit): the same binding is a uniform block holding the buffer's device
//   address, and loads go through GL_EXT_buffer_reference (no per-binding size limit). The
//   kernel must enable GL_EXT_buffer_reference itself (raycast.comp does). Indices stay 32-bit:
//   SPIR-V treats access-chain indices as signed, so a buffer holds at most 2^31 texels here.
//   A 16-byte texel is loaded as two 64-bit words (so the `*_address` kernels need shaderInt64):
//   llvmpipe turns a global load into one masked gather per component, and on a host whose
//   gathers cost per element (AMD Zen) four 32-bit gathers per texel made the address path
//   0.5-0.7x the texel path (issue 27; the roofline probe measures both forms). Two 64-bit
//   gathers load the same bytes; GPUs load either form in one instruction.
// - SCENE_STORAGE (the raycast kernels' `*_storage` variants, issue 38): the same binding is a
//   readonly storage buffer of 16-byte (or 4-byte) words, loaded as uvec4 (uint). Its limit is
//   maxStorageBufferRange bytes per binding (1 GiB on SwiftShader, whose texel buffers hold only
//   65,536 texels), and it needs neither 64-bit integers nor device addresses: the path for
//   devices that lack shaderInt64 (SwiftShader). On lavapipe a lane-varying storage load is
//   gathered once per 32-bit word, so it is the slowest of the three there (the roofline).
#if defined(SCENE_STORAGE)
#define SCENE_STORAGE_TYPE_F4 uvec4
#define SCENE_STORAGE_TYPE_U4 uvec4
#define SCENE_STORAGE_TYPE_U1 uint
#define SCENE_STORAGE_CAST_F4(w_) uintBitsToFloat(w_)
#define SCENE_STORAGE_CAST_U4(w_) (w_)
#define SCENE_STORAGE_CAST_U1(w_) (w_)
#define SCENE_STORAGE_RESULT_F4 vec4
#define SCENE_STORAGE_RESULT_U4 uvec4
#define SCENE_STORAGE_RESULT_U1 uint
#define SCENE_BUFFER(binding_, format_, kind_, name_) \
    layout(std430, set = 0, binding = binding_) readonly restrict buffer name_##Storage { SCENE_STORAGE_TYPE_##kind_ texels[]; } name_; \
    SCENE_STORAGE_RESULT_##kind_ name_##_texel(uint i) { return SCENE_STORAGE_CAST_##kind_(name_.texels[i]); }
#define SCENE_TEXEL(name_, i_) name_##_texel(uint(i_))
#define SCENE_TEXEL_R32(name_, i_) name_##_texel(uint(i_))
#elif defined(SCENE_ADDRESS)
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneF4 { u64vec2 texels[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer SceneU4 { u64vec2 texels[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer SceneU1 { uint texels[]; };
uvec4 scene_words(u64vec2 w) {
    return uvec4(unpackUint2x32(w.x), unpackUint2x32(w.y));
}
#define SCENE_TEXEL_TYPE_F4 vec4
#define SCENE_TEXEL_TYPE_U4 uvec4
#define SCENE_TEXEL_TYPE_U1 uint
#define SCENE_TEXEL_CAST_F4(w_) uintBitsToFloat(scene_words(w_))
#define SCENE_TEXEL_CAST_U4(w_) scene_words(w_)
#define SCENE_TEXEL_CAST_U1(w_) (w_)
#define SCENE_BUFFER(binding_, format_, kind_, name_) \
    layout(std140, set = 0, binding = binding_) uniform name_##Address { Scene##kind_ name_; }; \
    SCENE_TEXEL_TYPE_##kind_ name_##_texel(uint i) { return SCENE_TEXEL_CAST_##kind_(name_.texels[i]); } \
    const uint name_##_texel_bytes = 16u
#define SCENE_TEXEL(name_, i_) name_##_texel(uint(i_))
#define SCENE_TEXEL_R32(name_, i_) name_##_texel(uint(i_))
#else
#define SCENE_IMAGE_F4 imageBuffer
#define SCENE_IMAGE_U4 uimageBuffer
#define SCENE_IMAGE_U1 uimageBuffer
#define SCENE_BUFFER(binding_, format_, kind_, name_) \
    layout(set = 0, binding = binding_, format_) uniform readonly restrict SCENE_IMAGE_##kind_ name_
#define SCENE_TEXEL(name_, i_) imageLoad(name_, int(i_))
#define SCENE_TEXEL_R32(name_, i_) imageLoad(name_, int(i_)).x
#endif

SCENE_BUFFER(BINDING_NODES, rgba32ui, U4, scene_nodes);
// Triangle slot (the encoding's storage order) -> OBJ triangle id.
SCENE_BUFFER(BINDING_SLOT_IDS, r32ui, U1, scene_slot_ids);

BvhNode load_node(uint i) {
    uvec4 lo = SCENE_TEXEL(scene_nodes, 2u * i);
    uvec4 hi = SCENE_TEXEL(scene_nodes, 2u * i + 1u);
    BvhNode n;
    n.bmin = uintBitsToFloat(lo.xyz);
    n.left_or_first = lo.w;
    n.bmax = uintBitsToFloat(hi.xyz);
    n.count = hi.w;
    return n;
}

uint load_slot_id(uint slot) {
    return SCENE_TEXEL_R32(scene_slot_ids, slot);
}

// The ray as traversal sees it.
struct TraceRay {
    vec3 origin;
    vec3 dir;
    vec3 inv_dir;       // 1/dir, with zero components replaced by a tiny signed value
    float tmin;
};

// Closest (or any) hit so far. t starts at the ray's tmax, so `t` is always the far end of
// the interval still searched.
struct HitState {
    float t;
    uint slot;
    float u;
    float v;
};

// Nothing hit yet: the search interval ends at the ray's tmax.
HitState hit_start(float tmax) {
    return HitState(tmax, MISS_ID, 0.0, 0.0);
}

// The hit record of a ray's closest hit so far: the one hit writer of raycast.comp,
// raycast_coop.comp and raycast_persistent.comp (a miss: t = +inf, id MISS_ID, u = v = 0).
Hit hit_record(HitState h) {
    Hit o;
    if (h.slot == MISS_ID) {
        o.t = uintBitsToFloat(0x7f800000u); // +inf
        o.id = MISS_ID;
        o.u = 0.0;
        o.v = 0.0;
    } else {
        o.t = h.t;
        o.id = load_slot_id(h.slot);
        o.u = h.u;
        o.v = h.v;
    }
    return o;
}

#endif
