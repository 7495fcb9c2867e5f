//! Error measures against the f64 reference, and the tallies of one (method, leaf size, case).

use serde::Serialize;

use crate::rays::{Hit, Ray};
use crate::reference::RefHit;
use crate::shared::MISS_ID;

/// One f32 ULP at `x`: the gap between |x| rounded to f32 and the next f32 above it.
pub fn ulp_f32(x: f64) -> f64 {
    let a = (x.abs() as f32).min(f32::MAX);
    if a == f32::MAX {
        return (a - f32::from_bits(a.to_bits() - 1)) as f64;
    }
    let next = f32::from_bits(a.to_bits() + 1);
    (next - a) as f64
}

/// |t_gpu - t_ref| in f32 ULPs of t_ref.
pub fn t_error_ulps(t_gpu: f32, t_ref: f64) -> f64 {
    (t_gpu as f64 - t_ref).abs() / ulp_f32(t_ref)
}

/// Median, 99th percentile and maximum of a sample (`n = 0`: all zero).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Dist {
    pub n: usize,
    pub median: f64,
    pub p99: f64,
    pub max: f64,
}

impl Dist {
    pub fn of(mut xs: Vec<f64>) -> Dist {
        if xs.is_empty() {
            return Dist::default();
        }
        xs.sort_by(f64::total_cmp);
        let at = |q: f64| xs[((xs.len() - 1) as f64 * q).round() as usize];
        Dist { n: xs.len(), median: at(0.5), p99: at(0.99), max: xs[xs.len() - 1] }
    }
}

/// What one set of rays did, compared with the f64 reference (and, for rays that must hit a
/// closed mesh, with that proof).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Tally {
    pub rays: usize,
    pub reference_hits: usize,
    pub gpu_hits: usize,
    /// Rays that must hit (closed mesh, proven-inside origin) or that the reference hits, and
    /// that the GPU missed.
    pub leaks: usize,
    /// Reference misses that the GPU reported as hits.
    pub false_hits: usize,
    /// Both hit, different triangles.
    pub different_triangle: usize,
    /// Hits with a NaN or infinite t, u or v (misses must be t = +inf, u = v = 0).
    pub nan: usize,
    /// Hits on a triangle listed as degenerate.
    pub degenerate_hits: usize,
    /// For rays where both hit the same triangle: t error in f32 ULPs of t_ref.
    pub t_ulps: Dist,
    /// ... and max(|u - u_ref|, |v - v_ref|).
    pub bary: Dist,
}

impl Tally {
    /// Compares GPU hits with reference hits. `must_hit`: every ray is proven to hit (a miss is
    /// a leak even where the f64 reference also misses).
    pub fn of(rays: &[Ray], gpu: &[Hit], reference: &[RefHit], must_hit: bool, degenerate: &[u32]) -> Tally {
        let mut b = TallyBuilder::default();
        b.add(rays, gpu, reference, must_hit, degenerate);
        b.finish()
    }

    /// Leaks per 10^6 rays.
    pub fn leaks_per_million(&self) -> f64 {
        per_million(self.leaks, self.rays)
    }

    /// Adds another tally's counts (the distributions are merged by the caller's samples, so
    /// here only counts add; `t_ulps`/`bary` keep the larger maxima).
    pub fn add_counts(&mut self, o: &Tally) {
        self.rays += o.rays;
        self.reference_hits += o.reference_hits;
        self.gpu_hits += o.gpu_hits;
        self.leaks += o.leaks;
        self.false_hits += o.false_hits;
        self.different_triangle += o.different_triangle;
        self.nan += o.nan;
        self.degenerate_hits += o.degenerate_hits;
    }
}

/// A [`Tally`] over rays given in parts, keeping per ray only the two error values (8 bytes), not
/// the rays and hits: the accuracy sweep tallies millions of leak rays per (method, leaf size,
/// layout).
#[derive(Default)]
pub struct TallyBuilder {
    counts: Tally,
    tu: Vec<f32>,
    bary: Vec<f32>,
}

impl TallyBuilder {
    /// Adds `rays` with their GPU and reference hits (as [`Tally::of`] reads them).
    pub fn add(&mut self, rays: &[Ray], gpu: &[Hit], reference: &[RefHit], must_hit: bool, degenerate: &[u32]) {
        assert_eq!(gpu.len(), rays.len());
        assert_eq!(reference.len(), rays.len());
        let t = &mut self.counts;
        t.rays += rays.len();
        for (h, r) in gpu.iter().zip(reference) {
            let hit = h.id != MISS_ID;
            t.reference_hits += r.is_hit() as usize;
            t.gpu_hits += hit as usize;
            if hit && !(h.t.is_finite() && h.u.is_finite() && h.v.is_finite()) {
                t.nan += 1;
            }
            if !hit && (h.t.is_nan() || h.u.is_nan() || h.v.is_nan()) {
                t.nan += 1;
            }
            if hit && degenerate.contains(&h.id) {
                t.degenerate_hits += 1;
            }
            match (hit, r.is_hit()) {
                (false, true) => t.leaks += 1,
                (false, false) if must_hit => t.leaks += 1,
                (true, false) if !must_hit => t.false_hits += 1,
                (true, true) if h.id != r.id => t.different_triangle += 1,
                (true, true) if h.t.is_finite() && h.u.is_finite() && h.v.is_finite() => {
                    // f32 keeps an error's value to 2^-24 relative: far below what the tables print.
                    self.tu.push(t_error_ulps(h.t, r.t) as f32);
                    self.bary.push((h.u as f64 - r.u).abs().max((h.v as f64 - r.v).abs()) as f32);
                }
                _ => {}
            }
        }
    }

    pub fn finish(self) -> Tally {
        let mut t = self.counts;
        t.t_ulps = Dist::of(self.tu.into_iter().map(f64::from).collect());
        t.bary = Dist::of(self.bary.into_iter().map(f64::from).collect());
        t
    }
}

pub fn per_million(count: usize, total: usize) -> f64 {
    if total == 0 {
        0.0
    } else {
        count as f64 * 1e6 / total as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ulps_count_f32_steps() {
        assert_eq!(ulp_f32(1.0), f32::EPSILON as f64);
        assert_eq!(t_error_ulps(1.0 + f32::EPSILON, 1.0), 1.0);
        assert!(ulp_f32(0.0) > 0.0);
        assert!(ulp_f32(1e300).is_finite());
    }

    #[test]
    fn dist_picks_median_p99_max() {
        let d = Dist::of((1..=101).map(f64::from).collect());
        assert_eq!((d.n, d.median, d.p99, d.max), (101, 51.0, 100.0, 101.0));
        assert_eq!(Dist::of(vec![]).n, 0);
    }

    #[test]
    fn tally_counts_leaks_false_hits_and_nan() {
        let ray = Ray::new([0.0; 3], [0.0, 0.0, 1.0]);
        let rays = vec![ray; 4];
        let hit = Hit { t: 1.0, id: 3, u: 0.25, v: 0.25 };
        let gpu = vec![Hit::MISS, hit, Hit { t: f32::NAN, ..hit }, hit];
        let r = RefHit { t: 1.0, id: 3, u: 0.25, v: 0.25 };
        let reference = vec![r, RefHit::MISS, r, r];
        let t = Tally::of(&rays, &gpu, &reference, false, &[3]);
        assert_eq!((t.leaks, t.false_hits, t.nan, t.degenerate_hits), (1, 1, 1, 3));
        assert_eq!(t.t_ulps.n, 1, "the NaN hit is counted, not measured");
        let closed = Tally::of(&rays, &[Hit::MISS; 4], &[RefHit::MISS; 4], true, &[]);
        assert_eq!(closed.leaks, 4);
    }
}
