//! Wide BVHs (issue 15 groundwork, CPU side): the binary SAH tree collapsed into nodes of `N`
//! children (`N` = 4 or 8; 2 gives the binary tree in the same layout, for comparisons), each
//! node holding its children's boxes.
//!
//! # How the tree is collapsed
//!
//! Two ways ([`Collapse`]), both top down from the binary root, both keeping the leaves:
//! - [`Collapse::Sah`] (the default): Ylitie, Karras & Laine, "Efficient Incoherent Ray
//!   Traversal on GPUs Through Compressed Wide BVHs" (HPG 2017), sec. 4.1: a dynamic program
//!   over the binary tree finds, for every binary node and every number of slots `j <= N`, the
//!   cheapest way to cover its subtree with `j` child slots, each slot a leaf or a new wide
//!   node; the wide tree is the one of least [`WideBvh::sah_cost`] among all collapses that
//!   keep the leaves (see `SahPlan`). Unlike the paper, leaves are never merged (so the
//!   encodings' leaf ranges stay valid) and the price is our SAH's, not the paper's per-slot
//!   one. O(N²) per binary node.
//! - [`Collapse::Greedy`]: as tinybvh's `MBVH<M>::ConvertFrom` (tiny_bvh.h, the peer in
//!   `../shared/peers/tinybvh/`) and Wald, Benthin & Boulos, "Getting Rid of Packets" (IEEE RT
//!   2008, sec. 3) collapse a binary tree: a wide node starts from the two children of a
//!   binary inner node and repeatedly *opens* the inner child with the largest surface area
//!   (ties: the first in slot order), replacing it by its two children, until it has `N`
//!   children or only leaves are left; each inner child then becomes a wide node of its own.
//!   (tinybvh puts the second grandchild in the last slot; here both take the opened child's
//!   place, so slots keep the binary tree's left-to-right order.) On a balanced tree this
//!   fills the top levels and leaves half-empty nodes at the bottom: bunny, leaf 4, N = 8 uses
//!   4.6 of 8 slots per node (22.0 node bytes per triangle) against the SAH collapse's 6.0
//!   (15.5 bytes); on a 3,000-triangle grid its 8-wide tree has more nodes than its 4-wide one.
//!
//! Leaves are never split or merged: every leaf of the wide tree is a leaf of the binary tree
//! with the same `(first, count)` range of [`Bvh::prim_ids`], so every encoding's per-slot
//! triangle order stays valid and leaf sizes obey the binary tree's limits
//! ([`WideBvh::validate`] checks both). A binary tree whose root is a leaf (one leaf in all)
//! becomes one wide node with one leaf child.
//!
//! # Node layout ([`WideNode`], `#[repr(C)]`, 32·N bytes, all fields 4 bytes, no padding)
//!
//! | bytes (N = 4) | bytes (N = 8) | field | meaning per child slot i |
//! |---|---|---|---|
//! | 0..16    | 0..32    | `min_x[N]` | child box |
//! | 16..32   | 32..64   | `min_y[N]` | |
//! | 32..48   | 64..96   | `min_z[N]` | |
//! | 48..64   | 96..128  | `max_x[N]` | |
//! | 64..80   | 128..160 | `max_y[N]` | |
//! | 80..96   | 160..192 | `max_z[N]` | |
//! | 96..112  | 192..224 | `child[N]` | inner: node index; leaf: first slot of `prim_ids`; empty: [`EMPTY_CHILD`] |
//! | 112..128 | 224..256 | `count[N]` | inner: 0; leaf: triangles (1..=max leaf size); empty: 0 |
//!
//! So a 4-wide node is 8 `vec4`/`uvec4` texels (one per field: the slab test of all four
//! children for one plane is one texel load) and an 8-wide node 16 texels, two per field.
//!
//! Empty slots come after the occupied ones (a kernel may stop at the first `EMPTY_CHILD`)
//! and have the inverted box `min = +inf, max = -inf`. A slab test that picks the near and far
//! plane by the sign of the ray direction (near = `min` where the direction is positive, `max`
//! where it is negative, as Embree and tinybvh's BVH4/8 do) never hits that box, whatever the
//! ray ([`slab_ordered`], tested for every octant and zero components). The min/max-swapping
//! test of `glsl/box.glsl`'s `hit_box` does NOT miss it (on each axis the swap turns
//! `(+inf, -inf)` into an unbounded interval), so a kernel with that test must check the slot.
//!
//! The root's own box is [`WideBvh::bounds`] (the binary root's); node 0 is the root. The inner
//! children of one node occupy consecutive node indices (allocated together), in slot order.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use serde::Serialize;

use super::{Aabb, BuildOptions, Bvh, BvhNode, PAD_SLOT};
use crate::rays::Ray;
use crate::scene::Mesh;
use crate::shared::MISS_ID;

/// `child[i]` of an empty slot.
pub const EMPTY_CHILD: u32 = u32::MAX;

/// A node of `N` children, child boxes stored structure-of-arrays (see the module docs for the
/// byte layout). `N` must be 2..=8.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode<const N: usize> {
    pub min_x: [f32; N],
    pub min_y: [f32; N],
    pub min_z: [f32; N],
    pub max_x: [f32; N],
    pub max_y: [f32; N],
    pub max_z: [f32; N],
    pub child: [u32; N],
    pub count: [u32; N],
}

// SAFETY: `WideNode<N>` is `#[repr(C)]` and made only of `[f32; N]` and `[u32; N]` arrays:
// every field has size 4·N and alignment 4, so there is no padding anywhere, every bit pattern
// is a valid value, and the all-zero pattern is too. That is all `Zeroable` and `Pod` require
// (`#[derive(Pod)]` does not accept const-generic structs, hence the manual impls).
unsafe impl<const N: usize> Zeroable for WideNode<N> {}
// SAFETY: as above.
unsafe impl<const N: usize> Pod for WideNode<N> {}

/// The binary tree in the wide layout: 64 bytes, both children's boxes in the parent, like
/// Aila & Laine's node (whose fields are ordered per child, not per plane). Not the bvh2
/// layout's node: that is [`crate::bvh::BvhNode`], 32 bytes, one box per node.
pub type Wide2Node = WideNode<2>;
/// 4 children, 128 bytes.
pub type Bvh4Node = WideNode<4>;
/// 8 children, 256 bytes.
pub type Bvh8Node = WideNode<8>;

const _: () = assert!(std::mem::size_of::<Wide2Node>() == 64);
const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 4 && std::mem::align_of::<Bvh8Node>() == 4);

/// The box of an empty slot: inverted, so that no ray hits it ([`slab_ordered`]).
pub const EMPTY_BOX: Aabb = Aabb::EMPTY;

impl<const N: usize> WideNode<N> {
    /// Refuses widths the traversal's fixed stack and the layout docs do not cover.
    const WIDTH_OK: () = assert!(N >= 2 && N <= 8, "wide nodes have 2..=8 children");

    /// Every slot empty.
    pub const EMPTY: Self = WideNode {
        min_x: [f32::INFINITY; N],
        min_y: [f32::INFINITY; N],
        min_z: [f32::INFINITY; N],
        max_x: [f32::NEG_INFINITY; N],
        max_y: [f32::NEG_INFINITY; N],
        max_z: [f32::NEG_INFINITY; N],
        child: [EMPTY_CHILD; N],
        count: [0; N],
    };

    pub fn child_box(&self, i: usize) -> Aabb {
        Aabb {
            min: Vec3::new(self.min_x[i], self.min_y[i], self.min_z[i]),
            max: Vec3::new(self.max_x[i], self.max_y[i], self.max_z[i]),
        }
    }

    pub fn set_child_box(&mut self, i: usize, b: &Aabb) {
        [self.min_x[i], self.min_y[i], self.min_z[i]] = b.min.to_array();
        [self.max_x[i], self.max_y[i], self.max_z[i]] = b.max.to_array();
    }

    pub fn is_empty_slot(&self, i: usize) -> bool {
        self.child[i] == EMPTY_CHILD && self.count[i] == 0
    }

    pub fn is_leaf(&self, i: usize) -> bool {
        self.count[i] > 0
    }

    /// Occupied slots (they come first).
    pub fn children(&self) -> usize {
        (0..N).take_while(|&i| !self.is_empty_slot(i)).count()
    }
}

/// A wide tree over the same leaves (and the same `prim_ids`) as the binary tree it came from.
#[derive(Clone, Debug)]
pub struct WideBvh<const N: usize> {
    /// Root at 0.
    pub nodes: Vec<WideNode<N>>,
    /// The root's box (the binary root's).
    pub bounds: Aabb,
    /// Leaf slot -> triangle id: a copy of the binary tree's [`Bvh::prim_ids`].
    pub prim_ids: Vec<u32>,
    /// The binary tree's leaf size limit.
    pub max_leaf_size: u32,
    pub collapse_seconds: f64,
}

pub type Bvh4 = WideBvh<4>;
pub type Bvh8 = WideBvh<8>;

/// Sizes and costs of a wide tree.
#[derive(Clone, Debug, Serialize)]
pub struct WideStats {
    pub width: usize,
    pub nodes: usize,
    /// Leaf children (equal to the binary tree's leaves).
    pub leaves: usize,
    /// Occupied child slots per node, mean.
    pub mean_children: f64,
    pub empty_slots: usize,
    /// Deepest node; root at depth 0.
    pub depth: u32,
    /// [`WideBvh::sah_cost`].
    pub sah_cost: f64,
    /// [`WideBvh::sah_cost_per_box`].
    pub sah_cost_per_box: f64,
    pub node_bytes: usize,
    /// `node_bytes` over the triangles in the hierarchy.
    pub node_bytes_per_triangle: f64,
    pub collapse_ms: f64,
    /// Most entries [`WideBvh::trace`]'s stack can hold, whatever the ray: the size of a
    /// kernel's fixed stack ([`WideBvh::stack_bound`]).
    pub stack_bound: usize,
}

/// Work of one ray in [`WideBvh::trace`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WideSteps {
    /// Wide nodes visited (each tests all its occupied children's boxes).
    pub nodes: u32,
    /// Child boxes tested (occupied slots of the visited nodes; the root box not counted).
    pub boxes: u32,
    /// Leaves visited.
    pub leaves: u32,
    /// Triangles tested (padding excluded).
    pub triangles: u32,
    /// Most stack entries held at once.
    pub stack_peak: u32,
}

/// A hit of [`WideBvh::trace`], in the f64 of the triangle test it was given. `id ==
/// MISS_ID` and `t = inf` on a miss.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideHit {
    pub t: f64,
    pub id: u32,
    pub u: f64,
    pub v: f64,
}

impl WideHit {
    pub const MISS: WideHit = WideHit { t: f64::INFINITY, id: MISS_ID, u: 0.0, v: 0.0 };

    pub fn is_hit(&self) -> bool {
        self.id != MISS_ID
    }
}

/// Relative widening of the f64 box test, as the f64 reference's (`reference::Reference`):
/// rounding never culls a box the ray touches.
const BOX_SLACK: f64 = 1e-9;

/// The f64 slab test of [`WideBvh::trace`]: near and far planes chosen by the direction's sign
/// (no min/max swap), intervals widened by `BOX_SLACK` (1e-9, relative) where finite. Returns the entry
/// distance, or `None` when the ray misses the box within `[tmin, tmax]`. An inverted box
/// (`min > max` on an axis) is always missed.
pub fn slab_f64(origin: [f64; 3], dir: [f64; 3], b: &Aabb, tmin: f64, tmax: f64) -> Option<f64> {
    let widen = |t: f64, s: f64| if t.is_finite() { t + s * BOX_SLACK * t.abs() } else { t };
    let (mut t0, mut t1) = (tmin, tmax);
    for k in 0..3 {
        let (lo, hi) = (b.min[k] as f64, b.max[k] as f64);
        let (o, d) = (origin[k], dir[k]);
        if d == 0.0 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (near, far) = if d > 0.0 { (lo, hi) } else { (hi, lo) };
        t0 = t0.max(widen((near - o) / d, -1.0));
        t1 = t1.min(widen((far - o) / d, 1.0));
    }
    (t0 <= t1).then_some(t0)
}

/// The f32 slab test a wide kernel should use, mirrored: `inv_dir` as `make_trace_ray()`
/// computes it (zero components replaced by ±2^-126, f32::MIN_POSITIVE, before the division), near and far planes
/// chosen by the sign of `inv_dir`. With it an empty slot's [`EMPTY_BOX`] is never hit, so the
/// kernel needs no per-slot flag test (tested).
pub fn slab_ordered(origin: Vec3, inv_dir: Vec3, b: &Aabb, tmin: f32, tmax: f32) -> Option<f32> {
    let pos = inv_dir.cmpge(Vec3::ZERO);
    let near = Vec3::select(pos, b.min, b.max);
    let far = Vec3::select(pos, b.max, b.min);
    let tn = ((near - origin) * inv_dir).max_element().max(tmin);
    let tf = ((far - origin) * inv_dir).min_element().min(tmax);
    (tn <= tf).then_some(tn)
}

/// The children of binary node `b` as the wide node collapsed from it sees them: greedy
/// opening of the largest-area inner child (see the module docs).
fn open<const N: usize>(nodes: &[BvhNode], b: usize) -> Vec<usize> {
    let n = &nodes[b];
    if n.is_leaf() {
        return vec![b];
    }
    let l = n.left_or_first as usize;
    let mut kids = vec![l, l + 1];
    while kids.len() < N {
        let mut best: Option<(usize, f64)> = None;
        for (slot, &k) in kids.iter().enumerate() {
            let kn = &nodes[k];
            if !kn.is_leaf() {
                let a = kn.aabb().area();
                if best.is_none_or(|(_, ba)| a > ba) {
                    best = Some((slot, a));
                }
            }
        }
        let Some((slot, _)) = best else { break };
        let l = nodes[kids[slot]].left_or_first as usize;
        kids.splice(slot..=slot, [l, l + 1]);
    }
    kids
}

/// How [`WideBvh::collapse_with`] chooses each wide node's children.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Collapse {
    /// Open the largest-area inner child until the node is full (Wald et al. 2008, tinybvh).
    Greedy,
    /// The collapse of least [`WideBvh::sah_cost`] (Ylitie, Karras & Laine 2017's dynamic
    /// programming, leaves kept).
    Sah,
}

/// Ylitie, Karras & Laine (HPG 2017, sec. 4.1) dynamic programming over the binary tree, with
/// the leaves kept as they are (their version may also merge leaves, which would change the
/// encodings' leaf ranges) and [`WideBvh::sah_cost`]'s prices. For binary node `n` and `j` in
/// 1..=N, `cost[n][j]` is the least cost of covering `n`'s subtree by at most `j` child slots:
/// - one slot: a leaf costs `C_i tests(|n|) A(n)`; an inner node becomes a wide node,
///   `C_t A(n) + split(n, N)`;
/// - `j >= 2` slots: `min(cost[n][1], split(n, j))`, where `split(n, j) = min over k of
///   cost[left][k] + cost[right][j - k]` hands `k` slots to the left subtree.
///
/// The wide tree's cost is `cost[root][1]` over `A(root)` (for a root that is not a leaf); the
/// greedy collapse is one of the trees searched, so this one never costs more (tested).
struct SahPlan {
    n: usize,
    /// `cost[i * n + j - 1]`.
    cost: Vec<f64>,
    /// How `cost[i][j]` was reached: 0 = one slot, k = `k` slots to the left child.
    choice: Vec<u8>,
}

impl SahPlan {
    fn new(nodes: &[BvhNode], o: &BuildOptions, n: usize) -> SahPlan {
        let len = nodes.len();
        let mut p = SahPlan { n, cost: vec![0.0; len * n], choice: vec![0; len * n] };
        // Children have larger indices than their parent (the builder's order; validate checks
        // it), so one reverse sweep sees every child before its parent.
        for i in (0..len).rev() {
            let b = &nodes[i];
            let area = b.aabb().area();
            if b.is_leaf() {
                let c = o.cost_intersect as f64 * o.tests(b.count as usize) * area;
                p.cost[i * n..(i + 1) * n].fill(c);
                continue;
            }
            let l = b.left_or_first as usize;
            let one = o.cost_traversal as f64 * area + p.split(l, n).0;
            p.cost[i * n] = one;
            for j in 2..=n {
                let (c, k) = p.split(l, j);
                let at = i * n + j - 1;
                (p.cost[at], p.choice[at]) = if c < one { (c, k as u8) } else { (one, 0) };
            }
        }
        p
    }

    /// Least cost of covering the subtrees of `l` and `l + 1` with `j` slots, and how many of
    /// them go left.
    fn split(&self, l: usize, j: usize) -> (f64, usize) {
        let n = self.n;
        (1..j)
            .map(|k| (self.cost[l * n + k - 1] + self.cost[(l + 1) * n + j - k - 1], k))
            .fold((f64::INFINITY, 0), |a, b| if b.0 < a.0 { b } else { a })
    }

    /// The child slots of the wide node collapsed from binary node `b`.
    fn children(&self, nodes: &[BvhNode], b: usize) -> Vec<usize> {
        let node = &nodes[b];
        if node.is_leaf() {
            return vec![b];
        }
        let mut out = Vec::with_capacity(self.n);
        let l = node.left_or_first as usize;
        let k = self.split(l, self.n).1;
        self.expand(nodes, l, k, &mut out);
        self.expand(nodes, l + 1, self.n - k, &mut out);
        out
    }

    /// The slots (binary nodes) that cover `i`'s subtree with at most `j` slots.
    fn expand(&self, nodes: &[BvhNode], i: usize, j: usize, out: &mut Vec<usize>) {
        let k = self.choice[i * self.n + j - 1] as usize;
        if k == 0 {
            out.push(i);
        } else {
            let l = nodes[i].left_or_first as usize;
            self.expand(nodes, l, k, out);
            self.expand(nodes, l + 1, j - k, out);
        }
    }
}

impl<const N: usize> WideBvh<N> {
    /// Collapses `bvh` with [`Collapse::Sah`] (see the module docs).
    pub fn collapse(bvh: &Bvh) -> WideBvh<N> {
        Self::collapse_with(bvh, Collapse::Sah)
    }

    /// Collapses `bvh` the way `how` says (see the module docs).
    pub fn collapse_with(bvh: &Bvh, how: Collapse) -> WideBvh<N> {
        let t0 = Instant::now();
        let nodes = Self::collapse_nodes(&bvh.nodes, &bvh.options, how);
        WideBvh {
            nodes,
            bounds: bvh.nodes[0].aabb(),
            prim_ids: bvh.prim_ids.clone(),
            max_leaf_size: bvh.options.max_leaf_size,
            collapse_seconds: t0.elapsed().as_secs_f64(),
        }
    }

    /// The wide nodes of a binary node array (root at 0, the children of an inner node
    /// adjacent and after it, as [`Bvh::nodes`]) priced with `o`. A leaf child copies its
    /// binary leaf's `(left_or_first, count)` as they are, so collapsing an encoding's nodes
    /// (`encoding::EncodedScene::nodes`, leaves in the encoding's units, e.g. quads) gives the
    /// same tree with the leaves in that encoding's units (tested): that is how a wide kernel
    /// gets its nodes.
    pub fn collapse_nodes(binary: &[BvhNode], o: &BuildOptions, how: Collapse) -> Vec<WideNode<N>> {
        #[allow(clippy::let_unit_value)]
        let () = WideNode::<N>::WIDTH_OK;
        let plan = match how {
            Collapse::Greedy => None,
            Collapse::Sah => Some(SahPlan::new(binary, o, N)),
        };
        let mut nodes = vec![WideNode::<N>::EMPTY];
        // (wide node to fill, binary node it is collapsed from)
        let mut work = vec![(0usize, 0usize)];
        while let Some((w, b)) = work.pop() {
            let mut node = WideNode::<N>::EMPTY;
            let kids = match &plan {
                None => open::<N>(binary, b),
                Some(p) => p.children(binary, b),
            };
            for (slot, k) in kids.into_iter().enumerate() {
                let kn = &binary[k];
                node.set_child_box(slot, &kn.aabb());
                if kn.is_leaf() {
                    node.child[slot] = kn.left_or_first;
                    node.count[slot] = kn.count;
                } else {
                    node.child[slot] = nodes.len() as u32;
                    node.count[slot] = 0;
                    nodes.push(WideNode::EMPTY);
                    work.push((nodes.len() - 1, k));
                }
            }
            nodes[w] = node;
        }
        nodes
    }

    /// Calls `f(node_index, depth, area of the node's box)` for every node, depth first.
    fn visit(&self, mut f: impl FnMut(usize, u32, f64)) {
        let mut stack = vec![(0usize, 0u32, self.bounds.area())];
        while let Some((i, d, a)) = stack.pop() {
            f(i, d, a);
            let n = &self.nodes[i];
            for s in 0..n.children() {
                if !n.is_leaf(s) {
                    stack.push((n.child[s] as usize, d + 1, n.child_box(s).area()));
                }
            }
        }
    }

    fn sah(&self, o: &BuildOptions, per_box: bool) -> f64 {
        let root_area = self.bounds.area().max(f64::MIN_POSITIVE);
        let mut cost = 0.0;
        self.visit(|i, _, a| {
            let n = &self.nodes[i];
            let k = n.children();
            let boxes = if per_box { k as f64 / 2.0 } else { 1.0 };
            cost += o.cost_traversal as f64 * boxes * a / root_area;
            for s in (0..k).filter(|&s| n.is_leaf(s)) {
                cost += o.cost_intersect as f64 * o.tests(n.count[s] as usize) * n.child_box(s).area() / root_area;
            }
        });
        cost
    }

    /// The SAH cost with [`Bvh::sah_cost`]'s formula and `o`'s constants: each wide node is one
    /// traversal step, `C_t A(n)/A(root)`, and each leaf `C_i ceil(|n|/g) A(n)/A(root)`. The
    /// leaves are the binary tree's, so only the node term differs between widths; for `N` = 2
    /// it equals `Bvh::sah_cost` (tested). It prices node *visits*: a wide node's extra box
    /// tests are free, which flatters wide trees where box tests are serial (one lane per ray).
    pub fn sah_cost(&self, o: &BuildOptions) -> f64 {
        self.sah(o, false)
    }

    /// The same with each node priced per box tested, `C_t (k/2) A(n)/A(root)` for `k`
    /// occupied children (a binary node's two boxes cost `C_t`, as in [`Bvh::sah_cost`]): the
    /// cost when a ray tests its node's boxes one after another. Also equals `Bvh::sah_cost`
    /// for `N` = 2.
    pub fn sah_cost_per_box(&self, o: &BuildOptions) -> f64 {
        self.sah(o, true)
    }

    /// Most entries the traversal stack can hold: a node of `k` children pushes `k` entries and
    /// pops one to descend, so the worst path from the root adds `k - 1` per node above the
    /// last, which pushes all of its `k`. A kernel's fixed stack needs this many entries.
    pub fn stack_bound(&self) -> usize {
        // Nodes come after their parents (validate checks it): one reverse sweep.
        let mut need = vec![0usize; self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let n = &self.nodes[i];
            let k = n.children();
            let below = (0..k).filter(|&s| !n.is_leaf(s)).map(|s| need[n.child[s] as usize]).max();
            need[i] = match below {
                Some(b) => (k - 1 + b).max(k),
                None => k,
            };
        }
        need[0]
    }

    /// Triangles in the hierarchy (padding not counted).
    pub fn triangle_count(&self) -> usize {
        self.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count()
    }

    /// Sizes and SAH costs, priced with `o` (normally the binary tree's build options).
    pub fn stats(&self, o: &BuildOptions) -> WideStats {
        let (mut leaves, mut occupied, mut depth) = (0, 0, 0);
        self.visit(|i, d, _| {
            let n = &self.nodes[i];
            depth = depth.max(d);
            occupied += n.children();
            leaves += (0..n.children()).filter(|&s| n.is_leaf(s)).count();
        });
        let node_bytes = std::mem::size_of_val(self.nodes.as_slice());
        WideStats {
            width: N,
            nodes: self.nodes.len(),
            leaves,
            mean_children: occupied as f64 / self.nodes.len() as f64,
            empty_slots: self.nodes.len() * N - occupied,
            depth,
            sah_cost: self.sah_cost(o),
            sah_cost_per_box: self.sah_cost_per_box(o),
            node_bytes,
            node_bytes_per_triangle: node_bytes as f64 / self.triangle_count().max(1) as f64,
            collapse_ms: self.collapse_seconds * 1e3,
            stack_bound: self.stack_bound(),
        }
    }

    /// Closest hit (`any = false`; ties to the lower triangle id, as the f64 reference) or the
    /// first hit found (`any = true`), with the work it took. `intersect(id, tmax)` is the
    /// triangle test: `(t, u, v)` when the ray (with its far end cut to `tmax`) meets triangle
    /// `id`; callers pass the f64 reference's (`reference::intersect`).
    ///
    /// The loop a wide kernel runs: test the root box; at a node, test every occupied child's
    /// box ([`slab_f64`]), push the hit children on the stack farthest first with their entry
    /// distance, pop the nearest; a popped entry farther than the closest hit so far is
    /// skipped; a leaf tests its triangles.
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
        // (child, count, entry distance): count 0 is a node.
        let mut stack: Vec<(u32, u32, f64)> = Vec::with_capacity(64);
        if let Some(t) = slab_f64(o, d, &self.bounds, tmin, tmax) {
            stack.push((0, 0, t));
        }
        let mut hits: Vec<(f64, usize)> = Vec::with_capacity(N);
        while let Some((child, count, tnear)) = stack.pop() {
            if tnear > tmax {
                continue;
            }
            if count > 0 {
                steps.leaves += 1;
                for &id in &self.prim_ids[child as usize..(child + count) as usize] {
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
                continue;
            }
            steps.nodes += 1;
            let n = &self.nodes[child as usize];
            hits.clear();
            for s in 0..N {
                if n.is_empty_slot(s) {
                    break;
                }
                steps.boxes += 1;
                if let Some(t) = slab_f64(o, d, &n.child_box(s), tmin, tmax) {
                    hits.push((t, s));
                }
            }
            // Nearest on top; equal distances keep slot order.
            hits.sort_by(|a, b| a.0.total_cmp(&b.0));
            for &(t, s) in hits.iter().rev() {
                stack.push((n.child[s], n.count[s], t));
            }
            steps.stack_peak = steps.stack_peak.max(stack.len() as u32);
        }
        (best, steps)
    }

    /// Checks the invariants every consumer relies on, against the binary tree it was collapsed
    /// from and the mesh; returns the first violation. Every node is reached exactly once from
    /// the root, by an index larger than its parent's; occupied slots come first, a node has at
    /// least two children (one, a leaf, only for a one-leaf tree); each child box contains the
    /// boxes its node stores (so every box contains its whole subtree) or, for a leaf, its
    /// triangles; leaves hold 1..=max leaf size triangles and are exactly the binary tree's
    /// leaf ranges, every slot of `prim_ids` in exactly one leaf; empty slots carry
    /// [`EMPTY_CHILD`], count 0 and [`EMPTY_BOX`].
    pub fn validate(&self, bvh: &Bvh, mesh: &Mesh) -> Result<(), String> {
        if self.nodes.is_empty() {
            return Err("no nodes".into());
        }
        if self.prim_ids != bvh.prim_ids {
            return Err("prim_ids differ from the binary tree's".into());
        }
        if self.bounds != bvh.nodes[0].aabb() {
            return Err("root bounds differ from the binary root's".into());
        }
        let one_leaf_tree = bvh.nodes[0].is_leaf();
        let mut reached = vec![false; self.nodes.len()];
        let mut seen = vec![false; self.prim_ids.len()];
        let mut leaves: Vec<(u32, u32)> = vec![];
        let mut stack = vec![(0usize, self.bounds)];
        while let Some((i, parent_box)) = stack.pop() {
            if std::mem::replace(&mut reached[i], true) {
                return Err(format!("node {i} reached twice"));
            }
            let n = &self.nodes[i];
            let k = n.children();
            if let Some(s) = (k..N).find(|&s| !n.is_empty_slot(s)) {
                return Err(format!("node {i} slot {s} is occupied after an empty slot"));
            }
            for s in k..N {
                let b = n.child_box(s);
                if b.min != EMPTY_BOX.min || b.max != EMPTY_BOX.max {
                    return Err(format!("node {i} empty slot {s} has box {b:?}, not the inverted one"));
                }
            }
            let min_children = if one_leaf_tree { 1 } else { 2 };
            if k < min_children {
                return Err(format!("node {i} has {k} children"));
            }
            for s in 0..k {
                let b = n.child_box(s);
                // A padding-only leaf (an all-degenerate scene) has an empty box.
                let padding_leaf = n.is_leaf(s) && b.is_empty();
                if !parent_box.contains(&b) && !padding_leaf {
                    return Err(format!("node {i}: the box of child slot {s} is not inside the node's box"));
                }
                if n.is_leaf(s) {
                    let (first, count) = (n.child[s], n.count[s]);
                    if count > self.max_leaf_size {
                        return Err(format!("node {i} slot {s}: leaf holds {count} > {}", self.max_leaf_size));
                    }
                    for slot in first..first.saturating_add(count) {
                        let Some(flag) = seen.get_mut(slot as usize) else {
                            return Err(format!("node {i} slot {s}: leaf slot {slot} out of range"));
                        };
                        if std::mem::replace(flag, true) {
                            return Err(format!("prim slot {slot} in two leaves"));
                        }
                        let id = self.prim_ids[slot as usize];
                        if id != PAD_SLOT && !b.contains(&Aabb::from_points(&mesh.vertices(id as usize))) {
                            return Err(format!("node {i} slot {s}: leaf box does not contain triangle {id}"));
                        }
                    }
                    leaves.push((first, count));
                } else {
                    let c = n.child[s] as usize;
                    if c >= self.nodes.len() || c <= i {
                        return Err(format!("node {i} slot {s}: bad child index {c}"));
                    }
                    stack.push((c, b));
                }
            }
        }
        if let Some(i) = reached.iter().position(|&r| !r) {
            return Err(format!("node {i} is not reachable from the root"));
        }
        if let Some(s) = seen.iter().position(|&x| !x) {
            return Err(format!("prim slot {s} in no leaf"));
        }
        let mut binary: Vec<(u32, u32)> =
            bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.left_or_first, n.count)).collect();
        binary.sort_unstable();
        leaves.sort_unstable();
        if leaves != binary {
            return Err("leaf ranges differ from the binary tree's".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    use crate::bvh::tests::grid;

    /// Möller–Trumbore in f64 (the bvh layer cannot import `reference`; tests/wide_bvh.rs uses
    /// the reference's own).
    fn mt(mesh: &Mesh, ray: &Ray, id: u32, tmax: f64) -> Option<(f64, f64, f64)> {
        let [a, b, c] = mesh.vertices_f64(id as usize);
        let (o, d) = (DVec3::from_array(ray.origin.map(f64::from)), DVec3::from_array(ray.dir.map(f64::from)));
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            return None;
        }
        let tv = o - a;
        let (u, q) = (tv.dot(p) / det, tv.cross(e1));
        let (v, t) = (d.dot(q) / det, e2.dot(q) / det);
        (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= ray.tmin as f64 && t <= tmax).then_some((t, u, v))
    }

    fn rays(n: usize) -> Vec<Ray> {
        let mut s = 99u64;
        let mut rnd = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        (0..n)
            .map(|_| Ray::new([rnd() * 40.0, rnd() * 80.0, -5.0], [0.2 * rnd() - 0.1, 0.2 * rnd() - 0.1, 1.0]))
            .collect()
    }

    #[test]
    fn collapsed_trees_are_valid_and_keep_the_binary_leaves() {
        let mesh = grid(3000);
        for leaf in [1, 4, 8, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let leaves = bvh.stats().leaves;
            let w2 = WideBvh::<2>::collapse(&bvh);
            let w4 = WideBvh::<4>::collapse(&bvh);
            let w8 = WideBvh::<8>::collapse(&bvh);
            let g4 = WideBvh::<4>::collapse_with(&bvh, Collapse::Greedy);
            let g8 = WideBvh::<8>::collapse_with(&bvh, Collapse::Greedy);
            let g2 = WideBvh::<2>::collapse_with(&bvh, Collapse::Greedy);
            for e in [w2.validate(&bvh, &mesh), w4.validate(&bvh, &mesh), w8.validate(&bvh, &mesh)] {
                e.unwrap();
            }
            for e in [g2.validate(&bvh, &mesh), g4.validate(&bvh, &mesh), g8.validate(&bvh, &mesh)] {
                e.unwrap();
            }
            let o = &bvh.options;
            // N = 2 leaves nothing to choose.
            assert_eq!(w2.nodes, g2.nodes);
            // The SAH collapse is the cheapest; the greedy one is among those it searched.
            let (c4, c8) = (g4.sah_cost(o), g8.sah_cost(o));
            assert!(w4.sah_cost(o) <= c4 * (1.0 + 1e-12), "leaf {leaf}: {} > greedy {c4}", w4.sah_cost(o));
            assert!(w8.sah_cost(o) <= c8 * (1.0 + 1e-12), "leaf {leaf}: {} > greedy {c8}", w8.sah_cost(o));
            // ... and its cost is the dynamic program's.
            let plan = SahPlan::new(&bvh.nodes, &bvh.options, 8);
            let dp = plan.cost[0] / bvh.nodes[0].aabb().area();
            assert!((dp - w8.sah_cost(o)).abs() <= 1e-9 * dp, "{dp} vs {}", w8.sah_cost(o));
            let (s2, s4, s8) = (w2.stats(o), w4.stats(o), w8.stats(o));
            // N = 2 is the binary tree: one wide node per binary inner node, same SAH.
            assert_eq!(s2.nodes, bvh.stats().inner_nodes);
            assert_eq!((s2.leaves, s4.leaves, s8.leaves), (leaves, leaves, leaves));
            let binary = bvh.sah_cost(o);
            assert!((s2.sah_cost - binary).abs() <= 1e-9 * binary, "{} vs {binary}", s2.sah_cost);
            assert!((s2.sah_cost_per_box - binary).abs() <= 1e-9 * binary);
            // Wide nodes are a subset of the binary inner nodes, leaves are the same.
            assert!(s8.sah_cost <= binary && s4.sah_cost <= binary);
            assert!(s4.nodes < s2.nodes && s8.nodes < s4.nodes, "leaf {leaf}: {s2:?} {s4:?} {s8:?}");
            assert!(s8.mean_children > s4.mean_children && s4.mean_children > 3.0);
            assert!(s4.depth <= s2.depth && s8.depth <= s4.depth);
        }
    }

    #[test]
    fn greedy_opening_takes_the_largest_inner_child() {
        let mesh = grid(500);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let kids = open::<3>(&bvh.nodes, 0);
        let root = &bvh.nodes[0];
        let (l, r) = (root.left_or_first as usize, root.left_or_first as usize + 1);
        let big = if bvh.nodes[l].aabb().area() >= bvh.nodes[r].aabb().area() { l } else { r };
        let gl = bvh.nodes[big].left_or_first as usize;
        let expect = if big == l { vec![gl, gl + 1, r] } else { vec![l, gl, gl + 1] };
        assert_eq!(kids, expect);
        // A leaf never opens.
        let leaf = (0..bvh.nodes.len()).find(|&i| bvh.nodes[i].is_leaf()).unwrap();
        assert_eq!(open::<8>(&bvh.nodes, leaf), vec![leaf]);
    }

    #[test]
    fn one_leaf_tree_is_one_node_with_one_leaf() {
        let mesh = grid(3);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        assert!(bvh.nodes[0].is_leaf());
        let w = WideBvh::<8>::collapse(&bvh);
        w.validate(&bvh, &mesh).unwrap();
        assert_eq!((w.nodes.len(), w.nodes[0].children(), w.nodes[0].count[0]), (1, 1, 3));
        // All-degenerate: the padding leaf survives.
        let deg = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], vec![[0, 1, 1]]);
        let bvh = Bvh::build(&deg, &BuildOptions::new(4));
        let w = WideBvh::<4>::collapse(&bvh);
        w.validate(&bvh, &deg).unwrap();
        let r = Ray::new([0.5, 0.0, -1.0], [0.0, 0.0, 1.0]);
        assert!(!w.trace(&r, false, |id, t| mt(&deg, &r, id, t)).0.is_hit());
    }

    #[test]
    fn corruption_is_caught() {
        let mesh = grid(2000);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let w = WideBvh::<4>::collapse(&bvh);
        w.validate(&bvh, &mesh).unwrap();
        let expect = |f: &dyn Fn(&mut WideBvh<4>), what: &str| {
            let mut c = w.clone();
            f(&mut c);
            let e = c.validate(&bvh, &mesh).expect_err(what);
            assert!(e.contains(what), "{e} should say {what}");
        };
        // An inner child's box shrunk: its node's boxes stick out.
        let (ni, si) = (0..w.nodes.len())
            .flat_map(|i| (0..4).map(move |s| (i, s)))
            .find(|&(i, s)| !w.nodes[i].is_empty_slot(s) && !w.nodes[i].is_leaf(s))
            .unwrap();
        expect(&|c| c.nodes[ni].max_x[si] -= 0.25, "is not inside the node's box");
        // A leaf's box shrunk.
        let (nl, sl) = (0..w.nodes.len())
            .flat_map(|i| (0..4).map(move |s| (i, s)))
            .find(|&(i, s)| w.nodes[i].count[s] >= 2)
            .unwrap();
        expect(&|c| c.nodes[nl].min_y[sl] += 0.25, "leaf box does not contain");
        expect(&|c| c.nodes[nl].count[sl] = 17, "leaf holds 17");
        expect(&|c| c.nodes[nl].count[sl] -= 1, "in no leaf");
        expect(&|c| c.nodes[nl].child[sl] = c.nodes[nl].child[(sl + 1) % c.nodes[nl].children()], "leaf");
        // An empty slot before an occupied one.
        let ne = (0..w.nodes.len()).find(|&i| w.nodes[i].children() < 4).unwrap();
        expect(
            &|c| {
                let n = &mut c.nodes[ne];
                let k = n.children();
                n.child.swap(0, k);
                n.count.swap(0, k);
            },
            "occupied after an empty slot",
        );
        expect(&|c| c.nodes[ne].max_z[3] = 0.0, "not the inverted one");
        expect(&|c| c.nodes[ni].child[si] = ni as u32, "bad child index");
        expect(&|c| c.prim_ids.swap(0, 1), "prim_ids differ");
    }

    #[test]
    fn empty_slots_are_missed_by_the_ordered_slab_test_in_every_octant() {
        let comps = [-1.0f32, -1e-3, 0.0, 1e-3, 1.0];
        let mut n = 0;
        for x in comps {
            for y in comps {
                for z in comps {
                    let dir = Vec3::new(x, y, z);
                    if dir == Vec3::ZERO {
                        continue;
                    }
                    // make_trace_ray()'s guard against zero components.
                    let safe = Vec3::select(dir.cmplt(Vec3::ZERO), -Vec3::ONE, Vec3::ONE)
                        * dir.abs().max(Vec3::splat(f32::MIN_POSITIVE));
                    for origin in [Vec3::ZERO, Vec3::splat(1e30), Vec3::new(-3.0, 5.0, 1e-20)] {
                        let inv = Vec3::ONE / safe;
                        assert_eq!(slab_ordered(origin, inv, &EMPTY_BOX, 0.0, f32::INFINITY), None, "{dir} {origin}");
                        let (o, d) = (origin.as_dvec3().to_array(), dir.as_dvec3().to_array());
                        assert_eq!(slab_f64(o, d, &EMPTY_BOX, 0.0, f64::INFINITY), None, "{dir} {origin}");
                        // A real box on the ray is hit by both.
                        let b = Aabb { min: origin + dir - 0.5, max: origin + dir + 0.5 };
                        if origin == Vec3::ZERO {
                            assert!(slab_ordered(origin, inv, &b, 0.0, f32::INFINITY).is_some());
                            assert!(slab_f64(o, d, &b, 0.0, f64::INFINITY).is_some());
                        }
                        n += 1;
                    }
                }
            }
        }
        assert_eq!(n, 124 * 3);
        // The swapping test (box.glsl's hit_box) does hit it: why kernels must not use it
        // on empty slots without checking them.
        let (o, inv) = (Vec3::ZERO, Vec3::ONE);
        let (t0, t1) = ((EMPTY_BOX.min - o) * inv, (EMPTY_BOX.max - o) * inv);
        assert!(t0.min(t1).max_element() <= t0.max(t1).min_element());
    }

    #[test]
    fn traversal_finds_the_binary_trees_hits() {
        let mesh = grid(3000);
        let rays = rays(3000);
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let w2 = WideBvh::<2>::collapse(&bvh);
            let w4 = WideBvh::<4>::collapse(&bvh);
            let w8 = WideBvh::<8>::collapse(&bvh);
            let mut hits = 0;
            let mut visits = [0u64; 3];
            for r in &rays {
                let test = |id, t| mt(&mesh, r, id, t);
                let (h2, s2) = w2.trace(r, false, test);
                let (h4, s4) = w4.trace(r, false, test);
                let (h8, s8) = w8.trace(r, false, test);
                assert_eq!(h2, h4, "leaf {leaf} {r:?}");
                assert_eq!(h2, h8, "leaf {leaf} {r:?}");
                for w in [w4.trace(r, true, test).0, w8.trace(r, true, test).0] {
                    assert_eq!(w.is_hit(), h2.is_hit());
                }
                hits += h2.is_hit() as usize;
                for (v, s) in visits.iter_mut().zip([s2, s4, s8]) {
                    *v += s.nodes as u64;
                }
            }
            assert!(hits > 250, "the rays should hit often ({hits})");
            assert!(visits[2] < visits[1] && visits[1] < visits[0], "{visits:?}");
        }
    }
}
