//! Traversal statistics from the GPU: the `stats` variant of `glsl/raycast.comp` writes, per
//! ray, how many BVH nodes its traversal visited and how many triangles it tested (the counters
//! are defined in `glsl/counts.glsl`). `traversal::ray_steps` is the CPU mirror these are
//! checked against (`tests/traversal_stats.rs`).

use bytemuck::{Pod, Zeroable};
use serde::Serialize;

/// One ray's traversal work, GLSL `TraversalCounts` (20 bytes, std430 at
/// `BINDING_TRAVERSAL_STATS`; `tests/reflection.rs` checks the offsets).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable, Serialize)]
pub struct TraversalCounts {
    /// Loop iterations at inner nodes (each loads and slab-tests both children).
    pub inner: u32,
    /// Loop iterations at leaves (each runs the intersector once).
    pub leaves: u32,
    /// Real triangles tested: the sum of the visited leaves' triangle counts.
    pub triangles: u32,
    /// Triangle slots evaluated: each leaf's count rounded up to whole primitives (4 for the
    /// Quad methods, padding lanes included; equal to `triangles` for MT and unit).
    pub slots: u32,
    /// Slab tests: the root's and two per inner iteration in the binary tree; in a wide layout
    /// one per occupied child slot of each node visited.
    pub boxes: u32,
}

const _: () = assert!(std::mem::size_of::<TraversalCounts>() == 20);
const _: () = assert!(std::mem::align_of::<TraversalCounts>() == 4);

impl TraversalCounts {
    /// BVH nodes visited: loop iterations, inner and leaf.
    pub fn nodes(&self) -> u32 {
        self.inner + self.leaves
    }
}

/// Mean and maximum of one counter over the rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct MeanMax {
    pub mean: f64,
    pub max: u32,
}

impl MeanMax {
    fn of(counts: &[TraversalCounts], f: impl Fn(&TraversalCounts) -> u32) -> MeanMax {
        let sum: u64 = counts.iter().map(|c| f(c) as u64).sum();
        MeanMax { mean: sum as f64 / counts.len().max(1) as f64, max: counts.iter().map(f).max().unwrap_or(0) }
    }
}

/// Per-ray means and maxima of the traversal counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TraversalSummary {
    pub rays: usize,
    /// Nodes visited (inner + leaf iterations).
    pub nodes: MeanMax,
    pub inner: MeanMax,
    pub leaves: MeanMax,
    /// Real triangles tested.
    pub triangles: MeanMax,
    /// Triangle slots evaluated (padding included).
    pub slots: MeanMax,
    /// Boxes slab-tested.
    pub boxes: MeanMax,
}

impl TraversalSummary {
    pub fn of(counts: &[TraversalCounts]) -> TraversalSummary {
        TraversalSummary {
            rays: counts.len(),
            nodes: MeanMax::of(counts, TraversalCounts::nodes),
            inner: MeanMax::of(counts, |c| c.inner),
            leaves: MeanMax::of(counts, |c| c.leaves),
            triangles: MeanMax::of(counts, |c| c.triangles),
            slots: MeanMax::of(counts, |c| c.slots),
            boxes: MeanMax::of(counts, |c| c.boxes),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn summary_means_and_maxima() {
        let c =
            |inner, leaves, triangles, slots| TraversalCounts { inner, leaves, triangles, slots, boxes: 2 * inner + 1 };
        let s = TraversalSummary::of(&[c(3, 1, 4, 4), c(0, 0, 0, 0), c(6, 3, 7, 12)]);
        assert_eq!(s.rays, 3);
        assert_eq!(s.nodes, MeanMax { mean: 13.0 / 3.0, max: 9 });
        assert_eq!(s.inner, MeanMax { mean: 3.0, max: 6 });
        assert_eq!(s.leaves, MeanMax { mean: 4.0 / 3.0, max: 3 });
        assert_eq!(s.triangles, MeanMax { mean: 11.0 / 3.0, max: 7 });
        assert_eq!(s.slots, MeanMax { mean: 16.0 / 3.0, max: 12 });
        assert_eq!(TraversalSummary::of(&[]), TraversalSummary::default());
    }
}
