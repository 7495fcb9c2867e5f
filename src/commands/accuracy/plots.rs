//! The frontier plots: Mrays/s against leaks per 10^6 rays, and against the median and p99 t
//! error in ULPs, one marker per method (the study's PNG helpers: bundled font, in memory,
//! written atomically).

use std::path::Path;

use plotters::prelude::*;

use super::AccuracyReport;
use crate::error::Result;
use crate::services::plots::{chart_on, colour, plot_err, render_png, LegendEntry, Marker, Plot};

/// x values on a log axis: 0 is drawn at a tenth of the smallest positive value (labelled in
/// the table), so perfect methods stay on the plot.
fn log_floor(xs: &[f64]) -> f64 {
    let min = xs.iter().copied().filter(|&x| x > 0.0 && x.is_finite()).fold(f64::INFINITY, f64::min);
    if min.is_finite() {
        min / 10.0
    } else {
        0.1
    }
}

/// One panel: Mrays/s (median, min-max bar) against `x(row)` on a log axis.
fn panel(
    report: &AccuracyReport,
    area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    title: &str,
    x_desc: &str,
    x: &dyn Fn(&super::FrontierRow) -> f64,
) -> Result<()> {
    let what = "frontier";
    let rows: Vec<_> = report.frontier.iter().filter(|r| r.mrays_per_s.is_some()).collect();
    let xs: Vec<f64> = rows.iter().map(|r| x(r)).collect();
    let floor = log_floor(&xs);
    let xv = |v: f64| if v > 0.0 && v.is_finite() { v } else { floor };
    let xmax = xs.iter().copied().map(xv).fold(floor, f64::max) * 10.0;
    let ymax = rows.iter().map(|r| r.mrays_per_s.expect("filtered").max).fold(0.0, f64::max) * 1.2;
    let mut chart = chart_on(area, title, 18)
        .build_cartesian_2d((floor / 2.0..xmax).log_scale(), 0f64..ymax.max(1e-9))
        .map_err(|e| plot_err(what, e))?;
    chart
        .configure_mesh()
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .x_desc(format!("{x_desc} (0 drawn at {floor:.2e})"))
        .y_desc("Mrays/s (median, min-max)")
        .draw()
        .map_err(|e| plot_err(what, e))?;
    for r in rows {
        let s = r.mrays_per_s.expect("filtered");
        let c = colour(r.method);
        let p = (xv(x(r)), s.median);
        chart.draw_series(std::iter::once(Circle::new(p, 6, c.filled()))).map_err(|e| plot_err(what, e))?;
        chart
            .draw_series(std::iter::once(ErrorBar::new_vertical(p.0, s.min, s.median, s.max, c.filled(), 6)))
            .map_err(|e| plot_err(what, e))?;
    }
    Ok(())
}

/// One legend entry per method with a speed.
fn legend(report: &AccuracyReport) -> Vec<LegendEntry> {
    report
        .frontier
        .iter()
        .filter(|r| r.mrays_per_s.is_some())
        .map(|r| LegendEntry::new(r.method.to_string(), colour(r.method), Marker::Dot))
        .collect()
}

/// A panel: its title, its x axis's description and its x value.
type Panel = (&'static str, &'static str, fn(&super::FrontierRow) -> f64);

/// Writes `frontier_leaks.png` and `frontier_t_error.png`.
pub fn all(report: &AccuracyReport, dir: &Path) -> Result<Vec<Plot>> {
    if report.frontier.iter().all(|r| r.mrays_per_s.is_none()) {
        return Ok(vec![]);
    }
    let plots: [(&str, &str, [Panel; 2]); 2] = [
        (
            "Mrays/s against leaks and false hits per 10^6 rays (leaf 4)",
            "frontier_leaks.png",
            [
                ("Mrays/s vs leaks", "leaks per 10^6 rays", |r| r.leaks_per_million),
                ("Mrays/s vs false hits", "false hits per 10^6 rays", |r| r.false_hits_per_million),
            ],
        ),
        (
            "Mrays/s against t error in f32 ULPs, median and p99 (leaf 4)",
            "frontier_t_error.png",
            [
                ("Mrays/s vs median t error", "median |t - t_ref| (ULPs)", |r| r.t_ulps_median),
                ("Mrays/s vs p99 t error", "p99 |t - t_ref| (ULPs)", |r| r.t_ulps_p99),
            ],
        ),
    ];
    let mut out = vec![];
    for (title, file, panels) in plots {
        let plot = Plot { title: title.into(), path: dir.join(file) };
        render_png(&plot.path, 2, "frontier", &legend(report), |area, i| {
            let (title, x_desc, x) = panels[i];
            panel(report, area, title, x_desc, &x)
        })?;
        out.push(plot);
    }
    Ok(out)
}
