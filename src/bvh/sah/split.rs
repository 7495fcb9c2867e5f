//! Where a node is split, or whether it becomes a leaf ([`choose_split`]): the binned and
//! full-sweep SAH split finders, the depth bound's median fallback.

use super::scan::{bin_index, by_centroid, NodeBounds, SplitOps};
use super::{Aabb, BuildOptions, Builder, LeafPolicy, Prim, MAX_DEPTH};

enum Split {
    /// Primitives whose centroid falls in bins `0..=bin` along `axis` go left.
    Bin { axis: usize, bin: usize, bins: usize, lo: f32, scale: f32 },
    /// After sorting by centroid along `axis`, the first `left` go left.
    Sorted { axis: usize, left: usize },
}

/// How many primitives go left, and the two children's bounds when the split gathered them.
type Cut = (usize, Option<[NodeBounds; 2]>);

/// Decides the node's fate: `None` makes it a leaf, `Some((k, _))` splits it with the first
/// `k` primitives (reordered in place) going to the left child.
pub(super) fn choose_split(
    range: &mut [Prim],
    nb: &NodeBounds,
    depth: u32,
    o: &BuildOptions,
    ops: &mut impl SplitOps,
) -> Option<Cut> {
    let (bounds, cbounds) = (&nb.bounds, &nb.cbounds);
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
        Builder::Binned { bins } => best_binned(range, bounds, cbounds, bins as usize, o, ops),
        Builder::Sweep => best_sweep(range, bounds, o, ops),
    };
    if fits && best.as_ref().is_none_or(|(c, _)| leaf_cost <= *c) {
        return None;
    }
    let left = best.map(|(_, s)| apply(range, &s, ops)).filter(|&(k, _)| k > 0 && k < n);
    let levels_left = MAX_DEPTH - depth - 1; // for each child
    let ok = |k: usize| {
        levels_needed(k, o.max_leaf_size) <= levels_left && levels_needed(n - k, o.max_leaf_size) <= levels_left
    };
    match left {
        Some((k, sides)) if ok(k) => Some((k, sides)),
        _ if fits => None,
        _ => Some((median_split(range, cbounds), None)),
    }
}

/// Object median along the largest centroid extent (or in index order when all centroids
/// coincide): halves the count, so depth stays logarithmic. Serial in both builders (it only
/// runs where the depth bound forces it): `select_nth_unstable_by` is deterministic for a
/// given input order.
fn median_split(range: &mut [Prim], cbounds: &Aabb) -> usize {
    let mid = range.len() / 2;
    let axis = cbounds.largest_axis();
    if cbounds.extent()[axis] > 0.0 {
        range.select_nth_unstable_by(mid, |a, b| by_centroid(a, b, axis));
    }
    mid
}

fn sah(o: &BuildOptions, parent_area: f64, la: f64, ln: usize, ra: f64, rn: usize) -> f64 {
    o.cost_traversal as f64 + o.cost_intersect as f64 * (la * o.tests(ln) + ra * o.tests(rn)) / parent_area
}

fn best_binned(
    range: &[Prim],
    bounds: &Aabb,
    cbounds: &Aabb,
    bins: usize,
    o: &BuildOptions,
    ops: &mut impl SplitOps,
) -> Option<(f64, Split)> {
    let parent_area = bounds.area().max(f64::MIN_POSITIVE);
    let axes: [Option<(f32, f32)>; 3] = std::array::from_fn(|axis| {
        let lo = cbounds.min[axis];
        let extent = cbounds.max[axis] - lo;
        (!extent.is_nan() && extent > 0.0).then(|| (lo, bins as f32 / extent))
    });
    if axes.iter().all(Option::is_none) {
        return None;
    }
    let binned = ops.bins(range, &axes, bins);
    let mut best: Option<(f64, Split)> = None;
    let mut right_area = vec![0.0f64; bins];
    let mut right_count = vec![0usize; bins];
    for (axis, a) in axes.iter().enumerate() {
        let Some((lo, scale)) = *a else { continue };
        let bin_bounds = &binned.boxes[axis * bins..(axis + 1) * bins];
        let bin_counts = &binned.counts[axis * bins..(axis + 1) * bins];
        // Right-to-left sweep: area and count of bins b+1..bins. An empty bin changes neither
        // (growing by an empty box is exact), so its area is the previous one.
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        let mut area = 0.0;
        for b in (1..bins).rev() {
            if bin_counts[b] > 0 {
                acc.grow(&bin_bounds[b]);
                cnt += bin_counts[b];
                area = acc.area();
            }
            right_area[b - 1] = area;
            right_count[b - 1] = cnt;
        }
        let mut acc = Aabb::EMPTY;
        let mut cnt = 0;
        for b in 0..bins - 1 {
            if bin_counts[b] == 0 {
                // The same two sides as the boundary before, already priced (or not a split):
                // skipping it changes no choice, since a later candidate must be strictly cheaper.
                continue;
            }
            acc.grow(&bin_bounds[b]);
            cnt += bin_counts[b];
            if right_count[b] == 0 {
                break;
            }
            let c = sah(o, parent_area, acc.area(), cnt, right_area[b], right_count[b]);
            if best.as_ref().is_none_or(|(bc, _)| c < *bc) {
                best = Some((c, Split::Bin { axis, bin: b, bins, lo, scale }));
            }
        }
    }
    best
}

fn best_sweep(range: &mut [Prim], bounds: &Aabb, o: &BuildOptions, ops: &mut impl SplitOps) -> Option<(f64, Split)> {
    let n = range.len();
    let parent_area = bounds.area().max(f64::MIN_POSITIVE);
    let mut best: Option<(f64, Split)> = None;
    for axis in 0..3 {
        ops.sort(range, axis);
        let right = ops.boxes();
        right.resize(n, Aabb::EMPTY);
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

/// Reorders `range` for the split; returns how many primitives go left, and the children's
/// bounds where the reordering gathered them.
fn apply(range: &mut [Prim], split: &Split, ops: &mut impl SplitOps) -> Cut {
    match *split {
        Split::Bin { axis, bin, bins, lo, scale } => {
            let (k, sides) = ops.partition(range, |p: &Prim| bin_index(p.centroid(axis), lo, scale, bins) <= bin);
            (k, Some(sides))
        }
        Split::Sorted { axis, left } => {
            ops.sort(range, axis);
            (left, None)
        }
    }
}

/// Levels below a node needed to split `n` primitives into leaves of at most `leaf` each.
fn levels_needed(n: usize, leaf: u32) -> u32 {
    let leaves = n.div_ceil(leaf as usize);
    leaves.next_power_of_two().trailing_zeros()
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
