#version 460
// trilab:variants closest any=ANY_HIT stats=TRAVERSAL_STATS closest_storage=SCENE_STORAGE any_storage=ANY_HIT,SCENE_STORAGE stats_storage=TRAVERSAL_STATS,SCENE_STORAGE closest_hybrid=HYBRID any_hybrid=ANY_HIT,HYBRID stats_hybrid=TRAVERSAL_STATS,HYBRID
// trilab:layouts(stepped) closest any stats closest_storage any_storage stats_storage closest_hybrid any_hybrid stats_hybrid
// Packet ray casting (`--traversals packet`): the lanes of a subgroup walk ONE path through the
// tree together, each with its own ray, and share one stack (Wald, Slusallek, Benthin & Wagner,
// "Interactive Rendering with Coherent Ray Tracing", EG 2001: coherent packets; on GPUs,
// Garanzha & Loop, EG 2010). The node the subgroup is at is the same in every lane (made
// explicit with subgroupBroadcastFirst), so its loads are uniform: on SIMD hardware one scalar
// load where the per-ray kernels gather one address per lane, and no lane waits on another's
// control flow.
//
// Per inner node: every lane whose ray may still enter the node (its own entry distance not
// beyond its closest hit) slab-tests every child (box.glsl's hit_box); a child hit by some lane
// is visited, the one nearest to any lane (subgroupMin of the lanes' entry distances; ties to
// the lower slot) next, the others pushed farthest first. A stack entry is the same in every
// lane, with each lane's own entry distance (+inf where its ray missed the child), so a popped
// entry no lane can find a closer hit in is skipped, and a lane whose ray misses an entry idles
// through it.
//
// Per leaf: each lane whose ray entered it runs the leaf loop (leaf.glsl) on its own ray. The
// hits are while-if's: a lane tests every leaf its ray enters before a closer hit rules the leaf
// out, and a leaf its ray does not enter holds no hit for it; only the order of the leaves
// differs, which changes the hit only between triangles at exactly the same distance.
//
// Its weakness is incoherent rays: the subgroup visits the union of its lanes' paths. HYBRID
// (`*_hybrid`, `--traversals hybrid`; Benthin, Wald, Woop, Ernst & Mark, "Combining Single and
// Packet-Ray Tracing for Arbitrary Ray Distributions on the Intel MIC Architecture", TVCG 2012):
// packets while at least HYBRID_MIN_PERCENT of the lanes that hold a ray take part in the node,
// then every lane goes on alone with while-if (traversal/while_if.glsl's loop) from where the
// packet was, on the same stack: its entries are already the lane's, with its own distances.
// The
// layouts: every layout that gives a step (layout_interface.glsl: bvh2, bvh4, bvh8, qbvh4), not
// cwbvh, whose traversal is its own. Needs subgroup basic, vote, arithmetic, ballot and shuffle
// operations (the host checks them: gpu::Capabilities::traversal). Any subgroup width: no lane
// returns early (lanes past the dispatch's rays carry no ray; the wide layouts' spread loads
// need every lane, which the host's full subgroups give).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_shader_subgroup_shuffle : require

#include "types.glsl"

layout(std430, set = 0, binding = BINDING_RAYS) readonly buffer Rays { Ray rays[]; };
layout(std430, set = 0, binding = BINDING_HITS) writeonly buffer Hits { Hit hits[]; };

layout(push_constant) uniform Push {
    uint ray_count; // rays in this dispatch (the bound ray/hit ranges hold exactly these)
} pc;

#include "intersector.glsl"
#include "bvh.glsl"
#ifdef HYBRID
#include "traversal/while_if.glsl"
#ifndef HYBRID_MIN_PERCENT
// The switch point: as soon as one lane with a ray has no part in the node. Of the two tried on
// the bunny's bvh4 (docs/bvh.md), 100 beat 50 on random rays (1.53 against 0.93 Mrays/s).
#define HYBRID_MIN_PERCENT 100u
#endif
#endif

#ifdef TRAVERSAL_STATS
layout(std430, set = 0, binding = BINDING_TRAVERSAL_STATS) writeonly buffer Counts { TraversalCounts counts[]; };
#endif

#ifdef ANY_HIT
const bool ANY = true;
#else
const bool ANY = false;
#endif

#ifdef LAYOUT_TRACE
#error "raycast_packet.comp drives a layout's step; cwbvh's traversal is its own (`// trilab:layouts(stepped)` leaves it out)"
#endif

layout(local_size_x_id = SPEC_ID_WORKGROUP_SIZE, local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

#define PACKET_INF uintBitsToFloat(0x7f800000u)

#ifdef LAYOUT_NODE_TEXELS
// The structure-of-arrays layouts (bvh4, bvh8): the node's texels loaded once, spread over the
// lanes, each child's fields taken from the lane that loaded them (node_spread.glsl): one
// texel load per lane per node where every lane loading every field makes LAYOUT_NODE_TEXELS
// (on lavapipe each is a per-lane loop: gallivm loads a dynamically uniform address lane by
// lane, docs/bvh.md).
#include "node_spread.glsl"
#define PacketNode SpreadTexels
#define packet_node(node) spread_load(node)
#define packet_child(n, node, ch) spread_child(n, ch)
#else
// The layouts that give a lane one child (bvh2, qbvh4: layout_child), the same in every lane.
#define PacketNode uint
#define packet_node(node) (node)
#define packet_child(n, node, ch) layout_child(node, ch)
#endif

// Traces each lane's `r` (`alive`: the lane has a ray) with the whole subgroup on one path,
// updating the lane's `h` (h.t must start at the ray's tmax).
void packet_trace(TraceRay r, inout HitState h, bool alive, bool any_hit) {
    LayoutRoot root = layout_root();
    BoxRay b;
    alive = alive && ray_enter(r, h, root, b);
    uint current = root.entry;
    float mine = alive ? 0.0 : PACKET_INF; // this lane's entry distance of `current`
    stack_size = 0u;
    if (!subgroupAny(alive)) {
        return;
    }
    while (true) {
        current = subgroupBroadcastFirst(current);
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        bool want = alive && mine <= h.t;
#ifdef HYBRID
        // Too few lanes left in the packet: each goes on alone (its entry, or the stack's).
        uint busy = subgroupAdd(want ? 1u : 0u);
        uint live = subgroupAdd(alive ? 1u : 0u);
        if (busy * 100u < live * HYBRID_MIN_PERCENT) {
            if (alive && (want || stack_pop_nearest(h.t, current))) {
#ifdef TRAVERSAL_STATS
                uint before = trav_counts.inner + trav_counts.leaves;
#endif
                while_if_from(r, h, b, current, any_hit);
#ifdef TRAVERSAL_STATS
                trav_counts.alone = trav_counts.inner + trav_counts.leaves - before;
#endif
            }
            return;
        }
#endif
        bool visit = false;
        if (count > 0u) {
            if (want) {
                COUNT_LEAF(count);
                if (intersect_leaf(r, first, count, h, any_hit) && any_hit) {
                    alive = false;
                }
            }
        } else {
            if (want) {
                COUNT_INNER();
            }
            // Each lane's entry distance of each child (+inf: missed), and the nearest over
            // the lanes (+inf: no lane hit it).
            float lane_t[LAYOUT_WIDTH];
            float near_t[LAYOUT_WIDTH];
            uint entry[LAYOUT_WIDTH];
            uint hit_children = 0u;
            PacketNode node = packet_node(first);
            for (uint ch = 0u; ch < LAYOUT_WIDTH; ++ch) {
                NodeChild c = packet_child(node, first, ch);
                float tn = PACKET_INF;
                if (want && c.occupied) {
                    COUNT_BOXES(1u);
                    float t;
                    if (hit_box(b, c.bmin, c.bmax, h.t, t)) {
                        tn = t;
                    }
                }
                lane_t[ch] = tn;
                near_t[ch] = subgroupMin(tn);
                entry[ch] = c.entry;
                hit_children += near_t[ch] < PACKET_INF ? 1u : 0u;
            }
            if (hit_children > 0u) {
                // Farthest first onto the stack (ties: the higher slot first), the nearest next.
                for (uint n = 1u; n < hit_children; ++n) {
                    uint far = 0u;
                    float far_t = -1.0;
                    for (uint ch = 0u; ch < LAYOUT_WIDTH; ++ch) {
                        if (near_t[ch] < PACKET_INF && near_t[ch] >= far_t) {
                            far = ch;
                            far_t = near_t[ch];
                        }
                    }
                    stack_push(entry[far], lane_t[far]);
                    near_t[far] = PACKET_INF;
                }
                for (uint ch = 0u; ch < LAYOUT_WIDTH; ++ch) {
                    if (near_t[ch] < PACKET_INF) {
                        current = entry[ch];
                        mine = lane_t[ch];
                    }
                }
                visit = true;
            }
        }
        if (visit) {
            continue;
        }
        // Pop the top entry in which some lane may still find a closer hit.
        bool found = false;
        while (stack_size > 0u && !found) {
            stack_size -= 1u;
            mine = stack_t[stack_size];
            found = subgroupAny(alive && mine <= h.t);
        }
        if (!found) {
            return;
        }
        current = stack_entry[stack_size];
    }
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    bool valid = i < pc.ray_count;
    Ray ray;
    if (valid) {
        ray = rays[i];
    } else {
        ray = Ray(vec3(0.0), 0.0, vec3(0.0, 0.0, 1.0), 0.0);
    }
    HitState h = hit_start(ray.tmax);
    // No lane returns early: every lane takes part in every subgroup operation.
    packet_trace(make_trace_ray(ray), h, valid, ANY);
    if (valid) {
        hits[i] = hit_record(h);
#ifdef TRAVERSAL_STATS
        counts[i] = trav_counts;
#endif
    }
}
