//! Compressed wide BVH (`cwbvh`): Ylitie, Karras & Laine, "Efficient Incoherent Ray Traversal
//! on GPUs Through Compressed Wide BVHs" (HPG 2017), sec. 3 (node format) and sec. 4
//! (traversal): 8-wide nodes of 80 bytes whose child boxes are quantized to 8 bits per plane
//! on a grid anchored at the node's box, walked in the ray's octant order with hit masks.
//!
//! The tree is the SAH collapse of the binary tree into 8-wide nodes ([`WideBvh<8>`],
//! [`Collapse::Sah`], the paper's sec. 4.1 dynamic program with our leaves kept), re-laid out
//! and quantized here.
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

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use serde::Serialize;

use super::wide::{slab_f64, WideHit, WideNode, WideSteps};
use super::{Aabb, BuildOptions, Bvh, BvhNode, Collapse, WideBvh, PAD_SLOT};
use crate::rays::Ray;
use crate::scene::Mesh;
use crate::shared::{self, leaf_entry_count, leaf_entry_first, LEAF_ENTRY_FIRST_LIMIT, LEAF_ENTRY_MAX_COUNT};

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
/// Largest grid coordinate.
pub const Q_MAX: u8 = 255;

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

/// The scale `2^(e - 127)` of biased exponent `e` (1..=254), as the kernel makes it
/// (`uintBitsToFloat(e << 23)`).
pub fn scale_of(e: u8) -> f32 {
    f32::from_bits((e as u32) << 23)
}

/// A subnormal result read as a device that flushes denormals reads it (zero, same sign).
fn flushed(x: f32) -> f32 {
    if x.is_subnormal() {
        0.0f32.copysign(x)
    } else {
        x
    }
}

/// Plane `q` of a grid (origin `p`, biased exponent `e`) in the kernel's arithmetic,
/// `p + float(q) * scale` in f32, and that value flushed as a denormal-flushing device would
/// return it. A plane is conservative when both values are.
pub fn decode_plane(p: f32, e: u8, q: u8) -> [f32; 2] {
    let d = p + q as f32 * scale_of(e);
    [d, flushed(d)]
}

fn lo_ok(p: f32, e: u8, q: u8, lo: f32) -> bool {
    decode_plane(p, e, q).iter().all(|&d| d <= lo)
}

fn hi_ok(p: f32, e: u8, q: u8, hi: f32) -> bool {
    decode_plane(p, e, q).iter().all(|&d| d >= hi)
}

/// The grid of one axis of a node box `[lo, hi]`: origin `p <= lo` (never subnormal) and the
/// smallest biased exponent whose 255th step reaches `hi` in the kernel's arithmetic; `None`
/// when none does (a non-finite box).
pub fn axis_grid(lo: f32, hi: f32) -> Option<(f32, u8)> {
    if !lo.is_finite() || !hi.is_finite() || lo > hi {
        return None;
    }
    let p = if lo.is_subnormal() {
        if lo > 0.0 {
            0.0
        } else {
            -f32::MIN_POSITIVE
        }
    } else {
        lo
    };
    let extent = hi as f64 - p as f64;
    let mut e: i32 = if extent > 0.0 { (extent / Q_MAX as f64).log2().ceil() as i32 + 127 } else { 1 };
    e = e.clamp(1, 254);
    // The f64 estimate may be one short (the extent rounded, or the sum rounding down).
    while !hi_ok(p, e as u8, Q_MAX, hi) {
        if e == 254 {
            return None;
        }
        e += 1;
    }
    Some((p, e as u8))
}

/// The unchecked grid coordinates of `[lo, hi]` (floor and ceil in f64, clamped to 0..=255):
/// the first guess [`quantize_axis`] corrects.
fn quantize_guess(p: f32, e: u8, lo: f32, hi: f32) -> (u8, u8) {
    let s = scale_of(e) as f64;
    let ql = ((lo as f64 - p as f64) / s).floor().clamp(0.0, Q_MAX as f64) as u8;
    let qh = ((hi as f64 - p as f64) / s).ceil().clamp(0.0, Q_MAX as f64) as u8;
    (ql, qh)
}

/// The grid coordinates of a child's `[lo, hi]` on one axis of its parent's grid, rounded
/// outwards: the decoded planes (both [`decode_plane`] values) satisfy `q_lo -> <= lo` and
/// `q_hi -> >= hi`. `None` when the grid cannot hold the interval (it is not inside
/// `[p, p + 255 scale]`).
pub fn quantize_axis(p: f32, e: u8, lo: f32, hi: f32) -> Option<(u8, u8)> {
    if lo.partial_cmp(&hi).is_none_or(|o| o == std::cmp::Ordering::Greater) {
        return None;
    }
    let (mut ql, mut qh) = quantize_guess(p, e, lo, hi);
    while !lo_ok(p, e, ql, lo) {
        ql = ql.checked_sub(1)?;
    }
    while !hi_ok(p, e, qh, hi) {
        qh = qh.checked_add(1)?;
    }
    Some((ql, qh))
}

/// How a node's children are assigned to its 8 slots (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SlotOrder {
    /// Cheapest (child, slot) pair first, repeatedly.
    Greedy,
    /// The assignment of least total cost (the optimum the paper's auction approximates).
    Exact,
    /// The collapse's slot order, slots 0.. (no octant ordering; for comparison).
    Plain,
}

/// `cost[i][s]`: child `i` (box centre `c`) in slot `s` of a node with box centre `parent`.
fn slot_costs(parent: Vec3, centres: &[Vec3]) -> Vec<[f64; CW_WIDTH]> {
    centres
        .iter()
        .map(|c| {
            let d = (*c - parent).as_dvec3();
            std::array::from_fn(|s| {
                let sign = |k: usize| if s >> k & 1 == 1 { -1.0 } else { 1.0 };
                d.x * sign(0) + d.y * sign(1) + d.z * sign(2)
            })
        })
        .collect()
}

/// Slot of each child under `how`.
fn assign_slots(how: SlotOrder, cost: &[[f64; CW_WIDTH]]) -> Vec<usize> {
    let n = cost.len();
    match how {
        SlotOrder::Plain => (0..n).collect(),
        SlotOrder::Greedy => {
            let mut pairs: Vec<(f64, usize, usize)> =
                (0..n).flat_map(|i| (0..CW_WIDTH).map(move |s| (cost[i][s], i, s))).collect();
            pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
            let mut slot = vec![usize::MAX; n];
            let mut taken = [false; CW_WIDTH];
            for (_, i, s) in pairs {
                if slot[i] == usize::MAX && !taken[s] {
                    slot[i] = s;
                    taken[s] = true;
                }
            }
            slot
        }
        SlotOrder::Exact => {
            // Depth-first over children, slots free; prune with the cost so far plus each
            // remaining child's cheapest slot.
            let best_row: Vec<f64> = cost.iter().map(|r| r.iter().copied().fold(f64::INFINITY, f64::min)).collect();
            let mut rest = vec![0.0; n + 1];
            for i in (0..n).rev() {
                rest[i] = rest[i + 1] + best_row[i];
            }
            struct Search<'a> {
                cost: &'a [[f64; CW_WIDTH]],
                rest: Vec<f64>,
                cur: Vec<usize>,
                best: Vec<usize>,
                best_cost: f64,
            }
            fn go(st: &mut Search, i: usize, taken: u32, sum: f64) {
                if sum + st.rest[i] >= st.best_cost {
                    return;
                }
                if i == st.cost.len() {
                    st.best_cost = sum;
                    st.best = st.cur.clone();
                    return;
                }
                let mut order: [usize; CW_WIDTH] = std::array::from_fn(|s| s);
                order.sort_by(|&a, &b| st.cost[i][a].total_cmp(&st.cost[i][b]));
                for s in order {
                    if taken >> s & 1 == 0 {
                        st.cur[i] = s;
                        go(st, i + 1, taken | 1 << s, sum + st.cost[i][s]);
                    }
                }
            }
            // Start from the greedy assignment's cost (a bound to beat, and the answer on ties).
            let greedy = assign_slots(SlotOrder::Greedy, cost);
            let gcost: f64 = greedy.iter().enumerate().map(|(i, &s)| cost[i][s]).sum();
            let mut st = Search { cost, rest, cur: vec![0; n], best: greedy, best_cost: gcost };
            go(&mut st, 0, 0, 0.0);
            st.best
        }
    }
}

/// A compressed wide BVH: the nodes, the leaf table, and (when built from a [`Bvh`]) the
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

/// Sizes of a compressed tree.
#[derive(Clone, Debug, Serialize)]
pub struct CwStats {
    pub nodes: usize,
    pub leaves: usize,
    /// Occupied child slots per node, mean.
    pub mean_children: f64,
    /// Deepest node; root at depth 0.
    pub depth: u32,
    /// Nodes (80 bytes each) plus the leaf table, padded to a whole texel.
    pub bytes: usize,
    /// `bytes` over the triangles in the hierarchy.
    pub bytes_per_triangle: f64,
    /// [`CwBvh::stack_bound`].
    pub stack_bound: usize,
    /// The SAH cost with the decoded (quantized) boxes, priced as [`WideBvh::sah_cost`].
    pub sah_cost: f64,
    pub build_ms: f64,
}

/// A leaf-table entry (`crate::shared::leaf_entry`), or why it cannot hold the leaf: more than
/// 2^27 units, or 32 and more in one leaf (the binary tree's limit is 16).
fn leaf_entry(first: u32, count: u32) -> Result<u32, String> {
    if u64::from(first) >= LEAF_ENTRY_FIRST_LIMIT || count == 0 || count > LEAF_ENTRY_MAX_COUNT {
        return Err(format!("a leaf of {count} units from unit {first} does not fit a leaf-table entry"));
    }
    Ok(shared::leaf_entry(first, count))
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

    /// Child `s`'s box as the kernel decodes it (without flushing).
    pub fn child_box(&self, s: usize) -> Aabb {
        let lo = [self.q_lo_x[s], self.q_lo_y[s], self.q_lo_z[s]];
        let hi = [self.q_hi_x[s], self.q_hi_y[s], self.q_hi_z[s]];
        let d = |k: usize, q: u8| decode_plane(self.p[k], self.e[k], q)[0];
        Aabb {
            min: Vec3::new(d(0, lo[0]), d(1, lo[1]), d(2, lo[2])),
            max: Vec3::new(d(0, hi[0]), d(1, hi[1]), d(2, hi[2])),
        }
    }

    /// Node index of inner slot `s`.
    pub fn inner_child(&self, s: usize) -> u32 {
        self.child_base + (self.imask as u32 & ((1u32 << s) - 1)).count_ones()
    }

    fn set_q(&mut self, s: usize, lo: [u8; 3], hi: [u8; 3]) {
        [self.q_lo_x[s], self.q_lo_y[s], self.q_lo_z[s]] = lo;
        [self.q_hi_x[s], self.q_hi_y[s], self.q_hi_z[s]] = hi;
    }
}

/// One child being laid out: its true box and what it is.
#[derive(Clone, Copy)]
enum Kid {
    /// A wide node's index.
    Inner(usize, Aabb),
    /// `(first_unit, count)`.
    Leaf(u32, u32, Aabb),
}

impl Kid {
    fn bounds(&self) -> Aabb {
        match *self {
            Kid::Inner(_, b) | Kid::Leaf(_, _, b) => b,
        }
    }
}

/// Quantizes `kids` (in their slots) against the grid of their union; fills `p`, `e` and the
/// planes of `node`.
fn quantize_node(node: &mut CwNode, kids: &[(usize, Kid)]) -> Result<(), String> {
    let mut union = Aabb::EMPTY;
    for (_, k) in kids {
        let b = k.bounds();
        if !b.is_empty() {
            union.grow(&b);
        }
    }
    if union.is_empty() {
        // Only padding leaves (an all-degenerate scene): any grid; boxes at its origin.
        union = Aabb { min: Vec3::ZERO, max: Vec3::ZERO };
    }
    for k in 0..3 {
        let (p, e) = axis_grid(union.min[k], union.max[k])
            .ok_or_else(|| format!("a node box [{}, {}] on axis {k} has no grid", union.min[k], union.max[k]))?;
        node.p[k] = p;
        node.e[k] = e;
    }
    for &(s, kid) in kids {
        let b = kid.bounds();
        let (mut lo, mut hi) = ([0u8; 3], [0u8; 3]);
        if !b.is_empty() {
            for k in 0..3 {
                (lo[k], hi[k]) = quantize_axis(node.p[k], node.e[k], b.min[k], b.max[k]).ok_or_else(|| {
                    format!("child box [{}, {}] on axis {k} does not fit its parent's grid", b.min[k], b.max[k])
                })?;
            }
        }
        node.set_q(s, lo, hi);
    }
    Ok(())
}

impl CwBvh {
    /// The binary tree collapsed ([`Collapse::Sah`]) and compressed, slots in
    /// [`SlotOrder::Greedy`] order.
    pub fn build(bvh: &Bvh) -> Result<CwBvh, String> {
        Self::build_with(bvh, SlotOrder::Greedy)
    }

    pub fn build_with(bvh: &Bvh, order: SlotOrder) -> Result<CwBvh, String> {
        let t0 = Instant::now();
        let mut cw = Self::from_binary_nodes(&bvh.nodes, &bvh.options, order)?;
        cw.prim_ids = bvh.prim_ids.clone();
        cw.build_seconds = t0.elapsed().as_secs_f64();
        Ok(cw)
    }

    /// The compressed tree of a binary node array (as [`WideBvh::collapse_nodes`] takes it:
    /// an encoding's nodes give leaves in the encoding's units). `prim_ids` is left empty.
    pub fn from_binary_nodes(binary: &[BvhNode], o: &BuildOptions, order: SlotOrder) -> Result<CwBvh, String> {
        let t0 = Instant::now();
        let wide = WideBvh::<8>::collapse_nodes(binary, o, Collapse::Sah);
        let mut cw = Self::from_wide(&wide, binary[0].aabb(), order)?;
        cw.max_leaf_size = o.max_leaf_size;
        cw.build_seconds = t0.elapsed().as_secs_f64();
        Ok(cw)
    }

    /// Compresses 8-wide nodes (root at 0; `bounds` the root's box).
    pub fn from_wide(wide: &[WideNode<8>], bounds: Aabb, order: SlotOrder) -> Result<CwBvh, String> {
        let t0 = Instant::now();
        let mut nodes = vec![CwNode::zeroed()];
        let mut leaves: Vec<u32> = vec![];
        // (compressed node to fill, wide node it comes from)
        let mut work = std::collections::VecDeque::from([(0usize, 0usize)]);
        while let Some((ci, wi)) = work.pop_front() {
            let w = &wide[wi];
            let kids: Vec<Kid> = (0..w.children())
                .map(|s| {
                    let b = w.child_box(s);
                    if w.is_leaf(s) {
                        Kid::Leaf(w.child[s], w.count[s], b)
                    } else {
                        Kid::Inner(w.child[s] as usize, b)
                    }
                })
                .collect();
            let mut union = Aabb::EMPTY;
            kids.iter().filter(|k| !k.bounds().is_empty()).for_each(|k| union.grow(&k.bounds()));
            let centre = if union.is_empty() { Vec3::ZERO } else { union.center() };
            let centres: Vec<Vec3> =
                kids.iter().map(|k| if k.bounds().is_empty() { centre } else { k.bounds().center() }).collect();
            let slots = assign_slots(order, &slot_costs(centre, &centres));
            let mut placed: Vec<(usize, Kid)> = slots.iter().copied().zip(kids.iter().copied()).collect();
            placed.sort_by_key(|&(s, _)| s);
            let mut node = CwNode::zeroed();
            node.child_base = nodes.len() as u32;
            node.leaf_base = leaves.len() as u32;
            let mut rank = 0u8;
            for &(s, kid) in &placed {
                match kid {
                    Kid::Inner(child, _) => {
                        node.imask |= 1 << s;
                        node.meta[s] = META_PRESENT | (INNER_BIT0 as u8 + s as u8);
                        work.push_back((nodes.len(), child));
                        nodes.push(CwNode::zeroed());
                    }
                    Kid::Leaf(first, count, _) => {
                        node.meta[s] = META_PRESENT | rank;
                        rank += 1;
                        leaves.push(leaf_entry(first, count)?);
                    }
                }
            }
            quantize_node(&mut node, &placed)?;
            nodes[ci] = node;
        }
        let table = (nodes.len() * CW_NODE_WORDS) as u64;
        if table + leaves.len() as u64 > u32::MAX as u64 {
            return Err(format!("{} nodes and {} leaves overflow 32-bit word indices", nodes.len(), leaves.len()));
        }
        for n in &mut nodes {
            n.leaf_base += table as u32;
        }
        Ok(CwBvh {
            nodes,
            leaves,
            bounds,
            prim_ids: vec![],
            max_leaf_size: 0,
            slot_order: order,
            build_seconds: t0.elapsed().as_secs_f64(),
        })
    }

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
        let r = &self.nodes[0];
        let hi: [f32; 3] = std::array::from_fn(|k| decode_plane(r.p[k], r.e[k], Q_MAX)[0]);
        Aabb { min: Vec3::from_array(r.p), max: Vec3::from_array(hi) }
    }

    /// Most node groups the traversal's stack can hold, whatever the ray: descending from a node
    /// pushes its group only when another of its inner children is still pending, and a node's
    /// group is on the stack at most once, so the bound is the largest number of nodes with two
    /// or more inner children on one path from the root.
    pub fn stack_bound(&self) -> usize {
        let mut need = vec![0usize; self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let n = &self.nodes[i];
            let inner = n.imask.count_ones() as usize;
            let below = (0..CW_WIDTH).filter(|&s| n.is_inner(s)).map(|s| need[n.inner_child(s) as usize]).max();
            need[i] = below.map_or(0, |b| b + (inner >= 2) as usize);
        }
        need[0]
    }

    /// Triangles in the hierarchy (padding not counted); 0 without `prim_ids`.
    pub fn triangle_count(&self) -> usize {
        self.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count()
    }

    /// Calls `f(node, depth)` for every node, depth first.
    fn visit(&self, mut f: impl FnMut(usize, u32)) {
        let mut stack = vec![(0usize, 0u32)];
        while let Some((i, d)) = stack.pop() {
            f(i, d);
            let n = &self.nodes[i];
            for s in (0..CW_WIDTH).filter(|&s| n.is_inner(s)) {
                stack.push((n.inner_child(s) as usize, d + 1));
            }
        }
    }

    /// SAH cost over the decoded boxes, [`WideBvh::sah_cost`]'s formula (`C_t A(n)` per node,
    /// `C_i tests(|leaf|) A(leaf)` per leaf, over `A(root)`; the root node priced with the
    /// binary root's box), so it can be set beside the uncompressed 8-wide tree's cost.
    pub fn sah_cost(&self, o: &BuildOptions) -> f64 {
        let root_area = self.bounds.area().max(f64::MIN_POSITIVE);
        let mut area = vec![0.0; self.nodes.len()];
        area[0] = self.bounds.area();
        let mut cost = 0.0;
        self.visit(|i, _| {
            let n = &self.nodes[i];
            cost += o.cost_traversal as f64 * area[i] / root_area;
            for s in 0..CW_WIDTH {
                if n.is_inner(s) {
                    area[n.inner_child(s) as usize] = n.child_box(s).area();
                } else if n.is_present(s) {
                    let entry = self.leaf(n, (n.meta[s] & 31) as u32);
                    cost += o.cost_intersect as f64 * o.tests(leaf_entry_count(entry) as usize) * n.child_box(s).area()
                        / root_area;
                }
            }
        });
        cost
    }

    pub fn stats(&self, o: &BuildOptions) -> CwStats {
        let (mut occupied, mut depth) = (0, 0);
        self.visit(|i, d| {
            depth = depth.max(d);
            occupied += (0..CW_WIDTH).filter(|&s| self.nodes[i].is_present(s)).count();
        });
        let bytes = self.bytes();
        CwStats {
            nodes: self.nodes.len(),
            leaves: self.leaves.len(),
            mean_children: occupied as f64 / self.nodes.len() as f64,
            depth,
            bytes,
            bytes_per_triangle: bytes as f64 / self.triangle_count().max(1) as f64,
            stack_bound: self.stack_bound(),
            sah_cost: self.sah_cost(o),
            build_ms: self.build_seconds * 1e3,
        }
    }

    /// Closest hit (`any = false`; ties to the lower triangle id) or the first hit found, with
    /// the work it took, walking the compressed tree as the kernel does (module docs): the box
    /// test is [`slab_f64`] on the decoded boxes, `intersect(id, tmax)` the triangle test (the
    /// f64 reference's in the tests). Needs `prim_ids` (a tree from [`CwBvh::build`]).
    pub fn trace(
        &self,
        ray: &Ray,
        any: bool,
        mut intersect: impl FnMut(u32, f64) -> Option<(f64, f64, f64)>,
    ) -> (WideHit, WideSteps) {
        let o = ray.origin.map(f64::from);
        let d = ray.dir.map(f64::from);
        let tmin = ray.tmin as f64;
        let mut best = WideHit::MISS;
        let mut tmax = ray.tmax as f64;
        let mut steps = WideSteps::default();
        let octant = (ray.dir[0] < 0.0) as u32 | ((ray.dir[1] < 0.0) as u32) << 1 | ((ray.dir[2] < 0.0) as u32) << 2;
        let oct_inv = 7 ^ octant;
        // Node groups: (child_base, hits); the root group names node 0 alone.
        let mut stack: Vec<(u32, u32)> = Vec::with_capacity(32);
        let mut group = (0u32, 1u32 << 31);
        loop {
            if group.1 & 0xff00_0000 == 0 {
                match stack.pop() {
                    Some(g) => group = g,
                    None => break,
                }
            }
            // The next child: highest hit bit.
            let bit = 31 - group.1.leading_zeros();
            group.1 &= !(1 << bit);
            let slot = (bit - INNER_BIT0) ^ oct_inv;
            let imask = group.1 & 0xff;
            let index = group.0 + (imask & ((1u32 << slot) - 1)).count_ones();
            if group.1 & 0xff00_0000 != 0 {
                stack.push(group);
                steps.stack_peak = steps.stack_peak.max(stack.len() as u32);
            }
            steps.nodes += 1;
            let n = &self.nodes[index as usize];
            let mut hits = 0u32;
            for s in 0..CW_WIDTH {
                let meta = n.meta[s] as u32;
                if meta == 0 {
                    continue;
                }
                steps.boxes += 1;
                if slab_f64(o, d, &n.child_box(s), tmin, tmax).is_some() {
                    let inner = meta & 0b11000 == 0b11000;
                    let bit = if inner { (meta & 31) ^ oct_inv } else { meta & 31 };
                    hits |= (meta >> 5) << bit;
                }
            }
            group = (n.child_base, (hits & 0xff00_0000) | n.imask as u32);
            // The leaf group, at once.
            let mut leaf_bits = hits & 0x00ff_ffff;
            while leaf_bits != 0 {
                let rank = leaf_bits.trailing_zeros();
                leaf_bits &= leaf_bits - 1;
                let entry = self.leaf(n, rank);
                let (first, count) = (leaf_entry_first(entry), leaf_entry_count(entry));
                steps.leaves += 1;
                for &id in &self.prim_ids[first as usize..(first + count) as usize] {
                    if id == PAD_SLOT {
                        continue;
                    }
                    steps.triangles += 1;
                    if let Some((t, u, v)) = intersect(id, tmax) {
                        if t < best.t || (t == best.t && id < best.id) {
                            best = WideHit { t, id, u, v };
                            tmax = t;
                            if any {
                                return (best, steps);
                            }
                        }
                    }
                }
            }
        }
        (best, steps)
    }

    /// Checks the invariants the kernel relies on, against the binary tree it was built from
    /// and the mesh; returns the first violation. Every node is reached exactly once from the
    /// root, by an index larger than its parent's; the inner children of a node are
    /// `child_base..` in slot order and its leaves `leaf_base..` in slot order; every meta byte
    /// is empty, inner (`0b001_11sss` with `sss` = the slot, matching `imask`) or a leaf of the
    /// right rank; every grid's exponent is normal; every decoded child box contains every
    /// triangle under it (both decode variants, [`decode_plane`]); the leaves are exactly the
    /// binary tree's leaf ranges.
    pub fn validate(&self, bvh: &Bvh, mesh: &Mesh) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("no nodes".into());
        }
        if self.prim_ids != bvh.prim_ids {
            return Err("prim_ids differ from the binary tree's".into());
        }
        // The true box of every node's subtree, from the triangles up.
        let tri_box = |first: u32, count: u32| -> Result<Aabb, String> {
            let mut b = Aabb::EMPTY;
            for slot in first..first.saturating_add(count) {
                let Some(&id) = self.prim_ids.get(slot as usize) else {
                    return Err(format!("leaf slot {slot} out of range"));
                };
                if id != PAD_SLOT {
                    b.grow(&Aabb::from_points(&mesh.vertices(id as usize)));
                }
            }
            Ok(b)
        };
        let mut parent = vec![usize::MAX; self.nodes.len()];
        let mut order = vec![];
        let mut seen = vec![false; self.prim_ids.len()];
        let mut ranges = vec![];
        let mut stack = vec![0usize];
        parent[0] = 0;
        while let Some(i) = stack.pop() {
            order.push(i);
            let n = &self.nodes[i];
            if n.e.iter().any(|&e| e == 0 || e == 255) {
                return Err(format!("node {i}: exponent {:?} is not a normal scale", n.e));
            }
            let (mut inner, mut rank) = (0u32, 0u8);
            for s in 0..CW_WIDTH {
                let m = n.meta[s];
                if m == META_EMPTY {
                    if n.is_inner(s) {
                        return Err(format!("node {i} slot {s}: empty but set in imask"));
                    }
                    continue;
                }
                if m >> 5 != 1 {
                    return Err(format!("node {i} slot {s}: meta {m:#010b} is not one unit"));
                }
                if n.is_inner(s) {
                    if m & 31 != INNER_BIT0 as u8 + s as u8 {
                        return Err(format!("node {i} slot {s}: inner meta {m:#010b} does not name its slot"));
                    }
                    let c = n.child_base as usize + inner as usize;
                    if n.inner_child(s) as usize != c || c >= self.nodes.len() || c <= i {
                        return Err(format!("node {i} slot {s}: bad child index {c}"));
                    }
                    if parent[c] != usize::MAX {
                        return Err(format!("node {c} reached twice"));
                    }
                    parent[c] = i;
                    inner += 1;
                    stack.push(c);
                } else {
                    if m & 31 != rank {
                        return Err(format!("node {i} slot {s}: leaf rank {} where {rank} was due", m & 31));
                    }
                    let w = n.leaf_base as usize + rank as usize;
                    if w < self.table_word() || w - self.table_word() >= self.leaves.len() {
                        return Err(format!("node {i} slot {s}: leaf word {w} outside the table"));
                    }
                    rank += 1;
                    let e = self.leaf(n, m as u32 & 31);
                    let (first, count) = (leaf_entry_first(e), leaf_entry_count(e));
                    if count == 0 || count > self.max_leaf_size {
                        return Err(format!("node {i} slot {s}: leaf of {count} triangles"));
                    }
                    for slot in first..first + count {
                        let Some(f) = seen.get_mut(slot as usize) else {
                            return Err(format!("node {i} slot {s}: leaf slot {slot} out of range"));
                        };
                        if std::mem::replace(f, true) {
                            return Err(format!("prim slot {slot} in two leaves"));
                        }
                    }
                    ranges.push((first, count));
                }
            }
        }
        if let Some(i) = parent.iter().position(|&p| p == usize::MAX) {
            return Err(format!("node {i} is not reachable from the root"));
        }
        if let Some(s) = seen.iter().position(|&x| !x) {
            return Err(format!("prim slot {s} in no leaf"));
        }
        // Containment, children before parents.
        let mut under = vec![Aabb::EMPTY; self.nodes.len()];
        for &i in order.iter().rev() {
            let n = &self.nodes[i];
            let mut all = Aabb::EMPTY;
            for s in (0..CW_WIDTH).filter(|&s| n.is_present(s)) {
                let truth = if n.is_inner(s) {
                    under[n.inner_child(s) as usize]
                } else {
                    let e = self.leaf(n, (n.meta[s] & 31) as u32);
                    tri_box(leaf_entry_first(e), leaf_entry_count(e))?
                };
                if !truth.is_empty() {
                    check_contains(n, s, &truth).map_err(|e| format!("node {i} slot {s}: {e}"))?;
                    all.grow(&truth);
                }
            }
            under[i] = all;
        }
        let mut binary: Vec<(u32, u32)> =
            bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.left_or_first, n.count)).collect();
        binary.sort_unstable();
        ranges.sort_unstable();
        if ranges != binary {
            return Err("leaf ranges differ from the binary tree's".into());
        }
        Ok(())
    }
}

/// Whether child `s`'s decoded box (both decode variants) contains `truth`, plane by plane.
pub fn check_contains(n: &CwNode, s: usize, truth: &Aabb) -> Result<(), String> {
    let lo = [n.q_lo_x[s], n.q_lo_y[s], n.q_lo_z[s]];
    let hi = [n.q_hi_x[s], n.q_hi_y[s], n.q_hi_z[s]];
    for k in 0..3 {
        if !lo_ok(n.p[k], n.e[k], lo[k], truth.min[k]) {
            return Err(format!(
                "decoded min {:?} > {} on axis {k}",
                decode_plane(n.p[k], n.e[k], lo[k]),
                truth.min[k]
            ));
        }
        if !hi_ok(n.p[k], n.e[k], hi[k], truth.max[k]) {
            return Err(format!(
                "decoded max {:?} < {} on axis {k}",
                decode_plane(n.p[k], n.e[k], hi[k]),
                truth.max[k]
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::tests::grid;

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

    #[test]
    fn scales_are_powers_of_two() {
        assert_eq!(scale_of(127), 1.0);
        assert_eq!(scale_of(1), f32::MIN_POSITIVE);
        assert_eq!(scale_of(128), 2.0);
        assert_eq!(scale_of(254), 2f32.powi(127));
    }

    #[test]
    fn slot_orders_are_permutations_and_exact_is_cheapest() {
        let mut s = 5u64;
        let mut rnd = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32 - 0.5
        };
        for n in 1..=8 {
            for _ in 0..50 {
                let centres: Vec<Vec3> = (0..n).map(|_| Vec3::new(rnd(), rnd(), rnd())).collect();
                let cost = slot_costs(Vec3::ZERO, &centres);
                let total = |a: &[usize]| a.iter().enumerate().map(|(i, &s)| cost[i][s]).sum::<f64>();
                let mut best = f64::INFINITY;
                // Brute force over all injective maps for small n.
                if n <= 4 {
                    let mut a = vec![0; n];
                    fn all(i: usize, a: &mut Vec<usize>, used: u32, f: &mut dyn FnMut(&[usize])) {
                        if i == a.len() {
                            f(a);
                            return;
                        }
                        for s in 0..8 {
                            if used >> s & 1 == 0 {
                                a[i] = s;
                                all(i + 1, a, used | 1 << s, f);
                            }
                        }
                    }
                    all(0, &mut a, 0, &mut |a| best = best.min(total(a)));
                }
                for how in [SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] {
                    let a = assign_slots(how, &cost);
                    let mut sorted = a.clone();
                    sorted.sort_unstable();
                    sorted.dedup();
                    assert_eq!(sorted.len(), n, "{how:?} {a:?}");
                    assert!(a.iter().all(|&s| s < 8));
                }
                let (g, e) =
                    (total(&assign_slots(SlotOrder::Greedy, &cost)), total(&assign_slots(SlotOrder::Exact, &cost)));
                assert!(e <= g + 1e-12);
                if n <= 4 {
                    assert!((e - best).abs() < 1e-12, "n {n}: exact {e} brute {best}");
                }
            }
        }
        // A child towards -x-y-z goes to the slot of rays in octant 0 (all positive): they meet it first.
        let cost = slot_costs(Vec3::ZERO, &[Vec3::splat(-1.0), Vec3::splat(1.0)]);
        assert_eq!(assign_slots(SlotOrder::Exact, &cost), vec![0, 7]);
    }

    #[test]
    fn grid_tree_is_valid_for_every_slot_order() {
        let mesh = grid(3000);
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            for how in [SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] {
                let cw = CwBvh::build_with(&bvh, how).unwrap();
                cw.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("leaf {leaf} {how:?}: {e}"));
                let w8 = WideBvh::<8>::collapse(&bvh);
                assert_eq!(cw.nodes.len(), w8.nodes.len());
                assert_eq!(cw.leaves.len(), w8.stats(&bvh.options).leaves);
            }
        }
    }

    #[test]
    fn one_leaf_and_all_degenerate_trees() {
        let mesh = grid(3);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &mesh).unwrap();
        assert_eq!((cw.nodes.len(), cw.leaves.len(), cw.leaves[0] & 31), (1, 1, 3));
        assert_eq!(cw.stack_bound(), 0);
        let deg = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], vec![[0, 1, 1]]);
        let bvh = Bvh::build(&deg, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &deg).unwrap();
        let r = Ray::new([0.5, 0.0, -1.0], [0.0, 0.0, 1.0]);
        assert!(!cw.trace(&r, false, |_, _| Some((1.0, 0.0, 0.0))).0.is_hit(), "padding is never tested");
    }

    #[test]
    fn corruption_is_caught() {
        let mesh = grid(2000);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &mesh).unwrap();
        let expect = |f: &dyn Fn(&mut CwBvh), what: &str| {
            let mut c = cw.clone();
            f(&mut c);
            let e = c.validate(&bvh, &mesh).expect_err(what);
            assert!(e.contains(what), "{e} should say {what}");
        };
        let (ni, si) = (0..cw.nodes.len())
            .flat_map(|i| (0..8).map(move |s| (i, s)))
            .find(|&(i, s)| cw.nodes[i].is_present(s) && !cw.nodes[i].is_inner(s) && cw.nodes[i].q_hi_x[s] > 0)
            .unwrap();
        expect(&|c| c.nodes[ni].q_hi_x[si] -= 1, "decoded max");
        expect(&|c| c.nodes[ni].q_lo_y[si] += 1, "decoded min");
        expect(&|c| c.nodes[ni].p[2] += 1.0, "decoded");
        expect(&|c| c.nodes[ni].e[0] = 0, "normal scale");
        expect(&|c| c.nodes[ni].meta[si] ^= 0b1000_0000, "one unit");
        let inner = (0..8).find(|&s| cw.nodes[0].is_inner(s)).unwrap();
        expect(&|c| c.nodes[0].meta[inner] ^= 1, "does not name its slot");
        expect(&|c| c.nodes[0].child_base = 0, "bad child index");
        expect(&|c| c.nodes[0].child_base += 1, "not reachable");
        expect(&|c| c.leaves[0] += 1, "leaf");
        expect(&|c| c.prim_ids.swap(0, 1), "prim_ids differ");
    }
}
