//! The study's plots (plotters, drawn into memory and written as PNG atomically):
//! render time against leaf size per method and scene, Mrays/s per method and ray set, and
//! SPIR-V instruction counts against time. With layouts other than bvh2 (`--layouts`) every plot
//! has one panel per scene and layout (a scene's panels share their y axis). The font is bundled (assets/fonts, DejaVu Sans,
//! Bitstream Vera licence) so plots look the same on every machine.

use std::path::Path;

use plotters::prelude::*;

use super::{counts, layouts_of, names_layouts, scenes, StudyReport, StudyRow};
use crate::encoding::{Layout, Method};
use crate::error::Result;
pub use crate::services::plots::Plot;
use crate::services::plots::{
    bar_series, category_chart, chart_on, colour, leaf_size_chart, line_with_error_bars, plot_err, render_png,
    series_colour, LegendEntry, Marker,
};
use crate::services::rayset::RaySet;

fn rows_of<'a>(report: &'a StudyReport, scene: &'a str) -> impl Iterator<Item = &'a StudyRow> + 'a {
    report.rows.iter().filter(move |r| r.scene == scene)
}

/// The panels: (scene, layout), scene by scene.
fn panels(report: &StudyReport) -> Vec<(String, Layout)> {
    let ls = layouts_of(report);
    scenes(report).into_iter().flat_map(|s| ls.iter().map(move |&l| (s.clone(), l))).collect()
}

/// A panel's caption: `scene: what`, naming the layout when the report names layouts.
fn caption(report: &StudyReport, scene: &str, layout: Layout, what: &str) -> String {
    if names_layouts(report) {
        format!("{scene}, {}: {what}", layout.title())
    } else {
        format!("{scene}: {what}")
    }
}

/// Render time against leaf size, one panel per scene (and layout), one line per method
/// (min-max bars).
fn time_vs_leaf(report: &StudyReport, path: &Path) -> Result<()> {
    let panels = panels(report);
    let leaves = report.options.leaf_sizes.clone();
    let what = "time against leaf size";
    let legend: Vec<_> =
        report.options.methods.iter().map(|&m| LegendEntry::new(m.to_string(), colour(m), Marker::Line)).collect();
    render_png(path, panels.len(), what, &legend, |area, i| {
        let (scene, layout) = (&panels[i].0, panels[i].1);
        let ymax = rows_of(report, scene).map(|r| r.render_seconds().max).fold(0.0, f64::max) * 1.1;
        let mut chart = leaf_size_chart(
            area,
            &caption(report, scene, layout, "path-trace time"),
            &leaves,
            0f64..ymax.max(1e-9),
            "seconds (median, min-max)",
            what,
        )?;
        for &m in &report.options.methods {
            let pts: Vec<(u32, f64, f64, f64)> = leaves
                .iter()
                .enumerate()
                .filter_map(|(i, &l)| {
                    let r = rows_of(report, scene).find(|r| r.leaf_size == l && r.method == m && r.layout == layout)?;
                    let s = r.render_seconds();
                    Some((i as u32, s.median, s.min, s.max))
                })
                .collect();
            line_with_error_bars(&mut chart, &pts, colour(m), what)?;
        }
        Ok(())
    })
}

/// Mrays/s per method and ray set at one leaf size (4 when the study has it), one panel per
/// scene (and layout).
fn mrays_per_set(report: &StudyReport, path: &Path, leaf: u32) -> Result<()> {
    let panels = panels(report);
    let sets = ["primary", "diffuse", "random", "path trace"];
    let ray_sets = [RaySet::Primary, RaySet::Diffuse, RaySet::Random];
    let methods = report.options.methods.clone();
    let what = "Mrays/s per ray set";
    let value = |r: &StudyRow, set: usize| {
        if set < 3 {
            r.set(ray_sets[set]).map(|s| s.mrays_per_s.median)
        } else {
            Some(r.render.mrays_per_s.median)
        }
    };
    let legend: Vec<_> = methods.iter().map(|&m| LegendEntry::new(m.to_string(), colour(m), Marker::Bar)).collect();
    render_png(path, panels.len(), what, &legend, |area, i| {
        let (scene, layout) = (&panels[i].0, panels[i].1);
        let at_leaf: Vec<&StudyRow> = rows_of(report, scene).filter(|r| r.leaf_size == leaf).collect();
        let ymax = at_leaf.iter().flat_map(|r| (0..sets.len()).filter_map(|s| value(r, s))).fold(0.0, f64::max) * 1.15;
        let rows: Vec<&StudyRow> = at_leaf.into_iter().filter(|r| r.layout == layout).collect();
        let caption = caption(report, scene, layout, &format!("Mrays/s, leaf {leaf}"));
        let mut chart = category_chart(area, &caption, &sets, ymax, "Mrays/s (median)", what)?;
        for (j, &m) in methods.iter().enumerate() {
            let Some(r) = rows.iter().find(|r| r.method == m) else { continue };
            let values: Vec<Option<f64>> = (0..sets.len()).map(|s| value(r, s)).collect();
            bar_series(&mut chart, &values, (j, methods.len()), colour(m), what)?;
        }
        Ok(())
    })
}

/// SPIR-V function-body instructions of each method's kernels against time relative to the
/// scene's Möller-Trumbore time (on the same layout), at one leaf size: path tracer (left),
/// primary ray cast (right); a pair of panels per layout.
fn instructions_vs_time(report: &StudyReport, path: &Path, leaf: u32) -> Result<()> {
    let scenes = scenes(report);
    let what = "instructions against time";
    let panels = ["path tracer: render time / MT", "ray cast, primary rays: time / MT"];
    let ls = layouts_of(report);
    let legend: Vec<_> =
        scenes.iter().enumerate().map(|(i, s)| LegendEntry::new(s.clone(), series_colour(i), Marker::Dot)).collect();
    render_png(path, panels.len() * ls.len(), what, &legend, |area, panel| {
        let (layout, p) = (ls[panel / panels.len()], panel % panels.len());
        // (scene index, method, instructions, relative time)
        let mut pts: Vec<(usize, Method, f64, f64)> = vec![];
        for (si, scene) in scenes.iter().enumerate() {
            let at = |m: Method| {
                report
                    .rows
                    .iter()
                    .find(|r| &r.scene == scene && r.leaf_size == leaf && r.method == m && r.layout == layout)
            };
            let Some(mt) = at(Method::Mt) else { continue };
            for &m in &report.options.methods {
                let Some(r) = at(m) else { continue };
                let (kernel, t, t0) = if p == 0 {
                    (r.render_kernel, r.render.ms.median, mt.render.ms.median)
                } else {
                    let ms = |r: &StudyRow| r.set(RaySet::Primary).map(|s| s.kernel_ms.median).unwrap_or(f64::NAN);
                    (r.raycast_kernel, ms(r), ms(mt))
                };
                pts.push((si, m, counts(kernel).functions as f64, t / t0));
            }
        }
        let (xmin, xmax) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.2), b.max(p.2)));
        let (ymin, ymax) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.3), b.max(p.3)));
        let (xpad, ypad) = (((xmax - xmin) * 0.15).max(50.0), ((ymax - ymin) * 0.2).max(0.05));
        let xr = if pts.is_empty() { 0.0..1.0 } else { (xmin - xpad)..(xmax + xpad) };
        let yr = if pts.is_empty() { 0.0..1.0 } else { (ymin - ypad)..(ymax + ypad) };
        let caption = if names_layouts(report) {
            format!("{}, {}, leaf {leaf}", layout.title(), panels[p])
        } else {
            format!("{}, leaf {leaf}", panels[p])
        };
        let mut chart = chart_on(area, &caption, 18).build_cartesian_2d(xr, yr).map_err(|e| plot_err(what, e))?;
        chart
            .configure_mesh()
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .x_desc("SPIR-V function-body instructions")
            .x_label_formatter(&|x| format!("{x:.0}"))
            .y_desc("time relative to Möller-Trumbore")
            .draw()
            .map_err(|e| plot_err(what, e))?;
        for si in 0..scenes.len() {
            let c = series_colour(si);
            let mine: Vec<_> = pts.iter().filter(|q| q.0 == si).collect();
            chart
                .draw_series(mine.iter().map(|q| Circle::new((q.2, q.3), 5, c.filled())))
                .map_err(|e| plot_err(what, e))?;
            if si == 0 {
                chart
                    .draw_series(
                        mine.iter().map(|q| {
                            Text::new(q.1.to_string(), (q.2, q.3), ("sans-serif", 13).into_font().color(&BLACK))
                        }),
                    )
                    .map_err(|e| plot_err(what, e))?;
            }
        }
        Ok(())
    })
}

/// Writes every plot into `dir`.
pub fn all(report: &StudyReport, dir: &Path) -> Result<Vec<Plot>> {
    let leaf = if report.options.leaf_sizes.contains(&4) { 4 } else { report.options.leaf_sizes[0] };
    let plots = [
        ("Path-trace time against triangles per leaf, per method and scene", "study-time-vs-leaf.png"),
        ("Mrays/s per method and ray set", "study-mrays-per-set.png"),
        ("SPIR-V instruction counts against time", "study-instructions-vs-time.png"),
    ];
    let mut out = vec![];
    for (i, (title, file)) in plots.iter().enumerate() {
        let path = dir.join(file);
        match i {
            0 => time_vs_leaf(report, &path)?,
            1 => mrays_per_set(report, &path, leaf)?,
            _ => instructions_vs_time(report, &path, leaf)?,
        }
        out.push(Plot { title: title.to_string(), path });
    }
    Ok(out)
}
