//! Compressed wide BVH (`cwbvh`): Ylitie, Karras & Laine, "Efficient Incoherent Ray Traversal
//! on GPUs Through Compressed Wide BVHs" (HPG 2017), sec. 3 (node format) and sec. 4
//! (traversal): 8-wide nodes of 80 bytes whose child boxes are quantized to 8 bits per plane
//! on a grid anchored at the node's box, walked in the ray's octant order with hit masks.
//!
//! The tree is the SAH collapse of the binary tree into 8-wide nodes ([`WideBvh<8>`],
//! [`Collapse::Sah`], the paper's sec. 4.1 dynamic program with our leaves kept), re-laid out
//! and quantized here.
//!
//! [`WideBvh<8>`]: crate::bvh::WideBvh
//! [`Collapse::Sah`]: crate::bvh::Collapse::Sah
//!
//! # Node ([`CwNode`], `#[repr(C)]`, 80 bytes = 5 `uvec4` texels)
//!
//! | bytes | texel | field | meaning |
//! |---|---|---|---|
//! | 0..12  | 0.xyz | `p[3]` | grid origin: the node box's min corner (f32) |
//! | 12..15 | 0.w   | `e[3]` | per-axis scale `2^(e - 127)`: the biased exponent of an f32 (`uintBitsToFloat(e << 23)`) |
//! | 15     | 0.w   | `imask` | bit `s` set: slot `s` holds an inner node |
//! | 16..20 | 1.x   | `child_base` | node index of the first inner child; inner children are consecutive, in slot order |
//! | 20..24 | 1.y   | `leaf_base` | u32-word index, in the whole buffer, of the node's first leaf-table entry (the paper's triangle base index) |
//! | 24..32 | 1.zw  | `meta[8]` | per slot: 0 empty; `0b001_xxxxx` present, `xxxxx` = `24 + s` for an inner child, its rank among the node's leaves (0..=7) for a leaf |
//! | 32..80 | 2..4  | `q_lo_x[8]`, `q_lo_y`, `q_lo_z`, `q_hi_x`, `q_hi_y`, `q_hi_z` | child box planes on the grid |
//!
//! Child `s`'s box on axis `k` decodes as `p[k] + float(q_lo[k][s]) * scale[k]` ..
//! `p[k] + float(q_hi[k][s]) * scale[k]`, in f32, the sum rounded to nearest (an `fma` gives the
//! same: the product is exact). That is the only box arithmetic the kernel may use: the paper's
//! faster form, which folds the grid into the ray (`q * (scale / d) + (p - o) / d`), rounds
//! differently and is not covered by the guarantee below.
//!
//! # Leaves: one indirection (our adaptation)
//!
//! Ylitie's leaf meta holds up to 3 triangles in unary plus a 5-bit offset from the node's
//! triangle base, and the triangles of a node are stored consecutively. Our leaves hold up to
//! 16 triangles in an encoding's units (1 or 4 triangles per unit; up to 16 units), which that
//! byte cannot describe, and their units sit where the binary tree put them. So a leaf child
//! stands for exactly one "triangle" of the paper's format: an entry of a per-node *leaf table*,
//! `leaf_entry(first_unit, count)` (`crate::shared`; the traversals' packed stack entry), at word `leaf_base + rank`.
//! The node stays 80 bytes, every intersector's leaf format (1- and 4-triangle units) fits
//! unchanged, the paper's hit-mask traversal is unchanged (its triangle group becomes a group of
//! leaf-table entries), and a leaf costs one extra 4-byte load. The leaf table follows the nodes
//! in one buffer of `uvec4` texels ([`CwBvh::words`]): node `i` is texels `5i..5i+4`, the table
//! starts at word `20 * nodes`, padded to a whole texel at the end.
//!
//! # Quantization (conservative in the kernel's arithmetic)
//!
//! Per node and axis (the paper's eq. 1-2): `p` = the node box's min (a subnormal `p` is moved
//! down to 0 or `-f32::MIN_POSITIVE`, so a flushing device reads the same origin), the scale
//! the smallest power of two with `p + 255 * scale >= max` in the kernel's f32 arithmetic
//! (biased exponent at least 1: never a subnormal scale), then `q_lo = floor((lo - p) /
//! scale)` and `q_hi = ceil((hi - p) / scale)`, computed in f64. Those are not always
//! conservative once decoded in f32: `lo - p` is inexact in f64 when the magnitudes are far apart
//! (`p = -2^66`, `lo = -1e-20`: the floor lands on the grid point 0, above `lo`). So every plane
//! is then checked with the kernel's own decode — `p + float(q) * scale` in f32, and the same
//! value flushed to zero where it is subnormal (a device may flush) — and `q_lo` is lowered /
//! `q_hi` raised one step at a time until the decoded box contains the child's true box
//! ([`decode_plane`], [`quantize_axis`]; tested on every child of the bunny's trees and on
//! adversarial boxes, where the unchecked floor/ceil fails). `q_lo = 0` decodes to `p <= lo`, so
//! lowering always ends; `q_hi = 255` reaches the grid's end `>= max` by the choice of scale.
//!
//! # Slots in octant order
//!
//! Sec. 3.2 of the paper: a node's children are assigned to its 8 slots so that slot `s` holds
//! the child a ray whose direction lies in octant `s` should meet first. The cost of child `i` in slot `s` is
//! `dot(c_i - c_parent, d_s)` (box centres; `d_s` = the diagonal direction of octant `s`, whose
//! bit `k` set means negative along axis `k`); the paper minimises the total with an auction
//! algorithm. [`SlotOrder::Greedy`] takes the cheapest (child, slot) pair left, repeatedly;
//! [`SlotOrder::Exact`] finds the least total cost (exhaustive over assignments, with pruning:
//! at most 8 children).
//!
//! # Traversal ([`CwBvh::trace`], sec. 4 of the paper, mirrored by the kernel)
//!
//! Per ray: `oct_inv = 7 ^ octant`, octant bit `k` = direction negative along axis `k`. A node
//! group is `(child_base, hits)`: bits 24..31 of `hits` are the hit inner children, each at bit
//! `24 + (s ^ oct_inv)`, and bits 0..7 the node's `imask`; the next child is the highest set
//! bit (for the slot matching the ray's octant first), its node index `child_base +
//! popcount(imask & ((1 << s) - 1))`. Testing a node's 8 child boxes yields its node group and
//! its leaf group `(leaf_base, leaf bits)`; the leaf group is intersected at once (the
//! paper's triangle postponing is not done), the node group's remainder is pushed when it has
//! more than the child taken. Groups carry no distance, so nothing is culled on pop: a child is
//! skipped only by its box test against the closest hit at its parent's visit.
//!
//! The root box is not stored: the walk starts at node 0 (its children's boxes), and
//! [`CwBvh::root_grid`] (the root's whole 255-step grid) is a box around the scene a
//! conservative kernel can start from.

//!
//! # Files
//!
//! The node, the tree and the kernel's buffer are here; the grid arithmetic ([`decode_plane`],
//! [`axis_grid`], [`quantize_axis`], [`check_contains`]) is `bvh::quantize`'s (shared with qbvh4), the octant slot
//! order ([`SlotOrder`]) in `slots.rs`, the build ([`CwBvh::build_with`]) in `compress.rs`, sizes
//! and costs ([`CwStats`]) in `stats.rs`, the CPU traversal in `trace.rs`, the invariants in
//! `validate.rs`. The leaf loop, the slab test, the hit and its tie-break rule are every
//! layout's (`bvh::walk`, [`bvh::slab`](crate::bvh::slab), [`bvh::hit`](crate::bvh::hit)).

use bytemuck::{Pod, Zeroable};

use super::{Aabb, PAD_SLOT};

mod compress;
mod slots;
mod stats;
mod trace;
mod validate;

pub use crate::bvh::quantize::{axis_grid, check_contains, decode_plane, quantize_axis, scale_of, Q_MAX};
use crate::bvh::quantize::{Grid, Planes};
pub use slots::SlotOrder;
pub use stats::CwStats;

/// Children per node.
pub const CW_WIDTH: usize = 8;
/// 16-byte texels per node.
pub const CW_NODE_TEXELS: usize = 5;
/// u32 words per node.
pub const CW_NODE_WORDS: usize = 4 * CW_NODE_TEXELS;
/// `meta` of an empty slot.
pub const META_EMPTY: u8 = 0;
/// `meta`'s top three bits for a present child: one unit in the paper's unary count (one node,
/// or one leaf-table entry).
pub const META_PRESENT: u8 = 0b001 << 5;
/// Bit of slot 0 in a node group's hit mask (inner children's `meta` low bits are `24 + s`).
pub const INNER_BIT0: u32 = 24;

/// One compressed 8-wide node (see the module docs for the fields).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CwNode {
    pub p: [f32; 3],
    pub e: [u8; 3],
    pub imask: u8,
    pub child_base: u32,
    pub leaf_base: u32,
    pub meta: [u8; 8],
    pub q_lo_x: [u8; 8],
    pub q_lo_y: [u8; 8],
    pub q_lo_z: [u8; 8],
    pub q_hi_x: [u8; 8],
    pub q_hi_y: [u8; 8],
    pub q_hi_z: [u8; 8],
}

const _: () = assert!(std::mem::size_of::<CwNode>() == 80);
const _: () = assert!(std::mem::size_of::<CwNode>() == 16 * CW_NODE_TEXELS);
const _: () = assert!(std::mem::align_of::<CwNode>() == 4);

/// A compressed wide BVH: the nodes, the leaf table, and (when built from a [`Bvh`](crate::bvh::Bvh)) the
/// binary tree's `prim_ids` for the CPU traversal.
#[derive(Clone, Debug)]
pub struct CwBvh {
    /// Root at 0.
    pub nodes: Vec<CwNode>,
    /// Leaf table: `leaf_entry(first_unit, count)` per leaf child; node `i`'s leaves are entries
    /// `nodes[i].leaf_base - 20 * nodes.len()` onwards, in slot order.
    pub leaves: Vec<u32>,
    /// The binary root's box.
    pub bounds: Aabb,
    /// Leaf slot -> triangle id (the binary tree's); empty when built from an encoding's nodes
    /// (then the units are the encoding's and only a kernel can intersect them).
    pub prim_ids: Vec<u32>,
    pub max_leaf_size: u32,
    pub slot_order: SlotOrder,
    /// Collapse and compression, seconds.
    pub build_seconds: f64,
}

impl CwNode {
    /// The grid's scale per axis.
    pub fn scales(&self) -> [f32; 3] {
        self.e.map(scale_of)
    }

    /// Whether slot `s` holds a child.
    pub fn is_present(&self, s: usize) -> bool {
        self.meta[s] != META_EMPTY
    }

    /// Whether slot `s` holds an inner node.
    pub fn is_inner(&self, s: usize) -> bool {
        self.imask >> s & 1 == 1
    }

    /// The node's grid.
    pub fn grid(&self) -> Grid {
        Grid { p: self.p, e: self.e }
    }

    /// Child `s`'s planes on the grid.
    pub fn planes(&self, s: usize) -> Planes {
        ([self.q_lo_x[s], self.q_lo_y[s], self.q_lo_z[s]], [self.q_hi_x[s], self.q_hi_y[s], self.q_hi_z[s]])
    }

    /// Child `s`'s box as the kernel decodes it (without flushing).
    pub fn child_box(&self, s: usize) -> Aabb {
        self.grid().decode(self.planes(s))
    }

    /// Node index of inner slot `s`.
    pub fn inner_child(&self, s: usize) -> u32 {
        self.child_base + (self.imask as u32 & ((1u32 << s) - 1)).count_ones()
    }

    fn set_q(&mut self, s: usize, (lo, hi): Planes) {
        [self.q_lo_x[s], self.q_lo_y[s], self.q_lo_z[s]] = lo;
        [self.q_hi_x[s], self.q_hi_y[s], self.q_hi_z[s]] = hi;
    }
}

impl CwBvh {
    /// Word index where the leaf table starts.
    pub fn table_word(&self) -> usize {
        self.nodes.len() * CW_NODE_WORDS
    }

    /// Leaf-table entry `rank` of node `n`.
    pub fn leaf(&self, n: &CwNode, rank: u32) -> u32 {
        self.leaves[n.leaf_base as usize - self.table_word() + rank as usize]
    }

    /// The kernel's buffer: the nodes, then the leaf table, zero-padded to whole 16-byte texels.
    pub fn words(&self) -> Vec<u32> {
        let mut w: Vec<u32> = bytemuck::cast_slice(&self.nodes).to_vec();
        w.extend_from_slice(&self.leaves);
        w.resize(w.len().div_ceil(4) * 4, 0);
        w
    }

    /// Bytes of [`CwBvh::words`].
    pub fn bytes(&self) -> usize {
        (self.table_word() + self.leaves.len()).div_ceil(4) * 16
    }

    /// The root node's whole grid, `p` to `p + 255 scale` per axis (f32, as the kernel would
    /// compute it): contains every box in the tree.
    pub fn root_grid(&self) -> Aabb {
        self.nodes[0].grid().extent()
    }

    /// Triangles in the hierarchy (padding not counted); 0 without `prim_ids`.
    pub fn triangle_count(&self) -> usize {
        self.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_texels_are_the_documented_ones() {
        let mut n = CwNode::zeroed();
        n.p = [1.0, 2.0, 3.0];
        n.e = [10, 11, 12];
        n.imask = 0b1000_0001;
        n.child_base = 7;
        n.leaf_base = 9;
        n.meta = [1, 2, 3, 4, 5, 6, 7, 8];
        n.q_lo_x[0] = 0xaa;
        n.q_hi_z[7] = 0xbb;
        let w: &[u32] = bytemuck::cast_slice(std::slice::from_ref(&n));
        assert_eq!(w.len(), 20);
        assert_eq!(&w[0..3], &[1.0f32.to_bits(), 2.0f32.to_bits(), 3.0f32.to_bits()]);
        // Little-endian bytes: e in the low three bytes of word 3, imask in the top one.
        assert_eq!(w[3], 10 | 11 << 8 | 12 << 16 | 0b1000_0001 << 24);
        assert_eq!((w[4], w[5]), (7, 9));
        assert_eq!((w[6], w[7]), (0x0403_0201, 0x0807_0605));
        assert_eq!(w[8] & 0xff, 0xaa);
        assert_eq!(w[19] >> 24, 0xbb);
    }
}
