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
// fetched; `closest_bvh4`, `closest_bvh8`, `closest_qbvh4`); not cwbvh, whose traversal is its own. Closest hit
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

// The ray state of an invocation, between fetches.
uint ray_id;
TraceRay ray_r;
BoxRay ray_b;
HitState ray_h;

// Dynamic fetch: takes the next ray of the dispatch and starts it (ray_enter). A ray that misses
// the tree (LAYOUT_TESTS_ROOT) is written at once and the next one taken. False when no ray is
// left. One exit (glsl/README.md, "Writing a unit").
bool fetch_ray(LayoutRoot root) {
    bool entered = false;
    bool left = true;
#ifdef LAYOUT_TESTS_ROOT
    while (left && !entered) {
#endif
        ray_id = atomicAdd(next_ray, 1u);
        left = ray_id < pc.ray_count;
        if (left) {
            Ray ray = rays[ray_id];
            ray_r = make_trace_ray(ray);
            ray_h = hit_start(ray.tmax);
            entered = ray_enter(ray_r, ray_h, root, ray_b);
            if (!entered) {
                hits[ray_id] = hit_record(ray_h);
            }
        }
#ifdef LAYOUT_TESTS_ROOT
    }
#endif
    return entered;
}

void main() {
    // The root, once per invocation.
    LayoutRoot root = layout_root();
    if (!fetch_ray(root)) {
        return;
    }
    uint current = root.entry;
    stack_size = 0u;
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        bool pop = true;
        if (count > 0u) {
            intersect_leaf(ray_r, first, count, ray_h, false);
        } else {
            pop = !layout_visit(ray_b, ray_h.t, first, current);
        }
        if (!pop) {
            continue;
        }
        if (stack_pop_nearest(ray_h.t, current)) {
            continue;
        }
        // The ray is done: store its hit, take the next one inside the same loop.
        hits[ray_id] = hit_record(ray_h);
        if (!fetch_ray(root)) {
            return;
        }
        current = root.entry;
        stack_size = 0u;
    }
}
