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
//!
//! Two drivers build the same tree, bit for bit:
//! - `build_serial`: one loop on one thread, the reference.
//! - `build`: parallel on rayon's current pool, in the two ways Wald (2007, sec. 4) describes
//!   for binned builders: near the root, where one node holds most primitives, its scans
//!   (bounds, bins, partition) run over chunks in parallel ("horizontal"); below, the two
//!   subtrees of each split are built as `rayon::join` tasks ("vertical") into separate node
//!   vectors that are concatenated left subtree first, the serial loop's order.
//!
//! Why the results are identical: every decision at a node is a function of its primitives
//! in their order, and both drivers keep the same order. Bin boxes, node boxes and counts are
//! min/max/sum reductions, exact in any grouping: rayon combines chunk results in order, and
//! `Vec3::min`/`max` keep the later of two equal values (so even +0.0 against -0.0 resolves
//! as in the serial loop; this needs finite coordinates, which the loader guarantees). Sorts
//! use a total order (centroid, then id); the partition is *stable* (lefts in their order,
//! then rights in theirs), which a chunked prefix-sum scatter reproduces exactly; the rare
//! depth-limit median split runs serially in both. The SAH sums over bins are evaluated
//! serially from the same bins. (The partition used to swap in place, which no parallel
//! partition reproduces; the stable one changes only the order of triangles within leaves.)
//!
//! # Files
//!
//! The drivers are here; what the builder is asked for ([`BuildOptions`]) is in `options.rs`,
//! where a node is split (the split finders, the depth bound) in `split.rs`, how a node's
//! primitives are scanned and reordered (serially or in parallel chunks) in `scan.rs`, how a
//! subtree's nodes are laid out (the serial loop, the parallel fragments) in `subtree.rs`.

use std::time::Instant;

use rayon::prelude::*;

use super::{Aabb, Bvh, BvhNode, PAD_SLOT};
use crate::scene::Mesh;

mod options;
mod scan;
mod split;
mod subtree;
#[cfg(test)]
mod tests;

pub use options::{BuildOptions, Builder, LeafPolicy, MAX_DEPTH, MAX_LEAF_SIZE, PAPER_LEAF_SIZES};
use scan::Scratch;
use subtree::{assemble, build_par, build_subtree};

/// A primitive during the build: its box and triangle id. The centroid is recomputed from the
/// box where needed (two flops) rather than stored, which keeps a primitive at 28 bytes: at ten
/// million triangles the primitive array and the partition buffer are the build's largest.
#[derive(Clone, Copy)]
struct Prim {
    bounds: Aabb,
    id: u32,
}

impl Prim {
    /// Box centre along `axis`: the same value as `bounds.center()[axis]`.
    #[inline]
    fn centroid(&self, axis: usize) -> f32 {
        0.5 * (self.bounds.min[axis] + self.bounds.max[axis])
    }
}

/// Granularity of the parallel build. The output does not depend on it (tests build with tiny
/// grains so that small scenes take every parallel path).
#[derive(Clone, Copy, Debug)]
struct Grain {
    /// Nodes with fewer primitives are built as one serial task (rayon's `join` below them
    /// would only add overhead).
    serial_below: usize,
    /// Primitives per chunk when a node's scans (bounds, bins, partition) run in parallel.
    chunk: usize,
}

impl Grain {
    const DEFAULT: Grain = Grain { serial_below: 1 << 12, chunk: 1 << 14 };
}

/// Builds on rayon's current thread pool; bitwise identical to [`build_serial`] for every
/// option and pool size (see the module comment for why).
pub(super) fn build(mesh: &Mesh, options: &BuildOptions) -> Bvh {
    build_grain(mesh, options, Grain::DEFAULT)
}

fn build_grain(mesh: &Mesh, options: &BuildOptions, g: Grain) -> Bvh {
    assert!((1..=MAX_LEAF_SIZE).contains(&options.max_leaf_size), "max_leaf_size must be 1..={MAX_LEAF_SIZE}");
    let start = Instant::now();
    let threads = rayon::current_num_threads();
    let mut prims: Vec<Prim> = (0..mesh.triangle_count()).into_par_iter().map(|i| prim(mesh, i)).collect();
    prims.retain(|p| p.id != PAD_SLOT);
    let excluded = mesh.triangle_count() - prims.len();
    if prims.is_empty() {
        return empty_bvh(mesh, options, excluded, start, threads);
    }
    let nodes = {
        let mut tmp =
            vec![Prim { bounds: Aabb::EMPTY, id: 0 }; if prims.len() < g.serial_below { 0 } else { prims.len() }];
        let (root, frag) = build_par(&mut prims, &mut tmp, 0, 0, None, options, g);
        drop(tmp);
        assemble(root, frag)
    };
    Bvh {
        nodes,
        prim_ids: prims.par_iter().map(|p| p.id).collect(),
        options: *options,
        build_seconds: start.elapsed().as_secs_f64(),
        build_threads: threads,
        degenerate_excluded: excluded,
    }
}

/// The single-threaded reference: one loop, no rayon.
pub(super) fn build_serial(mesh: &Mesh, options: &BuildOptions) -> Bvh {
    assert!((1..=MAX_LEAF_SIZE).contains(&options.max_leaf_size), "max_leaf_size must be 1..={MAX_LEAF_SIZE}");
    let start = Instant::now();
    let mut prims: Vec<Prim> = (0..mesh.triangle_count()).map(|i| prim(mesh, i)).collect();
    prims.retain(|p| p.id != PAD_SLOT);
    let excluded = mesh.triangle_count() - prims.len();
    if prims.is_empty() {
        return empty_bvh(mesh, options, excluded, start, 1);
    }
    let nodes = build_subtree(&mut prims, 0, 0, None, options, &mut Scratch::default());
    Bvh {
        nodes,
        prim_ids: prims.iter().map(|p| p.id).collect(),
        options: *options,
        build_seconds: start.elapsed().as_secs_f64(),
        build_threads: 1,
        degenerate_excluded: excluded,
    }
}

/// Triangle `i` as a primitive, or one with id [`PAD_SLOT`] when it is degenerate (left out).
fn prim(mesh: &Mesh, i: usize) -> Prim {
    if mesh.is_degenerate(i) {
        return Prim { bounds: Aabb::EMPTY, id: PAD_SLOT };
    }
    let b = Aabb::from_points(&mesh.vertices(i));
    Prim { bounds: b, id: i as u32 }
}

fn empty_bvh(mesh: &Mesh, options: &BuildOptions, excluded: usize, start: Instant, threads: usize) -> Bvh {
    // Nothing can be hit. One leaf over a single padding slot (a degenerate triangle every
    // encoding rejects exactly) keeps the GPU path uniform.
    let p = mesh.positions.first().copied().unwrap_or([0.0; 3]);
    let root = BvhNode { min: p, left_or_first: 0, max: p, count: 1 };
    Bvh {
        nodes: vec![root],
        prim_ids: vec![PAD_SLOT],
        options: *options,
        build_seconds: start.elapsed().as_secs_f64(),
        build_threads: threads,
        degenerate_excluded: excluded,
    }
}
