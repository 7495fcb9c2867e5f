// "While-while" traversal of the binary BVH with leaf postponing (the `*_while_while` variants of
// raycast.comp, WHILE_WHILE): Aila & Laine, "Understanding the Efficiency of Ray Traversal on
// GPUs", HPG 2009, sec. 3 (while-while, postponed leaves), as in their 2012 kernels' structure.
// Included by traverse.glsl in place of while-if for the binary nodes (raycast.comp's `*_while_while`
// variants); the step is the layout's (layout_visit), the stack stack.glsl's (a sentinel at the
// bottom, popped without a distance test), the box test and the leaf loop every traversal's.
//
// One ray per invocation. The inner loop runs over inner nodes only: when it reaches a leaf and
// has none postponed, it keeps that leaf for later and goes on with the next entry of the stack;
// it ends for a lane when it reaches a second leaf or runs out of nodes, and for the whole
// subgroup as soon as every lane still in it holds a postponed leaf (subgroupAll). Then the leaf
// loop tests the postponed leaf, and the current entry too while that is a leaf. On SIMD
// hardware (a lavapipe subgroup is a CPU vector register) this keeps the lanes doing the same
// kind of work: box tests with box tests, triangles with triangles.
//
// Same results as while-if: the leaves are tested in the same order; a postponed leaf only lets
// the inner loop test a few boxes against a farther h.t than while-if would have (more boxes,
// never fewer, so never a missed hit).
#ifndef TRILAB_WHILE_WHILE
#define TRILAB_WHILE_WHILE


// Bottom-of-stack sentinel (the count bits are 31 > MAX_LEAF_SIZE: no real entry has it).
const uint WW_DONE = 0xFFFFFFFFu;

bool ww_is_leaf(uint e) {
    return e != WW_DONE && LEAF_ENTRY_COUNT(e) != 0u;
}

// Traces `r` through the BVH, updating `h` (h.t must start at the ray's tmax).
void trace(TraceRay r, inout HitState h, bool any_hit) {
    LayoutRoot root = layout_root();
    BoxRay b;
    if (!ray_enter(r, h, root, b)) {
        return;
    }
    stack_size = 0u;
    stack_push(WW_DONE, 0.0);
    uint current = root.entry;
    uint leaf = WW_DONE; // the postponed leaf, or none
    if (ww_is_leaf(current)) {
        leaf = current;
        current = WW_DONE;
    }
    while (true) {
        // Inner nodes, until a second leaf or the end (or every lane holds a leaf).
        while (LEAF_ENTRY_COUNT(current) == 0u) {
            COUNT_INNER();
            if (!layout_visit(b, h.t, LEAF_ENTRY_FIRST(current), current)) {
                current = stack_pop();
            }
            // Postpone a leaf: keep it and go on with the next entry.
            if (leaf == WW_DONE && ww_is_leaf(current)) {
                leaf = current;
                current = stack_pop();
            }
            if (subgroupAll(leaf != WW_DONE)) {
                break;
            }
        }
        // The postponed leaf, then the current entry while it is a leaf.
        while (leaf != WW_DONE) {
            uint count = LEAF_ENTRY_COUNT(leaf);
            COUNT_LEAF(count);
            bool found = intersect_leaf(r, LEAF_ENTRY_FIRST(leaf), count, h, any_hit);
            if (any_hit && found) {
                return;
            }
            leaf = WW_DONE;
            if (ww_is_leaf(current)) {
                leaf = current;
                current = stack_pop();
            }
        }
        if (current == WW_DONE) {
            return;
        }
    }
}

#endif
