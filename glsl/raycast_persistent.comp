#version 460
// trilab:variants closest
// trilab:layouts(stepped) closest
// Persistent threads with dynamic ray fetch (`--traversal persistent`): Aila & Laine,
// "Understanding the Efficiency of Ray Traversal on GPUs", HPG 2009, sec. 4 ("persistent
// threads", "dynamic fetch"). The host launches a fixed number of workgroups
// (gpu::raycast::PERSISTENT_WORKGROUPS), not one invocation per ray; each invocation takes a ray
// index with atomicAdd on the counter at BINDING_RAY_COUNTER (zeroed by the host before every
// dispatch), and when its ray is done (the stack is empty) it writes the hit, takes the next
// index and starts that ray inside the same traversal loop, so a lane refills without waiting
// for the rest of its subgroup. Where the paper fetches a batch for the whole warp when most of
// its lanes are idle, each lane fetches its own ray here (one atomic per ray).
//
// The traversal is the per-ray kernels' step for step (the layout's layout_visit and the stack's
// pop, as traversal/while_if.glsl), so the hits equal theirs ray for ray; only the loop around it
// differs. Every layout that gives a step runs here (`closest`: the binary nodes, whose root box
// is tested when a ray starts, so a ray that misses it is written at once and the next one
// fetched; `closest_bvh4`, `closest_bvh8`); not cwbvh, whose traversal is its own. Closest hit
// only, texel path.
#extension GL_GOOGLE_include_directive : require

#include "types.glsl"

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };
layout(std430, set = 0, binding = BINDING_RAY_COUNTER) buffer RayCounter { uint next_ray; };

layout(push_constant) uniform Push {
    uint ray_count; // rays in this dispatch (the bound ray/hit ranges hold exactly these)
} pc;

#include "intersector.glsl"
#include "bvh.glsl"

#ifdef LAYOUT_TRACE
#error "raycast_persistent.comp drives a layout's step; cwbvh's traversal is its own (`// trilab:layouts(stepped)` leaves it out)"
#endif

layout(local_size_x_id = SPEC_ID_WORKGROUP_SIZE, local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void main() {
    // The root, once per invocation.
    LayoutRoot root = layout_root();
    uint ray_id = 0u;
    TraceRay r;
    BoxRay b;
    HitState h;
    uint current = 0u;
    bool fetch = true;
    while (true) {
        if (fetch) {
            // Dynamic fetch: the next ray of the dispatch.
            ray_id = atomicAdd(next_ray, 1u);
            if (ray_id >= pc.ray_count) {
                return;
            }
            Ray ray = rays[ray_id];
            r = make_trace_ray(ray);
            h = hit_start(ray.tmax);
            if (!ray_enter(r, h, root, b)) {
                // It misses the tree: written at once, and the next one fetched.
                hits[ray_id] = hit_record(h);
                continue;
            }
            current = root.entry;
            stack_size = 0u;
            fetch = false;
        }
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        if (count > 0u) {
            intersect_leaf(r, first, count, h, false);
        } else if (layout_visit(b, h.t, first, current)) {
            continue;
        }
        if (!stack_pop_nearest(h.t, current)) {
            // The ray is done: store its hit; the next one is fetched at the top.
            hits[ray_id] = hit_record(h);
            fetch = true;
        }
    }
}
