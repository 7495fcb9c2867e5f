// Buffer layouts shared by every kernel. Each struct has a #[repr(C)] twin in Rust with the same
// std430 offsets; tests/reflection.rs checks them against the Offset/ArrayStride decorations.
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

// The paper's 32-byte BVH node. Inner node: count == 0, children at left_or_first and
// left_or_first + 1. Leaf: count > 0 triangles starting at left_or_first (in the encoding's
// own units: triangle slots, or quads for the Quad encodings).
struct BvhNode {
    vec3 bmin;
    uint left_or_first;
    vec3 bmax;
    uint count;
};

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };
layout(std430, set = 0, binding = BINDING_NODES) readonly buffer Nodes { BvhNode nodes[]; };
// Triangle slot (the encoding's storage order) -> OBJ triangle id.
layout(std430, set = 0, binding = BINDING_SLOT_IDS) readonly buffer SlotIds { uint slot_ids[]; };

layout(push_constant) uniform Push {
    uint ray_count;  // rays in this dispatch (the bound ray/hit ranges hold exactly these)
} pc;

// The ray as traversal sees it.
struct TraceRay {
    vec3 origin;
    vec3 dir;
    vec3 inv_dir;      // 1/dir, with zero components replaced by a tiny signed value
    vec3 origin_scaled; // origin * inv_dir, for the slab test
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

#endif
