//! End-point overlap (EPO), the BVH quality metric of Aila, Karras & Laine, "On Quality Metrics
//! of Bounding Volume Hierarchies", HPG 2013 (sec. 4):
//!
//!   EPO = sum over nodes n of C(n) A(Q \ Q(n) ∩ box(n)) / A(Q)
//!
//! A(Q) is the surface area of all triangles, Q(n) the triangles in n's subtree, and
//! A(Q \ Q(n) ∩ box(n)) the area of the parts of the *other* triangles that lie inside n's box:
//! a ray ending on such a surface point must still visit n although n cannot hold its hit.
//! C(n) is the node's cost as in the SAH (the paper's eq. 1; here with the build's costs, as in
//! [`Bvh::sah_cost`]): `cost_traversal` for an inner node, `cost_intersect` x ceil(|n| /
//! `sah_group`) for a leaf of |n| triangles.
//!
//! Each triangle's part inside a box is found by clipping the triangle against the box's six
//! planes (Sutherland & Hodgman, "Reentrant polygon clipping", CACM 17(1), 1974) in f64 and
//! taking the polygon's area. Boxes are closed: a triangle lying in a box face counts as inside.
//! The candidates for node n come from the BVH itself: a depth-first query for the leaves whose
//! boxes overlap box(n), skipping n's own subtree (every triangle lies in exactly one leaf, so
//! that is exactly Q \ Q(n)). Two shortcuts keep piles of triangles from costing a clip per
//! pair: a subtree whose box lies inside box(n) adds its precomputed area without a visit below
//! it, and a subtree whose triangles are all copies of one triangle (the same vertices) adds that
//! triangle's clipped area times their number. So copies of one triangle, where every box holds
//! every other triangle, cost O(1) per node rather than O(triangles), however many piles of
//! copies cross one another. Nodes are processed in parallel.
//!
//! What no exact method avoids: where each small box holds a large share of all other triangles
//! *in part* (copies of one triangle, each moved a little), every such pair must be clipped, and
//! the work grows as the square of the triangle count. [`epo_within`] stops past a work limit
//! ([`default_work_limit`], proportional to the tree's size) and reports no value; `trilab bvh`
//! and the study then print `-` for the EPO and say why.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use super::{Bvh, PAD_SLOT};
use crate::scene::Mesh;

mod clip;

pub use clip::{clipped_area, triangle_area, Box64};

/// A triangle of the hierarchy, ready for clipping.
struct Tri {
    v: [DVec3; 3],
    bounds: Box64,
    area: f64,
}

/// The hierarchy as the queries read it: each node's box in f64, the total triangle area of its
/// subtree, and its place in a depth-first (preorder) walk, so that whether one node lies in
/// another's subtree is two comparisons.
struct Tree<'a> {
    bvh: &'a Bvh,
    tris: Vec<Option<Tri>>,
    boxes: Vec<Box64>,
    /// Area of the triangles under each node.
    subtree_area: Vec<f64>,
    /// Preorder number of each node, and the number of nodes in its subtree (itself included).
    pre: Vec<usize>,
    size: Vec<usize>,
    /// Triangles under each node (padding slots left out).
    count: Vec<f64>,
    /// The slot of a triangle of which every triangle under the node is a copy (the same
    /// vertices in the same order), if they all are.
    copies_of: Vec<Option<usize>>,
}

impl Tree<'_> {
    fn new<'a>(mesh: &Mesh, bvh: &'a Bvh) -> Tree<'a> {
        let tris: Vec<Option<Tri>> = bvh
            .prim_ids
            .par_iter()
            .map(|&id| {
                (id != PAD_SLOT).then(|| {
                    let v = mesh.vertices_f64(id as usize);
                    Tri { v, bounds: Box64::of_triangle(&v), area: triangle_area(&v) }
                })
            })
            .collect();
        let mut order = Vec::with_capacity(bvh.nodes.len());
        bvh.visit(|i, _| order.push(i));
        let n = bvh.nodes.len();
        let (mut pre, mut size, mut subtree_area) = (vec![0; n], vec![1; n], vec![0.0; n]);
        let (mut count, mut copies_of) = (vec![0.0; n], vec![None; n]);
        for (k, &i) in order.iter().enumerate() {
            pre[i] = k;
        }
        let same = |a: Option<usize>, b: Option<usize>| match (a, b) {
            (Some(a), Some(b)) => tris[a].as_ref().map(|t| t.v) == tris[b].as_ref().map(|t| t.v),
            _ => false,
        };
        // Children come after their parent in preorder: backwards, they are done first.
        for &i in order.iter().rev() {
            let node = &bvh.nodes[i];
            let first = node.left_or_first as usize;
            if node.is_leaf() {
                let slots = first..first + node.count as usize;
                subtree_area[i] = tris[slots.clone()].iter().flatten().map(|t| t.area).sum();
                count[i] = tris[slots.clone()].iter().flatten().count() as f64;
                let mut real = slots.filter(|&s| tris[s].is_some());
                copies_of[i] = real.next().filter(|&r| real.all(|s| same(Some(r), Some(s))));
            } else {
                size[i] = 1 + size[first] + size[first + 1];
                subtree_area[i] = subtree_area[first] + subtree_area[first + 1];
                count[i] = count[first] + count[first + 1];
                copies_of[i] = copies_of[first].filter(|_| same(copies_of[first], copies_of[first + 1]));
            }
        }
        let boxes = bvh.nodes.iter().map(Box64::of_node).collect();
        Tree { bvh, tris, boxes, subtree_area, pre, size, count, copies_of }
    }

    /// Whether `n` is `m` or lies in `m`'s subtree.
    fn holds(&self, m: usize, n: usize) -> bool {
        (self.pre[m]..self.pre[m] + self.size[m]).contains(&self.pre[n])
    }
}

/// Work units (nodes visited plus triangles tested) of a query, counted before they are added to
/// the shared total, so a query over the limit stops within this many units of it.
const WORK_CHUNK: u64 = 1 << 12;

/// Work units a tree's EPO may take by default ([`Bvh::stats_with_epo`]), per node and triangle.
/// The bundled scenes take at most 80 (bunny, dragon, Buddha at leaf size 1, either builder; 25 to
/// 50 at larger leaves), and piles of copies of one triangle a few; copies each moved by 1 % of
/// their size take 870 at 16,000 triangles (leaf size 1), and more the more there are.
pub const WORK_PER_ELEMENT: u64 = 256;

/// The work [`epo_within`] may spend on a tree by default: [`WORK_PER_ELEMENT`] units (a node
/// visited or a triangle tested, about 60 ns each on one core) per node and triangle, and at least
/// 2^24 (about a second), so a small tree is always priced. A tree over it is one whose leaves'
/// boxes each hold a large share of all the other triangles in part, which no exact method prices
/// in less than their product.
pub fn default_work_limit(bvh: &Bvh) -> u64 {
    ((bvh.nodes.len() + bvh.prim_ids.len()) as u64).saturating_mul(WORK_PER_ELEMENT).max(1 << 24)
}

/// Why [`Bvh::stats_with_epo`] left a tree's EPO out, for a report's notes.
pub fn not_computed(bvh: &Bvh) -> String {
    format!(
        "EPO not computed: it would take more than {} units of work (nodes visited and triangles tested; the limit is \
         {WORK_PER_ELEMENT} per node and triangle): the scene's triangles overlap one another in part so much that \
         the exact metric grows as the square of their number",
        default_work_limit(bvh)
    )
}

/// EPO of `bvh` over `mesh`, with the node costs of `bvh.options` (see the module docs).
/// 0 for a tree whose triangles have no area. No bound on the work: quadratic in the triangle
/// count where many triangles overlap one another in part ([`epo_within`] bounds it).
pub fn epo(mesh: &Mesh, bvh: &Bvh) -> f64 {
    epo_within(mesh, bvh, u64::MAX).expect("no work limit")
}

/// [`epo`], or `None` when it would take more than `max_work` units of work (a node visited or a
/// triangle tested; [`default_work_limit`]). Whether it gives up depends only on the tree, never
/// on the thread count: the total work of the queries is fixed, and the queries stop only once
/// their shared count is past the limit.
pub fn epo_within(mesh: &Mesh, bvh: &Bvh, max_work: u64) -> Option<f64> {
    epo_counted(mesh, bvh, max_work).0
}

/// [`epo_within`] and the work it spent (all of it where it gave a value).
fn epo_counted(mesh: &Mesh, bvh: &Bvh, max_work: u64) -> (Option<f64>, u64) {
    let tree = Tree::new(mesh, bvh);
    let total_area: f64 = tree.tris.iter().flatten().map(|t| t.area).sum();
    if total_area <= 0.0 {
        return (Some(0.0), 0);
    }
    let o = &bvh.options;
    let spent = AtomicU64::new(0);
    // Per node in parallel, summed in node order: a count compared exactly between runs
    // (`trilab compare`), the same whatever the thread count (a parallel sum's order is not).
    let per_node: Option<Vec<f64>> = (1..bvh.nodes.len())
        .into_par_iter()
        .map(|n| {
            let node = &bvh.nodes[n];
            let cost = if node.is_leaf() {
                o.cost_intersect as f64 * o.tests(node.count as usize)
            } else {
                o.cost_traversal as f64
            };
            foreign_area_in_box(&tree, n, &spent, max_work).map(|a| cost * a)
        })
        .collect();
    (per_node.map(|w| w.iter().sum::<f64>() / total_area), spent.into_inner())
}

/// A(Q \ Q(n) ∩ box(n)): the area inside node `n`'s box of the triangles outside its subtree, or
/// `None` once the work of all queries together (`spent`) is past `max_work`.
///
/// A depth-first query from the root, skipping `n`'s subtree. A subtree whose box lies inside
/// box(n) and that does not hold `n` adds its whole area at once, and one of copies of a single
/// triangle adds that triangle's clipped area times the copies outside `n`'s subtree; neither
/// is visited below.
fn foreign_area_in_box(tree: &Tree, n: usize, spent: &AtomicU64, max_work: u64) -> Option<f64> {
    let b = tree.boxes[n];
    let mut area = 0.0;
    let mut work = 0u64;
    let mut stack = Vec::with_capacity(64);
    stack.push(0usize);
    while let Some(m) = stack.pop() {
        work += 1;
        if m == n || !tree.boxes[m].overlaps(&b) {
            continue;
        }
        if b.contains(&tree.boxes[m]) && !tree.holds(m, n) {
            area += tree.subtree_area[m];
            continue;
        }
        if let Some(Some(t)) = tree.copies_of[m].map(|s| tree.tris[s].as_ref()) {
            // Copies of one triangle: one clip for all of them (those under `n` left out).
            let foreign = tree.count[m] - if tree.holds(m, n) { tree.count[n] } else { 0.0 };
            area += foreign * clipped_area(&t.v, &b);
            continue;
        }
        let node = &tree.bvh.nodes[m];
        let first = node.left_or_first as usize;
        if node.is_leaf() {
            for t in tree.tris[first..first + node.count as usize].iter().flatten() {
                work += 1;
                if t.bounds.overlaps(&b) {
                    area += clipped_area(&t.v, &b);
                }
            }
        } else {
            stack.push(first);
            stack.push(first + 1);
        }
        if work >= WORK_CHUNK {
            if spent.fetch_add(work, Ordering::Relaxed).saturating_add(work) > max_work {
                return None;
            }
            work = 0;
        }
    }
    (spent.fetch_add(work, Ordering::Relaxed).saturating_add(work) <= max_work).then_some(area)
}

#[cfg(test)]
mod tests;
