//! The binary tree collapsed into wide nodes ([`WideBvh::collapse_with`]): the greedy opening
//! and the SAH dynamic program (the module docs of [`super`] describe both).

use std::time::Instant;

use serde::Serialize;

use super::{WideBvh, WideNode};
use crate::bvh::{BuildOptions, Bvh, BvhNode};

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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::testing::{grid, mt};
    use crate::rays::Ray;
    use crate::scene::Mesh;

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
}
