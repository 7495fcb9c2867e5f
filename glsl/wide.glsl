// What the wide layouts (glsl/layout/bvh4.glsl, bvh8.glsl) share: their nodes' marker for an
// empty child slot (bvh::EMPTY_CHILD; empty slots come last in a node).
#ifndef TRILAB_WIDE
#define TRILAB_WIDE

const uint EMPTY_CHILD = 0xFFFFFFFFu;

#endif
