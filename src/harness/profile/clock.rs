//! Shader-clock ticks per ray (raycast.comp's `clock` variant): summary statistics and heat-map
//! PNGs of a camera image on a log colour scale clipped to percentiles.

use serde::Serialize;

use crate::error::{Error, Result};

/// Ticks per ray. The clock has subgroup scope: lanes in lock-step read the same value, so on
/// SIMD hardware every ray of a subgroup gets its subgroup's count.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CycleStats {
    pub mean: f64,
    pub median: f64,
    pub p99: f64,
    pub min: u32,
    pub max: u32,
    /// Rays whose count did not fit 32 bits (written as 0xFFFFFFFF).
    pub saturated: usize,
}

/// The `p`-th percentile (0..=100, nearest rank) of sorted values.
fn percentile(sorted: &[u32], p: f64) -> f64 {
    let n = sorted.len();
    let rank = ((p / 100.0) * n as f64).ceil().max(1.0) as usize;
    f64::from(sorted[rank.min(n) - 1])
}

impl CycleStats {
    pub fn of(cycles: &[u32]) -> Option<CycleStats> {
        if cycles.is_empty() {
            return None;
        }
        let mut v = cycles.to_vec();
        v.sort_unstable();
        let mean = v.iter().map(|&c| f64::from(c)).sum::<f64>() / v.len() as f64;
        Some(CycleStats {
            mean,
            median: percentile(&v, 50.0),
            p99: percentile(&v, 99.0),
            min: v[0],
            max: v[v.len() - 1],
            saturated: v.iter().filter(|&&c| c == u32::MAX).count(),
        })
    }
}

/// The colour scale of the heat maps: log of ticks, clipped to [lo, hi], the given percentiles
/// of every method's counts together (so one colour means the same count in every image).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct HeatScale {
    pub lo: f64,
    pub hi: f64,
    pub percentile_lo: f64,
    pub percentile_hi: f64,
}

impl HeatScale {
    pub fn of(all: &[&[u32]], percentile_lo: f64, percentile_hi: f64) -> Option<HeatScale> {
        let mut v: Vec<u32> = all.iter().flat_map(|c| c.iter().copied()).filter(|&c| c > 0).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_unstable();
        let lo = percentile(&v, percentile_lo).max(1.0);
        let hi = percentile(&v, percentile_hi).max(lo + 1.0);
        Some(HeatScale { lo, hi, percentile_lo, percentile_hi })
    }

    /// 0..=1 along the log scale.
    fn position(&self, c: u32) -> f64 {
        let x = f64::from(c.max(1)).ln();
        ((x - self.lo.ln()) / (self.hi.ln() - self.lo.ln())).clamp(0.0, 1.0)
    }
}

/// Matplotlib's "inferno" at five stops, linearly interpolated (dark = few ticks).
fn inferno(t: f64) -> [u8; 3] {
    const STOPS: [[f64; 3]; 5] =
        [[0.0, 0.0, 4.0], [87.0, 16.0, 110.0], [188.0, 55.0, 84.0], [249.0, 142.0, 9.0], [252.0, 255.0, 164.0]];
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - i as f64;
    let c = |k: usize| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8;
    [c(0), c(1), c(2)]
}

/// A PNG of `cycles` as a `width` x `height` image (rays row by row, as `rays::primary_rays`
/// makes them).
pub fn heat_map_png(cycles: &[u32], width: u32, height: u32, scale: &HeatScale) -> Result<Vec<u8>> {
    if cycles.len() != (width as usize) * (height as usize) {
        return Err(Error::Usage(format!("{} cycle counts for a {width}x{height} image", cycles.len())));
    }
    let pixels: Vec<u8> = cycles.iter().flat_map(|&c| inferno(scale.position(c))).collect();
    let img = image::RgbImage::from_raw(width, height, pixels).expect("buffer matches the image size");
    let mut png = std::io::Cursor::new(Vec::new());
    img.write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| Error::Usage(format!("encoding a {width}x{height} heat map: {e}")))?;
    Ok(png.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_and_scale() {
        let c: Vec<u32> = (1..=100).collect();
        let s = CycleStats::of(&c).unwrap();
        assert_eq!((s.median, s.p99, s.min, s.max, s.saturated), (50.0, 99.0, 1, 100, 0));
        assert!((s.mean - 50.5).abs() < 1e-12);
        let scale = HeatScale::of(&[&c], 1.0, 99.0).unwrap();
        assert_eq!((scale.lo, scale.hi), (1.0, 99.0));
        assert_eq!(scale.position(1), 0.0);
        assert_eq!(scale.position(1000), 1.0);
        assert_eq!(inferno(0.0), [0, 0, 4]);
        assert_eq!(inferno(1.0), [252, 255, 164]);
        let png = heat_map_png(&c, 10, 10, &scale).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        assert!(heat_map_png(&c, 10, 9, &scale).is_err());
    }
}
