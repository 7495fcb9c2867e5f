// A structure-of-arrays wide node's texels (LAYOUT_NODE_TEXELS, wide.glsl) loaded once per node,
// spread over the subgroup's lanes, and each child's fields taken from the lane that loaded them
// (subgroupShuffle): one texel load per lane for a 128-byte node and a subgroup of 8, where a
// lane loading every field itself makes eight. For the kernels whose lanes walk a node together:
// raycast_coop.comp (lane k takes child k) and raycast_packet.comp (every lane takes every
// child). Every lane of the subgroup must be active (the host creates kernels that read
// gl_SubgroupSize with full subgroups: gpu::kernel). Needs subgroup basic and shuffle operations.
#ifndef TRILAB_NODE_SPREAD
#define TRILAB_NODE_SPREAD

#ifdef LAYOUT_NODE_TEXELS
// The node's texels spread over the lanes: lane k holds texels k, k + S, k + 2S, k + 3S.
struct SpreadTexels {
    uvec4 t0, t1, t2, t3;
};

SpreadTexels spread_load(uint node) {
    uint s = gl_SubgroupSize;
    uint k = gl_SubgroupInvocationID;
    uint base = LAYOUT_NODE_TEXELS * node;
    // Only the node's own texels: with S > LAYOUT_NODE_TEXELS lanes (16 for bvh4, 32 for bvh8) the
    // lanes beyond load nothing (never the next node, never past the buffer's end).
    SpreadTexels c;
    c.t0 = uvec4(0u);
    c.t1 = uvec4(0u);
    c.t2 = uvec4(0u);
    c.t3 = uvec4(0u);
    if (k < LAYOUT_NODE_TEXELS) {
        c.t0 = SCENE_TEXEL(scene_nodes, base + k);
    }
    if (s + k < LAYOUT_NODE_TEXELS) {
        c.t1 = SCENE_TEXEL(scene_nodes, base + s + k);
    }
    if (2u * s + k < LAYOUT_NODE_TEXELS) {
        c.t2 = SCENE_TEXEL(scene_nodes, base + 2u * s + k);
    }
    if (3u * s + k < LAYOUT_NODE_TEXELS) {
        c.t3 = SCENE_TEXEL(scene_nodes, base + 3u * s + k);
    }
    return c;
}

// Texel `t` of the node, from the lane that loaded it. subgroupShuffle returns `src` as the
// SOURCE lane computed it, so the block (which of t0..t3) must be the same in every lane: it is
// passed in, computed from the field alone (uniform), never from a lane's child index.
uvec4 spread_texel(SpreadTexels c, uint block, uint t) {
    uvec4 src = block == 0u ? c.t0 : block == 1u ? c.t1 : block == 2u ? c.t2 : c.t3;
    return subgroupShuffle(src, t % gl_SubgroupSize);
}

// Field `f` (0..7: min x, y, z, max x, y, z, child, count) of child `ch` (ch >= LAYOUT_WIDTH:
// any in-node value, the caller marks it unoccupied), where the layout keeps it
// (layout_field_texel). A field's texels for all children lie in one block (bvh8's at 2f and
// 2f + 1, as S is even), so the block is taken from child 0's.
uint spread_field(SpreadTexels c, uint ch, uint f) {
    return spread_texel(c, layout_field_texel(f, 0u) / gl_SubgroupSize, layout_field_texel(f, ch))[ch & 3u];
}

NodeChild spread_child(SpreadTexels c, uint ch) {
    NodeChild o;
    o.bmin = uintBitsToFloat(uvec3(spread_field(c, ch, 0u), spread_field(c, ch, 1u), spread_field(c, ch, 2u)));
    o.bmax = uintBitsToFloat(uvec3(spread_field(c, ch, 3u), spread_field(c, ch, 4u), spread_field(c, ch, 5u)));
    uint kid = spread_field(c, ch, 6u);
    uint cnt = spread_field(c, ch, 7u);
    o.occupied = ch < LAYOUT_WIDTH && kid != EMPTY_CHILD;
    o.entry = LEAF_ENTRY(kid, cnt);
    return o;
}
#endif

#endif
