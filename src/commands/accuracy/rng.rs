//! The accuracy study's random numbers.

use glam::{DMat3, DVec3};

/// A small deterministic generator (PCG-style LCG with an output shuffle), so every run of the
/// study sees the same rays.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(0x2545_F491_4F6C_DD1D))
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let x = self.0;
        (x ^ (x >> 33)).wrapping_mul(0xff51afd7ed558ccd) ^ (x >> 29)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [-1, 1).
    pub fn symmetric(&mut self) -> f64 {
        2.0 * self.unit() - 1.0
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.unit() * n as f64) as usize % n.max(1)
    }

    /// Uniform on the unit sphere.
    pub fn direction(&mut self) -> DVec3 {
        let z = self.symmetric();
        let phi = std::f64::consts::TAU * self.unit();
        let r = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform in the unit ball.
    pub fn in_ball(&mut self) -> DVec3 {
        self.direction() * self.unit().cbrt()
    }

    /// A random rotation (from two random directions, Gram-Schmidt).
    pub fn rotation(&mut self) -> DMat3 {
        let a = self.direction();
        let b = (self.direction() - a * a.dot(self.direction())).normalize_or(a.any_orthonormal_vector());
        let b = (b - a * a.dot(b)).normalize();
        DMat3::from_cols(a, b, a.cross(b))
    }
}
