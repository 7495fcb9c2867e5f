// What the structure-of-arrays wide layouts share (glsl/layout/bvh4.glsl, bvh8.glsl): a node is
// LAYOUT_NODE_TEXELS texels holding eight fields (min x, y, z, max x, y, z of the children's
// boxes as f32 bits, child, count), each field of four children in one texel; the layout says
// where (layout_field_texel, defined before this file). A child with count 0 is a node index,
// count > 0 a leaf of `count` units from `child`; child == EMPTY_CHILD marks an empty slot, and
// empty slots come last. Node 0 is the root; its box is not stored (the union of its children's).
//
// Here: loading four children's fields (wide_load), testing one child (wide_test) and the root
// (layout_root); the empty-slot marker and the sorting networks' swap are wide_step.glsl's.
#ifndef TRILAB_WIDE
#define TRILAB_WIDE

#include "layout_interface.glsl"
#include "wide_step.glsl"

// Four children's fields: children 4 quad .. 4 quad + 3 of a node.
struct WideQuad {
    vec4 mnx, mny, mnz, mxx, mxy, mxz;
    uvec4 kid, cnt;
};

// Children 4 quad .. 4 quad + 3 of node `node`: one texel per field.
WideQuad wide_load(uint node, uint quad) {
    uint base = LAYOUT_NODE_TEXELS * node;
    uint ch = 4u * quad;
    WideQuad q;
    q.mnx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + layout_field_texel(0u, ch)));
    q.mny = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + layout_field_texel(1u, ch)));
    q.mnz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + layout_field_texel(2u, ch)));
    q.mxx = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + layout_field_texel(3u, ch)));
    q.mxy = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + layout_field_texel(4u, ch)));
    q.mxz = uintBitsToFloat(SCENE_TEXEL(scene_nodes, base + layout_field_texel(5u, ch)));
    q.kid = SCENE_TEXEL(scene_nodes, base + layout_field_texel(6u, ch));
    q.cnt = SCENE_TEXEL(scene_nodes, base + layout_field_texel(7u, ch));
    return q;
}

// Child `k` (0..3) of a quad against [tmin, tmax]: its entry distance and its packed entry in
// `entry` (`hits` counted up) when hit, else `miss` and 0. hit_box swaps min and max per axis, so
// an empty slot's inverted box (+inf, -inf) would be hit: the slot's child word is checked
// instead (empty slots are never tested).
float wide_test(BoxRay b, WideQuad q, uint k, float tmax, float miss, inout uint hits, out uint entry) {
    WIDE_TEST_CHILD(q.kid[k] != EMPTY_CHILD, vec3(q.mnx[k], q.mny[k], q.mnz[k]), vec3(q.mxx[k], q.mxy[k], q.mxz[k]),
                    LEAF_ENTRY(q.kid[k], q.cnt[k]))
}

// Node 0, an inner node; the tree's box (only for the conservative test) is the union of its
// children's (an empty slot's +inf/-inf changes nothing in a min/max union).
LayoutRoot layout_root() {
    LayoutRoot root;
    root.entry = 0u;
    root.bmin = vec3(3.40282347e38);
    root.bmax = vec3(-3.40282347e38);
#ifdef CONSERVATIVE_TRAVERSAL
    for (uint quad = 0u; quad < LAYOUT_WIDTH / 4u; ++quad) {
        WideQuad q = wide_load(0u, quad);
        root.bmin = min(root.bmin, vec3(min(min(q.mnx.x, q.mnx.y), min(q.mnx.z, q.mnx.w)),
                                        min(min(q.mny.x, q.mny.y), min(q.mny.z, q.mny.w)),
                                        min(min(q.mnz.x, q.mnz.y), min(q.mnz.z, q.mnz.w))));
        root.bmax = max(root.bmax, vec3(max(max(q.mxx.x, q.mxx.y), max(q.mxx.z, q.mxx.w)),
                                        max(max(q.mxy.x, q.mxy.y), max(q.mxy.z, q.mxy.w)),
                                        max(max(q.mxz.x, q.mxz.y), max(q.mxz.z, q.mxz.w))));
    }
#endif
    return root;
}

#endif
