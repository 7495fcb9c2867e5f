// Stack-based "while-if" BVH traversal (Shumskiy & Parshin, appendix 8.3; after Aila & Laine
// 2009), for every layout that gives a step (layout_interface.glsl): one node per loop
// iteration; at an inner node the layout's step tests its children, visits the nearest next and
// pushes the others with their box's entry distance; a popped entry whose entry distance is
// beyond the closest hit so far is skipped without being visited (measured 1.04-1.09x on the
// bunny's binary tree, results/lavapipe/traversals/bvh2-cull-ab.md); a leaf goes through the leaf
// loop (leaf.glsl). Rust twins: traversal.rs (binary nodes), bvh::WideBvh::trace (bvh4, bvh8).
#ifndef TRILAB_WHILE_IF
#define TRILAB_WHILE_IF

// The loop from entry `current` (its box hit, not beyond h.t) with the stack as it is: the rest
// of a ray's traversal (raycast_packet.comp's hybrid hands each lane over to it).
void while_if_from(TraceRay r, inout HitState h, BoxRay b, uint current, bool any_hit) {
    while (true) {
        uint count = LEAF_ENTRY_COUNT(current);
        uint first = LEAF_ENTRY_FIRST(current);
        bool pop = true;
        if (count > 0u) {
            COUNT_LEAF(count);
            bool found = intersect_leaf(r, first, count, h, any_hit);
            if (any_hit && found) {
                return;
            }
        } else {
            COUNT_INNER();
            pop = !layout_visit(b, h.t, first, current);
        }
        if (pop && !stack_pop_nearest(h.t, current)) {
            return;
        }
    }
}

void trace(TraceRay r, inout HitState h, bool any_hit) {
    LayoutRoot root = layout_root();
    BoxRay b;
    if (!ray_enter(r, h, root, b)) {
        return;
    }
    stack_size = 0u;
    while_if_from(r, h, b, root.entry, any_hit);
}

#endif
