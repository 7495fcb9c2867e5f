//! The frontier plots: Mrays/s against leaks per 10^6 rays, and against the median and p99 t
//! error in ULPs, one marker per method (the study's PNG helpers: bundled font, in memory,
//! written atomically).

use std::path::Path;

use plotters::prelude::*;

use super::AccuracyReport;
use crate::error::Result;
use crate::harness::plots::{colour, plot_err, render_png, LegendEntry, Marker, Plot, X_LABEL_AREA, Y_LABEL_AREA};

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
    let mut chart = ChartBuilder::on(area)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
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

/// Writes `frontier_leaks.png` and `frontier_t_error.png`.
pub fn all(report: &AccuracyReport, dir: &Path) -> Result<Vec<Plot>> {
    if report.frontier.iter().all(|r| r.mrays_per_s.is_none()) {
        return Ok(vec![]);
    }
    let leaks = Plot {
        title: "Mrays/s against leaks and false hits per 10^6 rays (leaf 4)".into(),
        path: dir.join("frontier_leaks.png"),
    };
    render_png(&leaks.path, 2, "frontier", &legend(report), |area, i| {
        if i == 0 {
            panel(report, area, "Mrays/s vs leaks", "leaks per 10^6 rays", &|r| r.leaks_per_million)
        } else {
            panel(report, area, "Mrays/s vs false hits", "false hits per 10^6 rays", &|r| r.false_hits_per_million)
        }
    })?;
    let terr = Plot {
        title: "Mrays/s against t error in f32 ULPs, median and p99 (leaf 4)".into(),
        path: dir.join("frontier_t_error.png"),
    };
    render_png(&terr.path, 2, "frontier", &legend(report), |area, i| {
        if i == 0 {
            panel(report, area, "Mrays/s vs median t error", "median |t - t_ref| (ULPs)", &|r| r.t_ulps_median)
        } else {
            panel(report, area, "Mrays/s vs p99 t error", "p99 |t - t_ref| (ULPs)", &|r| r.t_ulps_p99)
        }
    })?;
    Ok(vec![leaks, terr])
}
