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
//! that is exactly Q \ Q(n)). Nodes are processed in parallel.

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

/// EPO of `bvh` over `mesh`, with the node costs of `bvh.options` (see the module docs).
/// 0 for a tree whose triangles have no area.
pub fn epo(mesh: &Mesh, bvh: &Bvh) -> f64 {
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
    let total_area: f64 = tris.iter().flatten().map(|t| t.area).sum();
    if total_area <= 0.0 {
        return 0.0;
    }
    let boxes: Vec<Box64> = bvh.nodes.iter().map(Box64::of_node).collect();
    let o = &bvh.options;
    // Per node in parallel, summed in node order: a count compared exactly between runs
    // (`trilab compare`), the same whatever the thread count (a parallel sum's order is not).
    let per_node: Vec<f64> = (1..bvh.nodes.len())
        .into_par_iter()
        .map(|n| {
            let node = &bvh.nodes[n];
            let cost = if node.is_leaf() {
                o.cost_intersect as f64 * o.tests(node.count as usize)
            } else {
                o.cost_traversal as f64
            };
            cost * foreign_area_in_box(bvh, &boxes, &tris, n)
        })
        .collect();
    let weighted: f64 = per_node.iter().sum();
    weighted / total_area
}

/// A(Q \ Q(n) ∩ box(n)): the area inside node `n`'s box of the triangles outside its subtree.
fn foreign_area_in_box(bvh: &Bvh, boxes: &[Box64], tris: &[Option<Tri>], n: usize) -> f64 {
    let b = boxes[n];
    let mut area = 0.0;
    let mut stack = Vec::with_capacity(64);
    stack.push(0usize);
    while let Some(m) = stack.pop() {
        if m == n || !boxes[m].overlaps(&b) {
            continue;
        }
        let node = &bvh.nodes[m];
        let first = node.left_or_first as usize;
        if node.is_leaf() {
            for t in tris[first..first + node.count as usize].iter().flatten() {
                if t.bounds.overlaps(&b) {
                    area += clipped_area(&t.v, &b);
                }
            }
        } else {
            stack.push(first);
            stack.push(first + 1);
        }
    }
    area
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
                let c = if n.is_leaf() { n.count as f64 } else { 1.0 };
                let bx = Box64::of_node(n);
                for t in 0..mesh.triangle_count() as u32 {
                    if !under[i].contains(&t) {
                        sum += c * clipped_area(&mesh.vertices_f64(t as usize), &bx);
                    }
                }
            }
            let brute = sum / total;
            let fast = epo(&mesh, &bvh);
            assert!(brute > 0.1, "the soup overlaps");
            assert!((fast - brute).abs() <= 1e-12 * brute, "leaf {leaf}: {fast} vs {brute}");
            // Exactly the same on one thread and on four: a count `trilab compare` holds exact.
            let on = |threads: usize| {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                pool.install(|| epo(&mesh, &bvh))
            };
            assert_eq!(on(1).to_bits(), on(4).to_bits(), "leaf {leaf}");
            assert_eq!(on(1).to_bits(), fast.to_bits(), "leaf {leaf}");
        }
    }
}
