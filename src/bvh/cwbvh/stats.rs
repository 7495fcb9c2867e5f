//! A compressed tree's sizes, SAH cost over its decoded boxes and the traversal stack it
//! needs ([`CwStats`]).

use serde::Serialize;

use super::{CwBvh, CW_WIDTH};
use crate::bvh::BuildOptions;
use crate::shared::leaf_entry_count;

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
    /// The SAH cost with the decoded (quantized) boxes, priced as [`WideBvh::sah_cost`](crate::bvh::WideBvh::sah_cost).
    pub sah_cost: f64,
    pub build_ms: f64,
}

impl CwBvh {
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
    ///
    /// [`WideBvh::sah_cost`]: crate::bvh::WideBvh::sah_cost
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
}
