//! Top-down SAH BVH construction (MacDonald & Booth 1990; binning after Wald, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies", RT 2007).
//!
//! Two split finders share one driver:
//! - [`Builder::Binned`]: centroids binned along each axis, every bin boundary priced. The default.
//! - [`Builder::Sweep`]: every primitive boundary along each axis priced after a sort (the
//!   "full sweep"): slower, and the reference the binned SAH cost is measured against.
//!
//! Depth is bounded by construction: a node whose primitives need `r` more levels to fit into
//! leaves of `max_leaf_size` is split at the object median whenever the SAH split would leave
//! a child needing more levels than remain under [`MAX_DEPTH`]. Degenerate (zero-area)
//! triangles are left out: they can never be hit.

use std::time::Instant;

use glam::Vec3;

use super::{Aabb, Bvh, BvhNode, PAD_SLOT};
use crate::scene::Mesh;

/// Deepest leaf allowed (root at depth 0). The traversal pushes at most one node per level, so
/// its stack of `STACK_SIZE` entries never overflows.
pub const MAX_DEPTH: u32 = crate::gpu::shared::STACK_SIZE;

/// Largest supported `max_leaf_size`.
pub const MAX_LEAF_SIZE: u32 = 16;

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Builder {
    /// Binned SAH with this many bins per axis.
    Binned { bins: u32 },
    /// Full-sweep SAH: every split position along every axis.
    Sweep,
}

impl Default for Builder {
    fn default() -> Self {
        Builder::Binned { bins: 32 }
    }
}

impl std::fmt::Display for Builder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Builder::Binned { bins } => write!(f, "binned SAH ({bins} bins)"),
            Builder::Sweep => write!(f, "full-sweep SAH"),
        }
    }
}

/// When a node becomes a leaf.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum LeafPolicy {
    /// The paper's: a node with at most `max_leaf_size` triangles is a leaf, so leaves hold
    /// close to that many ("try to fill BVH with four triangles per node", sec. 3.1); SAH
    /// chooses the split planes above that.
    #[default]
    Fill,
    /// SAH decides: a node is a leaf when that is cheaper than its best split (or it holds one
    /// triangle); `max_leaf_size` is only an upper bound.
    Sah,
}

impl std::fmt::Display for LeafPolicy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            LeafPolicy::Fill => "fill",
            LeafPolicy::Sah => "sah",
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct BuildOptions {
    /// Most triangles in one leaf (1..=16).
    pub max_leaf_size: u32,
    pub leaf_policy: LeafPolicy,
    pub builder: Builder,
    /// SAH cost of one traversal step, relative to `cost_intersect`.
    pub cost_traversal: f32,
    /// SAH cost of one ray-triangle test (of one group, when `sah_group` > 1).
    pub cost_intersect: f32,
    /// Triangles the intersector tests at once: 1, or 4 for the Quad methods. The SAH prices a
    /// leaf of n triangles at ceil(n / sah_group) tests, as tinybvh and madmann91/bvh price
    /// SIMD leaves, so splits that fill whole quads are preferred. 1 is the classic SAH.
    pub sah_group: u32,
}

impl BuildOptions {
    /// Intersection tests for a leaf of `n` triangles: ceil(n / sah_group).
    pub fn tests(&self, n: usize) -> f64 {
        n.div_ceil(self.sah_group.max(1) as usize) as f64
    }

    pub fn new(max_leaf_size: u32) -> Self {
        BuildOptions {
            max_leaf_size,
            leaf_policy: LeafPolicy::default(),
            builder: Builder::default(),
            cost_traversal: 1.0,
            cost_intersect: 1.0,
            sah_group: 1,
        }
    }
}

#[derive(Clone, Copy)]
struct Prim {
    bounds: Aabb,
    centroid: Vec3,
    id: u32,
}

enum Split {
    /// Primitives whose centroid falls in bins `0..=bin` along `axis` go left.
    Bin { axis: usize, bin: usize, bins: usize, lo: f32, scale: f32 },
    /// After sorting by centroid along `axis`, the first `left` go left.
    Sorted { axis: usize, left: usize },
}

pub(super) fn build(mesh: &Mesh, options: &BuildOptions) -> Bvh {
    assert!((1..=MAX_LEAF_SIZE).contains(&options.max_leaf_size), "max_leaf_size must be 1..={MAX_LEAF_SIZE}");
    let start = Instant::now();
    let mut prims: Vec<Prim> = (0..mesh.triangle_count())
        .filter(|&i| !mesh.is_degenerate(i))
        .map(|i| {
            let b = Aabb::from_points(&mesh.vertices(i));
            Prim { bounds: b, centroid: b.center(), id: i as u32 }
        })
        .collect();
    let excluded = mesh.triangle_count() - prims.len();

    if prims.is_empty() {
        // Nothing can be hit. One leaf over a single padding slot (a degenerate triangle every
        // encoding rejects exactly) keeps the GPU path uniform.
        let p = mesh.positions.first().copied().unwrap_or([0.0; 3]);
        let root = BvhNode { min: p, left_or_first: 0, max: p, count: 1 };
        return Bvh {
            nodes: vec![root],
            prim_ids: vec![PAD_SLOT],
            options: *options,
            build_seconds: start.elapsed().as_secs_f64(),
            degenerate_excluded: excluded,
        };
    }

    let n = prims.len();
    let mut nodes = Vec::with_capacity(2 * n);
    nodes.push(BvhNode::default());
    // (node index, first prim, prim count, depth); popped depth-first, left child first.
    let mut work = vec![(0usize, 0usize, n, 0u32)];
    let mut scratch = Vec::new();
    while let Some((node, first, count, depth)) = work.pop() {
        let range = &mut prims[first..first + count];
        let mut bounds = Aabb::EMPTY;
        let mut cbounds = Aabb::EMPTY;
        for p in range.iter() {
            bounds.grow(&p.bounds);
            cbounds.grow_point(p.centroid);
        }
        nodes[node].set_aabb(&bounds);

        let left_count = choose_split(range, &bounds, &cbounds, depth, options, &mut scratch);
        let Some(left_count) = left_count else {
            nodes[node].left_or_first = first as u32;
            nodes[node].count = count as u32;
            continue;
        };
        let left = nodes.len();
        nodes.push(BvhNode::default());
        nodes.push(BvhNode::default());
        nodes[node].left_or_first = left as u32;
        nodes[node].count = 0;
        work.push((left + 1, first + left_count, count - left_count, depth + 1));
        work.push((left, first, left_count, depth + 1));
    }

    Bvh {
        nodes,
        prim_ids: prims.iter().map(|p| p.id).collect(),
        options: *options,
        build_seconds: start.elapsed().as_secs_f64(),
        degenerate_excluded: excluded,
    }
}

/// Levels below a node needed to split `n` primitives into leaves of at most `leaf` each.
fn levels_needed(n: usize, leaf: u32) -> u32 {
    let leaves = n.div_ceil(leaf as usize);
    leaves.next_power_of_two().trailing_zeros()
}

/// Decides the node's fate: `None` makes it a leaf, `Some(k)` splits it with the first `k`
/// primitives (reordered in place) going to the left child.
fn choose_split(
    range: &mut [Prim],
    bounds: &Aabb,
    cbounds: &Aabb,
    depth: u32,
    o: &BuildOptions,
    scratch: &mut Vec<Aabb>,
) -> Option<usize> {
    let n = range.len();
    if n == 1 || depth >= MAX_DEPTH {
        // At MAX_DEPTH the depth rule below has already left at most max_leaf_size here.
        debug_assert!(n <= o.max_leaf_size as usize);
        return None;
    }
    let fits = n <= o.max_leaf_size as usize;
    if fits && o.leaf_policy == LeafPolicy::Fill {
        return None;
    }
    let leaf_cost = o.cost_intersect as f64 * o.tests(n);
    let best = match o.builder {
        Builder::Binned { bins } => best_binned(range, bounds, cbounds, bins as usize, o),
        Builder::Sweep => best_sweep(range, bounds, o, scratch),
    };
    if fits && best.as_ref().is_none_or(|(c, _)| leaf_cost <= *c) {
        return None;
    }
    let left = best.map(|(_, s)| apply(range, &s)).filter(|&k| k > 0 && k < n);
    let levels_left = MAX_DEPTH - depth - 1; // for each child
    let ok = |k: usize| {
        levels_needed(k, o.max_leaf_size) <= levels_left && levels_needed(n - k, o.max_leaf_size) <= levels_left
    };
    match left {
        Some(k) if ok(k) => Some(k),
        _ if fits => None,
        _ => Some(median_split(range, cbounds)),
    }
}

/// Object median along the largest centroid extent (or in index order when all centroids
/// coincide): halves the count, so depth stays logarithmic.
fn median_split(range: &mut [Prim], cbounds: &Aabb) -> usize {
    let mid = range.len() / 2;
    let axis = cbounds.largest_axis();
    if cbounds.extent()[axis] > 0.0 {
        range.select_nth_unstable_by(mid, |a, b| a.centroid[axis].total_cmp(&b.centroid[axis]).then(a.id.cmp(&b.id)));
    }
    mid
}

fn sah(o: &BuildOptions, parent_area: f64, la: f64, ln: usize, ra: f64, rn: usize) -> f64 {
    o.cost_traversal as f64 + o.cost_intersect as f64 * (la * o.tests(ln) + ra * o.tests(rn)) / parent_area
}

fn best_binned(range: &[Prim], bounds: &Aabb, cbounds: &Aabb, bins: usize, o: &BuildOptions) -> Option<(f64, Split)> {
    let parent_area = bounds.area().max(f64::MIN_POSITIVE);
    let mut best: Option<(f64, Split)> = None;
    let mut bin_bounds = vec![Aabb::EMPTY; bins];
    let mut bin_counts = vec![0usize; bins];
    let mut right_area = vec![0.0f64; bins];
    let mut right_count = vec![0usize; bins];
    for axis in 0..3 {
        let lo = cbounds.min[axis];
        let extent = cbounds.max[axis] - lo;
        if extent.is_nan() || extent <= 0.0 {
            continue;
        }
        let scale = bins as f32 / extent;
        bin_bounds.fill(Aabb::EMPTY);
        bin_counts.fill(0);
        for p in range {
            let b = bin_index(p.centroid[axis], lo, scale, bins);
            bin_bounds[b].grow(&p.bounds);
            bin_counts[b] += 1;
        }
        // Right-to-left sweep: area and count of bins b+1..bins.
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in (1..bins).rev() {
            acc.grow(&bin_bounds[b]);
            cnt += bin_counts[b];
            right_area[b - 1] = acc.area();
            right_count[b - 1] = cnt;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in 0..bins - 1 {
            acc.grow(&bin_bounds[b]);
            cnt += bin_counts[b];
            if cnt == 0 || right_count[b] == 0 {
                continue;
            }
            let c = sah(o, parent_area, acc.area(), cnt, right_area[b], right_count[b]);
            if best.as_ref().is_none_or(|(bc, _)| c < *bc) {
                best = Some((c, Split::Bin { axis, bin: b, bins, lo, scale }));
            }
        }
    }
    best
}

fn bin_index(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

fn sort_axis(range: &mut [Prim], axis: usize) {
    range.sort_unstable_by(|a, b| a.centroid[axis].total_cmp(&b.centroid[axis]).then(a.id.cmp(&b.id)));
}

fn best_sweep(range: &mut [Prim], bounds: &Aabb, o: &BuildOptions, right: &mut Vec<Aabb>) -> Option<(f64, Split)> {
    let n = range.len();
    let parent_area = bounds.area().max(f64::MIN_POSITIVE);
    let mut best: Option<(f64, Split)> = None;
    right.resize(n, Aabb::EMPTY);
    for axis in 0..3 {
        sort_axis(range, axis);
        let mut acc = Aabb::EMPTY;
        for i in (1..n).rev() {
            acc.grow(&range[i].bounds);
            right[i] = acc;
        }
        let mut acc = Aabb::EMPTY;
        for i in 1..n {
            acc.grow(&range[i - 1].bounds);
            let c = sah(o, parent_area, acc.area(), i, right[i].area(), n - i);
            if best.as_ref().is_none_or(|(bc, _)| c < *bc) {
                best = Some((c, Split::Sorted { axis, left: i }));
            }
        }
    }
    best
}

/// Reorders `range` for the split; returns how many primitives go left.
fn apply(range: &mut [Prim], split: &Split) -> usize {
    match *split {
        Split::Bin { axis, bin, bins, lo, scale } => {
            let mut i = 0;
            let mut j = range.len();
            while i < j {
                if bin_index(range[i].centroid[axis], lo, scale, bins) <= bin {
                    i += 1;
                } else {
                    j -= 1;
                    range.swap(i, j);
                }
            }
            i
        }
        Split::Sorted { axis, left } => {
            sort_axis(range, axis);
            left
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_needed_matches_definition() {
        assert_eq!(levels_needed(1, 1), 0);
        assert_eq!(levels_needed(2, 1), 1);
        assert_eq!(levels_needed(3, 1), 2);
        assert_eq!(levels_needed(4, 4), 0);
        assert_eq!(levels_needed(5, 4), 1);
        assert_eq!(levels_needed(9, 4), 2);
        assert_eq!(levels_needed(1 << 20, 16), 16);
    }
}
