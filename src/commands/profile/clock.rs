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
    /// Rays whose count did not fit 32 bits ([`SATURATED`]): more than 2^32 ticks between the
    /// two reads, which a ray of microseconds reaches only when its thread is stopped for
    /// seconds (a host that paused the process or the VM).
    pub saturated: usize,
    /// Rays whose clock read lower at the end than at the start ([`STEPPED_BACK`]): a clock that
    /// is not monotonic across the CPUs a driver thread moves between.
    pub stepped_back: usize,
}

/// The kernel's mark of a count beyond 32 bits.
pub const SATURATED: u32 = u32::MAX;
/// The kernel's mark of a clock that read lower at the end.
pub const STEPPED_BACK: u32 = u32::MAX - 1;

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
            saturated: v.iter().filter(|&&c| c == SATURATED).count(),
            stepped_back: v.iter().filter(|&&c| c == STEPPED_BACK).count(),
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

/// Least width of a heat map's image area, pixels: smaller ray images are scaled up (nearest
/// neighbour) so the plot stays readable.
const HEAT_MIN_WIDTH: u32 = 480;

/// A PNG of `cycles` as a `width` x `height` image (rays row by row, as `rays::primary_rays`
/// makes them) under `title`, with pixel axes and a colour bar labelled in ticks per ray.
pub fn heat_map_png(cycles: &[u32], width: u32, height: u32, scale: &HeatScale, title: &str) -> Result<Vec<u8>> {
    use plotters::prelude::*;

    use crate::services::plots::{encode_png, plot_err, register_font, X_LABEL_AREA, Y_LABEL_AREA};
    if width == 0 || height == 0 || cycles.len() != (width as usize) * (height as usize) {
        return Err(Error::Usage(format!("{} cycle counts for a {width}x{height} image", cycles.len())));
    }
    register_font();
    let what = "heat map";
    let zoom = HEAT_MIN_WIDTH.div_ceil(width).max(1);
    let (iw, ih) = (width.saturating_mul(zoom).min(4096), height.saturating_mul(zoom).min(4096));
    let (bar_w, caption, margin) = (170u32, 44u32, 10u32);
    let (w, h) = (iw + Y_LABEL_AREA + bar_w + 2 * margin, ih + caption + X_LABEL_AREA + 2 * margin);
    let mut buf = vec![255u8; (w as usize) * (h as usize) * 3];
    let err = |e| plot_err(what, e);
    let (xs, ys) = {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(err)?;
        let (main, bar) = root.split_horizontally(w - bar_w);
        let mut chart = ChartBuilder::on(&main)
            .caption(title, ("sans-serif", 20))
            .margin(margin)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(0u32..width, height..0u32)
            .map_err(err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .x_desc("pixel x")
            .y_desc("pixel y (rays row by row)")
            .draw()
            .map_err(err)?;
        let range = chart.plotting_area().get_pixel_range();
        // The colour bar: ticks per ray on the log scale the image uses.
        let mut cb = ChartBuilder::on(&bar)
            .margin_top(caption as i32 + margin as i32)
            .margin_bottom(X_LABEL_AREA as i32 + margin as i32)
            .margin_right(30)
            .y_label_area_size(95)
            .build_cartesian_2d(0f64..1.0, (scale.lo..scale.hi).log_scale())
            .map_err(err)?;
        cb.configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .y_desc(format!("ticks per ray (p{} to p{})", scale.percentile_lo, scale.percentile_hi))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .draw()
            .map_err(err)?;
        let steps = 128;
        let at = |i: usize| (scale.lo.ln() + (scale.hi.ln() - scale.lo.ln()) * i as f64 / steps as f64).exp();
        cb.draw_series((0..steps).map(|i| {
            let [r, g, b] = inferno((i as f64 + 0.5) / steps as f64);
            Rectangle::new([(0.0, at(i)), (1.0, at(i + 1))], RGBColor(r, g, b).filled())
        }))
        .map_err(err)?;
        root.present().map_err(err)?;
        range
    };
    // The image itself, nearest neighbour into the plotting area.
    let (x0, x1, y0, y1) = (xs.start.max(0) as u32, xs.end.max(0) as u32, ys.start.max(0) as u32, ys.end.max(0) as u32);
    for py in y0..y1.min(h) {
        let ry = (((py - y0) as u64 * height as u64) / (y1 - y0).max(1) as u64).min(height as u64 - 1) as usize;
        for px in x0..x1.min(w) {
            let rx = (((px - x0) as u64 * width as u64) / (x1 - x0).max(1) as u64).min(width as u64 - 1) as usize;
            let c = inferno(scale.position(cycles[ry * width as usize + rx]));
            let o = (py as usize * w as usize + px as usize) * 3;
            buf[o..o + 3].copy_from_slice(&c);
        }
    }
    encode_png(w, h, buf, what)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_and_scale() {
        let c: Vec<u32> = (1..=100).collect();
        let s = CycleStats::of(&c).unwrap();
        assert_eq!((s.median, s.p99, s.min, s.max, s.saturated, s.stepped_back), (50.0, 99.0, 1, 100, 0, 0));
        let marks = CycleStats::of(&[5, SATURATED, STEPPED_BACK, STEPPED_BACK]).unwrap();
        assert_eq!((marks.saturated, marks.stepped_back), (1, 2));
        assert!((s.mean - 50.5).abs() < 1e-12);
        let scale = HeatScale::of(&[&c], 1.0, 99.0).unwrap();
        assert_eq!((scale.lo, scale.hi), (1.0, 99.0));
        assert_eq!(scale.position(1), 0.0);
        assert_eq!(scale.position(1000), 1.0);
        assert_eq!(inferno(0.0), [0, 0, 4]);
        assert_eq!(inferno(1.0), [252, 255, 164]);
        let png = heat_map_png(&c, 10, 10, &scale, "test").unwrap();
        assert_eq!(&png[1..4], b"PNG");
        assert!(heat_map_png(&c, 10, 9, &scale, "test").is_err());
        // A useful size: a title, axes and a colour bar around an image scaled up to be seen.
        let img = image::load_from_memory(&png).unwrap();
        assert!(
            img.width() >= HEAT_MIN_WIDTH + 200 && img.height() >= HEAT_MIN_WIDTH + 60,
            "{}x{}",
            img.width(),
            img.height()
        );
    }
}
