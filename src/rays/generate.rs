//! Ray sets: diffuse (cosine bounces off primary hits) and random (from a sphere around the
//! scene towards points in its box); primary rays are `super::camera`'s.
//!
//! They follow the distributions of the Embree peer in ../shared/peers (same camera, same
//! offsets), so trilab's numbers can be set beside the peer's; all are deterministic for a seed.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;

use super::{Hit, Ray};
use crate::scene::{Aabb, Mesh};

/// For every primary ray that hits (`hits[i]` is `primary[i]`'s hit: the f64 reference's, rounded
/// to a hit record, in every ray set trilab makes), `per_hit` cosine-distributed rays leaving the
/// hit point on the side the ray came from, offset along the normal by 1e-4 of the scene's
/// largest coordinate magnitude (the peer's offset).
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
            let mut rng = Pcg32::seed_from_u64(seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
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
                    let dir =
                        (tx * (r1 * phi.cos()) + ty * (r1 * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize();
                    Ray::new(p.to_array(), dir.to_array())
                })
                .collect()
        })
        .collect();
    per_ray.into_iter().flatten().collect()
}

/// `n` rays from uniform points on the sphere of 1.5x the bounding radius towards uniform
/// points in the bounding box.
pub fn random_rays(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
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
