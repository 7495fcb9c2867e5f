//! The kernels' random numbers, bit for bit (`glsl/rng.glsl`): every draw is a pure function of
//! (seed, pixel, sample, dimension), so a test can replay any path on the host.

/// PCG-RXS-M-XS 32 used as a hash (Jarzynski & Olano, JCGT 9(3), 2020).
pub fn pcg_hash(v: u32) -> u32 {
    let state = v.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// The key of one path.
pub fn path_key(seed: u32, pixel: u32, sample: u32) -> u32 {
    pcg_hash(seed.wrapping_add(pcg_hash(pixel.wrapping_add(pcg_hash(sample)))))
}

/// Draw `dim` of a path, 32 bits.
pub fn rand_u32(key: u32, dim: u32) -> u32 {
    pcg_hash(key.wrapping_add(dim.wrapping_mul(0x9E37_79B9)))
}

/// Draw `dim` of a path, uniform in [0, 1) with 24 bits.
pub fn rand01(key: u32, dim: u32) -> f32 {
    (rand_u32(key, dim) >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// `glsl/rng_probe.comp`: writes `rng.glsl`'s draws, for the bit-for-bit comparison with this
/// module (`tests/render.rs`).
pub fn probe_kernel() -> &'static crate::kernels::KernelSource {
    crate::kernels::find("rng_probe", crate::kernels::NO_INTERSECTOR, "main")
        .expect("rng_probe.none.main was compiled (glsl/rng_probe.comp)")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg_hash_matches_the_published_function() {
        // Reference values computed by hand from the published pcg_hash (Jarzynski & Olano,
        // listing "pcg"): state = 0 * 747796405 + 2891336453 = 0xAC564B05, shift 10 + 4 = 14.
        let state: u32 = 0xAC56_4B05;
        let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
        assert_eq!(pcg_hash(0), (word >> 22) ^ word);
        assert_ne!(pcg_hash(1), pcg_hash(0));
    }

    #[test]
    fn draws_are_uniform_and_in_range() {
        // 2^16 draws of one dimension over many paths: mean 1/2, variance 1/12, nothing >= 1.
        let n = 1 << 16;
        let xs: Vec<f64> = (0..n).map(|i| rand01(path_key(7, i, 3), 5) as f64).collect();
        assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
        // Standard error of the mean: sqrt(1/12 / 65536) = 0.00113; 5 sigma.
        assert!((mean - 0.5).abs() < 0.0057, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.003, "variance {var}");
        // Neighbouring dimensions of one path are not correlated.
        let c: f64 = (0..n)
            .map(|i| {
                let k = path_key(1, i, 0);
                (rand01(k, 0) as f64 - 0.5) * (rand01(k, 1) as f64 - 0.5)
            })
            .sum::<f64>()
            / n as f64;
        assert!(c.abs() < 5.0 * (1.0 / 12.0) / (n as f64).sqrt(), "correlation {c}");
    }
}
