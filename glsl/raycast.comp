#version 460
// trilab:variants closest any=ANY_HIT stats=TRAVERSAL_STATS
// Ray casting: one ray per invocation, closest hit (t, u, v, OBJ triangle id) or, with ANY_HIT,
// any hit in [tmin, tmax] (occlusion). The intersector is chosen per variant by build.rs.
// With TRAVERSAL_STATS (closest hit) it also writes each ray's traversal work (traverse.glsl).
#extension GL_GOOGLE_include_directive : require

#include "types.glsl"

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };

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

layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.ray_count) {
        return;
    }
    Ray ray = rays[i];
    HitState h;
    h.t = ray.tmax;
    h.slot = MISS_ID;
    h.u = 0.0;
    h.v = 0.0;
    trace(make_trace_ray(ray), h, ANY);
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
    hits[i] = o;
#ifdef TRAVERSAL_STATS
    counts[i] = trav_counts;
#endif
}
