#version 460
// trilab:variants closest any=ANY_HIT stats=TRAVERSAL_STATS clock=SHADER_CLOCK closest_address=SCENE_ADDRESS any_address=ANY_HIT,SCENE_ADDRESS stats_address=TRAVERSAL_STATS,SCENE_ADDRESS clock_address=SHADER_CLOCK,SCENE_ADDRESS closest_storage=SCENE_STORAGE any_storage=ANY_HIT,SCENE_STORAGE stats_storage=TRAVERSAL_STATS,SCENE_STORAGE closest_while_while=WHILE_WHILE any_while_while=ANY_HIT,WHILE_WHILE stats_while_while=TRAVERSAL_STATS,WHILE_WHILE
// trilab:layouts closest any stats clock closest_address any_address stats_address clock_address closest_storage any_storage stats_storage
// Ray casting: one ray per invocation, closest hit (t, u, v, OBJ triangle id) or, with ANY_HIT,
// any hit in [tmin, tmax] (occlusion). The intersector is chosen per variant by build.rs.
// With TRAVERSAL_STATS (closest hit) it also writes each ray's traversal work (counts.glsl).
// SHADER_CLOCK (profiling, `trilab profile`): closest hit, plus the subgroup clock's ticks
// around the trace written per ray to BINDING_CYCLES (needs VK_KHR_shader_clock's
// shaderSubgroupClock). Lanes in lock-step read the same clock, so on SIMD hardware a ray's
// count is its subgroup's.
// SCENE_ADDRESS (`*_address`: each of the four above): the scene is read through buffer device
// addresses instead of storage texel buffers (types.glsl), for scenes beyond
// maxTexelBufferElements.
// SCENE_STORAGE (`*_storage`: closest, any and stats): the scene is read from storage buffers
// (types.glsl), for devices whose texel buffers are small and which lack shaderInt64
// (SwiftShader: 65,536 texels, no Int64; issue 38).
// Each of the eight once more per layout in glsl/layout/ (`closest_bvh4`, `any_address_bvh8`, ...):
// that layout's traversal (WIDE_LAYOUT), whose nodes the pipeline binds at BINDING_NODES in
// place of the binary ones.
// WHILE_WHILE (`closest_while_while`, `any_while_while`, `stats_while_while`; binary nodes): Aila & Laine's while-while
// traversal with leaf postponing (glsl/traversal/while_while.glsl) in place of while-if.
#extension GL_GOOGLE_include_directive : require
#ifdef SHADER_CLOCK
#extension GL_ARB_shader_clock : require
#endif
#ifdef SCENE_ADDRESS
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#endif
#ifdef WHILE_WHILE
#extension GL_KHR_shader_subgroup_vote : require
#endif

#include "types.glsl"

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };
#ifdef SHADER_CLOCK
// Ticks per ray (the low 32 bits of the difference; 0xFFFFFFFF if it does not fit).
layout(std430, set = 0, binding = BINDING_CYCLES) writeonly buffer Cycles { uint cycles[]; };
#endif

layout(push_constant) uniform Push {
    uint ray_count; // rays in this dispatch (the bound ray/hit ranges hold exactly these)
} pc;

#include "intersector.glsl"
#include "traverse.glsl"

#ifdef TRAVERSAL_STATS
layout(std430, set = 0, binding = BINDING_TRAVERSAL_STATS) writeonly buffer Counts { TraversalCounts counts[]; };
#endif

#ifdef ANY_HIT
const bool ANY = true;
#else
const bool ANY = false;
#endif

// The workgroup size is specialisation constant SPEC_ID_WORKGROUP_SIZE (default WORKGROUP_SIZE),
// so `trilab profile` can sweep it; the host reads the size a pipeline was created with.
layout(local_size_x_id = SPEC_ID_WORKGROUP_SIZE, local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.ray_count) {
        return;
    }
    Ray ray = rays[i];
    HitState h = hit_start(ray.tmax);
#ifdef SHADER_CLOCK
    uvec2 clock_start = clock2x32ARB();
#endif
    trace(make_trace_ray(ray), h, ANY);
#ifdef SHADER_CLOCK
    uvec2 clock_end = clock2x32ARB();
    uint borrow = clock_end.x < clock_start.x ? 1u : 0u;
    uint hi = clock_end.y - clock_start.y - borrow;
    // 0xFFFFFFFE: the clock read lower at the end than at the start (stepped back);
    // 0xFFFFFFFF: end - start did not fit 32 bits (src/commands/profile/clock.rs).
    bool back = clock_end.y < clock_start.y || (clock_end.y == clock_start.y && clock_end.x < clock_start.x);
    cycles[i] = back ? 0xFFFFFFFEu : hi == 0u ? clock_end.x - clock_start.x : 0xFFFFFFFFu;
#endif
    hits[i] = hit_record(h);
#ifdef TRAVERSAL_STATS
    counts[i] = trav_counts;
#endif
}
