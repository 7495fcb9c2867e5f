//! The merge's plots, one series per device (plotters, written as PNG atomically, like the
//! study's): render time against leaf size per method, and each method's render time relative
//! to Möller-Trumbore. Devices of very different speed share an axis because every series is
//! normalised by its own device: times by the device's fastest leaf size of that method, methods
//! by the device's Möller-Trumbore time at the same leaf size.

use std::path::Path;

use plotters::prelude::*;

use super::{MergeReport, SpeedRow};
use crate::commands::study::StudyCell;
use crate::encoding::{Layout, Method};
use crate::error::Result;
use crate::named::Named;
use crate::rows::Figure;
use crate::services::plots::{
    bar_series, category_chart, leaf_size_chart, line_with_error_bars, plot_err, render_png, series_colour,
    LegendEntry, Marker, Plot,
};

/// One render-time row: its study cell and its figure per device.
struct TimeRow<'a> {
    cell: StudyCell,
    per_device: &'a [Option<Figure>],
}

/// The study's render-time rows.
struct Times<'a> {
    rows: Vec<TimeRow<'a>>,
}

impl<'a> Times<'a> {
    /// Every study cell's render time (merge has read each of those cells already: none is
    /// unreadable here).
    fn of(report: &'a MergeReport) -> Times<'a> {
        let rows = report
            .speed
            .iter()
            .filter(|r| r.command == "study" && r.figure == "render_s")
            .filter_map(|r: &'a SpeedRow| {
                Some(TimeRow { cell: StudyCell::try_from(&r.cell).ok()?, per_device: r.per_device.as_slice() })
            })
            .collect();
        Times { rows }
    }

    fn of_panel<'s>(&'s self, scene: &'s str, layout: Layout) -> impl Iterator<Item = &'s StudyCell> {
        self.rows.iter().map(|r| &r.cell).filter(move |c| c.scene == scene && c.layout == layout)
    }

    /// (scene, layout) pairs in order of first appearance.
    fn panels(&self) -> Vec<(&str, Layout)> {
        let mut v = vec![];
        for c in self.rows.iter().map(|r| &r.cell) {
            if !v.contains(&(c.scene.as_str(), c.layout)) {
                v.push((c.scene.as_str(), c.layout));
            }
        }
        v
    }

    fn methods(&self, scene: &str, layout: Layout) -> Vec<Method> {
        let mut v = vec![];
        for c in self.of_panel(scene, layout) {
            if !v.contains(&c.method) {
                v.push(c.method);
            }
        }
        v
    }

    fn leaves(&self, scene: &str, layout: Layout) -> Vec<u32> {
        let mut v: Vec<u32> = self.of_panel(scene, layout).map(|c| c.leaf).collect();
        v.sort();
        v.dedup();
        v
    }

    fn get(&self, scene: &str, layout: Layout, method: Method, leaf: u32, device: usize) -> Option<&'a Figure> {
        self.rows
            .iter()
            .find(|r| {
                r.cell.scene == scene && r.cell.layout == layout && r.cell.method == method && r.cell.leaf == leaf
            })
            .and_then(|r| r.per_device.get(device)?.as_ref())
    }
}

fn file_part(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

fn legend(report: &MergeReport, marker: Marker) -> Vec<LegendEntry> {
    super::series_names(&report.devices)
        .into_iter()
        .enumerate()
        .map(|(i, name)| LegendEntry::new(name, series_colour(i), marker))
        .collect()
}

/// Render time against leaf size, one panel per method of one (scene, layout), one line per
/// device, each divided by the device's fastest median of that method (1 = its best leaf size).
fn time_vs_leaf(report: &MergeReport, t: &Times, scene: &str, layout: Layout, path: &Path) -> Result<()> {
    let methods = t.methods(scene, layout);
    let leaves = t.leaves(scene, layout);
    let what = "merged time against leaf size";
    // (method, device) -> points (leaf index, median, min, max), normalised.
    let series = |m: Method, d: usize| -> Vec<(u32, f64, f64, f64)> {
        let pts: Vec<(u32, &Figure)> =
            leaves.iter().enumerate().filter_map(|(i, &l)| Some((i as u32, t.get(scene, layout, m, l, d)?))).collect();
        let best = pts.iter().map(|p| p.1.median).fold(f64::INFINITY, f64::min);
        pts.iter().map(|(i, f)| (*i, f.median / best, f.min / best, f.max / best)).collect()
    };
    let devices = report.devices.len();
    render_png(path, methods.len(), what, &legend(report, Marker::Line), |area, i| {
        let m = methods[i];
        let all: Vec<Vec<(u32, f64, f64, f64)>> = (0..devices).map(|d| series(m, d)).collect();
        let ymax = all.iter().flatten().map(|p| p.3).fold(1.0, f64::max) * 1.05;
        let ymin = all.iter().flatten().map(|p| p.2).fold(1.0, f64::min) * 0.95;
        let caption =
            if layout == Layout::DEFAULT { format!("{scene}, {m}") } else { format!("{scene}, {layout}, {m}") };
        let mut chart =
            leaf_size_chart(area, &caption, &leaves, ymin..ymax, "time / device's fastest leaf (min-max)", what)?;
        for (d, pts) in all.iter().enumerate() {
            line_with_error_bars(&mut chart, pts, series_colour(d), what)?;
        }
        Ok(())
    })
}

/// Each method's render time over Möller-Trumbore's at the same leaf size (geometric mean over
/// leaf sizes), one panel per (scene, layout), one bar per device.
fn methods_vs_mt(report: &MergeReport, t: &Times, path: &Path) -> Result<()> {
    let panels = t.panels();
    let what = "merged method against Möller-Trumbore";
    let devices = report.devices.len();
    render_png(path, panels.len(), what, &legend(report, Marker::Bar), |area, i| {
        let (scene, layout) = panels[i];
        let methods = t.methods(scene, layout);
        let leaves = t.leaves(scene, layout);
        let rel = |m: Method, d: usize| -> Option<f64> {
            let logs: Vec<f64> = leaves
                .iter()
                .filter_map(|&l| {
                    Some((t.get(scene, layout, m, l, d)?.median / t.get(scene, layout, Method::Mt, l, d)?.median).ln())
                })
                .collect();
            (!logs.is_empty()).then(|| (logs.iter().sum::<f64>() / logs.len() as f64).exp())
        };
        let values: Vec<Vec<Option<f64>>> =
            methods.iter().map(|&m| (0..devices).map(|d| rel(m, d)).collect()).collect();
        let ymax = values.iter().flatten().flatten().copied().fold(1.0, f64::max) * 1.15;
        let caption = if layout == Layout::DEFAULT {
            format!("{scene}: time / MT")
        } else {
            format!("{scene}, {layout}: time / MT")
        };
        let y_desc = "render time / MT's (geo. mean over leaves)";
        let names: Vec<&str> = methods.iter().map(|m| m.name()).collect();
        let mut chart = category_chart(area, &caption, &names, ymax, y_desc, what)?;
        for d in 0..devices {
            let per_method: Vec<Option<f64>> = values.iter().map(|v| v[d]).collect();
            bar_series(&mut chart, &per_method, (d, devices.max(1)), series_colour(d), what)?;
        }
        chart
            .draw_series(LineSeries::new([(-0.5, 1.0), (methods.len() as f64 - 0.5, 1.0)], BLACK.stroke_width(1)))
            .map_err(|e| plot_err(what, e))?;
        Ok(())
    })
}

/// Writes every plot into `dir`: nothing when the merge has no study render times.
pub fn all(report: &MergeReport, dir: &Path) -> Result<Vec<Plot>> {
    let t = Times::of(report);
    let mut out = vec![];
    if t.rows.is_empty() {
        return Ok(out);
    }
    for (scene, layout) in t.panels() {
        let name = if layout == Layout::DEFAULT {
            format!("merge-time-vs-leaf-{}.png", file_part(scene))
        } else {
            format!("merge-time-vs-leaf-{}-{}.png", file_part(scene), file_part(layout.name()))
        };
        let path = dir.join(name);
        time_vs_leaf(report, &t, scene, layout, &path)?;
        let on = if layout == Layout::DEFAULT { String::new() } else { format!(" on {layout}") };
        out.push(Plot {
            title: format!(
                "{scene}{on}: render time against leaf size, per device (1 = the device's fastest leaf size)"
            ),
            path,
        });
    }
    let path = dir.join("merge-methods-vs-mt.png");
    methods_vs_mt(report, &t, &path)?;
    out.push(Plot { title: "Render time relative to Möller-Trumbore, per device".into(), path });
    Ok(out)
}
