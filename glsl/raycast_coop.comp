#version 460
// trilab:variants closest stats=TRAVERSAL_STATS
// trilab:layouts(bvh4,bvh8) closest stats
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
// Per inner node: the lanes that hold a child slab-test it (traverse.glsl's HIT_BOX); the hit
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
// ties to the higher slot (f64: compared in double). That is exactly what traverse.glsl's leaf
// loop keeps (the last slot among those at the smallest t), so the hits equal the per-ray
// kernels' where the visiting order of leaves is the same.
//
// Layouts: the binary nodes (`closest`, `stats`: two children, the root box tested first) and
// `bvh4`, `bvh8` (glsl/layout/: their node formats are read here, their trace() is unused).
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
#include "traverse.glsl"

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

#if !defined(WIDE_LAYOUT)
#define COOP_WIDTH 2u
#define COOP_STACK STACK_SIZE
#elif defined(LAYOUT_BVH4)
#define COOP_WIDTH 4u
#define COOP_STACK BVH4_STACK_SIZE
#define COOP_TEXELS 8u
#elif defined(LAYOUT_BVH8)
#define COOP_WIDTH 8u
#define COOP_STACK BVH8_STACK_SIZE
#define COOP_TEXELS 16u
#else
#error "raycast_coop.comp reads the binary, bvh4 and bvh8 nodes only (its `// trilab:layouts(...)` line)"
#endif

// One child slot as its lane sees it.
struct CoopChild {
    vec3 bmin;
    vec3 bmax;
    uint entry; // LEAF_ENTRY(first, count) (shared.glsl)
    bool occupied;
};

#ifdef WIDE_LAYOUT
// The node's texels spread over the lanes: lane k holds texels k, k + S, k + 2S, k + 3S.
struct CoopTexels {
    uvec4 t0, t1, t2, t3;
};

CoopTexels coop_load(uint node) {
    uint s = gl_SubgroupSize;
    uint k = gl_SubgroupInvocationID;
    uint base = COOP_TEXELS * node;
    // Only the node's own texels: with S > COOP_TEXELS lanes (16 for bvh4, 32 for bvh8) the
    // lanes beyond load nothing (never the next node, never past the buffer's end).
    CoopTexels c;
    c.t0 = uvec4(0u);
    c.t1 = uvec4(0u);
    c.t2 = uvec4(0u);
    c.t3 = uvec4(0u);
    if (k < COOP_TEXELS) {
        c.t0 = SCENE_TEXEL(scene_nodes, base + k);
    }
    if (s + k < COOP_TEXELS) {
        c.t1 = SCENE_TEXEL(scene_nodes, base + s + k);
    }
    if (2u * s + k < COOP_TEXELS) {
        c.t2 = SCENE_TEXEL(scene_nodes, base + 2u * s + k);
    }
    if (3u * s + k < COOP_TEXELS) {
        c.t3 = SCENE_TEXEL(scene_nodes, base + 3u * s + k);
    }
    return c;
}

// Texel `t` of the node, from the lane that loaded it. subgroupShuffle returns `src` as the
// SOURCE lane computed it, so the block (which of t0..t3) must be the same in every lane: it is
// passed in, computed from the field alone (uniform), never from a lane's child index.
uvec4 coop_texel(CoopTexels c, uint block, uint t) {
    uvec4 src = block == 0u ? c.t0 : block == 1u ? c.t1 : block == 2u ? c.t2 : c.t3;
    return subgroupShuffle(src, t % gl_SubgroupSize);
}

// Field `f` (0..7: min x, y, z, max x, y, z, child, count) of child `ch` (ch >= COOP_WIDTH:
// any in-node value, the caller marks it unoccupied). bvh8 keeps a field's texels for children
// 0-3 and 4-7 at 2f and 2f + 1: one block, as S is even.
uint coop_field(CoopTexels c, uint ch, uint f) {
#ifdef LAYOUT_BVH4
    return coop_texel(c, f / gl_SubgroupSize, f)[ch & 3u];
#else
    return coop_texel(c, 2u * f / gl_SubgroupSize, 2u * f + ((ch >> 2u) & 1u))[ch & 3u];
#endif
}

CoopChild coop_child(CoopTexels c, uint ch) {
    CoopChild o;
    o.bmin = uintBitsToFloat(uvec3(coop_field(c, ch, 0u), coop_field(c, ch, 1u), coop_field(c, ch, 2u)));
    o.bmax = uintBitsToFloat(uvec3(coop_field(c, ch, 3u), coop_field(c, ch, 4u), coop_field(c, ch, 5u)));
    uint kid = coop_field(c, ch, 6u);
    uint cnt = coop_field(c, ch, 7u);
    o.occupied = ch < COOP_WIDTH && kid != EMPTY_CHILD;
    o.entry = LEAF_ENTRY(kid, cnt);
    return o;
}
#else
// Binary nodes: child `ch` (0 or 1) of the inner node whose children start at `first`.
CoopChild coop_child_binary(uint first, uint ch) {
    BvhNode n = load_node(first + min(ch, 1u));
    CoopChild o;
    o.bmin = n.bmin;
    o.bmax = n.bmax;
    o.entry = pack_node(n);
    o.occupied = ch < 2u;
    return o;
}
#endif

// Slab test of a child: its entry distance, or -inf where it is missed or not there.
float coop_test(TraceRay r,
#ifdef CONSERVATIVE_TRAVERSAL
                ConservativeRay cons,
#endif
                CoopChild c, float tfar) {
    float tn;
    if (c.occupied && HIT_BOX(c.bmin, c.bmax, tfar, tn)) {
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
#ifdef INTERSECTOR_RAY_SETUP
    INTERSECTOR_RAY_SETUP(r, h);
#endif
#ifdef WIDE_LAYOUT
    // Node 0 is the root (an inner node); its box is the union of its children's.
#ifdef CONSERVATIVE_TRAVERSAL
    CoopTexels rt = coop_load(0u);
    vec3 rmin = vec3(COOP_INF);
    vec3 rmax = vec3(-COOP_INF);
    for (uint ci = 0u; ci < COOP_WIDTH; ci += s) {
        CoopChild c = coop_child(rt, ci + k);
        if (c.occupied) {
            rmin = min(rmin, c.bmin);
            rmax = max(rmax, c.bmax);
        }
    }
    ConservativeRay cons = make_conservative_ray(r, subgroupMin(rmin), subgroupMax(rmax));
#endif
    uint current = 0u;
#else
    BvhNode root = load_node(0u);
#ifdef CONSERVATIVE_TRAVERSAL
    ConservativeRay cons = make_conservative_ray(r, root.bmin, root.bmax);
#endif
    COUNT_BOXES(1u);
    float troot;
    if (!HIT_BOX(root.bmin, root.bmax, h.t, troot)) {
        return;
    }
    uint current = pack_node(root);
#endif
    uint stack[COOP_STACK];
    float stack_t[COOP_STACK];
    uint sp = 0u;
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
#ifdef WIDE_LAYOUT
            CoopTexels tex = coop_load(first);
            CoopChild c0 = coop_child(tex, k);
#else
            CoopChild c0 = coop_child_binary(first, k);
#endif
#ifdef CONSERVATIVE_TRAVERSAL
            t0 = coop_test(r, cons, c0, h.t);
#else
            t0 = coop_test(r, c0, h.t);
#endif
            e0 = c0.entry;
            occupied += c0.occupied ? 1u : 0u;
#ifdef WIDE_LAYOUT
            if (s < COOP_WIDTH) {
                CoopChild c1 = coop_child(tex, k + s);
#ifdef CONSERVATIVE_TRAVERSAL
                t1 = coop_test(r, cons, c1, h.t);
#else
                t1 = coop_test(r, c1, h.t);
#endif
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
                    stack[sp] = coop_take(m0, e0) | coop_take(m1, e1);
                    stack_t[sp] = far_t;
                    sp += 1u;
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
        while (true) {
            if (sp == 0u) {
                return;
            }
            sp -= 1u;
            if (stack_t[sp] <= h.t) {
                current = stack[sp];
                break;
            }
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
    HitState my_hit;
    my_hit.t = mine.tmax;
    my_hit.slot = MISS_ID;
    my_hit.u = 0.0;
    my_hit.v = 0.0;
#ifdef TRAVERSAL_STATS
    TraversalCounts my_counts = TraversalCounts(0u, 0u, 0u, 0u, 0u);
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
        HitState h;
        h.t = ray.tmax;
        h.slot = MISS_ID;
        h.u = 0.0;
        h.v = 0.0;
#ifdef TRAVERSAL_STATS
        trav_counts = TraversalCounts(0u, 0u, 0u, 0u, 0u);
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
