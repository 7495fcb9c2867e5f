#version 460
// trilab:variants closest stats=TRAVERSAL_STATS
// trilab:layouts(stepped) closest stats
// Subgroup-cooperative ray casting (`--traversal coop`): the lanes of a subgroup trace ONE ray at
// a time together, after Lier, Stamminger & Selgrad, "CPU-style SIMD Ray Traversal on GPUs",
// HPG 2018: lane k tests child k of the ray's current wide node (children k, k + S, ... where
// the node is wider than the subgroup's S lanes), and lane k tests unit k of a leaf (a triangle,
// or a quad for the Quad intersectors). On lavapipe a subgroup is a CPU SIMD register, so this is
// Embree's mapping (one ray, SIMD over the children) instead of one ray per lane.
//
// Dispatch geometry is raycast.comp's: one ray per invocation. Lane k loads its own ray; the
// subgroup then traces its lanes' rays in lane order, each broadcast to every lane, and lane k
// keeps ray k's hit (and counters) and writes them at the end. Every lane runs every step, so
// all traversal state (the current entry, the stack, the closest hit) is the same in every lane.
//
// Per inner node: the lanes that hold a child slab-test it (box.glsl's hit_box); the hit
// children are taken farthest first by subgroup reductions (subgroupMax of the entry distance,
// ties to the higher slot) and pushed with their entry distance, and the nearest is visited next
// (ties to the lower slot); a popped entry beyond the closest hit is skipped, as the wide
// layouts' per-ray traversals do. Node texels are loaded once per node, spread over the lanes
// (lane k loads texels k, k + S, ...), and each lane takes its child's fields from the lane that
// loaded them (subgroupShuffle): one texel load per lane for a 128-byte node and a subgroup of 8,
// instead of eight.
//
// Per leaf: each lane runs the intersector's chain over its units (the sequential leaf loop's
// rule, a hit at t <= the lane's best so far is kept); then the smallest t over the lanes wins,
// ties to the higher slot (f64: compared in double). That is exactly what leaf.glsl's leaf
// loop keeps (the last slot among those at the smallest t), so the hits equal the per-ray
// kernels' where the visiting order of leaves is the same.
//
// Layouts: every layout that gives its children to a lane (layout_interface.glsl): the binary
// nodes (`closest`, `stats`: layout_child, the root box tested first) and the structure-of-arrays
// `bvh4`, `bvh8` (their texels loaded spread over the lanes, each field where layout_field_texel
// says), and qbvh4 (layout_child: a lane decodes its child's quantized box); not cwbvh, whose
// traversal is its own.
// Closest hit only (no any-hit kernel). Needs subgroup basic, vote, arithmetic, ballot and
// shuffle operations and a subgroup of at least 4 lanes (the host checks both).
//
// Subgroup widths: written for any S >= 4 (Vulkan's are powers of two; lavapipe 4 or 8, GPUs 8
// to 64). S = 4 with bvh8: two children and four texel blocks per lane. S > the node's width:
// the lanes beyond hold unoccupied children, those beyond its texels load nothing, those beyond
// a leaf's units test nothing; they idle in that step. Every lane still owns one ray, so a
// subgroup of S lanes traces S rays in turn: wider subgroups take more rays, not more lanes per
// ray. The lanes' rays are picked from a uvec4 ballot (up to 128 lanes). Every lane must be
// active (coop_load and coop_leaf hand work to lanes by gl_SubgroupInvocationID up to
// gl_SubgroupSize): the host creates every kernel that reads gl_SubgroupSize with full
// subgroups (VK_PIPELINE_SHADER_STAGE_CREATE_REQUIRE_FULL_SUBGROUPS_BIT) and refuses a
// workgroup size that is not a multiple of the subgroup size (gpu::kernel).
// tests/subgroup_widths.rs models the lane assignment at 4 to 64 lanes.
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

#ifdef TRAVERSAL_STATS
layout(std430, set = 0, binding = BINDING_TRAVERSAL_STATS) writeonly buffer Counts { TraversalCounts counts[]; };
#endif

layout(local_size_x_id = SPEC_ID_WORKGROUP_SIZE, local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;

#define COOP_INF uintBitsToFloat(0x7f800000u)
const uint COOP_NONE = 0xFFFFFFFFu;

// The value `x` of the lane where `mine` holds (exactly one lane; 0 where none does).
uint coop_take(bool mine, uint x) {
    return subgroupOr(mine ? x : 0u);
}
float coop_take_f(bool mine, float x) {
    return uintBitsToFloat(subgroupOr(mine ? floatBitsToUint(x) : 0u));
}

#ifdef LAYOUT_TRACE
#error "raycast_coop.comp drives a layout's step; cwbvh's traversal is its own (`// trilab:layouts(stepped)` leaves it out)"
#endif

#include "node_spread.glsl"

// Slab test of a child: its entry distance, or -inf where it is missed or not there.
float coop_test(BoxRay b, NodeChild c, float tfar) {
    float tn;
    if (c.occupied && hit_box(b, c.bmin, c.bmax, tfar, tn)) {
        return tn;
    }
    return -COOP_INF;
}

// One leaf, `count` triangles from unit `first`, tested by all lanes; updates `h` uniformly.
void coop_leaf(TraceRay r, uint first, uint count, inout HitState h) {
    uint s = gl_SubgroupSize;
    uint k = gl_SubgroupInvocationID;
    bool found = false;
    float bt = h.t;
    uint bslot = 0u;
    float bu = 0.0;
    float bv = 0.0;
#if PRIM_TRIANGLES == 1
    for (uint i = 0u; i < count; i += s) {
        if (i + k < count) {
            float t, u, v;
            if (intersect_triangle(r, first + i + k, bt, t, u, v)) {
                bt = t;
                bslot = first + i + k;
                bu = u;
                bv = v;
                found = true;
            }
        }
    }
#else
    uint quads = (count + 3u) / 4u;
    for (uint i = 0u; i < quads; i += s) {
        if (i + k < quads) {
            uint p = first + i + k;
            vec4 t, u, v;
            bvec4 hit = intersect_quad(r, p, t, u, v);
            for (uint c = 0u; c < 4u; ++c) {
                if (hit[c] && t[c] <= bt) {
                    bt = t[c];
                    bslot = 4u * p + c;
                    bu = u[c];
                    bv = v[c];
                    found = true;
                }
            }
        }
    }
#endif
    if (!subgroupAny(found)) {
        return;
    }
#ifdef METHOD_F64
    // f64 decides the closest hit in double (intersect/f64.glsl): each lane's f64_best is its
    // own best; the smallest wins and becomes every lane's bound.
    double key = found ? f64_best : double(COOP_INF);
    double best = subgroupMin(key);
    f64_best = best;
#else
    float key = found ? bt : COOP_INF;
    float best = subgroupMin(key);
#endif
    bool cand = found && key == best;
    uint win = subgroupMax(cand ? bslot + 1u : 0u) - 1u;
    bool mine = cand && bslot == win;
    h.t = coop_take_f(mine, bt);
    h.slot = win;
    h.u = coop_take_f(mine, bu);
    h.v = coop_take_f(mine, bv);
}

// Traces `r` (the same in every lane) with the whole subgroup, updating `h` (the same in every
// lane; h.t must start at the ray's tmax).
void coop_trace(TraceRay r, inout HitState h) {
    uint s = gl_SubgroupSize;
    uint k = gl_SubgroupInvocationID;
    LayoutRoot root = layout_root();
    BoxRay b;
    if (!ray_enter(r, h, root, b)) {
        return;
    }
    uint current = root.entry;
    stack_size = 0u;
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        if (count > 0u) {
            COUNT_LEAF(count);
            coop_leaf(r, first, count, h);
        } else {
            COUNT_INNER();
            // Lane k's children: k (and k + S where the node is wider than the subgroup).
            float t0 = -COOP_INF;
            float t1 = -COOP_INF;
            uint e0 = 0u;
            uint e1 = 0u;
            uint occupied = 0u;
#ifdef LAYOUT_NODE_TEXELS
            SpreadTexels tex = spread_load(first);
            NodeChild c0 = spread_child(tex, k);
#else
            NodeChild c0 = layout_child(first, k);
#endif
            t0 = coop_test(b, c0, h.t);
            e0 = c0.entry;
            occupied += c0.occupied ? 1u : 0u;
#ifdef LAYOUT_NODE_TEXELS
            if (s < LAYOUT_WIDTH) {
                NodeChild c1 = spread_child(tex, k + s);
                t1 = coop_test(b, c1, h.t);
                e1 = c1.entry;
                occupied += c1.occupied ? 1u : 0u;
            }
#endif
            COUNT_BOXES(subgroupAdd(occupied));
            uint hits = subgroupAdd((t0 > -COOP_INF ? 1u : 0u) + (t1 > -COOP_INF ? 1u : 0u));
            if (hits > 0u) {
                // Farthest first onto the stack (ties: the higher slot first), the nearest
                // visited next.
                for (uint n = 1u; n < hits; ++n) {
                    float far_t = subgroupMax(max(t0, t1));
                    // Slot index of each candidate: k (t0) or k + S (t1).
                    uint slot = subgroupMax(t1 == far_t ? k + s + 1u : t0 == far_t ? k + 1u : 0u) - 1u;
                    bool m0 = slot == k;
                    bool m1 = slot == k + s;
                    stack_push(coop_take(m0, e0) | coop_take(m1, e1), far_t);
                    t0 = m0 ? -COOP_INF : t0;
                    t1 = m1 ? -COOP_INF : t1;
                }
                bool l0 = t0 > -COOP_INF;
                bool l1 = t1 > -COOP_INF;
                current = coop_take(l0, e0) | coop_take(l1, e1);
                continue;
            }
        }
        // Pop the nearest entry that may still hold a closer hit.
        if (!stack_pop_nearest(h.t, current)) {
            return;
        }
    }
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint k = gl_SubgroupInvocationID;
    bool valid = i < pc.ray_count;
    Ray mine;
    if (valid) {
        mine = rays[i];
    } else {
        mine = Ray(vec3(0.0), 0.0, vec3(0.0, 0.0, 1.0), 0.0);
    }
    HitState my_hit = hit_start(mine.tmax);
#ifdef TRAVERSAL_STATS
    TraversalCounts my_counts = TraversalCounts(0u, 0u, 0u, 0u, 0u, 0u);
#endif
    // Every lane of the subgroup traces each valid lane's ray in turn (no lane returns early:
    // all must take part in every subgroup operation).
    uvec4 todo = subgroupBallot(valid);
    while (subgroupBallotBitCount(todo) > 0u) {
        uint j = subgroupBallotFindLSB(todo);
        todo[j / 32u] &= ~(1u << (j % 32u));
        bool owner = k == j;
        Ray ray;
        ray.origin = vec3(coop_take_f(owner, mine.origin.x), coop_take_f(owner, mine.origin.y),
                          coop_take_f(owner, mine.origin.z));
        ray.tmin = coop_take_f(owner, mine.tmin);
        ray.dir = vec3(coop_take_f(owner, mine.dir.x), coop_take_f(owner, mine.dir.y), coop_take_f(owner, mine.dir.z));
        ray.tmax = coop_take_f(owner, mine.tmax);
        HitState h = hit_start(ray.tmax);
#ifdef TRAVERSAL_STATS
        trav_counts = TraversalCounts(0u, 0u, 0u, 0u, 0u, 0u);
#endif
        coop_trace(make_trace_ray(ray), h);
        if (owner) {
            my_hit = h;
#ifdef TRAVERSAL_STATS
            my_counts = trav_counts;
#endif
        }
    }
    if (!valid) {
        return;
    }
    hits[i] = hit_record(my_hit);
#ifdef TRAVERSAL_STATS
    counts[i] = my_counts;
#endif
}
