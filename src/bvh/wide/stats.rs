//! A wide tree's SAH costs, sizes and the traversal stack it needs ([`WideStats`]).

use serde::Serialize;

use super::WideBvh;
use crate::bvh::BuildOptions;

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

impl<const N: usize> WideBvh<N> {
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
    ///
    /// [`Bvh::sah_cost`]: crate::bvh::Bvh::sah_cost
    pub fn sah_cost(&self, o: &BuildOptions) -> f64 {
        self.sah(o, false)
    }

    /// The same with each node priced per box tested, `C_t (k/2) A(n)/A(root)` for `k`
    /// occupied children (a binary node's two boxes cost `C_t`, as in [`Bvh::sah_cost`]): the
    /// cost when a ray tests its node's boxes one after another. Also equals `Bvh::sah_cost`
    /// for `N` = 2.
    ///
    /// [`Bvh::sah_cost`]: crate::bvh::Bvh::sah_cost
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
}
