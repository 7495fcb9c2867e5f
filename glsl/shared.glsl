// Constants shared by the host and the kernels (the nvpro "one header" idea).
// build.rs turns every `#define NAME <unsigned integer>` below into `pub const NAME: u32`
// in Rust (trilab::shared), so bindings and sizes cannot drift apart.
// Only unsigned integer literals belong here, and function-like macros over them (build.rs
// skips those; their Rust twins are written in src/shared.rs beside the constants).
#ifndef TRILAB_SHARED
#define TRILAB_SHARED

// Invocations per workgroup along x (one ray per invocation).
#define WORKGROUP_SIZE 64
// raycast.comp's workgroup size is this specialisation constant (default WORKGROUP_SIZE).
#define SPEC_ID_WORKGROUP_SIZE 1
// Traversal stack entries: the BVH builder guarantees depth <= STACK_SIZE.
#define STACK_SIZE 64
// Stack entries of the wide traversals (glsl/layout/bvh4.glsl, bvh8.glsl); the host refuses a
// tree whose stack bound (LayoutNodes::stack_bound) exceeds its layout's.
#define BVH4_STACK_SIZE 64
#define BVH8_STACK_SIZE 96
// Node groups of the cwbvh traversal's stack (glsl/layout/cwbvh.glsl; CwBvh::stack_bound).
#define CWBVH_STACK_SIZE 32
// Entries every per-lane stack array has room for, whatever its layout's bound: 65 four-byte
// entries are 260 bytes, past the 256 bytes up to which RADV (Mesa's AMD driver, ACO and LLVM
// alike) keeps an indexed local array in registers, as an if-ladder over every entry. Held there,
// bvh4's, qbvh4's and cwbvh's stacks took 180-228 VGPRs, one subgroup per SIMD on GCN and LLVM
// spilling; in scratch, 56-96 VGPRs and 2-4 subgroups (results/radv/stack-53/). The stack's
// entries and distances stay two arrays of scalars: one array of pairs measured 1.08-2.57x slower
// on lavapipe. No layout's bound changes: the host still refuses a tree deeper than its layout's.
#define STACK_MIN_ENTRIES 65
#define STACK_CAPACITY(bound) ((bound) < STACK_MIN_ENTRIES ? STACK_MIN_ENTRIES : (bound))

// The packed entry every traversal keeps of a node once its box was tested (its stacks hold
// these), and the cwbvh leaf table's entries: (first << LEAF_ENTRY_COUNT_BITS) | count, where
// count is a leaf's triangles (0: an inner node; MAX_LEAF_SIZE <= 16 fits) and first its first
// slot or first child (the host checks it fits the rest: MAX_NODE_INDEX). Rust twin:
// trilab::shared::{leaf_entry, leaf_entry_first, leaf_entry_count}.
#define LEAF_ENTRY_COUNT_BITS 5u
#define LEAF_ENTRY(first, count) (((first) << LEAF_ENTRY_COUNT_BITS) | (count))
#define LEAF_ENTRY_FIRST(e) ((e) >> LEAF_ENTRY_COUNT_BITS)
#define LEAF_ENTRY_COUNT(e) ((e) & ((1u << LEAF_ENTRY_COUNT_BITS) - 1u))

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

// Path tracing (pathtrace.comp). Scene-side texel buffers:
#define BINDING_MATERIALS 9
#define BINDING_SHADING 10
#define BINDING_LIGHTS 11
// Per-render uniform parameters, the accumulation image and counters.
#define BINDING_PARAMS 12
#define BINDING_ACCUM 13
#define BINDING_STATS 14
// bsdf_probe.comp's input and output buffers.
#define BINDING_BSDF_PROBE_IN 15
#define BINDING_BSDF_PROBE_OUT 16
// rng_probe.comp's output.
#define BINDING_RNG_PROBE_OUT 17
// raycast.comp's `stats` variant: per-ray traversal counters (TraversalCounts, counts.glsl).
#define BINDING_TRAVERSAL_STATS 18
// raycast.comp's `clock` variant: shader-clock ticks per ray (uint), for `trilab profile`.
#define BINDING_CYCLES 19
// rayquery.comp: the driver's top-level acceleration structure (its primitive index -> OBJ id
// table is bound at BINDING_SLOT_IDS).
#define BINDING_TLAS 20
// raycast_persistent.comp: the next ray index of the dispatch (one uint, atomicAdd per fetch);
// the host zeroes it before each dispatch (gpu::raycast::cast_rays).
#define BINDING_RAY_COUNTER 21
// roofline.comp: one checksum (uint) per invocation. Its nodes are bound at BINDING_NODES.
#define BINDING_ROOFLINE_OUT 22
// subgroup_probe.comp's output: one SubgroupProbeOut per invocation.
#define BINDING_SUBGROUP_PROBE_OUT 23
// subgroup_probe.comp's inputs: the same eight 16-byte words as a storage texel buffer and as a
// storage buffer.
#define BINDING_SUBGROUP_PROBE_TEXELS 24
#define BINDING_SUBGROUP_PROBE_WORDS 25

// BSDF kinds (Material.kind; one file each in bsdf/). A kernel's BSDF_MASK has bit (1 << kind)
// set for every kind it carries.
#define BSDF_LAMBERT 0
#define BSDF_OREN_NAYAR 1
#define BSDF_PHONG 2
#define BSDF_BLINN_PHONG 3
#define BSDF_ASHIKHMIN_SHIRLEY 4
#define BSDF_GLASS 5
#define BSDF_MIRROR 6
#define BSDF_COUNT 7
#define BSDF_MASK_ALL 0x7F

// Triangle id of a miss (../shared/formats.md).
#define MISS_ID 0xFFFFFFFFu

#endif
