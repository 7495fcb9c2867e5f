// Per-ray traversal counters of the `stats` variants (TRAVERSAL_STATS): every traversal and layout
// counts its work through the COUNT_* macros below, which compile to nothing in the other
// variants (whose SPIR-V they leave unchanged).
#ifndef TRILAB_COUNTS
#define TRILAB_COUNTS

#ifdef TRAVERSAL_STATS
#ifdef ANY_HIT
#error "TRAVERSAL_STATS counts closest-hit traversal; an any-hit leaf stops at its first hit"
#endif
#ifndef PRIM_TRIANGLES
#error "TRAVERSAL_STATS needs the intersector's PRIM_TRIANGLES"
#endif
// The work trace() did for this invocation's ray (24 bytes; Rust twin gpu::TraversalCounts).
// A leaf's `count` is its triangles (padding slots are not counted in it), and the closest-hit
// intersectors test every one, so:
//   inner:     loop iterations at an inner node (each loads and slab-tests both children);
//   leaves:    loop iterations at a leaf (each calls intersect_leaf once);
//   triangles: sum of `count` over the leaves visited: real triangles tested;
//   slots:     triangle slots evaluated: `count` rounded up to a whole primitive
//              (PRIM_TRIANGLES: 4 for the Quad intersectors, whose padding lanes are computed
//              too; equal to `triangles` for the one-triangle intersectors);
//   boxes:     slab tests: the root's and both children's per inner iteration here; in a wide
//              layout, each occupied child slot of a visited node (glsl/layout/);
//   alone:     nodes (inner and leaf iterations, counted in the two above too) the ray visited
//              on its own after the hybrid packet traversal let it go (raycast_packet.comp's
//              HYBRID; 0 in every other kernel): a ray with alone > 0 switched.
// A ray that misses the root box does no other work (boxes 1, the rest zero).
// With a wide layout, `inner` counts wide nodes visited.
struct TraversalCounts {
    uint inner;
    uint leaves;
    uint triangles;
    uint slots;
    uint boxes;
    uint alone;
};
TraversalCounts trav_counts = TraversalCounts(0u, 0u, 0u, 0u, 0u, 0u);
#define COUNT_INNER() trav_counts.inner += 1u
#define COUNT_BOXES(n) trav_counts.boxes += (n)
#define COUNT_LEAF(count)                                                                      \
    trav_counts.leaves += 1u;                                                                  \
    trav_counts.triangles += (count);                                                          \
    trav_counts.slots += ((count) + uint(PRIM_TRIANGLES) - 1u) / uint(PRIM_TRIANGLES) * uint(PRIM_TRIANGLES)
#else
#define COUNT_INNER()
#define COUNT_LEAF(count)
#define COUNT_BOXES(n)
#endif

#endif
