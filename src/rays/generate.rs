//! Ray sets: diffuse (cosine bounces off primary hits) and random (from a sphere around the
//! scene towards points in its box); primary rays are `super::camera`'s.
//!
//! They follow the distributions of the Embree peer in ../shared/peers (same camera, same
//! offsets), so trilab's numbers can be set beside the peer's; all are deterministic for a seed.

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;

use super::{Hit, Ray};
use crate::error::{Error, Result};
use crate::scene::{Aabb, Mesh};

/// Whether every origin and direction component is finite.
fn finite(r: &Ray) -> bool {
    r.origin.iter().chain(&r.dir).all(|c| c.is_finite())
}

/// Why [`random_rays`] cannot aim at a scene with `bounds`, if it cannot: its rays leave a
/// sphere around the box for points inside it, and a box that is a single point (every vertex in
/// one place) leaves them no direction.
pub fn random_rays_problem(bounds: &Aabb) -> Option<String> {
    (!bounds.is_empty() && bounds.min == bounds.max).then(|| {
        format!(
            "the scene's bounding box is the single point {:?} (every vertex is there, so no triangle has area): \
             random rays aim from a sphere around the box at points inside it, and a point gives them no direction",
            bounds.min.to_array()
        )
    })
}

/// `rays` (a `set` made for a scene with `bounds`), or an error naming the scene's bounds when
/// an origin or a direction is not finite in f32 or a direction is zero: a set that cannot be
/// represented is refused where it is made, not by whatever reads it later.
pub fn check_rays(set: &str, bounds: &Aabb, rays: Vec<Ray>) -> Result<Vec<Ray>> {
    match rays.iter().enumerate().find(|(_, r)| !finite(r) || r.dir == [0.0; 3]) {
        None => Ok(rays),
        // Not a matter of f32's range: there is no box to aim into.
        Some(_) if set == "random" && random_rays_problem(bounds).is_some() => Err(Error::Usage(format!(
            "random rays cannot be made for this scene: {}",
            random_rays_problem(bounds).unwrap_or_default()
        ))),
        Some((i, r)) => Err(Error::Usage(format!(
            "{set} rays cannot be represented in f32 for this scene: ray {i} has origin {:?}, direction {:?}; \
             the scene's bounds are {:?} .. {:?}, too large for rays around it (f32 ends at {:e}); \
             scale the scene down or move it towards the origin",
            r.origin,
            r.dir,
            bounds.min.to_array(),
            bounds.max.to_array(),
            f32::MAX
        ))),
    }
}

/// For every primary ray that hits (`hits[i]` is `primary[i]`'s hit: the f64 reference's, rounded
/// to a hit record, in every ray set trilab makes), `per_hit` cosine-distributed rays leaving the
/// hit point on the side the ray came from, offset along the normal by 1e-4 of the scene's
/// largest coordinate magnitude (the peer's offset).
///
/// Computed in f32, as the peer does (the committed ray sets depend on these exact values); the
/// rays of a hit whose f32 arithmetic overflows (edges or normals of a scene with coordinates
/// near 1e20 and beyond) are computed again in f64 from the same random numbers. Rays that are
/// still not finite in f32 stay so: [`check_rays`] refuses them.
pub fn diffuse_rays(mesh: &Mesh, primary: &[Ray], hits: &[Hit], per_hit: u32, seed: u64) -> Vec<Ray> {
    assert_eq!(primary.len(), hits.len(), "one hit per primary ray");
    let b = mesh.bounds();
    let scale = b.min.abs().max(b.max.abs()).max_element();
    // One generator per primary ray, derived from the seed, so the set does not depend on
    // thread scheduling.
    let per_ray: Vec<Vec<Ray>> = primary
        .par_iter()
        .zip(hits)
        .enumerate()
        .map(|(i, (r, h))| {
            if !h.is_hit() {
                return Vec::new();
            }
            let rng = || Pcg32::seed_from_u64(seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            let rays = diffuse_f32(mesh, r, h, per_hit, scale, rng());
            if rays.iter().all(finite) {
                rays
            } else {
                diffuse_f64(mesh, r, h, per_hit, scale as f64, rng())
            }
        })
        .collect();
    per_ray.into_iter().flatten().collect()
}

/// One primary hit's diffuse rays in f32.
fn diffuse_f32(mesh: &Mesh, r: &Ray, h: &Hit, per_hit: u32, scale: f32, mut rng: Pcg32) -> Vec<Ray> {
    let [a, b, c] = mesh.vertices(h.id as usize);
    let d = Vec3::from_array(r.dir);
    let mut n = (b - a).cross(c - a).normalize();
    if n.dot(d) > 0.0 {
        n = -n;
    }
    let p = a + (b - a) * h.u + (c - a) * h.v + n * (1e-4 * scale);
    let tx = if n.x.abs() > 0.5 { n.cross(Vec3::Y) } else { n.cross(Vec3::X) }.normalize();
    let ty = n.cross(tx);
    (0..per_hit)
        .map(|_| {
            let (u1, u2): (f32, f32) = (rng.random(), rng.random());
            let r1 = u1.sqrt();
            let phi = std::f32::consts::TAU * u2;
            let dir = (tx * (r1 * phi.cos()) + ty * (r1 * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize();
            Ray::new(p.to_array(), dir.to_array())
        })
        .collect()
}

/// [`diffuse_f32`] in f64, from the same random numbers, rounded to f32 at the end.
fn diffuse_f64(mesh: &Mesh, r: &Ray, h: &Hit, per_hit: u32, scale: f64, mut rng: Pcg32) -> Vec<Ray> {
    let [a, b, c] = mesh.vertices_f64(h.id as usize);
    let d = Vec3::from_array(r.dir).as_dvec3();
    let mut n = (b - a).cross(c - a).normalize();
    if n.dot(d) > 0.0 {
        n = -n;
    }
    let p = a + (b - a) * h.u as f64 + (c - a) * h.v as f64 + n * (1e-4 * scale);
    let tx = if n.x.abs() > 0.5 { n.cross(DVec3::Y) } else { n.cross(DVec3::X) }.normalize();
    let ty = n.cross(tx);
    (0..per_hit)
        .map(|_| {
            let (u1, u2): (f32, f32) = (rng.random(), rng.random());
            let (u1, u2) = (u1 as f64, u2 as f64);
            let r1 = u1.sqrt();
            let phi = std::f64::consts::TAU * u2;
            let dir = (tx * (r1 * phi.cos()) + ty * (r1 * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize();
            Ray::new(p.as_vec3().to_array(), dir.as_vec3().to_array())
        })
        .collect()
}

/// `n` rays from uniform points on the sphere of 1.5x the bounding radius towards uniform
/// points in the bounding box.
///
/// Computed in f32, as the peer does (the committed ray sets depend on these exact values);
/// when that overflows (a scene with coordinates near 1e19 and beyond: its diagonal is not
/// finite in f32) the whole set is computed again in f64 from the same random numbers. Rays
/// still not finite in f32 stay so: [`check_rays`] refuses them.
pub fn random_rays(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let rays = random_rays_f32(bounds, n, seed);
    if rays.iter().all(finite) {
        rays
    } else {
        random_rays_f64(bounds, n, seed)
    }
}

/// [`random_rays_f32`] in f64, from the same random numbers, rounded to f32 at the end.
fn random_rays_f64(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg32::seed_from_u64(seed);
    let (lo, hi) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
    let c = (lo + hi) * 0.5;
    let radius = 0.5 * (hi - lo).length();
    (0..n)
        .map(|_| {
            let z = 2.0 * rng.random::<f32>() as f64 - 1.0;
            let phi = std::f64::consts::TAU * rng.random::<f32>() as f64;
            let s = (1.0 - z * z).max(0.0).sqrt();
            let o = c + DVec3::new(s * phi.cos(), s * phi.sin(), z) * (1.5 * radius);
            let u = DVec3::new(rng.random::<f32>() as f64, rng.random::<f32>() as f64, rng.random::<f32>() as f64);
            let t = lo + (hi - lo) * u;
            Ray::new(o.as_vec3().to_array(), (t - o).normalize().as_vec3().to_array())
        })
        .collect()
}

fn random_rays_f32(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg32::seed_from_u64(seed);
    let c = bounds.center();
    let radius = 0.5 * bounds.extent().length();
    (0..n)
        .map(|_| {
            let z: f32 = 2.0 * rng.random::<f32>() - 1.0;
            let phi = std::f32::consts::TAU * rng.random::<f32>();
            let s = (1.0 - z * z).max(0.0).sqrt();
            let o = c + Vec3::new(s * phi.cos(), s * phi.sin(), z) * (1.5 * radius);
            let t = bounds.min + bounds.extent() * Vec3::new(rng.random(), rng.random(), rng.random());
            Ray::new(o.to_array(), (t - o).normalize().to_array())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene near 1e20 overflows f32 (its diagonal, its edges' cross products): the sets are
    /// computed in f64 and come out finite; near 3e38 the random set cannot be represented and
    /// `check_rays` refuses it, naming the bounds.
    #[test]
    fn huge_scenes_get_f64_rays_or_a_refusal() {
        for s in [1e20f32, 1e30] {
            let b = Aabb { min: Vec3::splat(-s), max: Vec3::splat(s) };
            let rays = check_rays("random", &b, random_rays(&b, 200, 7)).unwrap();
            for r in &rays {
                let o = Vec3::from_array(r.origin).as_dvec3();
                assert!((o.length() / (1.5 * 3f64.sqrt() * s as f64) - 1.0).abs() < 1e-5, "{r:?}");
                assert!((Vec3::from_array(r.dir).length() - 1.0).abs() < 1e-5);
            }
            let mesh = Mesh::from_triangles(vec![[-s, -s, 0.0], [s, -s, 0.0], [0.0, s, 0.0]], vec![[0, 1, 2]]);
            let primary = [Ray::new([0.0, 0.0, 2.0 * s], [0.0, 0.0, -1.0])];
            let hit = [Hit { t: 2.0 * s, id: 0, u: 0.25, v: 0.5 }];
            let d = check_rays("diffuse", &mesh.bounds(), diffuse_rays(&mesh, &primary, &hit, 16, 3)).unwrap();
            assert_eq!(d.len(), 16);
            for r in &d {
                assert!(r.dir[2] > 0.0, "leaves on the side the ray came from: {r:?}");
                assert!(r.origin[2] > 0.0 && r.origin[2] < 2e-4 * s, "{r:?}");
            }
        }
        let b = Aabb { min: Vec3::splat(-3e38), max: Vec3::splat(3e38) };
        let e = check_rays("random", &b, random_rays(&b, 10, 7)).unwrap_err().to_string();
        assert!(e.contains("random rays cannot be represented") && e.contains("-3e38"), "{e}");
    }

    /// Issue 24: a box that is one point gave NaN directions, refused as "too large for f32".
    /// The reason is the point: nothing to aim into. A flat or thin box is fine.
    #[test]
    fn a_box_that_is_a_point_is_refused_as_a_point() {
        let p = Aabb { min: Vec3::new(1.0, 2.0, 3.0), max: Vec3::new(1.0, 2.0, 3.0) };
        let e = check_rays("random", &p, random_rays(&p, 10, 7)).unwrap_err().to_string();
        assert!(e.contains("single point [1.0, 2.0, 3.0]") && !e.contains("f32"), "{e}");
        assert!(random_rays_problem(&p).is_some());
        let line = Aabb { min: Vec3::new(0.0, 0.0, 0.0), max: Vec3::new(2.0, 0.0, 0.0) };
        assert!(random_rays_problem(&line).is_none());
        assert_eq!(check_rays("random", &line, random_rays(&line, 10, 7)).unwrap().len(), 10);
        assert!(random_rays_problem(&Aabb::EMPTY).is_none());
    }

    #[test]
    fn random_rays_are_deterministic_and_aim_into_the_box() {
        let b = Aabb { min: Vec3::new(0.0, 1.0, 2.0), max: Vec3::new(1.0, 3.0, 2.5) };
        let a = random_rays(&b, 500, 7);
        assert_eq!(a, random_rays(&b, 500, 7));
        assert_ne!(a, random_rays(&b, 500, 8));
        let radius = 0.5 * b.extent().length();
        for r in &a {
            let o = Vec3::from_array(r.origin);
            assert!(((o - b.center()).length() - 1.5 * radius).abs() < 1e-4);
            assert!((Vec3::from_array(r.dir).length() - 1.0).abs() < 1e-5);
            assert!(r.problem().is_none());
        }
    }
}
