// The BVH as every traversal reads it, in the variant's node layout: the box test (box.glsl),
// the traversal counters (counts.glsl), the leaf loop (leaf.glsl) and the layout's node format
// and step (`#include "layout.glsl"`: glsl/layout/<layout>.glsl for the `*_<layout>` variants,
// layout/bvh2.glsl for the others; layout_interface.glsl says what a layout gives). Included
// after the intersector (intersector.glsl) by traverse.glsl, and by the kernels that drive the
// layout with their own loop (raycast_persistent.comp, raycast_coop.comp).
#ifndef TRILAB_BVH
#define TRILAB_BVH

#include "types.glsl"
#include "box.glsl"
#include "counts.glsl"
#include "leaf.glsl"
#include "layout.glsl"

// Where every traversal of a ray starts: the intersector's per-ray setup (INTERSECTOR_RAY_SETUP:
// watertight's shear, f64's bound in double), the box ray from the tree's box (box_ray) into `b`,
// and, where the layout stores the root's box (LAYOUT_TESTS_ROOT), its test: false when the ray
// misses the tree.
bool ray_enter(TraceRay r, inout HitState h, LayoutRoot root, out BoxRay b) {
#ifdef INTERSECTOR_RAY_SETUP
    INTERSECTOR_RAY_SETUP(r, h);
#endif
    b = box_ray(r, root.bmin, root.bmax);
#ifdef LAYOUT_TESTS_ROOT
    COUNT_BOXES(1u);
    float troot;
    return hit_box(b, root.bmin, root.bmax, h.t, troot);
#else
    return true;
#endif
}

#endif
