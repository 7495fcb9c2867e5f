// The bvh2 layout: the paper's binary tree of 32-byte nodes (types.glsl's BvhNode, two texels),
// one node per step (Shumskiy & Parshin, appendix 8.3; after Aila & Laine 2009). The default
// layout: the variants without a layout suffix compile with it (`#include "layout.glsl"`
// resolves here). Host side: src/encoding/layout/bvh2.rs.
//
// What a layout gives the traversals: layout_interface.glsl.
//
// Here the root's box is stored, so a ray first tests it (LAYOUT_TESTS_ROOT); an inner node's two
// children are loaded and tested, the nearer visited next (the left one on a tie) and the
// farther pushed.
#ifndef TRILAB_LAYOUT_BVH2
#define TRILAB_LAYOUT_BVH2

#include "layout_interface.glsl"

// One more than the tree needs (STACK_SIZE): while-while keeps a sentinel at the bottom.
#define LAYOUT_STACK_SIZE (STACK_SIZE + 1)
#define LAYOUT_WIDTH 2u
#define LAYOUT_TESTS_ROOT
#include "stack.glsl"

// What traversal keeps of a node once its box has been tested: its packed entry (LEAF_ENTRY,
// shared.glsl; the paper's stack holds node indices and re-reads the node). count <= 16
// (MAX_LEAF_SIZE) fits in 5 bits; the host checks that every left_or_first fits in 27
// (EncodedScene::check_limits).
uint pack_node(BvhNode n) {
    return LEAF_ENTRY(n.left_or_first, n.count);
}

LayoutRoot layout_root() {
    BvhNode n = load_node(0u);
    return LayoutRoot(n.bmin, n.bmax, pack_node(n));
}

// The children of inner node `node` (at node and node + 1): the nearer hit one visited next (the
// left one on a tie), the farther pushed with its entry distance. One branch for the whole step,
// the push inside it (glsl/README.md, "Writing a unit": a second branch on a count returned by a
// helper cost while-while 20-30 %).
bool layout_visit(BoxRay b, float tmax, uint node, out uint next) {
    COUNT_BOXES(2u);
    BvhNode l = load_node(node);
    BvhNode rr = load_node(node + 1u);
    float tl, tr;
    bool want_l = hit_box(b, l.bmin, l.bmax, tmax, tl);
    bool want_r = hit_box(b, rr.bmin, rr.bmax, tmax, tr);
    next = 0u;
    if (want_l && want_r) {
        bool left_first = tl <= tr;
        stack_push(pack_node(left_first ? rr : l), left_first ? tr : tl);
        next = pack_node(left_first ? l : rr);
    } else if (want_l || want_r) {
        next = pack_node(want_l ? l : rr);
    }
    return want_l || want_r;
}

// Child `ch` of inner node `first` (ch >= 2: a copy of child 1, marked unoccupied).
NodeChild layout_child(uint first, uint ch) {
    BvhNode n = load_node(first + min(ch, 1u));
    return NodeChild(n.bmin, n.bmax, pack_node(n), ch < 2u);
}

#endif
