//! The CPU reference in f64: what every GPU result is checked against.
//!
//! Inputs are f32 (vertices, rays) widened exactly to f64; the Möller–Trumbore solve then
//! runs in f64, whose rounding (about 1e-16 relative) is eight orders of magnitude below the
//! kernels' f32, so reference and kernels can only disagree on rays that pass within a few
//! f32 ULPs of an edge. [`brute_force`] tests every triangle; [`Reference`] walks a BVH with
//! slightly widened boxes and must give the same answers (tested).

use glam::DVec3;
use rayon::prelude::*;

use crate::bvh::{Bvh, PAD_SLOT};
use crate::rays::{Hit, Ray};
use crate::scene::Mesh;
use crate::shared::MISS_ID;

/// An f64 hit. `id == MISS_ID` (and `t = inf`) on a miss.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefHit {
    pub t: f64,
    pub id: u32,
    pub u: f64,
    pub v: f64,
}

impl RefHit {
    pub const MISS: RefHit = RefHit { t: f64::INFINITY, id: MISS_ID, u: 0.0, v: 0.0 };

    pub fn is_hit(&self) -> bool {
        self.id != MISS_ID
    }

    /// Rounded to a hit record.
    pub fn to_hit(&self) -> Hit {
        if self.is_hit() {
            Hit { t: self.t as f32, id: self.id, u: self.u as f32, v: self.v as f32 }
        } else {
            Hit::MISS
        }
    }
}

/// The ray widened to f64.
#[derive(Clone, Copy, Debug)]
pub struct Ray64 {
    pub origin: DVec3,
    pub dir: DVec3,
    pub tmin: f64,
    pub tmax: f64,
}

impl From<&Ray> for Ray64 {
    fn from(r: &Ray) -> Self {
        Ray64 {
            origin: DVec3::from_array(r.origin.map(f64::from)),
            dir: DVec3::from_array(r.dir.map(f64::from)),
            tmin: r.tmin as f64,
            tmax: r.tmax as f64,
        }
    }
}

/// Möller–Trumbore in f64: `(t, u, v)` if the ray meets triangle (a, b, c) with
/// `u, v >= 0`, `u + v <= 1` and `tmin <= t <= tmax`. Zero-area triangles never hit.
pub fn intersect(r: &Ray64, [a, b, c]: [DVec3; 3]) -> Option<(f64, f64, f64)> {
    let e1 = b - a;
    let e2 = c - a;
    let p = r.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || e1.cross(e2) == DVec3::ZERO {
        return None;
    }
    let inv = 1.0 / det;
    let tv = r.origin - a;
    let u = tv.dot(p) * inv;
    let q = tv.cross(e1);
    let v = r.dir.dot(q) * inv;
    let t = e2.dot(q) * inv;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= r.tmin && t <= r.tmax).then_some((t, u, v))
}

/// Closest hit over every triangle (ties: the lowest id).
pub fn brute_force(mesh: &Mesh, ray: &Ray) -> RefHit {
    let mut r = Ray64::from(ray);
    let mut best = RefHit::MISS;
    for id in 0..mesh.triangle_count() {
        if let Some((t, u, v)) = intersect(&r, mesh.vertices_f64(id)) {
            if t < best.t {
                best = RefHit { t, id: id as u32, u, v };
                r.tmax = t;
            }
        }
    }
    best
}

/// f64 traversal of a BVH (any leaf size), closest or any hit.
pub struct Reference<'a> {
    mesh: &'a Mesh,
    bvh: &'a Bvh,
}

/// Relative widening of box intervals: f64 rounding in the slab test is ~1e-16, so boxes are
/// never wrongly culled; visiting a few extra nodes costs nothing in correctness.
const BOX_SLACK: f64 = 1e-9;

impl<'a> Reference<'a> {
    pub fn new(mesh: &'a Mesh, bvh: &'a Bvh) -> Self {
        Reference { mesh, bvh }
    }

    fn hit_box(r: &Ray64, min: [f32; 3], max: [f32; 3], tfar: f64) -> bool {
        let mut t0 = r.tmin;
        let mut t1 = tfar;
        for k in 0..3 {
            let (lo, hi) = (min[k] as f64, max[k] as f64);
            let (o, d) = (r.origin[k], r.dir[k]);
            if d == 0.0 {
                if o < lo || o > hi {
                    return false;
                }
                continue;
            }
            let (mut a, mut b) = ((lo - o) / d, (hi - o) / d);
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            t0 = t0.max(a - BOX_SLACK * a.abs());
            t1 = t1.min(b + BOX_SLACK * b.abs());
        }
        t0 <= t1
    }

    /// Closest hit (`any = false`) or the first hit found (`any = true`).
    pub fn trace(&self, ray: &Ray, any: bool) -> RefHit {
        let mut r = Ray64::from(ray);
        let mut best = RefHit::MISS;
        let nodes = &self.bvh.nodes;
        let mut stack = Vec::with_capacity(64);
        stack.push(0usize);
        while let Some(i) = stack.pop() {
            let n = &nodes[i];
            if !Self::hit_box(&r, n.min, n.max, r.tmax) {
                continue;
            }
            if n.is_leaf() {
                let first = n.left_or_first as usize;
                for &id in &self.bvh.prim_ids[first..first + n.count as usize] {
                    if id == PAD_SLOT {
                        continue;
                    }
                    if let Some((t, u, v)) = intersect(&r, self.mesh.vertices_f64(id as usize)) {
                        // Ties go to the lower id, as in brute_force.
                        if crate::bvh::hit::wins(t, id, best.t, best.id) {
                            best = RefHit { t, id, u, v };
                            r.tmax = t;
                            if any {
                                return best;
                            }
                        }
                    }
                }
            } else {
                let l = n.left_or_first as usize;
                stack.push(l + 1);
                stack.push(l);
            }
        }
        best
    }

    /// Traces every ray on all cores, in order.
    pub fn trace_all(&self, rays: &[Ray], any: bool) -> Vec<RefHit> {
        let _span = crate::timeline::span("reference", "f64 reference").with("rays", rays.len()).with("any_hit", any);
        rays.par_iter().map(|r| self.trace(r, any)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildOptions;

    #[test]
    fn intersect_known_values() {
        let tri = [DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 1.0), DVec3::new(0.0, 1.0, 1.0)];
        let r = Ray64 { origin: DVec3::new(0.25, 0.5, 0.0), dir: DVec3::Z, tmin: 0.0, tmax: f64::INFINITY };
        let (t, u, v) = intersect(&r, tri).unwrap();
        assert_eq!((t, u, v), (1.0, 0.25, 0.5));
        // t in units of the direction's length.
        let r2 = Ray64 { dir: DVec3::new(0.0, 0.0, 2.0), ..r };
        assert_eq!(intersect(&r2, tri).unwrap().0, 0.5);
        // tmax before the surface, tmin after it.
        assert!(intersect(&Ray64 { tmax: 0.99, ..r }, tri).is_none());
        assert!(intersect(&Ray64 { tmin: 1.01, ..r }, tri).is_none());
        // Outside the triangle, and parallel to it.
        assert!(intersect(&Ray64 { origin: DVec3::new(0.6, 0.6, 0.0), ..r }, tri).is_none());
        assert!(intersect(&Ray64 { dir: DVec3::X, ..r }, tri).is_none());
        // Both sides hit (no culling).
        let back = Ray64 { origin: DVec3::new(0.25, 0.5, 2.0), dir: -DVec3::Z, ..r };
        assert_eq!(intersect(&back, tri).unwrap().0, 1.0);
    }

    #[test]
    fn bvh_traversal_matches_brute_force() {
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        let mut s = 12345u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32) / (1u64 << 24) as f32
        };
        for _ in 0..400 {
            let c = [rnd() * 4.0, rnd() * 4.0, rnd() * 4.0];
            let b = pos.len() as u32;
            for _ in 0..3 {
                pos.push([c[0] + rnd() - 0.5, c[1] + rnd() - 0.5, c[2] + rnd() - 0.5]);
            }
            tris.push([b, b + 1, b + 2]);
        }
        let mesh = Mesh::from_triangles(pos, tris);
        let rays: Vec<Ray> = (0..2000)
            .map(|_| {
                let o = [rnd() * 8.0 - 2.0, rnd() * 8.0 - 2.0, -3.0];
                let d = [rnd() - 0.5, rnd() - 0.5, 1.0];
                Ray::new(o, d)
            })
            .collect();
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let rf = Reference::new(&mesh, &bvh);
            let mut hits = 0;
            for r in &rays {
                let a = brute_force(&mesh, r);
                let b = rf.trace(r, false);
                assert_eq!(a, b, "leaf {leaf} ray {r:?}");
                assert_eq!(rf.trace(r, true).is_hit(), a.is_hit());
                hits += a.is_hit() as usize;
            }
            assert!(hits > 200, "test rays should hit often ({hits})");
        }
    }
}
