//! The binary tree the SAH builder makes ([`Bvh`]): its nodes, the triangles in leaf order, and
//! the walks and costs every other part reads it with. Its 32-byte node is [`BvhNode`]
//! (`node.rs`), its statistics [`BvhStats`] (`stats.rs`), its invariants [`Bvh::validate`]
//! (`validate.rs`).

mod node;
mod stats;
mod validate;

pub use node::BvhNode;
pub use stats::BvhStats;

use super::{sah, BuildOptions, PAD_SLOT};
use crate::scene::Mesh;

/// A built hierarchy over one mesh. Leaves index `prim_ids` (`left_or_first`, `count`); the
/// encodings turn that into their own storage order.
#[derive(Clone, Debug)]
pub struct Bvh {
    /// Root at 0; the children of an inner node are adjacent.
    pub nodes: Vec<BvhNode>,
    /// Leaf slot -> triangle id, in leaf order ([`PAD_SLOT`] for padding).
    pub prim_ids: Vec<u32>,
    pub options: BuildOptions,
    pub build_seconds: f64,
    /// Threads the build ran on (rayon's pool; 1 for [`Bvh::build_serial`]).
    pub build_threads: usize,
    /// Zero-area triangles left out of the hierarchy (never hit).
    pub degenerate_excluded: usize,
}

impl Bvh {
    /// Builds a BVH over the mesh's non-degenerate triangles, in parallel on rayon's current
    /// thread pool (run it inside `ThreadPool::install` to choose the thread count). The tree
    /// is bitwise identical to [`Bvh::build_serial`]'s whatever the pool.
    pub fn build(mesh: &Mesh, options: &BuildOptions) -> Bvh {
        let span = crate::timeline::span("bvh", "BVH build").with("triangles", mesh.triangle_count());
        span.arg("leaf_size", options.max_leaf_size);
        let bvh = sah::build(mesh, options);
        span.arg("nodes", bvh.nodes.len());
        bvh
    }

    /// The same tree built by one single-threaded loop (the reference for the parallel build).
    pub fn build_serial(mesh: &Mesh, options: &BuildOptions) -> Bvh {
        sah::build_serial(mesh, options)
    }

    /// The same tree bit for bit: nodes (as bytes, so -0.0 and +0.0 differ), slot order and
    /// the degenerate triangles left out. Build settings and timings are not compared.
    pub fn same_tree(&self, other: &Bvh) -> bool {
        bytemuck::cast_slice::<_, u8>(&self.nodes) == bytemuck::cast_slice::<_, u8>(&other.nodes)
            && self.prim_ids == other.prim_ids
            && self.degenerate_excluded == other.degenerate_excluded
    }

    /// Triangles in the hierarchy (degenerate ones excluded, padding not counted).
    pub fn triangle_count(&self) -> usize {
        self.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count()
    }

    /// Calls `f(node_index, depth)` for every node, depth first.
    pub fn visit(&self, mut f: impl FnMut(usize, u32)) {
        let mut stack = vec![(0usize, 0u32)];
        while let Some((i, d)) = stack.pop() {
            f(i, d);
            let n = &self.nodes[i];
            if !n.is_leaf() {
                let l = n.left_or_first as usize;
                stack.push((l + 1, d + 1));
                stack.push((l, d + 1));
            }
        }
    }

    /// The SAH cost of this tree priced with `o`'s costs and `sah_group` (so trees built
    /// with different options can be compared on one scale).
    pub fn sah_cost(&self, o: &BuildOptions) -> f64 {
        let root_area = self.nodes[0].aabb().area().max(f64::MIN_POSITIVE);
        let mut cost = 0.0;
        self.visit(|i, _| {
            let n = &self.nodes[i];
            let rel = n.aabb().area() / root_area;
            cost += if n.is_leaf() {
                o.cost_intersect as f64 * o.tests(n.count as usize) * rel
            } else {
                o.cost_traversal as f64 * rel
            };
        });
        cost
    }
}
