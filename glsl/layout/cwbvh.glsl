// The cwbvh layout's traversal (the `*_cwbvh` variants: `// trilab:layouts` in raycast.comp and
// pathtrace.comp): Ylitie, Karras & Laine, "Efficient Incoherent Ray Traversal on GPUs Through
// Compressed Wide BVHs" (HPG 2017), sec. 4: octant-ordered node groups with hit masks over
// 8-wide 80-byte nodes whose child boxes are quantized to 8 bits per plane. Its traversal is its
// own (LAYOUT_TRACE, layout_interface.glsl): trace() here runs in place of the per-ray while-if
// loop, with the leaf loop (leaf.glsl), the box test (box.glsl) and the packed leaf entries
// (LEAF_ENTRY, shared.glsl) every layout uses. Host side: src/encoding/layout/cwbvh.rs; the
// format, the quantization and the CPU model of this loop: src/bvh/cwbvh/ (CwNode,
// CwBvh::trace).
//
// Buffer at BINDING_NODES, 16-byte texels: node i is texels 5i .. 5i + 4,
//   5i:     p.x, p.y, p.z (f32 bits), e.x | e.y << 8 | e.z << 16 | imask << 24
//   5i + 1: child_base, leaf_base, meta[0..4], meta[4..8] (bytes, slot 0 lowest)
//   5i + 2: q_lo_x[0..4], q_lo_x[4..8], q_lo_y[0..4], q_lo_y[4..8]
//   5i + 3: q_lo_z[0..4], q_lo_z[4..8], q_hi_x[0..4], q_hi_x[4..8]
//   5i + 4: q_hi_y[0..4], q_hi_y[4..8], q_hi_z[0..4], q_hi_z[4..8]
// then the leaf table: u32 word w is component w & 3 of texel w >> 2; leaf_base is a word index.
// Child s's box on axis k is p + float(q) * 2^(e - 127), decoded in f32 exactly as here (the
// product is exact; a fused multiply-add rounds the same): the host quantized every plane
// outwards and checked it in this arithmetic, so the decoded box contains the child's.
//
// meta[s]: 0 empty (never tested); 0b001_11sss an inner child in slot s (its node: child_base +
// the inner slots below s, from imask); 0b001_rrrrr a leaf, entry rrrrr of the node's leaf table
// (our adaptation: the table entry stands for the paper's triangle, so leaves of 16 units in
// any intersector's format fit).
//
// Per ray: oct_inv = 7 ^ octant (octant bit k: dir[k] < 0). A node's hit inner children go to
// bits 24 + (s ^ oct_inv) of its group's mask, so taking the highest bit first visits the slot
// of the ray's octant first (the host put there the child such rays meet first); hit leaves go
// to bits rrrrr and are intersected at once. A group (child_base, mask | imask) with inner bits
// left is pushed when one child is taken; groups carry no distance, so a box is culled only
// against the closest hit when its parent is visited.
//
// Stack: CWBVH_STACK_SIZE groups (shared.glsl); the host refuses a tree whose bound
// (CwBvh::stack_bound) exceeds it before anything is uploaded, so no check per push.
#ifndef TRILAB_LAYOUT_CWBVH
#define TRILAB_LAYOUT_CWBVH

#include "layout_interface.glsl"

#define LAYOUT_TRACE

// Tests present child `j` (0..3) of a half whose meta bytes are `meta4`, box bytes in the
// words lx .. hz; sets its bit in `hits`.
#define CWBVH_TEST(j, meta4, lx, ly, lz, hx, hy, hz)                                           \
    {                                                                                          \
        uint meta = bitfieldExtract(meta4, 8 * j, 8);                                          \
        if (meta != 0u) {                                                                      \
            COUNT_BOXES(1u);                                                                   \
            vec3 qlo = vec3(bitfieldExtract(lx, 8 * j, 8), bitfieldExtract(ly, 8 * j, 8),      \
                            bitfieldExtract(lz, 8 * j, 8));                                    \
            vec3 qhi = vec3(bitfieldExtract(hx, 8 * j, 8), bitfieldExtract(hy, 8 * j, 8),      \
                            bitfieldExtract(hz, 8 * j, 8));                                    \
            float tn;                                                                          \
            if (hit_box(b, p + qlo * scale, p + qhi * scale, h.t, tn)) {                       \
                uint bit = (meta & 0x18u) == 0x18u ? (meta & 31u) ^ oct_inv : meta & 31u;      \
                hits |= 1u << bit;                                                             \
            }                                                                                  \
        }                                                                                      \
    }

// The tree's box, for the conservative test only: the root's whole grid, p .. p + 255 scale,
// contains every box of the tree. (The traversal starts at the root group, not at an entry.)
LayoutRoot layout_root() {
    LayoutRoot root;
    root.entry = 0u;
    root.bmin = vec3(0.0);
    root.bmax = vec3(0.0);
#ifdef CONSERVATIVE_TRAVERSAL
    uvec4 root0 = SCENE_TEXEL(scene_nodes, 0u);
    root.bmin = uintBitsToFloat(root0.xyz);
    vec3 scale = uintBitsToFloat(
        uvec3(bitfieldExtract(root0.w, 0, 8), bitfieldExtract(root0.w, 8, 8), bitfieldExtract(root0.w, 16, 8)) << 23u);
    root.bmax = root.bmin + 255.0 * scale;
#endif
    return root;
}

// Traces `r` through the compressed 8-wide BVH, updating `h` (h.t must start at the ray's tmax).
void trace(TraceRay r, inout HitState h, bool any_hit) {
    BoxRay b;
    ray_enter(r, h, layout_root(), b);
    bvec3 neg = lessThan(r.dir, vec3(0.0));
    uint oct_inv = 7u ^ (uint(neg.x) | uint(neg.y) << 1u | uint(neg.z) << 2u);
    uint stack_base[STACK_CAPACITY(CWBVH_STACK_SIZE)];
    uint stack_mask[STACK_CAPACITY(CWBVH_STACK_SIZE)];
    uint sp = 0u;
    // The root group: node 0 alone (bit 31, imask 0).
    uint group_base = 0u;
    uint group_mask = 0x80000000u;
    while (true) {
        if (group_mask < 0x01000000u) {
            // No inner child left in this group.
            if (sp == 0u) {
                return;
            }
            sp -= 1u;
            group_base = stack_base[sp];
            group_mask = stack_mask[sp];
        }
        uint bit = uint(findMSB(group_mask));
        group_mask &= ~(1u << bit);
        uint slot = (bit - 24u) ^ oct_inv;
        uint index = group_base + bitCount(group_mask & ((1u << slot) - 1u) & 0xffu);
        if (group_mask >= 0x01000000u) {
            stack_base[sp] = group_base;
            stack_mask[sp] = group_mask;
            sp += 1u;
        }
        COUNT_INNER();
        uint base = 5u * index;
        uvec4 n0 = SCENE_TEXEL(scene_nodes, base);
        uvec4 n1 = SCENE_TEXEL(scene_nodes, base + 1u);
        uvec4 n2 = SCENE_TEXEL(scene_nodes, base + 2u);
        uvec4 n3 = SCENE_TEXEL(scene_nodes, base + 3u);
        uvec4 n4 = SCENE_TEXEL(scene_nodes, base + 4u);
        vec3 p = uintBitsToFloat(n0.xyz);
        vec3 scale = uintBitsToFloat(uvec3(bitfieldExtract(n0.w, 0, 8), bitfieldExtract(n0.w, 8, 8),
                                           bitfieldExtract(n0.w, 16, 8)) << 23u);
        uint hits = 0u;
        CWBVH_TEST(0, n1.z, n2.x, n2.z, n3.x, n3.z, n4.x, n4.z)
        CWBVH_TEST(1, n1.z, n2.x, n2.z, n3.x, n3.z, n4.x, n4.z)
        CWBVH_TEST(2, n1.z, n2.x, n2.z, n3.x, n3.z, n4.x, n4.z)
        CWBVH_TEST(3, n1.z, n2.x, n2.z, n3.x, n3.z, n4.x, n4.z)
        if (n1.w != 0u) {
            CWBVH_TEST(0, n1.w, n2.y, n2.w, n3.y, n3.w, n4.y, n4.w)
            CWBVH_TEST(1, n1.w, n2.y, n2.w, n3.y, n3.w, n4.y, n4.w)
            CWBVH_TEST(2, n1.w, n2.y, n2.w, n3.y, n3.w, n4.y, n4.w)
            CWBVH_TEST(3, n1.w, n2.y, n2.w, n3.y, n3.w, n4.y, n4.w)
        }
        group_base = n1.x;
        group_mask = (hits & 0xff000000u) | (n0.w >> 24u);
        // The leaf group, at once, in table order.
        uint leaf_bits = hits & 0x00ffffffu;
        while (leaf_bits != 0u) {
            uint rank = uint(findLSB(leaf_bits));
            leaf_bits &= leaf_bits - 1u;
            uint w = n1.y + rank;
            uint entry = SCENE_TEXEL(scene_nodes, w >> 2u)[w & 3u];
            uint count = LEAF_ENTRY_COUNT(entry);
            COUNT_LEAF(count);
            bool found = intersect_leaf(r, LEAF_ENTRY_FIRST(entry), count, h, any_hit);
            if (any_hit && found) {
                return;
            }
        }
    }
}

#endif
