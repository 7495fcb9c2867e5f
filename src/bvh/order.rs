//! Node order in memory (issue 27, item 4): where each node of a built tree sits in its node
//! buffer. The tree, its boxes, its leaves and the walk a ray takes through it stay the same;
//! only the indices change, and with them which nodes share a 64-byte cache line or a 4 KiB page.
//!
//! # What is moved
//!
//! Every layout's kernels find a node's children in one of two ways: the binary node's
//! `left_or_first` names both children (at `left_or_first` and `left_or_first + 1`,
//! `glsl/layout/bvh2.glsl`), cwbvh's `child_base` names the first of a node's inner children,
//! which follow it in slot order (`glsl/layout/cwbvh.glsl`); bvh4 and bvh8 store every child's
//! index, and their builder also allocates a node's inner children together
//! (`bvh::wide`). So the unit an order moves is a *child group*: the nodes of the array directly
//! below one node (bvh2: both children, leaves included, since a binary leaf is a node; the wide
//! layouts: the inner children, since their leaves live in the parent's slots), kept together and
//! in their order. The root stays at 0, every child after its parent, and the leaves' primitive
//! ranges (and cwbvh's leaf table) are left as they are. [`NodeTree`] is that view of a node
//! array; [`NodeOrder::permutation`] the new place of every node; `reorder_*` rewrite the child
//! indices.
//!
//! # The orders
//!
//! - [`NodeOrder::Built`] (the default): as the layout's builder writes it, unchanged. That is
//!   depth first for bvh2 (`[root] ++ desc(root)`, `desc(x) = children(x) ++ desc(first child)
//!   ++ desc(second)`; [`NodeOrder::DepthFirst`] gives exactly it), depth first last slot first
//!   for bvh4 and bvh8 (the collapse's work stack), and breadth first for cwbvh (its
//!   compression's work queue).
//! - [`NodeOrder::DepthFirst`]: child groups in depth-first pre-order, first child first.
//! - [`NodeOrder::BreadthFirst`]: child groups in level order (every node of depth d before any
//!   of depth d + 1), each level left to right.
//! - [`NodeOrder::Treelets`]: the tree cut into treelets of at most [`TREELET_BYTES`] of nodes,
//!   each treelet's nodes contiguous, the treelets in depth-first order of their roots. A
//!   treelet grows from its root group by adding, of the child groups below it, the one a ray
//!   is most likely to fetch (the largest surface area of the node whose visit reads it, the
//!   SAH's probability) while it fits, and lays the groups it took out depth first: Gil & Itai's greedy packing of a tree into pages ("How
//!   to pack trees", J. Algorithms 32(2), 1999), as Aila & Karras cut a BVH into treelets sized
//!   to a memory block ("Architecture considerations for tracing incoherent rays", HPG 2010,
//!   sec. 4) and Yoon & Manocha lay BVHs out cache-obliviously ("Cache-efficient layouts of
//!   bounding volume hierarchies", EG 2006), in the spirit of the van Emde Boas layout. The
//!   groups not taken become the next treelets' roots.
//!
//! 4 KiB, a page: on a CPU driver (lavapipe) a page is what a TLB entry and the L2 streamer's
//! prefetch cover, and a treelet of one 64-byte line would hold one bvh2 child pair, which every
//! order already keeps together. A page holds 128 bvh2 nodes (64 pairs, six to seven levels of a
//! balanced binary tree), 32 bvh4 nodes, 16 bvh8 nodes or 51 cwbvh nodes. Treelets are not
//! padded to page boundaries (the buffer keeps its bytes), so a full treelet usually spans two
//! pages.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, VecDeque};

use serde::Serialize;

use super::{Aabb, BvhNode, CwBvh, CwNode, WideNode};
use crate::named::named_enum;

named_enum! {
    /// Where each node of a built tree sits in its node buffer.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum NodeOrder: "node order" {
        /// As each layout's builder writes it: depth first for bvh2, bvh4 and bvh8, breadth
        /// first for cwbvh.
        Built = "built" (default),
        /// Child groups in depth-first pre-order, first child first (bvh2's built order).
        DepthFirst = "depth-first",
        /// Child groups in level order.
        BreadthFirst = "breadth-first",
        /// Treelets of at most 4 KiB of nodes, each contiguous, in depth-first order of their
        /// roots; a treelet takes the child groups rays reach most (surface area) first.
        Treelets = "treelets",
    }
}

/// Most bytes of nodes in one treelet of [`NodeOrder::Treelets`] (a page; see the module docs).
pub const TREELET_BYTES: usize = 4096;

/// Bytes of a cache line and of a page, for [`Locality`].
pub const LINE_BYTES: usize = 64;
pub const PAGE_BYTES: usize = 4096;

/// What a visit of a node reads from the node buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fetch {
    /// Its children's nodes (bvh2: the parent's `left_or_first` names the pair whose boxes are
    /// tested).
    Children,
    /// The node itself (the wide layouts: the children's boxes are in the parent).
    Node,
}

/// A node array as the orders see it: per node, the nodes directly below it (one run of
/// consecutive indices), and the chance a ray visits it.
#[derive(Clone, Debug)]
pub struct NodeTree {
    /// Node `i`'s child group: `(first, len)`, `len` 0 for none.
    kids: Vec<(u32, u32)>,
    /// Surface area of node `i`'s box (the SAH's visit probability, up to a constant).
    area: Vec<f64>,
    /// Bytes per node in the buffer.
    pub node_bytes: usize,
    pub fetch: Fetch,
}

/// How close in memory the nodes a descent reads are: over every step from a node to one of
/// its children, weighted by how often a ray takes it (the child's surface area), the 64-byte
/// lines and 4 KiB pages the child's visit reads that its parent's visit did not. A model of one
/// root-to-leaf path, cheap and the same for every layout (what a visit reads: [`Fetch`]); it
/// counts no reuse between the paths of one ray or between rays, and not cwbvh's leaf table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Locality {
    /// New 64-byte lines per step, mean.
    pub lines_per_step: f64,
    /// New 4 KiB pages per step, mean (the share of steps that leave the parent's pages).
    pub pages_per_step: f64,
}

/// A place in a priority queue of child groups: the heaviest first, then the earliest in
/// depth-first order.
struct Candidate {
    weight: f64,
    rank: u32,
    group: (u32, u32),
}

impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> Ordering {
        self.weight.total_cmp(&o.weight).then(o.rank.cmp(&self.rank))
    }
}

impl NodeTree {
    /// The binary nodes ([`BvhNode`], as `Bvh::nodes` or an encoding's): an inner node's group is
    /// its two children.
    pub fn binary(nodes: &[BvhNode]) -> NodeTree {
        NodeTree {
            kids: nodes.iter().map(|n| if n.is_leaf() { (0, 0) } else { (n.left_or_first, 2) }).collect(),
            area: nodes.iter().map(|n| n.aabb().area()).collect(),
            node_bytes: std::mem::size_of::<BvhNode>(),
            fetch: Fetch::Children,
        }
    }

    /// Wide nodes (root at 0, `bounds` the root's box): a node's group is its inner children,
    /// or an error where they are not consecutive in slot order.
    pub fn wide<const N: usize>(nodes: &[WideNode<N>], bounds: &Aabb) -> Result<NodeTree, String> {
        let mut t = NodeTree {
            kids: vec![(0, 0); nodes.len()],
            area: vec![0.0; nodes.len()],
            node_bytes: std::mem::size_of::<WideNode<N>>(),
            fetch: Fetch::Node,
        };
        if let Some(a) = t.area.first_mut() {
            *a = bounds.area();
        }
        for (i, n) in nodes.iter().enumerate() {
            let mut group: Option<(u32, u32)> = None;
            for s in (0..n.children()).filter(|&s| !n.is_leaf(s)) {
                let (first, len) = group.unwrap_or((n.child[s], 0));
                if n.child[s] != first + len || n.child[s] as usize >= nodes.len() {
                    return Err(format!("node {i}'s inner children are not consecutive in slot order"));
                }
                t.area[n.child[s] as usize] = n.child_box(s).area();
                group = Some((first, len + 1));
            }
            t.kids[i] = group.unwrap_or((0, 0));
        }
        Ok(t)
    }

    /// Compressed wide nodes: a node's group is its inner children from `child_base`.
    pub fn cwbvh(nodes: &[CwNode], bounds: &Aabb) -> NodeTree {
        let mut t = NodeTree {
            kids: vec![(0, 0); nodes.len()],
            area: vec![0.0; nodes.len()],
            node_bytes: std::mem::size_of::<CwNode>(),
            fetch: Fetch::Node,
        };
        if let Some(a) = t.area.first_mut() {
            *a = bounds.area();
        }
        for (i, n) in nodes.iter().enumerate() {
            let inner = n.imask.count_ones();
            if inner > 0 {
                t.kids[i] = (n.child_base, inner);
            }
            for s in (0..8).filter(|&s| n.is_inner(s)) {
                t.area[n.inner_child(s) as usize] = n.child_box(s).area();
            }
        }
        t
    }

    /// Nodes in the array.
    pub fn len(&self) -> usize {
        self.kids.len()
    }

    pub fn is_empty(&self) -> bool {
        self.kids.is_empty()
    }

    /// Node `i`'s child group, `(first, len)`.
    pub fn kids(&self, i: usize) -> (u32, u32) {
        self.kids[i]
    }

    fn group(&self, (first, len): (u32, u32)) -> std::ops::Range<usize> {
        first as usize..(first + len) as usize
    }

    /// Every node's depth (root 0).
    pub fn depths(&self) -> Vec<u32> {
        let mut d = vec![0; self.len()];
        for i in self.depth_first() {
            for c in self.group(self.kids[i as usize]) {
                d[c] = d[i as usize] + 1;
            }
        }
        d
    }

    /// The nodes in depth-first pre-order of their child groups, first child first.
    fn depth_first(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.len());
        if self.is_empty() {
            return out;
        }
        let mut stack = vec![(0u32, 1u32)];
        while let Some(g) = stack.pop() {
            let r = self.group(g);
            out.extend(r.clone().map(|i| i as u32));
            for i in r.rev() {
                if self.kids[i].1 > 0 {
                    stack.push(self.kids[i]);
                }
            }
        }
        out
    }

    fn breadth_first(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.len());
        if self.is_empty() {
            return out;
        }
        let mut queue = VecDeque::from([(0u32, 1u32)]);
        while let Some(g) = queue.pop_front() {
            for i in self.group(g) {
                out.push(i as u32);
                if self.kids[i].1 > 0 {
                    queue.push_back(self.kids[i]);
                }
            }
        }
        out
    }

    /// The treelets of [`NodeOrder::Treelets`] with at most `bytes` of nodes each (a child group
    /// larger than that is a treelet alone), in layout order; each lists its nodes in layout
    /// order (module docs).
    pub fn treelets(&self, bytes: usize) -> Vec<Vec<u32>> {
        let mut out = vec![];
        if self.is_empty() {
            return out;
        }
        let budget = (bytes / self.node_bytes).max(1);
        // Depth-first rank of every node: treelet roots are laid out in it, and it breaks ties.
        let mut rank = vec![0u32; self.len()];
        for (k, &i) in self.depth_first().iter().enumerate() {
            rank[i as usize] = k as u32;
        }
        let mut roots = vec![(0u32, 1u32)];
        while let Some(root) = roots.pop() {
            let (mut taken, mut size) = (vec![], 0);
            let mut heap =
                BinaryHeap::from([Candidate { weight: f64::INFINITY, rank: rank[root.0 as usize], group: root }]);
            let mut frontier = vec![];
            while let Some(c) = heap.pop() {
                if size > 0 && size + c.group.1 as usize > budget {
                    frontier.push(c.group);
                    continue;
                }
                taken.push(c.group);
                size += c.group.1 as usize;
                for i in self.group(c.group) {
                    let g = self.kids[i];
                    if g.1 > 0 {
                        heap.push(Candidate { weight: self.area[i], rank: rank[g.0 as usize], group: g });
                    }
                }
            }
            // Inside the treelet, depth first (a first child's group right after its parent's,
            // as in the depth-first order); the next treelets' roots, the first in depth-first
            // order on top.
            taken.sort_by_key(|g| rank[g.0 as usize]);
            frontier.sort_by_key(|g| std::cmp::Reverse(rank[g.0 as usize]));
            roots.extend(frontier);
            out.push(taken.into_iter().flat_map(|g| self.group(g).map(|i| i as u32)).collect());
        }
        out
    }

    /// The nodes in `order`, as old indices: entry `k` is the node placed at `k`.
    pub fn placement(&self, order: NodeOrder) -> Vec<u32> {
        match order {
            NodeOrder::Built => (0..self.len() as u32).collect(),
            NodeOrder::DepthFirst => self.depth_first(),
            NodeOrder::BreadthFirst => self.breadth_first(),
            NodeOrder::Treelets => self.treelets(TREELET_BYTES).concat(),
        }
    }

    /// Every node's index in `order` (entry `i`: the new index of node `i`); `None` for
    /// [`NodeOrder::Built`], or an error where the groups do not cover the array once (a node
    /// below two parents or below none: not a tree these orders can move).
    pub fn permutation(&self, order: NodeOrder) -> Result<Option<Vec<u32>>, String> {
        if order == NodeOrder::Built {
            return Ok(None);
        }
        let placed = self.placement(order);
        let mut new = vec![u32::MAX; self.len()];
        for (k, &i) in placed.iter().enumerate() {
            if std::mem::replace(&mut new[i as usize], k as u32) != u32::MAX {
                return Err(format!("node {i} is in two child groups; the {order} order needs a tree"));
            }
        }
        if let Some(i) = new.iter().position(|&k| k == u32::MAX) {
            return Err(format!("node {i} is in no child group below the root; the {order} order needs a tree"));
        }
        Ok(Some(new))
    }

    /// The bytes a visit of node `i` reads (an empty range for a binary leaf).
    fn fetched(&self, i: usize) -> std::ops::Range<usize> {
        let r = match self.fetch {
            Fetch::Node => i..i + 1,
            Fetch::Children => self.group(self.kids[i]),
        };
        r.start * self.node_bytes..r.end * self.node_bytes
    }

    /// [`Locality`] of the array as it is (apply an order first to measure it).
    pub fn locality(&self) -> Locality {
        // Units of `unit` bytes in `a` and not in `b`.
        fn fresh(a: &std::ops::Range<usize>, b: &std::ops::Range<usize>, unit: usize) -> usize {
            if a.is_empty() {
                return 0;
            }
            let (a0, a1) = (a.start / unit, (a.end - 1) / unit);
            let all = a1 - a0 + 1;
            if b.is_empty() {
                return all;
            }
            let (b0, b1) = (b.start / unit, (b.end - 1) / unit);
            let overlap = (a1.min(b1) + 1).saturating_sub(a0.max(b0));
            all - overlap
        }
        let (mut w, mut lines, mut pages) = (0.0, 0.0, 0.0);
        for p in 0..self.len() {
            let from = self.fetched(p);
            for c in self.group(self.kids[p]) {
                let to = self.fetched(c);
                if to.is_empty() {
                    continue;
                }
                let a = self.area[c];
                w += a;
                lines += a * fresh(&to, &from, LINE_BYTES) as f64;
                pages += a * fresh(&to, &from, PAGE_BYTES) as f64;
            }
        }
        if w > 0.0 {
            Locality { lines_per_step: lines / w, pages_per_step: pages / w }
        } else {
            Locality::default()
        }
    }
}

/// Rewrites `nodes` in `new`'s order (entry `i`: the new index of node `i`), child indices
/// renamed by `fix`.
fn permute<T: Copy>(nodes: &[T], new: &[u32], mut fix: impl FnMut(&mut T)) -> Vec<T> {
    let mut out = nodes.to_vec();
    for (i, n) in nodes.iter().enumerate() {
        let mut n = *n;
        fix(&mut n);
        out[new[i] as usize] = n;
    }
    out
}

impl NodeOrder {
    /// The binary nodes (as `Bvh::nodes` or an encoding's) in this order: an inner node's
    /// `left_or_first` renamed, leaves untouched.
    pub fn reorder_binary(self, nodes: &mut Vec<BvhNode>) -> Result<(), String> {
        if self == NodeOrder::Built {
            return Ok(());
        }
        let Some(new) = NodeTree::binary(nodes).permutation(self)? else { return Ok(()) };
        *nodes = permute(nodes, &new, |n| {
            if !n.is_leaf() {
                let l = n.left_or_first as usize;
                debug_assert_eq!(new[l + 1], new[l] + 1, "siblings stay adjacent");
                n.left_or_first = new[l];
            }
        });
        Ok(())
    }

    /// Wide nodes (`bounds`: the root's box) in this order: every inner slot's index renamed.
    pub fn reorder_wide<const N: usize>(self, nodes: &mut Vec<WideNode<N>>, bounds: &Aabb) -> Result<(), String> {
        if self == NodeOrder::Built {
            return Ok(());
        }
        let Some(new) = NodeTree::wide(nodes, bounds)?.permutation(self)? else { return Ok(()) };
        *nodes = permute(nodes, &new, |n| {
            for s in 0..n.children() {
                if !n.is_leaf(s) {
                    n.child[s] = new[n.child[s] as usize];
                }
            }
        });
        Ok(())
    }

    /// A compressed tree in this order: every `child_base` renamed (its inner children move
    /// together); the leaf table and every `leaf_base` stay.
    pub fn reorder_cwbvh(self, cw: &mut CwBvh) -> Result<(), String> {
        if self == NodeOrder::Built {
            return Ok(());
        }
        let Some(new) = NodeTree::cwbvh(&cw.nodes, &cw.bounds).permutation(self)? else { return Ok(()) };
        cw.nodes = permute(&cw.nodes, &new, |n| {
            if n.imask != 0 {
                n.child_base = new[n.child_base as usize];
            }
        });
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::tests::grid;
    use crate::bvh::{BuildOptions, Bvh, Collapse, CwBvh, WideBvh};
    use crate::named::Named;

    fn trees() -> Vec<Bvh> {
        [(1, 3), (40, 4), (3000, 1), (3000, 4), (3000, 16)]
            .into_iter()
            .map(|(n, leaf)| Bvh::build(&grid(n), &BuildOptions::new(leaf)))
            .collect()
    }

    /// Each order is a permutation that keeps the root at 0, puts every child after its parent
    /// and every child group together; `Built` changes nothing and bvh2's built order is
    /// depth first.
    #[test]
    fn every_order_is_a_permutation_keeping_groups_together() {
        for bvh in trees() {
            let t = NodeTree::binary(&bvh.nodes);
            assert_eq!(t.placement(NodeOrder::DepthFirst), t.placement(NodeOrder::Built), "bvh2 is built depth first");
            assert_eq!(t.permutation(NodeOrder::Built), Ok(None));
            for &order in NodeOrder::ALL {
                let placed = t.placement(order);
                let mut sorted = placed.clone();
                sorted.sort_unstable();
                assert_eq!(sorted, (0..t.len() as u32).collect::<Vec<_>>(), "{order}: every node once");
                assert_eq!(placed.first(), Some(&0), "{order}: the root first");
                let mut nodes = bvh.nodes.clone();
                order.reorder_binary(&mut nodes).unwrap();
                let r = Bvh { nodes, ..bvh.clone() };
                for (i, n) in r.nodes.iter().enumerate().filter(|(_, n)| !n.is_leaf()) {
                    assert!(n.left_or_first as usize > i, "{order}: children after their parent");
                }
                // The same tree: equal statistics and SAH cost, boxes and leaves where they were.
                let (a, b) = (bvh.stats(), r.stats());
                assert_eq!(
                    (a.nodes, a.leaves, a.depth, &a.leaf_histogram),
                    (b.nodes, b.leaves, b.depth, &b.leaf_histogram)
                );
                assert_eq!(a.sah_cost, b.sah_cost, "{order}");
                let mut walk = vec![(0usize, 0usize)];
                while let Some((i, j)) = walk.pop() {
                    let (x, y) = (&bvh.nodes[i], &r.nodes[j]);
                    assert_eq!((x.min, x.max, x.count), (y.min, y.max, y.count), "{order}");
                    if x.is_leaf() {
                        assert_eq!(x.left_or_first, y.left_or_first, "{order}: leaf ranges stay");
                    } else {
                        for k in 0..2 {
                            walk.push((x.left_or_first as usize + k, y.left_or_first as usize + k));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn breadth_first_is_level_order() {
        for bvh in trees() {
            let mut nodes = bvh.nodes.clone();
            NodeOrder::BreadthFirst.reorder_binary(&mut nodes).unwrap();
            let d = NodeTree::binary(&nodes).depths();
            assert!(d.windows(2).all(|w| w[0] <= w[1]), "depth never falls along the array");
            // And the built order is not (so the test can fail).
            if bvh.nodes.len() > 7 {
                let built = NodeTree::binary(&bvh.nodes).depths();
                assert!(built.windows(2).any(|w| w[0] > w[1]));
            }
        }
    }

    /// Treelets: within the byte budget (a bigger group alone), connected (every group but the
    /// first hangs below a node of the same treelet), the treelets' roots in depth-first order,
    /// and the order is their concatenation, so each treelet is contiguous.
    #[test]
    fn treelets_are_contiguous_connected_and_within_their_budget() {
        let check = |t: &NodeTree, bytes: usize, what: &str| {
            let treelets = t.treelets(bytes);
            let mut parent = vec![u32::MAX; t.len()];
            for p in 0..t.len() {
                for c in t.group(t.kids[p]) {
                    parent[c] = p as u32;
                }
            }
            let mut treelet_of = vec![usize::MAX; t.len()];
            for (k, tl) in treelets.iter().enumerate() {
                tl.iter().for_each(|&i| treelet_of[i as usize] = k);
            }
            let dfs: Vec<u32> = t.depth_first();
            let mut rank = vec![0; t.len()];
            dfs.iter().enumerate().for_each(|(k, &i)| rank[i as usize] = k);
            let mut last_root = None;
            for (k, tl) in treelets.iter().enumerate() {
                let root = tl[0] as usize;
                let group = if root == 0 { 1 } else { t.kids[parent[root] as usize].1 as usize };
                assert!(
                    tl.len() * t.node_bytes <= bytes || tl.len() == group,
                    "{what}: treelet {k} holds {} nodes",
                    tl.len()
                );
                for &i in &tl[group..] {
                    let p = parent[i as usize];
                    assert_eq!(treelet_of[p as usize], k, "{what}: treelet {k} is connected");
                }
                assert!(last_root.is_none_or(|r| r < rank[root]), "{what}: treelet roots in depth-first order");
                last_root = Some(rank[root]);
            }
            if bytes == TREELET_BYTES {
                assert_eq!(
                    treelets.concat(),
                    t.placement(NodeOrder::Treelets),
                    "{what}: the order is the treelets one after another"
                );
            }
            treelets.len()
        };
        for bvh in trees() {
            let t = NodeTree::binary(&bvh.nodes);
            for bytes in [64, 256, TREELET_BYTES] {
                let n = check(&t, bytes, "bvh2");
                assert!(n >= t.len() * t.node_bytes / bytes, "bvh2 {bytes}: {n} treelets");
            }
            let w = WideBvh::<8>::collapse_with(&bvh, Collapse::Sah);
            check(&NodeTree::wide(&w.nodes, &w.bounds).unwrap(), 1024, "bvh8");
        }
    }

    /// The wide and compressed trees keep their shape and cost in every order, and are still
    /// valid trees of the binary one.
    #[test]
    fn wide_and_compressed_trees_reorder_to_the_same_tree() {
        let mesh = grid(3000);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let o = &bvh.options;
        for &order in NodeOrder::ALL {
            let mut w4 = WideBvh::<4>::collapse(&bvh);
            let cost = w4.sah_cost(o);
            order.reorder_wide(&mut w4.nodes, &bvh.nodes[0].aabb()).unwrap();
            w4.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("{order}: {e}"));
            assert_eq!(w4.sah_cost(o), cost);
            let mut cw = CwBvh::build(&bvh).unwrap();
            let (cost, words) = (cw.sah_cost(o), cw.words().len());
            order.reorder_cwbvh(&mut cw).unwrap();
            cw.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("{order}: {e}"));
            assert_eq!((cw.sah_cost(o), cw.words().len()), (cost, words));
        }
        // cwbvh is built breadth first, the wide trees depth first (last slot first).
        let cw = CwBvh::build(&bvh).unwrap();
        let t = NodeTree::cwbvh(&cw.nodes, &cw.bounds);
        assert_eq!(t.placement(NodeOrder::BreadthFirst), t.placement(NodeOrder::Built));
        let w8 = WideBvh::<8>::collapse(&bvh);
        let t = NodeTree::wide(&w8.nodes, &w8.bounds).unwrap();
        assert_ne!(t.placement(NodeOrder::DepthFirst), t.placement(NodeOrder::Built));
    }

    /// A node below two parents is refused, naming the order.
    #[test]
    fn a_dag_is_refused() {
        let bvh = Bvh::build(&grid(100), &BuildOptions::new(4));
        let mut nodes = bvh.nodes.clone();
        let inner: Vec<usize> = (0..nodes.len()).filter(|&i| !nodes[i].is_leaf()).collect();
        let (a, b) = (inner[1], inner[2]);
        nodes[b].left_or_first = nodes[a].left_or_first;
        let e = NodeOrder::Treelets.reorder_binary(&mut nodes).unwrap_err();
        assert!(e.contains("treelets"), "{e}");
    }

    /// Locality: treelets leave the parent's page on fewer steps than breadth first; bvh2's
    /// child pairs straddle two lines (the root alone at 0 puts every pair at an odd index).
    #[test]
    fn treelets_leave_pages_less_than_breadth_first() {
        let bvh = Bvh::build(&grid(20_000), &BuildOptions::new(1));
        let l = |order: NodeOrder| {
            let mut nodes = bvh.nodes.clone();
            order.reorder_binary(&mut nodes).unwrap();
            NodeTree::binary(&nodes).locality()
        };
        let (bfs, tl) = (l(NodeOrder::BreadthFirst), l(NodeOrder::Treelets));
        assert!(tl.pages_per_step < 0.5 * bfs.pages_per_step, "treelets {tl:?}, breadth first {bfs:?}");
        // A pair straddles two lines; depth first inside the treelet shares one with the parent's
        // pair on a first child's step.
        assert!(tl.lines_per_step > 1.2 && tl.lines_per_step < bfs.lines_per_step, "{tl:?}");
        eprintln!("depth first {:?}\nbreadth first {bfs:?}\ntreelets {tl:?}", l(NodeOrder::DepthFirst));
    }
}
