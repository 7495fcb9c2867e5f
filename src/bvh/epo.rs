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

use super::{Bvh, BvhNode, PAD_SLOT};
use crate::scene::Mesh;

/// An axis-aligned box in f64 (closed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box64 {
    pub min: DVec3,
    pub max: DVec3,
}

impl Box64 {
    fn of_node(n: &BvhNode) -> Box64 {
        Box64 { min: DVec3::from(n.min.map(f64::from)), max: DVec3::from(n.max.map(f64::from)) }
    }

    fn of_triangle(v: &[DVec3; 3]) -> Box64 {
        Box64 { min: v[0].min(v[1]).min(v[2]), max: v[0].max(v[1]).max(v[2]) }
    }

    fn overlaps(&self, o: &Box64) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }

    fn contains(&self, o: &Box64) -> bool {
        self.min.cmple(o.min).all() && o.max.cmple(self.max).all()
    }
}

/// Area of a triangle in f64.
pub fn triangle_area(v: &[DVec3; 3]) -> f64 {
    0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length()
}

/// Most vertices a triangle clipped by six planes can have (3 + 6), rounded up.
const MAX_POLY: usize = 12;

/// A small polygon on the stack.
#[derive(Clone, Copy)]
struct Poly {
    v: [DVec3; MAX_POLY],
    n: usize,
}

impl Poly {
    /// Keeps the part where `sign * (p[axis] - bound) <= 0` (one Sutherland–Hodgman pass).
    fn clip(&self, axis: usize, bound: f64, sign: f64) -> Poly {
        let mut out = Poly { v: [DVec3::ZERO; MAX_POLY], n: 0 };
        let dist = |p: DVec3| sign * (p[axis] - bound);
        for i in 0..self.n {
            let (a, b) = (self.v[i], self.v[(i + 1) % self.n]);
            let (da, db) = (dist(a), dist(b));
            if da <= 0.0 {
                out.v[out.n] = a;
                out.n += 1;
            }
            if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
                let mut p = a + (b - a) * (da / (da - db));
                // Exactly on the plane, whatever the rounding of the interpolation.
                p[axis] = bound;
                out.v[out.n] = p;
                out.n += 1;
            }
        }
        out
    }

    /// Area of a planar polygon: half the length of the sum of its fan's cross products.
    fn area(&self) -> f64 {
        if self.n < 3 {
            return 0.0;
        }
        let o = self.v[0];
        let mut s = DVec3::ZERO;
        for i in 1..self.n - 1 {
            s += (self.v[i] - o).cross(self.v[i + 1] - o);
        }
        0.5 * s.length()
    }
}

/// Area of the part of triangle `v` inside the closed box `b`.
pub fn clipped_area(v: &[DVec3; 3], b: &Box64) -> f64 {
    let tb = Box64::of_triangle(v);
    if !tb.overlaps(b) {
        return 0.0;
    }
    if b.contains(&tb) {
        return triangle_area(v);
    }
    let mut p = Poly { v: [DVec3::ZERO; MAX_POLY], n: 3 };
    p.v[..3].copy_from_slice(v);
    for axis in 0..3 {
        // Only the planes that cut the triangle's box.
        if tb.min[axis] < b.min[axis] {
            p = p.clip(axis, b.min[axis], -1.0);
        }
        if tb.max[axis] > b.max[axis] {
            p = p.clip(axis, b.max[axis], 1.0);
        }
        if p.n < 3 {
            return 0.0;
        }
    }
    p.area()
}

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
mod tests {
    use super::*;
    use crate::bvh::{BuildOptions, Builder};

    fn b(min: [f64; 3], max: [f64; 3]) -> Box64 {
        Box64 { min: DVec3::from(min), max: DVec3::from(max) }
    }

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
        [DVec3::from(a), DVec3::from(b), DVec3::from(c)]
    }

    #[test]
    fn clipping_by_hand() {
        // Area 1, symmetric about x = 0: a box holding x >= 0 holds half.
        let t = tri([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(triangle_area(&t), 1.0);
        assert!((clipped_area(&t, &b([0.0, -5.0, -1.0], [5.0, 5.0, 1.0])) - 0.5).abs() < 1e-15);
        assert_eq!(clipped_area(&t, &b([-5.0; 3], [5.0; 3])), 1.0);
        assert_eq!(clipped_area(&t, &b([2.0, 0.0, 0.0], [3.0, 1.0, 1.0])), 0.0);
        // Right triangle with legs 2: the unit square [0,1]^2 lies wholly inside it.
        let r = tri([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        assert!((clipped_area(&r, &b([0.0, 0.0, -1.0], [1.0, 1.0, 1.0])) - 1.0).abs() < 1e-15);
        // Above y = 1 it is the triangle (0,1), (1,1), (0,2): area 1/2.
        assert!((clipped_area(&r, &b([-1.0, 1.0, -1.0], [3.0, 3.0, 1.0])) - 0.5).abs() < 1e-15);
        // Tilted out of every axis plane: the plane x + y + z = 1 cut by the unit cube is the
        // whole triangle; cut at x <= 1/2 it loses the corner triangle scaled by 1/2 (area 1/4).
        let s = tri([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let full = 3f64.sqrt() / 2.0;
        assert!((clipped_area(&s, &b([0.0; 3], [1.0; 3])) - full).abs() < 1e-15);
        assert!((clipped_area(&s, &b([0.0; 3], [0.5, 1.0, 1.0])) - 0.75 * full).abs() < 1e-15);
        // A triangle in a box face is inside the closed box.
        assert_eq!(clipped_area(&r, &b([0.0, 0.0, 0.0], [2.0, 2.0, 5.0])), 2.0);
    }

    /// A hand-built tree: root over two leaves of one triangle each.
    fn two_leaf_tree(mesh: &Mesh) -> Bvh {
        let node = |id: usize, first: u32| {
            let v = mesh.vertices(id);
            let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
            BvhNode { min: lo.to_array(), left_or_first: first, max: hi.to_array(), count: 1 }
        };
        let (l, r) = (node(0, 0), node(1, 1));
        let root = BvhNode {
            min: [l.min[0].min(r.min[0]), l.min[1].min(r.min[1]), l.min[2].min(r.min[2])],
            left_or_first: 1,
            max: [l.max[0].max(r.max[0]), l.max[1].max(r.max[1]), l.max[2].max(r.max[2])],
            count: 0,
        };
        Bvh {
            nodes: vec![root, l, r],
            prim_ids: vec![0, 1],
            options: BuildOptions::new(1),
            build_seconds: 0.0,
            build_threads: 1,
            degenerate_excluded: 0,
        }
    }

    #[test]
    fn two_overlapping_leaves() {
        // A = (0,0), (2,0), (0,2) and B = (1,1), (3,1), (1,3) in z = 0, area 2 each.
        // A's box [0,2]^2 holds B's unit square [1,2]^2 (area 1); B's box [1,3]^2 holds only
        // A's point (1,1) (area 0). Leaves cost 1 each, the root has no foreign triangles:
        // EPO = (1 * 1 + 1 * 0) / 4.
        let mesh = Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 0.0], [3.0, 1.0, 0.0], [1.0, 3.0, 0.0]],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let mut bvh = two_leaf_tree(&mesh);
        bvh.validate(&mesh).unwrap();
        assert_eq!(epo(&mesh, &bvh), 0.25);
        // With leaves priced 3 tests each it triples.
        bvh.options.cost_intersect = 3.0;
        assert_eq!(epo(&mesh, &bvh), 0.75);
    }

    #[test]
    fn disjoint_boxes_give_zero() {
        let mesh = Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 1.0, 0.0]],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let bvh = two_leaf_tree(&mesh);
        bvh.validate(&mesh).unwrap();
        assert_eq!(epo(&mesh, &bvh), 0.0);
        let built = Bvh::build(&mesh, &BuildOptions::new(1));
        assert_eq!(epo(&mesh, &built), 0.0);
    }

    /// EPO by its definition: every node against every triangle outside its subtree, clipped.
    fn brute(mesh: &Mesh, bvh: &Bvh) -> f64 {
        // Triangles under each node, from the leaves up (children follow their parent).
        let mut under: Vec<Vec<u32>> = vec![vec![]; bvh.nodes.len()];
        for i in (0..bvh.nodes.len()).rev() {
            let n = &bvh.nodes[i];
            let f = n.left_or_first as usize;
            under[i] = if n.is_leaf() {
                bvh.prim_ids[f..f + n.count as usize].to_vec()
            } else {
                [under[f].clone(), under[f + 1].clone()].concat()
            };
        }
        let total: f64 = (0..mesh.triangle_count()).map(|i| triangle_area(&mesh.vertices_f64(i))).sum();
        let mut sum = 0.0;
        for (i, n) in bvh.nodes.iter().enumerate() {
            // Build costs 1 and 1: a leaf costs its triangle count.
            let c = if n.is_leaf() { n.count as f64 } else { 1.0 };
            let bx = Box64::of_node(n);
            let mut outside = vec![true; mesh.triangle_count()];
            for &t in &under[i] {
                outside[t as usize] = false;
            }
            for t in (0..mesh.triangle_count()).filter(|&t| outside[t]) {
                sum += c * clipped_area(&mesh.vertices_f64(t), &bx);
            }
        }
        sum / total
    }

    fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
    }

    /// The BVH-pruned search finds what a brute-force pass over every (node, triangle) pair does.
    #[test]
    fn matches_brute_force_on_a_random_soup() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let mut pos = vec![];
        let mut tris = vec![];
        for i in 0..400u32 {
            let c = [rng.random::<f32>() * 10.0, rng.random::<f32>() * 10.0, rng.random::<f32>() * 10.0];
            for _ in 0..3 {
                pos.push(c.map(|x| x + rng.random::<f32>() * 2.0 - 1.0));
            }
            tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let mesh = Mesh::from_triangles(pos, tris);
        for (leaf, builder) in [(1, Builder::default()), (4, Builder::Sweep), (8, Builder::default())] {
            let bvh = Bvh::build(&mesh, &BuildOptions { builder, ..BuildOptions::new(leaf) });
            let brute = brute(&mesh, &bvh);
            let fast = epo(&mesh, &bvh);
            assert!(brute > 0.1, "the soup overlaps");
            assert!((fast - brute).abs() <= 1e-12 * brute, "leaf {leaf}: {fast} vs {brute}");
            // Exactly the same on one thread and on four: a count `trilab compare` holds exact.
            let on = |threads: usize| on_threads(threads, || epo(&mesh, &bvh));
            assert_eq!(on(1).to_bits(), on(4).to_bits(), "leaf {leaf}");
            assert_eq!(on(1).to_bits(), fast.to_bits(), "leaf {leaf}");
        }
    }

    /// Issue 24: copies of one triangle put every triangle in every node's box, and the query
    /// clipped each of them at each node (quadratic: 32,000 copies took 20 s per tree). Subtrees
    /// inside a node's box, and subtrees of copies, now add their area at once. Exact against the
    /// brute force with two piles that cross each other and a few triangles around them, and
    /// near-linear in work: far under the (nodes x copies) triangle tests of a per-leaf query.
    #[test]
    fn piles_of_copies_match_brute_force_in_near_linear_work() {
        let mut pos = vec![];
        let mut tris = vec![];
        let mut add = |p: [[f32; 3]; 3]| {
            let i = pos.len() as u32;
            pos.extend(p);
            tris.push([i, i + 1, i + 2]);
        };
        // 1,500 copies of one triangle, 1,000 of a second across it, 40 small ones here and there.
        for _ in 0..1500 {
            add([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        }
        for _ in 0..1000 {
            add([[0.5, -0.5, -0.5], [0.5, 1.5, -0.5], [0.5, 0.5, 1.5]]);
        }
        for k in 0..40 {
            let x = k as f32 * 0.05 - 0.5;
            add([[x, x, 0.1], [x + 0.2, x, 0.1], [x, x + 0.2, 0.3]]);
        }
        let mesh = Mesh::from_triangles(pos, tris);
        for (leaf, builder) in
            [(1, Builder::default()), (4, Builder::default()), (4, Builder::Sweep), (16, Builder::Sweep)]
        {
            let bvh = Bvh::build(&mesh, &BuildOptions { builder, ..BuildOptions::new(leaf) });
            let (fast, work) = epo_counted(&mesh, &bvh, u64::MAX);
            let fast = fast.unwrap();
            let brute = brute(&mesh, &bvh);
            assert!(brute > 100.0, "every node's box holds a pile: {brute}");
            assert!((fast - brute).abs() <= 1e-12 * brute, "leaf {leaf} {builder}: {fast} vs {brute}");
            let nodes = bvh.nodes.len() as u64;
            let pairwise = nodes * 1000;
            let elements = nodes + bvh.prim_ids.len() as u64;
            let depth = u64::from(bvh.stats().depth);
            assert!(
                work * 20 < pairwise && work <= 4 * (depth + 1) * elements,
                "leaf {leaf} {builder}: work {work}, depth {depth}, {elements} nodes and triangles"
            );
            assert!(work <= WORK_PER_ELEMENT * elements, "within the default limit: {work}");
            assert_eq!(on_threads(1, || epo(&mesh, &bvh)).to_bits(), on_threads(3, || epo(&mesh, &bvh)).to_bits());
        }
    }

    /// Copies each moved a little: every leaf's box holds nearly every other copy in part, and
    /// each such pair must be clipped. `epo_within` gives the exact value at a limit of the work
    /// it needs and none one unit below, on any thread count.
    #[test]
    fn the_work_limit_is_exact_and_independent_of_the_thread_count() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut pos = vec![];
        let mut tris = vec![];
        for i in 0..600u32 {
            let d = [0; 3].map(|_| rng.random::<f32>() * 0.02 - 0.01);
            for v in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
                pos.push([v[0] + d[0], v[1] + d[1], v[2] + d[2]]);
            }
            tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let mesh = Mesh::from_triangles(pos, tris);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(2));
        let (value, work) = epo_counted(&mesh, &bvh, u64::MAX);
        let value = value.unwrap();
        let brute = brute(&mesh, &bvh);
        assert!((value - brute).abs() <= 1e-12 * brute, "{value} vs {brute}");
        let leaves = bvh.stats().leaves as u64;
        assert!(work > leaves * 100, "hundreds of the other copies are clipped at each leaf: {work}");
        for threads in [1, 2, 5] {
            on_threads(threads, || {
                assert_eq!(epo_within(&mesh, &bvh, work).map(f64::to_bits), Some(value.to_bits()), "{threads}");
                assert_eq!(epo_within(&mesh, &bvh, work - 1), None, "{threads} threads");
                assert_eq!(epo_within(&mesh, &bvh, work / 3), None, "{threads} threads");
            });
        }
        // A small tree is always priced by default (the limit's floor); `stats_with_epo` says so.
        assert!(default_work_limit(&bvh) > work);
        assert_eq!(bvh.stats_with_epo(&mesh).epo.map(f64::to_bits), Some(value.to_bits()));
    }

    /// The bundled bunny is far inside the default limit at every leaf size: the limit only
    /// stops scenes whose triangles overlap one another far more than real models do.
    #[test]
    fn the_bunny_is_far_inside_the_default_work_limit() {
        let mesh =
            crate::scene::load_obj(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.obj")).unwrap();
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let (value, work) = epo_counted(&mesh, &bvh, u64::MAX);
            assert!(value.unwrap() > 1.0);
            assert!(work * 3 < default_work_limit(&bvh), "leaf {leaf}: {work} of {}", default_work_limit(&bvh));
        }
    }
}
