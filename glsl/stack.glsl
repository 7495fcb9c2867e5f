// The per-ray traversal stack: entries (LEAF_ENTRY, shared.glsl) with the entry distance of
// their box, so a pop costs no memory access and an entry beyond the closest hit so far is
// dropped unvisited. A layout's visit pushes onto it, the traversal loop pops from it
// (traversal/while_if.glsl, raycast_persistent.comp, raycast_coop.comp).
//
// Private globals: one stack per invocation, like trav_counts (counts.glsl); after inlining,
// the driver holds them as the locals they replace. LAYOUT_STACK_SIZE entries, defined by the
// layout before this file: the host refuses a tree whose stack bound exceeds its layout's
// (LayoutNodes::stack_bound) before anything is uploaded, so no push is checked. Each array has
// room for at least STACK_MIN_ENTRIES (shared.glsl), so that a GPU's compiler keeps it in
// scratch memory and not in registers.
#ifndef TRILAB_STACK
#define TRILAB_STACK

#ifndef LAYOUT_STACK_SIZE
#error "stack.glsl: the layout defines LAYOUT_STACK_SIZE before including it"
#endif

uint stack_entry[STACK_CAPACITY(LAYOUT_STACK_SIZE)];
float stack_t[STACK_CAPACITY(LAYOUT_STACK_SIZE)];
uint stack_size;

void stack_push(uint entry, float tnear) {
    stack_entry[stack_size] = entry;
    stack_t[stack_size] = tnear;
    stack_size += 1u;
}

// The top entry, whatever its distance (while-while, which pushes a sentinel first and culls
// nothing).
uint stack_pop() {
    stack_size -= 1u;
    return stack_entry[stack_size];
}

// The nearest pushed entry whose entry distance is not beyond `tmax` (the closest hit so far),
// into `entry`; the others on the way are dropped. False when none is left.
bool stack_pop_nearest(float tmax, out uint entry) {
    // One exit, `entry` written on every path (glsl/README.md, "Writing a unit").
    entry = 0u;
    bool found = false;
    while (stack_size > 0u) {
        stack_size -= 1u;
        if (stack_t[stack_size] <= tmax) {
            entry = stack_entry[stack_size];
            found = true;
            break;
        }
    }
    return found;
}

#endif
