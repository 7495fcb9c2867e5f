// What a node layout (glsl/layout/<name>.glsl) gives the traversals, so that a new layout is one
// file that reaches each of them: the per-ray loops (traversal/while_if.glsl, the persistent
// threads of raycast_persistent.comp) and the subgroup-cooperative one (raycast_coop.comp).
//
// Every layout defines, before including stack.glsl:
// - LAYOUT_STACK_SIZE: the per-ray stack's entries (shared.glsl's constant for the layout; the
//   host refuses a tree whose stack bound exceeds it);
// - LAYOUT_WIDTH: children per node;
// - LAYOUT_TESTS_ROOT, where the root's box is stored: a ray must hit it before its first step;
// and the functions:
// - LayoutRoot layout_root(): where a ray's traversal starts and the tree's box (what box_ray()
//   needs for the conservative test; a layout that does not store it computes it only then);
// - bool layout_visit(BoxRay b, float tmax, uint node, out uint next): slab-tests the children
//   of inner node `node` (LEAF_ENTRY_FIRST of its entry) against the closest hit so far `tmax`,
//   pushes every hit child but the nearest onto the stack (farthest first, each with its entry
//   distance: stack_push) and sets `next` to the nearest; false when none is hit. It counts the
//   boxes it tests (COUNT_BOXES); the loop counts the node (COUNT_INNER) and the leaves.
// - for raycast_coop.comp, where each lane takes one child, either
//   NodeChild layout_child(uint node, uint ch) (bvh2: a lane loads its child), or the node's
//   texels and where each child's fields lie in them (the structure-of-arrays layouts:
//   LAYOUT_NODE_TEXELS and layout_field_texel, wide.glsl), which the lanes load spread.
// A layout whose traversal is its own (cwbvh: node groups with hit masks, no per-entry stack)
// defines LAYOUT_TRACE, layout_root() and trace() instead; it runs in the per-ray loop's place
// only. Every traversal starts a ray with ray_enter() (bvh.glsl).
#ifndef TRILAB_LAYOUT_INTERFACE
#define TRILAB_LAYOUT_INTERFACE

#include "box.glsl"
#include "counts.glsl"

// Where a ray's traversal starts: the tree's box (bmin, bmax) and the entry of its first node.
struct LayoutRoot {
    vec3 bmin;
    vec3 bmax;
    uint entry;
};

// Where every traversal of a ray starts (defined in bvh.glsl, after the layout, whose
// LAYOUT_TESTS_ROOT it reads; declared here for a layout's own trace()).
bool ray_enter(TraceRay r, inout HitState h, LayoutRoot root, out BoxRay b);

// One child as a lane of raycast_coop.comp sees it.
struct NodeChild {
    vec3 bmin;
    vec3 bmax;
    uint entry; // LEAF_ENTRY(first, count)
    bool occupied;
};

#endif
