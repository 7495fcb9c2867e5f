//! Checking GPU hits against the f64 reference.
//!
//! A ray agrees when both miss, or both hit the same triangle, or both hit with t within
//! [`REL_T_TOL`] relative. Every other ray is a disagreement, and it is *explained* when f32
//! rounding can account for it, measured in f32 ULPs of the largest coordinate involved
//! (at most [`AMBIGUITY_ULPS`]):
//! - the ray passes that close to an edge of a triangle involved (the reference's for a GPU
//!   miss, the GPU's for a false hit, either for a different hit), or starts that close to it;
//! - or, for a different hit, the GPU's triangle really is hit (in f64) and its hit point is
//!   that close to the reference's: a tie, e.g. coplanar or back-to-back duplicate triangles
//!   (the Buddha has 24), which f32 and f64 may break differently. Relative t tolerance alone
//!   fails such ties for rays leaving a surface, whose t is tiny.
//!
//! Unexplained disagreements and impossible values (NaN, ids out of range, hits on zero-area
//! triangles, t outside [tmin, tmax]) are failures.

use glam::DVec3;
use serde::Serialize;

use crate::rays::{Hit, Ray};
use crate::reference::{intersect, Ray64, RefHit};
use crate::scene::Mesh;

/// Relative t tolerance for two hits on different triangles to count as the same hit.
pub const REL_T_TOL: f64 = 1e-5;

/// How close (in f32 ULPs of the largest coordinate involved) a disagreement must be to an
/// edge or a tie to be explained by rounding.
pub const AMBIGUITY_ULPS: f64 = 16.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum DisagreementKind {
    /// The GPU missed a triangle the reference hit (a leak).
    GpuMissed,
    /// The GPU hit where the reference found nothing (a false hit).
    GpuFalseHit,
    /// Both hit, different triangles at different t.
    DifferentHit,
}

#[derive(Clone, Copy, Debug, Serialize)]
pub struct Disagreement {
    pub ray: usize,
    pub kind: DisagreementKind,
    pub gpu_t: f32,
    pub gpu_id: u32,
    pub ref_t: f64,
    pub ref_id: u32,
    /// How far the ray is from a configuration where f32 rounding could explain the
    /// disagreement (an edge, or a tie between two hit points), in f32 ULPs.
    pub ambiguity_ulps: f64,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Agreement {
    pub rays: usize,
    pub agree: usize,
    pub both_miss: usize,
    pub reference_hits: usize,
    pub disagreements: Vec<Disagreement>,
    /// Disagreements farther than [`AMBIGUITY_ULPS`] from an edge or a tie.
    pub unexplained: usize,
    /// Largest `ambiguity_ulps` among the disagreements.
    pub max_ambiguity_ulps: f64,
    /// Hits with NaN/inf t or barycentrics, ids out of range, zero-area triangles, t outside
    /// the ray interval, or misses whose t is not +inf: (ray, what).
    pub invalid: Vec<(usize, String)>,
}

impl Agreement {
    pub fn fraction(&self) -> f64 {
        if self.rays == 0 {
            1.0
        } else {
            self.agree as f64 / self.rays as f64
        }
    }

    /// Every disagreement is explained by an edge and no value is invalid.
    pub fn all_explained(&self) -> bool {
        self.unexplained == 0 && self.invalid.is_empty()
    }

    /// The foundation's acceptance rule: at most a `1 - min_fraction` share of the rays
    /// disagree, rounded up to whole rays (so a 5,000-ray set at 99.99 % may have one
    /// disagreement, as a 10,000-ray set may; on large sets this is the plain fraction), and
    /// [`Agreement::all_explained`].
    pub fn passes(&self, min_fraction: f64) -> bool {
        let allowed = (self.rays as f64 * (1.0 - min_fraction)).ceil() as usize;
        self.rays - self.agree <= allowed && self.all_explained()
    }

    pub fn summary(&self) -> String {
        format!(
            "{}/{} rays agree ({:.4}%), {} disagreements ({} unexplained, max {:.1} ULPs from an edge or tie), {} invalid",
            self.agree,
            self.rays,
            100.0 * self.fraction(),
            self.disagreements.len(),
            self.unexplained,
            self.max_ambiguity_ulps,
            self.invalid.len()
        )
    }
}

/// f32 ULP at magnitude `x`.
pub fn ulp_f32(x: f64) -> f64 {
    let x = (x.abs() as f32).max(f32::MIN_POSITIVE);
    (f32::from_bits(x.to_bits() + 1) - x) as f64
}

/// Distance from the line o + t d to the segment pq.
fn line_segment_distance(o: DVec3, d: DVec3, p: DVec3, q: DVec3) -> f64 {
    let dd = d.length_squared();
    let perp = |x: DVec3| x - d * (d.dot(x) / dd);
    let w = perp(o - p);
    let v = perp(q - p);
    let vv = v.length_squared();
    let s = if vv > 0.0 { (w.dot(v) / vv).clamp(0.0, 1.0) } else { 0.0 };
    (w - v * s).length()
}

/// How close the ray passes to an edge of triangle `id`, in f32 ULPs of the coordinates the
/// intersector rounds, counted across the ray: on each axis, the ULP of the largest magnitude
/// among the triangle's vertices and the ray origin on that axis, times how much of that axis
/// lies across the ray (sqrt(1 - d_k^2) for the unit direction d); the largest of the three.
/// A rounding error along the ray moves the hit point, not the side of an edge it falls on, so
/// a triangle far out along the ray's own axis (x = 2^100, hit by a ray along x) does not make
/// a miss near its centre look like rounding; the old measure, one ULP of the largest
/// coordinate on any axis, called that miss 0.0 ULPs from an edge (issue 24).
pub fn edge_ulps(mesh: &Mesh, ray: &Ray, id: u32) -> f64 {
    let r = Ray64::from(ray);
    let [a, b, c] = mesh.vertices_f64(id as usize);
    let dist = [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(p, q)| line_segment_distance(r.origin, r.dir, p, q))
        .fold(f64::INFINITY, f64::min);
    dist / across_ulp(&r, &[r.origin, a, b, c])
}

/// The rounding of `points`' coordinates, across ray `r`: see [`edge_ulps`].
fn across_ulp(r: &Ray64, points: &[DVec3]) -> f64 {
    let d = r.dir.normalize();
    let largest = points.iter().fold(DVec3::ZERO, |m, p| m.max(p.abs()));
    (0..3).map(|k| ulp_f32(largest[k]) * (1.0 - d[k] * d[k]).max(0.0).sqrt()).fold(0.0, f64::max).max(ulp_f32(0.0))
}

/// For two different triangles hit: if the GPU's triangle really is hit (f64), the distance
/// between the GPU's hit point and the reference's, in f32 ULPs of the largest coordinate of the
/// ray origin and the hit point; infinite otherwise.
fn tie_ulps(mesh: &Mesh, ray: &Ray, gpu: &Hit, reference: &RefHit) -> f64 {
    let r = Ray64::from(ray);
    if intersect(&r, mesh.vertices_f64(gpu.id as usize)).is_none() {
        return f64::INFINITY;
    }
    let hit = r.origin + r.dir * reference.t;
    let scale = r.origin.abs().max_element().max(hit.abs().max_element());
    (gpu.t as f64 - reference.t).abs() * r.dir.length() / ulp_f32(scale)
}

fn check_valid(mesh: &Mesh, ray: &Ray, h: &Hit) -> Option<String> {
    if !h.is_hit() {
        return (h.t != f32::INFINITY).then(|| format!("miss with t = {} (expected +inf)", h.t));
    }
    if h.id as usize >= mesh.triangle_count() {
        return Some(format!("triangle id {} out of range", h.id));
    }
    if !(h.t.is_finite() && h.u.is_finite() && h.v.is_finite()) {
        return Some(format!("non-finite hit t={} u={} v={}", h.t, h.u, h.v));
    }
    if mesh.is_degenerate(h.id as usize) {
        return Some(format!("hit zero-area triangle {}", h.id));
    }
    if !(h.t >= ray.tmin && h.t <= ray.tmax) {
        return Some(format!("t = {} outside [{}, {}]", h.t, ray.tmin, ray.tmax));
    }
    None
}

/// Compares closest hits from the GPU with the reference, ray by ray.
pub fn compare_closest(mesh: &Mesh, rays: &[Ray], gpu: &[Hit], reference: &[RefHit]) -> Agreement {
    assert_eq!(rays.len(), gpu.len());
    assert_eq!(rays.len(), reference.len());
    let mut a = Agreement { rays: rays.len(), ..Default::default() };
    for (i, ((ray, g), r)) in rays.iter().zip(gpu).zip(reference).enumerate() {
        if let Some(why) = check_valid(mesh, ray, g) {
            a.invalid.push((i, why));
            continue;
        }
        a.reference_hits += r.is_hit() as usize;
        let kind = match (g.is_hit(), r.is_hit()) {
            (false, false) => {
                a.both_miss += 1;
                a.agree += 1;
                continue;
            }
            (true, true) if g.id == r.id || (g.t as f64 - r.t).abs() <= REL_T_TOL * r.t.abs().max(1e-30) => {
                a.agree += 1;
                continue;
            }
            (true, true) => DisagreementKind::DifferentHit,
            (false, true) => DisagreementKind::GpuMissed,
            (true, false) => DisagreementKind::GpuFalseHit,
        };
        let ulps = match kind {
            DisagreementKind::GpuMissed => edge_ulps(mesh, ray, r.id),
            DisagreementKind::GpuFalseHit => edge_ulps(mesh, ray, g.id),
            DisagreementKind::DifferentHit => {
                edge_ulps(mesh, ray, r.id).min(edge_ulps(mesh, ray, g.id)).min(tie_ulps(mesh, ray, g, r))
            }
        };
        a.max_ambiguity_ulps = a.max_ambiguity_ulps.max(ulps);
        if ulps > AMBIGUITY_ULPS {
            a.unexplained += 1;
        }
        a.disagreements.push(Disagreement {
            ray: i,
            kind,
            gpu_t: g.t,
            gpu_id: g.id,
            ref_t: r.t,
            ref_id: r.id,
            ambiguity_ulps: ulps,
        });
    }
    a
}

/// Any-hit against closest-hit on the same rays.
#[derive(Clone, Debug, Default, Serialize)]
pub struct AnyHitCheck {
    pub rays: usize,
    /// Rays where one query hit and the other did not.
    pub status_mismatch: Vec<usize>,
    /// Any-hit results that are not a real intersection of the reported triangle within the
    /// ray interval (f64, edge tolerance as for closest hits), or invalid values.
    pub bogus: Vec<(usize, String)>,
}

impl AnyHitCheck {
    pub fn passes(&self) -> bool {
        self.status_mismatch.is_empty() && self.bogus.is_empty()
    }
}

/// Any-hit must hit exactly when closest-hit does (both run the same triangle tests over the
/// same BVH), and whatever it reports must be a genuine hit.
pub fn compare_any(mesh: &Mesh, rays: &[Ray], closest: &[Hit], any: &[Hit]) -> AnyHitCheck {
    let mut c = AnyHitCheck { rays: rays.len(), ..Default::default() };
    for (i, ((ray, cl), an)) in rays.iter().zip(closest).zip(any).enumerate() {
        if cl.is_hit() != an.is_hit() {
            c.status_mismatch.push(i);
            continue;
        }
        if !an.is_hit() {
            continue;
        }
        if let Some(why) = check_valid(mesh, ray, an) {
            c.bogus.push((i, why));
            continue;
        }
        // The triangle must really be hit within [tmin, tmax] (t itself can be ill-conditioned
        // for rays starting next to the surface or grazing it; its accuracy is measured elsewhere).
        let genuine = intersect(&Ray64::from(ray), mesh.vertices_f64(an.id as usize)).is_some();
        if !genuine && edge_ulps(mesh, ray, an.id) > AMBIGUITY_ULPS {
            c.bogus.push((i, format!("reported triangle {} at t = {} is not hit", an.id, an.t)));
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The share of disagreements allowed is rounded up to whole rays: one explained
    /// disagreement in 5,000 rays passes at 99.99 % (the fraction alone, 99.98 %, would fail
    /// it), two do not, and one unexplained never does.
    #[test]
    fn small_sets_may_have_their_share_of_explained_disagreements_rounded_up() {
        let d = Disagreement {
            ray: 0,
            kind: DisagreementKind::DifferentHit,
            gpu_t: 1.0,
            gpu_id: 1,
            ref_t: 1.0,
            ref_id: 2,
            ambiguity_ulps: 0.5,
        };
        let a = |rays: usize, n: usize, unexplained: usize| Agreement {
            rays,
            agree: rays - n,
            disagreements: vec![d; n],
            unexplained,
            ..Default::default()
        };
        assert!(a(5000, 1, 0).passes(0.9999));
        assert!(!a(5000, 2, 0).passes(0.9999));
        assert!(!a(5000, 1, 1).passes(0.9999));
        assert!(a(1_000_000, 100, 0).passes(0.9999));
        assert!(!a(1_000_000, 101, 0).passes(0.9999));
        assert!(a(0, 0, 0).passes(0.9999));
    }

    fn mesh() -> Mesh {
        Mesh::from_triangles(
            vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]],
            vec![[0, 1, 2], [1, 3, 2], [4, 4, 4]],
        )
    }

    #[test]
    fn ulp_values() {
        assert_eq!(ulp_f32(1.0), f32::EPSILON as f64);
        assert_eq!(ulp_f32(0.75), f32::EPSILON as f64 / 2.0);
    }

    #[test]
    fn disagreements_on_edges_are_explained_others_are_not() {
        let m = mesh();
        // Ray 0 through the shared diagonal edge (x + y = 1) of triangles 0 and 1; ray 1 well
        // inside triangle 0.
        let rays = vec![Ray::new([0.5, 0.5, 0.0], [0.0, 0.0, 1.0]), Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 1.0])];
        let reference = vec![RefHit { t: 1.0, id: 0, u: 0.5, v: 0.5 }, RefHit { t: 1.0, id: 0, u: 0.2, v: 0.2 }];
        // GPU missed both: the first is an edge leak (explained), the second is not.
        let gpu = vec![Hit::MISS, Hit::MISS];
        let a = compare_closest(&m, &rays, &gpu, &reference);
        assert_eq!(a.agree, 0);
        assert_eq!(a.disagreements.len(), 2);
        assert_eq!(a.unexplained, 1);
        assert!(a.disagreements[0].ambiguity_ulps < 1.0);
        assert!(!a.passes(0.0));
        // The neighbour at the same t counts as agreement.
        let gpu = vec![Hit { t: 1.0, id: 1, u: 0.0, v: 0.5 }, Hit { t: 1.0, id: 0, u: 0.2, v: 0.2 }];
        let a = compare_closest(&m, &rays, &gpu, &reference);
        assert!(a.passes(1.0), "{}", a.summary());
    }

    #[test]
    fn ties_between_coincident_triangles_are_explained_only_when_both_are_hit_at_the_same_point() {
        // Triangles 0 and 1 share their vertices (opposite winding); triangle 2 lies behind.
        let m = Mesh::from_triangles(
            vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]],
            vec![[0, 1, 2], [0, 2, 1], [3, 4, 5]],
        );
        // Starts just in front of the surface, so t is tiny and t tolerance is meaningless.
        let rays = vec![Ray::new([0.2, 0.2, 0.999], [0.0, 0.0, 1.0])];
        let reference = vec![RefHit { t: 0.001, id: 0, u: 0.2, v: 0.2 }];
        let t_off = |ulps: f32| 0.001f32 + ulps * f32::EPSILON;
        let tie = compare_closest(&m, &rays, &[Hit { t: t_off(3.0), id: 1, u: 0.2, v: 0.2 }], &reference);
        assert_eq!((tie.disagreements.len(), tie.unexplained), (1, 0), "{}", tie.summary());
        let far = compare_closest(&m, &rays, &[Hit { t: t_off(100.0), id: 1, u: 0.2, v: 0.2 }], &reference);
        assert_eq!(far.unexplained, 1, "a hit point 100 ULPs away is no tie");
        let behind = compare_closest(&m, &rays, &[Hit { t: 1.001, id: 2, u: 0.2, v: 0.2 }], &reference);
        assert_eq!(behind.unexplained, 1, "a farther triangle is no tie");
    }

    #[test]
    fn impossible_values_are_invalid() {
        let m = mesh();
        let rays = vec![Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 1.0]); 4];
        let reference = vec![RefHit { t: 1.0, id: 0, u: 0.2, v: 0.2 }; 4];
        let gpu = vec![
            Hit { t: f32::NAN, id: 0, u: 0.2, v: 0.2 },
            Hit { t: 1.0, id: 2, u: 0.0, v: 0.0 },
            Hit { t: 1.0, id: 7, u: 0.0, v: 0.0 },
            Hit { t: 0.0, ..Hit::MISS },
        ];
        let a = compare_closest(&m, &rays, &gpu, &reference);
        assert_eq!(a.invalid.len(), 4, "{:?}", a.invalid);
    }

    #[test]
    fn any_hit_status_must_match() {
        let m = mesh();
        let rays = vec![Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 1.0]); 2];
        let closest = vec![Hit { t: 1.0, id: 0, u: 0.2, v: 0.2 }, Hit::MISS];
        let good = compare_any(&m, &rays, &closest, &[closest[0], Hit::MISS]);
        assert!(good.passes());
        let bad = compare_any(&m, &rays, &closest, &[Hit::MISS, Hit::MISS]);
        assert_eq!(bad.status_mismatch, vec![0]);
        let bogus = compare_any(
            &m,
            &rays,
            &closest,
            &[
                // Triangle 1 is not on this ray's path.
                Hit { t: 1.0, id: 1, u: 0.0, v: 0.0 },
                Hit::MISS,
            ],
        );
        assert_eq!(bogus.bogus.len(), 1);
    }
}
