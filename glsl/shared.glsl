// Constants shared by the host and the kernels (the nvpro "one header" idea).
// build.rs turns every `#define NAME <unsigned integer>` below into `pub const NAME: u32`
// in Rust (trilab::gpu::shared), so bindings and sizes cannot drift apart.
// Only unsigned integer literals belong here.
#ifndef TRILAB_SHARED
#define TRILAB_SHARED

// Invocations per workgroup along x (one ray per invocation).
#define WORKGROUP_SIZE 64
// Traversal stack entries: the BVH builder guarantees depth <= STACK_SIZE.
#define STACK_SIZE 64

// Descriptor set 0. Rays and hits: storage buffers holding one dispatch's sub-range.
#define BINDING_RAYS 0
#define BINDING_HITS 1
// The scene: storage texel buffers of 16-byte texels (types.glsl says why).
#define BINDING_NODES 2
#define BINDING_SLOT_IDS 3
#define BINDING_PRIMS 4
#define BINDING_INDICES 5
// probe.comp's outputs.
#define BINDING_PROBE_NODES 6
#define BINDING_PROBE_PRIMS 7
#define BINDING_PROBE_SLOT_IDS 8

// Triangle id of a miss (../shared/formats.md).
#define MISS_ID 0xFFFFFFFFu

#endif
