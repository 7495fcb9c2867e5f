// trace(): one ray per invocation through the variant's layout, for the kernels that cast or
// shoot rays one per invocation (raycast.comp, pathtrace.comp). The loop is the variant's
// traversal: while-if (traversal/while_if.glsl, every layout), while-while with leaf postponing
// (traversal/while_while.glsl, the `*_while_while` variants of the binary nodes, WHILE_WHILE), or the
// layout's own (LAYOUT_TRACE: cwbvh).
//
// void trace(TraceRay r, inout HitState h, bool any_hit): traces `r`, updating `h` (h.t must
// start at the ray's tmax); with `any_hit` it returns at the first accepted intersection
// (occlusion). Pass a constant: every call site is inlined and specialised by the compiler.
#ifndef TRILAB_TRAVERSE
#define TRILAB_TRAVERSE

#include "bvh.glsl"

#if defined(LAYOUT_TRACE)
// The layout's trace() (included with it by bvh.glsl).
#elif defined(WHILE_WHILE)
#include "traversal/while_while.glsl"
#else
#include "traversal/while_if.glsl"
#endif

#endif
