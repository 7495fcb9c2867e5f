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
    /// Nodes (inner and leaf iterations, counted in `inner` and `leaves` too) visited on the
    /// ray's own after the hybrid traversal let it go; 0 in every other kernel. A ray with
    /// `alone > 0` switched from the packet to per-lane traversal.
    pub alone: u32,
}

const _: () = assert!(std::mem::size_of::<TraversalCounts>() == 24);
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
    /// Nodes visited alone after the hybrid's switch.
    pub alone: MeanMax,
    /// The hybrid's switch rate: the share of rays that went on alone (`alone > 0`); 0 for
    /// every other kernel. `None` for no rays.
    pub switched: Option<f64>,
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
            alone: MeanMax::of(counts, |c| c.alone),
            switched: (!counts.is_empty())
                .then(|| counts.iter().filter(|c| c.alone > 0).count() as f64 / counts.len() as f64),
        }
    }
}

/// The share of SIMD lane-iterations that do a ray's work when `lanes` consecutive rays run in
/// lock-step, as one subgroup (a ray-casting kernel's invocation `i` traces ray `i`, and a
/// subgroup is `lanes` consecutive invocations): per group of rays, the sum of `work` over the
/// group against `lanes` x its largest, summed over the groups (a last partial group counts
/// its idle lanes too: the driver runs it as a whole row). 1 when every lane of a group does
/// the same work; `None` for no rays or no work.
///
/// An upper bound on the lanes kept busy: it lines the rays' work up as if every lane ran the
/// same step at the same time, whereas lanes at different kinds of step (one in a leaf, one at
/// an inner node) also wait for each other's branch.
pub fn lanes_busy(counts: &[TraversalCounts], lanes: usize, work: impl Fn(&TraversalCounts) -> u32) -> Option<f64> {
    let lanes = lanes.max(1);
    let (done, paid) = counts.chunks(lanes).fold((0u64, 0u64), |(done, paid), group| {
        let w = group.iter().map(&work);
        (done + w.clone().map(u64::from).sum::<u64>(), paid + lanes as u64 * u64::from(w.max().unwrap_or(0)))
    });
    (paid > 0).then(|| done as f64 / paid as f64)
}

/// A ray's fetches as the traversal roofline counts them: nodes visited and triangles tested.
pub fn fetches(c: &TraversalCounts) -> u32 {
    c.nodes() + c.triangles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_busy_is_work_done_over_lanes_times_the_longest() {
        let n = |inner| TraversalCounts { inner, ..Default::default() };
        let nodes = |c: &TraversalCounts| c.nodes();
        // Two groups of 4: (1, 2, 3, 4) pays 16 for 10, (4, 4, 4, 4) pays 16 for 16.
        let counts: Vec<_> = [1, 2, 3, 4, 4, 4, 4, 4].into_iter().map(n).collect();
        assert_eq!(lanes_busy(&counts, 4, nodes), Some(26.0 / 32.0));
        // One lane per group: nothing waits.
        assert_eq!(lanes_busy(&counts, 1, nodes), Some(1.0));
        // Eight lanes: one group, 8 x 4 paid for 26.
        assert_eq!(lanes_busy(&counts, 8, nodes), Some(26.0 / 32.0));
        // A partial last group pays for its idle lanes: (4, 4, 4, 4), (1) -> 17 of 16 + 4.
        let partial: Vec<_> = [4, 4, 4, 4, 1].into_iter().map(n).collect();
        assert_eq!(lanes_busy(&partial, 4, nodes), Some(17.0 / 20.0));
        // The order of the rays matters: sorted by work, the long rays share a group.
        let mut sorted = counts.clone();
        sorted.sort_by_key(|c| c.inner);
        let shuffled: Vec<_> = [1, 4, 2, 4, 3, 4, 4, 4].into_iter().map(n).collect();
        assert!(lanes_busy(&shuffled, 2, nodes) < lanes_busy(&sorted, 2, nodes));
        assert_eq!(lanes_busy(&[], 8, nodes), None);
        assert_eq!(lanes_busy(&[n(0), n(0)], 8, nodes), None);
        // Fetches are nodes plus triangles.
        let c = TraversalCounts { inner: 3, leaves: 2, triangles: 7, slots: 8, boxes: 7, alone: 4 };
        assert_eq!(fetches(&c), 12, "the nodes visited alone are counted in inner and leaves already");
    }

    #[test]
    fn summary_means_and_maxima() {
        let c = |inner, leaves, triangles, slots| TraversalCounts {
            inner,
            leaves,
            triangles,
            slots,
            boxes: 2 * inner + 1,
            alone: leaves / 2,
        };
        let s = TraversalSummary::of(&[c(3, 1, 4, 4), c(0, 0, 0, 0), c(6, 3, 7, 12)]);
        assert_eq!(s.rays, 3);
        assert_eq!(s.nodes, MeanMax { mean: 13.0 / 3.0, max: 9 });
        assert_eq!(s.inner, MeanMax { mean: 3.0, max: 6 });
        assert_eq!(s.leaves, MeanMax { mean: 4.0 / 3.0, max: 3 });
        assert_eq!(s.triangles, MeanMax { mean: 11.0 / 3.0, max: 7 });
        assert_eq!(s.slots, MeanMax { mean: 16.0 / 3.0, max: 12 });
        // alone 0, 0, 1: one ray of three switched.
        assert_eq!(s.alone, MeanMax { mean: 1.0 / 3.0, max: 1 });
        assert_eq!(s.switched, Some(1.0 / 3.0));
        assert_eq!(TraversalSummary::of(&[]), TraversalSummary::default());
    }
}
