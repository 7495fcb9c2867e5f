//! How the builder lays out a subtree's nodes: the serial loop ([`build_subtree`]) and the
//! parallel build ([`build_par`]), whose fragments [`assemble`] concatenates into the serial
//! loop's order.

use rayon::prelude::*;

use super::scan::{bounds_of, bounds_par, NodeBounds, ParOps, Scratch, SerialOps};
use super::split::choose_split;
use super::{BuildOptions, BvhNode, Grain, Prim};

/// Builds the subtree over `prims` serially. Its root is at `depth` and its first primitive at
/// slot `offset`. Returns its nodes root first, inner nodes' child indices relative to the
/// returned vector. Depth first, left child first: a node's two children are allocated when
/// the node is split, then the whole left subtree, then the right one, so the layout is
/// `[root] ++ desc(root)` with `desc(x) = [left, right] ++ desc(left) ++ desc(right)`, which
/// [`build_par`] reproduces piece by piece.
pub(super) fn build_subtree(
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
pub(super) struct Fragment {
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
pub(super) fn build_par(
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
pub(super) fn assemble(mut root: BvhNode, frag: Fragment) -> Vec<BvhNode> {
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
