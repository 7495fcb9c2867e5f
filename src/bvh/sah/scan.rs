//! How the split finders scan and reorder a node's primitives ([`SplitOps`]): serially
//! ([`SerialOps`]), or in parallel chunks for the large nodes near the root ([`ParOps`]), with
//! the same bounds, bins, sorts and partitions.

use rayon::prelude::*;

use super::{Aabb, Prim};

/// Reusable buffers of the serial builder.
#[derive(Default)]
pub(super) struct Scratch {
    /// Right-hand primitives during a stable partition.
    prims: Vec<Prim>,
    /// Suffix boxes of the full sweep.
    boxes: Vec<Aabb>,
}

/// Box of the primitives and box of their centroids.
pub(super) fn bounds_of(range: &[Prim]) -> NodeBounds {
    let mut nb = NodeBounds::EMPTY;
    for p in range {
        nb.add(p);
    }
    nb
}

pub(super) fn bounds_par(range: &[Prim], chunk: usize) -> NodeBounds {
    range.par_chunks(chunk).map(bounds_of).reduce(|| NodeBounds::EMPTY, NodeBounds::then)
}

/// How the split finders scan and reorder a node's primitives: serially, or in parallel chunks
/// for the large nodes near the root. Both give the same bins, sorts and partitions.
pub(super) trait SplitOps {
    fn bins(&mut self, range: &[Prim], axes: &[Option<(f32, f32)>; 3], bins: usize) -> Bins;
    fn sort(&mut self, range: &mut [Prim], axis: usize);
    fn boxes(&mut self) -> &mut Vec<Aabb>;
    /// Stable partition; also returns the bounds of each side, gathered on the way so the
    /// children need no pass of their own.
    fn partition<F: Fn(&Prim) -> bool + Sync>(&mut self, range: &mut [Prim], goes_left: F) -> (usize, [NodeBounds; 2]);
}

/// A node's box and the box of its primitives' centroids.
#[derive(Clone, Copy)]
pub(super) struct NodeBounds {
    pub(super) bounds: Aabb,
    pub(super) cbounds: Aabb,
}

impl NodeBounds {
    const EMPTY: NodeBounds = NodeBounds { bounds: Aabb::EMPTY, cbounds: Aabb::EMPTY };

    #[inline]
    fn add(&mut self, p: &Prim) {
        self.bounds.grow(&p.bounds);
        self.cbounds.grow_point(p.bounds.center());
    }

    /// `self` then `other`: the order matters only for which of two equal values (+0.0 and
    /// -0.0) is kept, and keeping the order keeps that as in one sequential pass.
    fn then(self, other: NodeBounds) -> NodeBounds {
        NodeBounds { bounds: self.bounds.union(&other.bounds), cbounds: self.cbounds.union(&other.cbounds) }
    }
}

pub(super) struct SerialOps<'a>(pub(super) &'a mut Scratch);

impl SplitOps for SerialOps<'_> {
    fn bins(&mut self, range: &[Prim], axes: &[Option<(f32, f32)>; 3], bins: usize) -> Bins {
        let mut b = Bins::new(bins);
        b.add(range, axes);
        b
    }

    fn sort(&mut self, range: &mut [Prim], axis: usize) {
        range.sort_unstable_by(|a, b| by_centroid(a, b, axis));
    }

    fn boxes(&mut self) -> &mut Vec<Aabb> {
        &mut self.0.boxes
    }

    /// Stable: lefts keep their order at the front, rights theirs behind them.
    fn partition<F: Fn(&Prim) -> bool + Sync>(&mut self, range: &mut [Prim], goes_left: F) -> (usize, [NodeBounds; 2]) {
        let rights = &mut self.0.prims;
        rights.clear();
        let mut sides = [NodeBounds::EMPTY; 2];
        let mut w = 0;
        for i in 0..range.len() {
            let p = range[i];
            if goes_left(&p) {
                sides[0].add(&p);
                range[w] = p;
                w += 1;
            } else {
                sides[1].add(&p);
                rights.push(p);
            }
        }
        range[w..].copy_from_slice(rights);
        (w, sides)
    }
}

pub(super) struct ParOps<'a> {
    /// Partition buffer, as long as the node's range.
    pub(super) tmp: &'a mut [Prim],
    /// Suffix boxes of the full sweep (which only small scenes use); empty unless it runs.
    pub(super) boxes: Vec<Aabb>,
    pub(super) chunk: usize,
}

impl SplitOps for ParOps<'_> {
    /// Per-chunk bins merged; min, max and counts do not depend on the grouping.
    fn bins(&mut self, range: &[Prim], axes: &[Option<(f32, f32)>; 3], bins: usize) -> Bins {
        range
            .par_chunks(self.chunk)
            .map(|c| {
                let mut b = Bins::new(bins);
                b.add(c, axes);
                b
            })
            .reduce(|| Bins::new(bins), Bins::merge)
    }

    /// The order is total (centroid, then id) and ids are unique, so any sort gives one result.
    fn sort(&mut self, range: &mut [Prim], axis: usize) {
        range.par_sort_unstable_by(|a, b| by_centroid(a, b, axis));
    }

    fn boxes(&mut self) -> &mut Vec<Aabb> {
        &mut self.boxes
    }

    /// The same stable partition: each chunk's lefts and rights go to their places in `tmp`
    /// (offsets from a prefix sum of per-chunk counts), then back.
    fn partition<F: Fn(&Prim) -> bool + Sync>(&mut self, range: &mut [Prim], goes_left: F) -> (usize, [NodeBounds; 2]) {
        debug_assert_eq!(range.len(), self.tmp.len());
        let goes_left = &goes_left;
        let counts: Vec<usize> =
            range.par_chunks(self.chunk).map(|c| c.iter().filter(|p| goes_left(p)).count()).collect();
        let left: usize = counts.iter().sum();
        let (mut lt, mut rt) = self.tmp.split_at_mut(left);
        let mut jobs = Vec::with_capacity(counts.len());
        for (chunk, &l) in range.chunks(self.chunk).zip(&counts) {
            let (a, rest) = std::mem::take(&mut lt).split_at_mut(l);
            lt = rest;
            let (b, rest) = std::mem::take(&mut rt).split_at_mut(chunk.len() - l);
            rt = rest;
            jobs.push((chunk, a, b));
        }
        let sides = jobs
            .into_par_iter()
            .map(|(chunk, a, b)| {
                let mut sides = [NodeBounds::EMPTY; 2];
                let (mut i, mut j) = (0, 0);
                for p in chunk {
                    if goes_left(p) {
                        sides[0].add(p);
                        a[i] = *p;
                        i += 1;
                    } else {
                        sides[1].add(p);
                        b[j] = *p;
                        j += 1;
                    }
                }
                sides
            })
            .reduce(|| [NodeBounds::EMPTY; 2], |x, y| [x[0].then(y[0]), x[1].then(y[1])]);
        range.par_chunks_mut(self.chunk).zip(self.tmp.par_chunks(self.chunk)).for_each(|(d, s)| d.copy_from_slice(s));
        (left, sides)
    }
}

/// Bin boxes and counts for all three axes, `axis * n + bin`.
pub(super) struct Bins {
    n: usize,
    pub(super) boxes: Vec<Aabb>,
    pub(super) counts: Vec<usize>,
}

impl Bins {
    fn new(n: usize) -> Bins {
        Bins { n, boxes: vec![Aabb::EMPTY; 3 * n], counts: vec![0; 3 * n] }
    }

    /// `axes[a]`: `(lo, scale)` of axis `a`, `None` when the centroids have no extent on it.
    fn add(&mut self, range: &[Prim], axes: &[Option<(f32, f32)>; 3]) {
        for p in range {
            let c = p.bounds.center();
            for (axis, a) in axes.iter().enumerate() {
                if let Some((lo, scale)) = *a {
                    let b = axis * self.n + bin_index(c[axis], lo, scale, self.n);
                    self.boxes[b].grow(&p.bounds);
                    self.counts[b] += 1;
                }
            }
        }
    }

    fn merge(mut self, other: Bins) -> Bins {
        for (a, b) in self.boxes.iter_mut().zip(&other.boxes) {
            a.grow(b);
        }
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += b;
        }
        self
    }
}

pub(super) fn bin_index(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

/// Centroid along `axis`, then id: a total order (ids are unique).
pub(super) fn by_centroid(a: &Prim, b: &Prim, axis: usize) -> std::cmp::Ordering {
    a.centroid(axis).total_cmp(&b.centroid(axis)).then(a.id.cmp(&b.id))
}
