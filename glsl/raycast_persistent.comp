#version 460
// trilab:variants closest
// trilab:layouts(bvh4) closest
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
// The traversal is the per-ray kernels' step for step, so the hits equal theirs ray for ray; only
// the loop around it differs: `closest` walks the binary nodes as traverse.glsl's trace() does
// (the root box tested when a ray starts: a ray that misses it is written at once and the next
// one fetched), `closest_bvh4` the bvh4 nodes as glsl/layout/bvh4.glsl's trace() does (its node
// tests, sorting network, push order, the skip of popped entries beyond the closest hit).
// Closest hit only, texel path.
#extension GL_GOOGLE_include_directive : require

#include "types.glsl"

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };
layout(std430, set = 0, binding = BINDING_RAY_COUNTER) buffer RayCounter { uint next_ray; };

layout(push_constant) uniform Push {
    uint ray_count; // rays in this dispatch (the bound ray/hit ranges hold exactly these)
} pc;

#include "intersector.glsl"
#include "traverse.glsl"

#if defined(WIDE_LAYOUT) && !defined(LAYOUT_BVH4)
#error "raycast_persistent.comp reads the binary and bvh4 nodes only (its `// trilab:layouts(bvh4)` line)"
#endif

layout(local_size_x_id = SPEC_ID_WORKGROUP_SIZE, local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

void write_hit(uint i, HitState h) {
    hits[i] = hit_record(h);
}

#ifndef WIDE_LAYOUT
// Binary nodes: traverse.glsl's trace(), with the fetch at the top of the loop (a ray whose root
// box is missed needs no step).
void main() {
    BvhNode root = load_node(0u);
    uint ray_id = 0u;
    Ray ray;
    TraceRay r;
    HitState h;
#ifdef CONSERVATIVE_TRAVERSAL
    ConservativeRay cons;
#endif
    uint stack[STACK_SIZE];
    float stack_t[STACK_SIZE];
    uint sp = 0u;
    uint current = 0u;
    bool fetch = true;
    while (true) {
        if (fetch) {
            ray_id = atomicAdd(next_ray, 1u);
            if (ray_id >= pc.ray_count) {
                return;
            }
            ray = rays[ray_id];
            r = make_trace_ray(ray);
            h.t = ray.tmax;
            h.slot = MISS_ID;
            h.u = 0.0;
            h.v = 0.0;
#ifdef INTERSECTOR_RAY_SETUP
            INTERSECTOR_RAY_SETUP(r, h);
#endif
#ifdef CONSERVATIVE_TRAVERSAL
            cons = make_conservative_ray(r, root.bmin, root.bmax);
#endif
            float troot;
            if (!HIT_BOX(root.bmin, root.bmax, h.t, troot)) {
                write_hit(ray_id, h);
                continue;
            }
            current = pack_node(root);
            sp = 0u;
            fetch = false;
        }
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        bool pop = true;
        if (count > 0u) {
            intersect_leaf(r, first, count, h, false);
        } else {
            BvhNode l = load_node(first);
            BvhNode rr = load_node(first + 1u);
            float tl, tr;
            bool want_l = HIT_BOX(l.bmin, l.bmax, h.t, tl);
            bool want_r = HIT_BOX(rr.bmin, rr.bmax, h.t, tr);
            if (want_l && want_r) {
                bool left_first = tl <= tr;
                stack[sp] = pack_node(left_first ? rr : l);
                stack_t[sp] = left_first ? tr : tl;
                sp += 1u;
                current = pack_node(left_first ? l : rr);
                pop = false;
            } else if (want_l || want_r) {
                current = pack_node(want_l ? l : rr);
                pop = false;
            }
        }
        if (!pop) {
            continue;
        }
        // The nearest pushed node whose box entry is not beyond the closest hit so far.
        fetch = true;
        while (sp > 0u) {
            sp -= 1u;
            if (stack_t[sp] <= h.t) {
                current = stack[sp];
                fetch = false;
                break;
            }
        }
        if (fetch) {
            // The ray is done: store its hit; the next one is fetched at the top.
            write_hit(ray_id, h);
        }
    }
}
#else
// bvh4 nodes: glsl/layout/bvh4.glsl's trace().
void main() {
    uint ray_id = atomicAdd(next_ray, 1u);
    if (ray_id >= pc.ray_count) {
        return;
    }
#ifdef CONSERVATIVE_TRAVERSAL
    // The root box (bvh4.glsl: the union of the root's child boxes), once per invocation.
    vec4 rmnx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 0u));
    vec4 rmny = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 1u));
    vec4 rmnz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 2u));
    vec4 rmxx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 3u));
    vec4 rmxy = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 4u));
    vec4 rmxz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, 5u));
    vec3 root_min = vec3(min(min(rmnx.x, rmnx.y), min(rmnx.z, rmnx.w)), min(min(rmny.x, rmny.y), min(rmny.z, rmny.w)),
                         min(min(rmnz.x, rmnz.y), min(rmnz.z, rmnz.w)));
    vec3 root_max = vec3(max(max(rmxx.x, rmxx.y), max(rmxx.z, rmxx.w)), max(max(rmxy.x, rmxy.y), max(rmxy.z, rmxy.w)),
                         max(max(rmxz.x, rmxz.y), max(rmxz.z, rmxz.w)));
#endif
    // The ray's state: what bvh4.glsl's trace() keeps in locals, reset at every fetch.
    Ray ray = rays[ray_id];
    TraceRay r = make_trace_ray(ray);
    HitState h;
    h.t = ray.tmax;
    h.slot = MISS_ID;
    h.u = 0.0;
    h.v = 0.0;
#ifdef INTERSECTOR_RAY_SETUP
    INTERSECTOR_RAY_SETUP(r, h);
#endif
#ifdef CONSERVATIVE_TRAVERSAL
    ConservativeRay cons = make_conservative_ray(r, root_min, root_max);
#endif
    uint stack[BVH4_STACK_SIZE];
    float stack_t[BVH4_STACK_SIZE];
    uint sp = 0u;
    uint current = 0u; // node 0, an inner node
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        bool pop = true;
        if (count > 0u) {
            intersect_leaf(r, first, count, h, false);
        } else {
            uint base = 8u * first;
            vec4 mnx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base));
            vec4 mny = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 1u));
            vec4 mnz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 2u));
            vec4 mxx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 3u));
            vec4 mxy = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 4u));
            vec4 mxz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + 5u));
            uvec4 kid = SCENE_TEXEL(scene_nodes, base + 6u);
            uvec4 cnt = SCENE_TEXEL(scene_nodes, base + 7u);
            uint hits = 0u;
            float t0, t1, t2, t3;
            uint e0, e1, e2, e3;
            BVH4_TEST(0, x)
            BVH4_TEST(1, y)
            BVH4_TEST(2, z)
            BVH4_TEST(3, w)
            if (hits > 0u) {
                BVH4_SORT(0, 1)
                BVH4_SORT(2, 3)
                BVH4_SORT(0, 2)
                BVH4_SORT(1, 3)
                BVH4_SORT(1, 2)
                pop = false;
                if (hits == 1u) {
                    current = e0;
                } else {
                    stack[sp] = e0;
                    stack_t[sp] = t0;
                    sp += 1u;
                    if (hits == 2u) {
                        current = e1;
                    } else {
                        stack[sp] = e1;
                        stack_t[sp] = t1;
                        sp += 1u;
                        if (hits == 3u) {
                            current = e2;
                        } else {
                            stack[sp] = e2;
                            stack_t[sp] = t2;
                            sp += 1u;
                            current = e3;
                        }
                    }
                }
            }
        }
        if (!pop) {
            continue;
        }
        // Pop the nearest entry that may still hold a closer hit.
        bool done = true;
        while (sp > 0u) {
            sp -= 1u;
            if (stack_t[sp] <= h.t) {
                current = stack[sp];
                done = false;
                break;
            }
        }
        if (!done) {
            continue;
        }
        // The ray is done: store its hit and fetch the next one (dynamic fetch).
        write_hit(ray_id, h);
        ray_id = atomicAdd(next_ray, 1u);
        if (ray_id >= pc.ray_count) {
            return;
        }
        ray = rays[ray_id];
        r = make_trace_ray(ray);
        h.t = ray.tmax;
        h.slot = MISS_ID;
        h.u = 0.0;
        h.v = 0.0;
#ifdef INTERSECTOR_RAY_SETUP
        INTERSECTOR_RAY_SETUP(r, h);
#endif
#ifdef CONSERVATIVE_TRAVERSAL
        cons = make_conservative_ray(r, root_min, root_max);
#endif
        sp = 0u;
        current = 0u;
    }
}
#endif
