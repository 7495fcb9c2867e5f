// The leaf loop, written once for every intersector and every traversal: a leaf's triangles (or
// quads) through the intersector's primitive test, the closest hit kept, the any-hit exit.
//
// The intersector, included before this file, provides the primitive test only:
// - PRIM_TRIANGLES: triangle slots per primitive, 1 or 4 (a plain integer literal);
// - with PRIM_TRIANGLES 1: bool intersect_triangle(TraceRay r, uint slot, float tmax,
//   out float t, out float u, out float v): whether the triangle in `slot` is hit at
//   r.tmin <= t <= tmax (u, v: barycentric weights of vertices 1 and 2); the intersector
//   decides where in its arithmetic to compare t, so it can reject early (early returns are
//   fine: on lavapipe this form measured within 1.5 % of the per-intersector loops it replaced,
//   and faster than single-exit or `inout` variants, results/lavapipe/refactor-ab.md);
// - with PRIM_TRIANGLES 4: bvec4 intersect_quad(TraceRay r, uint quad, out vec4 t, out vec4 u,
//   out vec4 v): per lane (slot 4 quad + lane), whether it is hit at t >= r.tmin; the leaf loop
//   compares each lane with the closest hit so far, in lane order;
// - optionally INTERSECTOR_RAY_SETUP(r, h): run once per ray when its traversal starts, before
//   any leaf (watertight.glsl: its shear; f64.glsl: its bound in double), and
//   CONSERVATIVE_TRAVERSAL: the conservative box test of box.glsl (watertight.glsl, pluecker.glsl).
#ifndef TRILAB_LEAF
#define TRILAB_LEAF

#include "types.glsl"

#if PRIM_TRIANGLES == 1
// The leaf loop: tests the leaf's `count` triangle slots from `first` in order; a hit at
// tmin <= t <= h.t becomes the closest so far (so of two hits at the same t the later slot is
// kept). With `any_hit` it returns at the first. Returns whether anything was hit.
bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h, bool any_hit) {
    bool found = false;
    for (uint s = first; s < first + count; ++s) {
        float t, u, v;
        if (intersect_triangle(r, s, h.t, t, u, v)) {
            h.t = t;
            h.slot = s;
            h.u = u;
            h.v = v;
            found = true;
            if (any_hit) {
                return true;
            }
        }
    }
    return found;
}
#elif PRIM_TRIANGLES == 4
// Lane `c` (x, y, z or w; slot 4 p + k) of a quad's results becomes the closest hit so far if it
// is a hit at t <= h.t.
#define ACCEPT_LANE(c, k)                                                                      \
    if (hit.c && t.c <= h.t) {                                                                 \
        h.t = t.c;                                                                             \
        h.slot = 4u * p + k;                                                                   \
        h.u = u.c;                                                                             \
        h.v = v.c;                                                                             \
        found = true;                                                                          \
    }

// The leaf loop for four-triangle primitives: `first` and the primitives count quads (a leaf of
// `count` triangles has ceil(count / 4) quads, padding lanes never hit); lanes are accepted in
// order within a quad, and with `any_hit` it returns after the first quad with a hit.
bool intersect_leaf(TraceRay r, uint first, uint count, inout HitState h, bool any_hit) {
    bool found = false;
    uint end = first + (count + 3u) / 4u;
    for (uint p = first; p < end; ++p) {
        vec4 t, u, v;
        bvec4 hit = intersect_quad(r, p, t, u, v);
        ACCEPT_LANE(x, 0u)
        ACCEPT_LANE(y, 1u)
        ACCEPT_LANE(z, 2u)
        ACCEPT_LANE(w, 3u)
        if (any_hit && found) {
            return true;
        }
    }
    return found;
}
#else
#error "PRIM_TRIANGLES must be 1 or 4"
#endif

#endif
