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
//! array; [`NodeTree::permutation`] the new place of every node; `reorder_*` rewrite the child
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
//! balanced binary tree), 32 bvh4 nodes, 16 bvh8 nodes, 64 qbvh4 nodes or 51 cwbvh nodes. Treelets are not
//! padded to page boundaries (the buffer keeps its bytes), so a full treelet usually spans two
//! pages.
//!
//! # Files
//!
//! The orders and the renaming of child indices are here; the view of a node array the orders
//! work on ([`NodeTree`]) is in `tree.rs`, the treelet packing in `treelets.rs`, the locality of
//! a descent ([`Locality`]) in `locality.rs`.

use serde::Serialize;

use super::{Aabb, BvhNode, CwBvh, WideNode};
use crate::named::named_enum;

mod locality;
mod tree;
mod treelets;

pub use locality::{Locality, LINE_BYTES, PAGE_BYTES};
pub use tree::{Fetch, NodeTree};

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
        self.reorder_wide_as(nodes, bounds, std::mem::size_of::<WideNode<N>>())
    }

    /// The same for a layout that stores the wide tree in `node_bytes` per node (qbvh4's
    /// quantized nodes: treelets count its bytes, not the wide node's).
    pub fn reorder_wide_as<const N: usize>(
        self,
        nodes: &mut Vec<WideNode<N>>,
        bounds: &Aabb,
        node_bytes: usize,
    ) -> Result<(), String> {
        if self == NodeOrder::Built {
            return Ok(());
        }
        let mut tree = NodeTree::wide(nodes, bounds)?;
        tree.node_bytes = node_bytes;
        let Some(new) = tree.permutation(self)? else { return Ok(()) };
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
    use crate::bvh::testing::{grid, grid_trees};
    use crate::bvh::{BuildOptions, Bvh, CwBvh, WideBvh};
    use crate::named::Named;

    /// Each order is a permutation that keeps the root at 0, puts every child after its parent
    /// and every child group together; `Built` changes nothing and bvh2's built order is
    /// depth first.
    #[test]
    fn every_order_is_a_permutation_keeping_groups_together() {
        for bvh in grid_trees() {
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
        for bvh in grid_trees() {
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
}
