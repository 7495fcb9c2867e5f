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
//! - [`build_serial`]: one loop on one thread, the reference.
//! - [`build`]: parallel on rayon's current pool, in the two ways Wald (2007, sec. 4) describes
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

use std::time::Instant;

use rayon::prelude::*;

use super::{Aabb, Bvh, BvhNode, PAD_SLOT};
use crate::named::named_enum;
use crate::scene::Mesh;

/// Deepest leaf allowed (root at depth 0). The traversal pushes at most one node per level, so
/// its stack of `STACK_SIZE` entries never overflows.
pub const MAX_DEPTH: u32 = crate::shared::STACK_SIZE;

/// Largest supported `max_leaf_size`.
pub const MAX_LEAF_SIZE: u32 = 16;

/// The triangles per leaf Shumskiy & Parshin study (their Tables 1-4).
pub const PAPER_LEAF_SIZES: [u32; 6] = [1, 2, 3, 4, 8, 16];

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

named_enum! {
    /// When a node becomes a leaf.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum LeafPolicy: "leaf policy" {
        /// The paper's: a node with at most `max_leaf_size` triangles is a leaf, so leaves hold
        /// close to that many ("try to fill BVH with four triangles per node", sec. 3.1); SAH
        /// chooses the split planes above that.
        Fill = "fill" (default),
        /// SAH decides: a node is a leaf when that is cheaper than its best split (or it holds one
        /// triangle); `max_leaf_size` is only an upper bound.
        Sah = "sah",
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

    /// Refuses options the builder cannot honour, naming the option: a leaf size outside
    /// 1..=16, or a SAH grouping outside 1..=16 (what `Bvh::build` asserts).
    pub fn check(&self) -> crate::error::Result<()> {
        let usage = |m: String| Err(crate::error::Error::Usage(m));
        if !(1..=MAX_LEAF_SIZE).contains(&self.max_leaf_size) {
            return usage(format!("--leaf-size {}: must be 1..={MAX_LEAF_SIZE}", self.max_leaf_size));
        }
        if !(1..=MAX_LEAF_SIZE).contains(&self.sah_group) {
            return usage(format!(
                "--sah-group {}: must be 1..={MAX_LEAF_SIZE} (4 prices leaves in quads)",
                self.sah_group
            ));
        }
        Ok(())
    }

    /// Serialises the options as every report and option record names them, `leaf_size`,
    /// `leaf_policy`, `sah_group` (the builder and the costs are the defaults there); a struct
    /// holding the options writes them among its own fields with
    /// `#[serde(flatten, serialize_with = "BuildOptions::serialize_fields")]`.
    pub fn serialize_fields<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("BuildOptions", 3)?;
        st.serialize_field("leaf_size", &self.max_leaf_size)?;
        st.serialize_field("leaf_policy", &self.leaf_policy)?;
        st.serialize_field("sah_group", &self.sah_group)?;
        st.end()
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

enum Split {
    /// Primitives whose centroid falls in bins `0..=bin` along `axis` go left.
    Bin { axis: usize, bin: usize, bins: usize, lo: f32, scale: f32 },
    /// After sorting by centroid along `axis`, the first `left` go left.
    Sorted { axis: usize, left: usize },
}

/// Granularity of the parallel build. The output does not depend on it (tests build with tiny
/// grains so that small scenes take every parallel path).
#[derive(Clone, Copy, Debug)]
pub(super) struct Grain {
    /// Nodes with fewer primitives are built as one serial task (rayon's `join` below them
    /// would only add overhead).
    pub(super) serial_below: usize,
    /// Primitives per chunk when a node's scans (bounds, bins, partition) run in parallel.
    pub(super) chunk: usize,
}

impl Grain {
    pub(super) const DEFAULT: Grain = Grain { serial_below: 1 << 12, chunk: 1 << 14 };
}

/// Builds on rayon's current thread pool; bitwise identical to [`build_serial`] for every
/// option and pool size (see the module comment for why).
pub(super) fn build(mesh: &Mesh, options: &BuildOptions) -> Bvh {
    build_grain(mesh, options, Grain::DEFAULT)
}

pub(super) fn build_grain(mesh: &Mesh, options: &BuildOptions, g: Grain) -> Bvh {
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

/// Reusable buffers of the serial builder.
#[derive(Default)]
struct Scratch {
    /// Right-hand primitives during a stable partition.
    prims: Vec<Prim>,
    /// Suffix boxes of the full sweep.
    boxes: Vec<Aabb>,
}

/// Builds the subtree over `prims` serially. Its root is at `depth` and its first primitive at
/// slot `offset`. Returns its nodes root first, inner nodes' child indices relative to the
/// returned vector. Depth first, left child first: a node's two children are allocated when
/// the node is split, then the whole left subtree, then the right one, so the layout is
/// `[root] ++ desc(root)` with `desc(x) = [left, right] ++ desc(left) ++ desc(right)`, which
/// [`build_par`] reproduces piece by piece.
fn build_subtree(
    prims: &mut [Prim],
    offset: usize,
    depth: u32,
    known: Option<NodeBounds>,
    o: &BuildOptions,
    scratch: &mut Scratch,
) -> Vec<BvhNode> {
    let mut nodes = Vec::with_capacity((2 * prims.len()).min(1 << 20));
    nodes.push(BvhNode::default());
    // (node index, first prim, prim count, depth, bounds if the parent's partition gathered
    // them); popped depth-first, left child first.
    let mut work = vec![(0usize, 0usize, prims.len(), depth, known)];
    while let Some((node, first, count, depth, known)) = work.pop() {
        let range = &mut prims[first..first + count];
        let nb = known.unwrap_or_else(|| bounds_of(range));
        nodes[node].set_aabb(&nb.bounds);
        let Some((left_count, sides)) = choose_split(range, &nb, depth, o, &mut SerialOps(scratch)) else {
            nodes[node].left_or_first = (offset + first) as u32;
            nodes[node].count = count as u32;
            continue;
        };
        let left = nodes.len();
        nodes.push(BvhNode::default());
        nodes.push(BvhNode::default());
        nodes[node].left_or_first = left as u32;
        nodes[node].count = 0;
        work.push((left + 1, first + left_count, count - left_count, depth + 1, sides.map(|s| s[1])));
        work.push((left, first, left_count, depth + 1, sides.map(|s| s[0])));
    }
    nodes
}

/// Part of the final node array: `nodes[skip..]`, whose inner nodes' child indices plus
/// `shift` are relative to the start of the [`Fragment`] holding the piece.
struct Piece {
    nodes: Vec<BvhNode>,
    skip: usize,
    shift: isize,
}

/// `desc(x)` of a subtree (its nodes below its root, in serial order) as pieces in order.
#[derive(Default)]
struct Fragment {
    pieces: Vec<Piece>,
    len: usize,
}

impl Fragment {
    /// Appends `other`, which starts `at` nodes into `self`.
    fn append(&mut self, other: Fragment, at: usize) {
        debug_assert_eq!(at, self.len);
        self.pieces.extend(other.pieces.into_iter().map(|p| Piece { shift: p.shift + at as isize, ..p }));
        self.len += other.len;
    }
}

/// The parallel build of the subtree over `prims` (`tmp`: a partition buffer of the same
/// length). Returns the subtree's root (for an inner node, `left_or_first` is left for the
/// caller to set) and `desc(root)`. Large nodes scan their primitives in parallel chunks; the
/// two subtrees of a split are built with `rayon::join` and their fragments concatenated
/// left first, so the layout is fixed by the tree, never by thread timing.
fn build_par(
    prims: &mut [Prim],
    tmp: &mut [Prim],
    offset: usize,
    depth: u32,
    known: Option<NodeBounds>,
    o: &BuildOptions,
    g: Grain,
) -> (BvhNode, Fragment) {
    let n = prims.len();
    if n < g.serial_below {
        let nodes = build_subtree(prims, offset, depth, known, o, &mut Scratch::default());
        let root = nodes[0];
        let len = nodes.len() - 1;
        let pieces = if len == 0 { vec![] } else { vec![Piece { nodes, skip: 1, shift: -1 }] };
        return (root, Fragment { pieces, len });
    }
    let nb = known.unwrap_or_else(|| bounds_par(prims, g.chunk));
    let mut node = BvhNode::default();
    node.set_aabb(&nb.bounds);
    let mut ops = ParOps { tmp: &mut *tmp, boxes: vec![], chunk: g.chunk };
    let Some((k, sides)) = choose_split(prims, &nb, depth, o, &mut ops) else {
        node.left_or_first = offset as u32;
        node.count = n as u32;
        return (node, Fragment::default());
    };
    let (lp, rp) = prims.split_at_mut(k);
    let (lt, rt) = tmp.split_at_mut(k);
    let ((mut l, lf), (mut r, rf)) = rayon::join(
        || build_par(lp, lt, offset, depth + 1, sides.map(|s| s[0]), o, g),
        || build_par(rp, rt, offset + k, depth + 1, sides.map(|s| s[1]), o, g),
    );
    if !l.is_leaf() {
        l.left_or_first = 2;
    }
    if !r.is_leaf() {
        r.left_or_first = (2 + lf.len) as u32;
    }
    let mut frag = Fragment { pieces: vec![Piece { nodes: vec![l, r], skip: 0, shift: 0 }], len: 2 };
    let at = frag.len;
    frag.append(lf, at);
    let at = frag.len;
    frag.append(rf, at);
    (node, frag)
}

/// `[root] ++ desc(root)` as one vector with absolute child indices; pieces copied in parallel.
fn assemble(mut root: BvhNode, frag: Fragment) -> Vec<BvhNode> {
    let mut nodes = vec![BvhNode::default(); 1 + frag.len];
    if !root.is_leaf() {
        root.left_or_first = 1;
    }
    nodes[0] = root;
    let mut rest = &mut nodes[1..];
    let mut jobs = Vec::with_capacity(frag.pieces.len());
    for p in frag.pieces {
        let (dst, r) = std::mem::take(&mut rest).split_at_mut(p.nodes.len() - p.skip);
        rest = r;
        jobs.push((p, dst));
    }
    debug_assert!(rest.is_empty());
    jobs.into_par_iter().for_each(|(p, dst)| {
        // desc(root) starts at index 1.
        let shift = p.shift + 1;
        for (d, s) in dst.iter_mut().zip(&p.nodes[p.skip..]) {
            *d = *s;
            if !s.is_leaf() {
                d.left_or_first = (s.left_or_first as isize + shift) as u32;
            }
        }
    });
    nodes
}

/// Box of the primitives and box of their centroids.
fn bounds_of(range: &[Prim]) -> NodeBounds {
    let mut nb = NodeBounds::EMPTY;
    for p in range {
        nb.add(p);
    }
    nb
}

fn bounds_par(range: &[Prim], chunk: usize) -> NodeBounds {
    range.par_chunks(chunk).map(bounds_of).reduce(|| NodeBounds::EMPTY, NodeBounds::then)
}

/// How the split finders scan and reorder a node's primitives: serially, or in parallel chunks
/// for the large nodes near the root. Both give the same bins, sorts and partitions.
trait SplitOps {
    fn bins(&mut self, range: &[Prim], axes: &[Option<(f32, f32)>; 3], bins: usize) -> Bins;
    fn sort(&mut self, range: &mut [Prim], axis: usize);
    fn boxes(&mut self) -> &mut Vec<Aabb>;
    /// Stable partition; also returns the bounds of each side, gathered on the way so the
    /// children need no pass of their own.
    fn partition<F: Fn(&Prim) -> bool + Sync>(&mut self, range: &mut [Prim], goes_left: F) -> (usize, [NodeBounds; 2]);
}

/// A node's box and the box of its primitives' centroids.
#[derive(Clone, Copy)]
struct NodeBounds {
    bounds: Aabb,
    cbounds: Aabb,
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

struct SerialOps<'a>(&'a mut Scratch);

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

struct ParOps<'a> {
    /// Partition buffer, as long as the node's range.
    tmp: &'a mut [Prim],
    /// Suffix boxes of the full sweep (which only small scenes use); empty unless it runs.
    boxes: Vec<Aabb>,
    chunk: usize,
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

/// How many primitives go left, and the two children's bounds when the split gathered them.
type Cut = (usize, Option<[NodeBounds; 2]>);

/// Decides the node's fate: `None` makes it a leaf, `Some((k, _))` splits it with the first
/// `k` primitives (reordered in place) going to the left child.
fn choose_split(
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

/// Bin boxes and counts for all three axes, `axis * n + bin`.
struct Bins {
    n: usize,
    boxes: Vec<Aabb>,
    counts: Vec<usize>,
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

fn bin_index(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    (((c - lo) * scale) as usize).min(bins - 1)
}

/// Centroid along `axis`, then id: a total order (ids are unique).
fn by_centroid(a: &Prim, b: &Prim, axis: usize) -> std::cmp::Ordering {
    a.centroid(axis).total_cmp(&b.centroid(axis)).then(a.id.cmp(&b.id))
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
