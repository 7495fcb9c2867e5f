//! accuracy.csv (one row per measurement, every row with the device, its float controls and the
//! commit) and accuracy.md (one table per question).

use std::fmt::Write as _;

use serde::Serialize;

use super::metrics::{per_million, Tally};
use super::probes::LeakKind;
use super::{AccuracyReport, SelfHitRow, FALSE_HIT_OFFSETS, FIXED_LEAF};
use crate::encoding::{Layout, Method};
use crate::error::{Error, Result};
use crate::rays::offset::{Offset, RECOMMENDED};
use crate::report::Table;
use crate::services::plots::Plot;

/// One CSV row. Sections: leaks, false-hits, errors, self-hits, extremes, frontier.
#[derive(Serialize, Default)]
struct CsvRow {
    section: String,
    case: String,
    param: String,
    method: String,
    leaf_size: u32,
    layout: String,
    rays: usize,
    reference_hits: Option<usize>,
    gpu_hits: Option<usize>,
    leaks: Option<usize>,
    leaks_per_million: Option<f64>,
    false_hits: Option<usize>,
    different_triangle: Option<usize>,
    nan: Option<usize>,
    degenerate_hits: Option<usize>,
    t_ulps_median: Option<f64>,
    t_ulps_p99: Option<f64>,
    t_ulps_max: Option<f64>,
    bary_median: Option<f64>,
    bary_p99: Option<f64>,
    bary_max: Option<f64>,
    self_hits: Option<usize>,
    near_hits: Option<usize>,
    escaped: Option<usize>,
    mrays_per_s: Option<f64>,
    mrays_per_s_min: Option<f64>,
    mrays_per_s_max: Option<f64>,
    device: String,
    driver: String,
    float_controls: String,
    commit: String,
}

fn from_tally(section: &str, case: &str, param: String, method: Method, leaf: u32, t: &Tally) -> CsvRow {
    CsvRow {
        section: section.into(),
        case: case.into(),
        param,
        method: method.to_string(),
        leaf_size: leaf,
        layout: Layout::DEFAULT.to_string(),
        rays: t.rays,
        reference_hits: Some(t.reference_hits),
        gpu_hits: Some(t.gpu_hits),
        leaks: Some(t.leaks),
        leaks_per_million: Some(t.leaks_per_million()),
        false_hits: Some(t.false_hits),
        different_triangle: Some(t.different_triangle),
        nan: Some(t.nan),
        degenerate_hits: Some(t.degenerate_hits),
        t_ulps_median: Some(t.t_ulps.median),
        t_ulps_p99: Some(t.t_ulps.p99),
        t_ulps_max: Some(t.t_ulps.max),
        bary_median: Some(t.bary.median),
        bary_p99: Some(t.bary.p99),
        bary_max: Some(t.bary.max),
        ..Default::default()
    }
}

/// The device's float controls in one cell.
pub fn float_controls(report: &AccuracyReport) -> String {
    let f = &report.device.float_controls;
    format!(
        "denorm independence {}; rounding independence {}; f32: signed zero/inf/nan preserve {}, denorm preserve {}, \
         denorm flush {}, RTE {}, RTZ {}; f64: signed zero/inf/nan preserve {}; shaderFloat64 {}",
        f.denorm_behavior_independence,
        f.rounding_mode_independence,
        f.signed_zero_inf_nan_preserve_f32,
        f.denorm_preserve_f32,
        f.denorm_flush_to_zero_f32,
        f.rounding_mode_rte_f32,
        f.rounding_mode_rtz_f32,
        f.signed_zero_inf_nan_preserve_f64,
        report.device.shader_float64
    )
}

/// `accuracy.csv`.
pub fn csv(report: &AccuracyReport) -> Result<String> {
    let mut rows = Vec::new();
    let on = |mut row: CsvRow, l: Layout| {
        row.layout = l.to_string();
        row
    };
    for r in &report.leaks {
        rows.push(on(from_tally("leaks", &r.mesh, r.kind.name().into(), r.method, r.leaf_size, &r.tally), r.layout));
    }
    for r in &report.false_hits {
        let param = format!("d=1e{}", r.d_exp);
        rows.push(on(from_tally("false-hits", &r.mesh, param, r.method, r.leaf_size, &r.tally), r.layout));
    }
    for r in &report.errors {
        let row = from_tally("errors", "all closed meshes", "leak rays".into(), r.method, r.leaf_size, &r.tally);
        rows.push(on(row, r.layout));
    }
    for r in &report.self_hits {
        rows.push(CsvRow {
            section: "self-hits".into(),
            case: r.scheme.name().into(),
            param: format!("scale=1e{}", r.scale_exp),
            method: r.method.to_string(),
            leaf_size: r.leaf_size,
            layout: Layout::DEFAULT.to_string(),
            rays: r.rays,
            nan: Some(r.nan),
            self_hits: Some(r.self_hits),
            near_hits: Some(r.near_hits),
            escaped: Some(r.escaped),
            ..Default::default()
        });
    }
    for r in &report.extremes {
        rows.push(from_tally("extremes", &r.kind, r.param.clone(), r.method, r.leaf_size, &r.tally));
    }
    for r in &report.frontier {
        rows.push(CsvRow {
            section: "frontier".into(),
            case: "bunny diffuse".into(),
            param: r.note.clone().unwrap_or_default(),
            method: r.method.to_string(),
            leaf_size: FIXED_LEAF,
            layout: r.layout.to_string(),
            rays: report.frontier_rays,
            leaks_per_million: Some(r.leaks_per_million),
            t_ulps_median: Some(r.t_ulps_median),
            t_ulps_p99: Some(r.t_ulps_p99),
            mrays_per_s: r.mrays_per_s.map(|s| s.median),
            mrays_per_s_min: r.mrays_per_s.map(|s| s.min),
            mrays_per_s_max: r.mrays_per_s.map(|s| s.max),
            ..Default::default()
        });
    }
    let fc = float_controls(report);
    for r in &mut rows {
        r.device = report.provenance.device.clone();
        r.driver = report.provenance.driver.clone();
        r.float_controls = fc.clone();
        r.commit = report.provenance.commit.clone();
    }
    csv_text("accuracy.csv", rows)
}

/// `rows` as CSV with a header from their field names; errors name `file`.
fn csv_text<T: Serialize>(file: &str, rows: impl IntoIterator<Item = T>) -> Result<String> {
    let err = |e: &dyn std::fmt::Display| Error::Usage(format!("{file}: {e}"));
    let mut w = csv::Writer::from_writer(vec![]);
    for r in rows {
        w.serialize(r).map_err(|e| err(&e))?;
    }
    String::from_utf8(w.into_inner().map_err(|e| err(&e))?).map_err(|e| err(&e))
}

fn methods(report: &AccuracyReport) -> Vec<Method> {
    let mut v: Vec<Method> = report.leaks.iter().map(|r| r.method).collect();
    v.extend(report.extremes.iter().map(|r| r.method));
    v.extend(report.self_hits.iter().map(|r| r.method));
    let mut seen = Vec::new();
    for m in v {
        if !seen.contains(&m) {
            seen.push(m);
        }
    }
    seen
}

/// The layouts of the leak study, in the order asked.
fn layouts(report: &AccuracyReport) -> Vec<Layout> {
    if report.options.layouts.is_empty() {
        vec![Layout::DEFAULT]
    } else {
        report.options.layouts.clone()
    }
}

/// Whether the tables name layouts (a layout other than bvh2 was measured).
pub fn names_layouts(report: &AccuracyReport) -> bool {
    layouts(report) != [Layout::DEFAULT]
}

/// (method, leaf size, layout) rows of the leak study's tables, method by method.
fn configurations(report: &AccuracyReport) -> Vec<(Method, u32, Layout)> {
    let ls = layouts(report);
    let mut v = vec![];
    for m in methods(report) {
        for &leaf in &report.options.leaf_sizes {
            v.extend(ls.iter().map(|&l| (m, leaf, l)));
        }
    }
    v
}

/// `head` (method first) with a layout column after the method when the report names layouts.
fn layout_head(report: &AccuracyReport, mut head: Vec<String>) -> Vec<String> {
    if names_layouts(report) {
        head.insert(1, "layout".into());
    }
    head
}

/// A row's first cells: method, (layout,) leaf.
fn first_cells(report: &AccuracyReport, m: Method, leaf: u32, l: Layout) -> Vec<String> {
    let mut v = vec![m.to_string(), leaf.to_string()];
    if names_layouts(report) {
        v.insert(1, l.to_string());
    }
    v
}

fn sum_tallies<'a>(it: impl Iterator<Item = &'a Tally>) -> Tally {
    let mut t = Tally::default();
    for x in it {
        t.add_counts(x);
    }
    t
}

fn rate(count: usize, total: usize) -> String {
    if total == 0 {
        "-".into()
    } else {
        format!("{:.1}", per_million(count, total))
    }
}

/// Leaks per 10^6 rays: method x leaf size, per mesh and per ray kind.
pub fn leaks_table(report: &AccuracyReport) -> Table {
    let meshes: Vec<String> = report.meshes.iter().map(|m| m.name.clone()).collect();
    let mut head = vec!["method".to_string(), "leaf".into()];
    head.extend(meshes.iter().cloned());
    head.extend(LeakKind::ALL.iter().map(|k| format!("at {}", k.name())));
    head.extend(["all".into(), "rays".into()]);
    let mut t = Table::new(layout_head(report, head));
    for (m, leaf, l) in configurations(report) {
        {
            let rows: Vec<_> =
                report.leaks.iter().filter(|r| r.method == m && r.leaf_size == leaf && r.layout == l).collect();
            if rows.is_empty() {
                continue;
            }
            let mut cells = first_cells(report, m, leaf, l);
            for mesh in &meshes {
                let s = sum_tallies(rows.iter().filter(|r| &r.mesh == mesh).map(|r| &r.tally));
                cells.push(rate(s.leaks, s.rays));
            }
            for k in LeakKind::ALL {
                let s = sum_tallies(rows.iter().filter(|r| r.kind == k).map(|r| &r.tally));
                cells.push(rate(s.leaks, s.rays));
            }
            let all = sum_tallies(rows.iter().map(|r| &r.tally));
            cells.push(rate(all.leaks, all.rays));
            cells.push(all.rays.to_string());
            t.row(cells);
        }
    }
    t
}

/// Leaks per method and layout over every leaf size, mesh and kind: (leaks, rays).
pub fn leaks_per_layout(report: &AccuracyReport, m: Method, l: Layout) -> (usize, usize) {
    let t = sum_tallies(report.leaks.iter().filter(|r| r.method == m && r.layout == l).map(|r| &r.tally));
    (t.leaks, t.rays)
}

/// One row per method, one column per layout: leaks of all leak rays (every leaf size, mesh and
/// kind), and whether the method is leak-free on every layout.
pub fn layouts_table(report: &AccuracyReport) -> Table {
    let ls = layouts(report);
    let mut head = vec!["method".to_string()];
    head.extend(ls.iter().map(|l| format!("leaks on {l} (of rays)")));
    head.push("leak-free on every layout".into());
    let mut t = Table::new(head);
    for m in methods(report) {
        let counts: Vec<(usize, usize)> = ls.iter().map(|&l| leaks_per_layout(report, m, l)).collect();
        if counts.iter().all(|c| c.1 == 0) {
            continue;
        }
        let mut cells = vec![m.to_string()];
        cells.extend(counts.iter().map(|(k, n)| format!("{k} ({n})")));
        cells.push(if counts.iter().all(|c| c.0 == 0 && c.1 > 0) { "yes" } else { "no" }.into());
        t.row(cells);
    }
    t
}

/// The claim the layout axis must keep: `watertight` leak-free on every layout, in words.
pub fn watertight_on_layouts(report: &AccuracyReport) -> Option<String> {
    let counts: Vec<(Layout, usize, usize)> = layouts(report)
        .into_iter()
        .map(|l| {
            let (k, n) = leaks_per_layout(report, Method::Watertight, l);
            (l, k, n)
        })
        .filter(|c| c.2 > 0)
        .collect();
    if counts.is_empty() {
        return None;
    }
    let leaky: Vec<String> =
        counts.iter().filter(|c| c.1 > 0).map(|(l, k, n)| format!("{k} of {n} rays on {l}")).collect();
    Some(if leaky.is_empty() {
        format!(
            "**watertight stays leak-free on every layout**: 0 leaks in {} rays on each of {}.",
            counts[0].2,
            counts.iter().map(|c| c.0.to_string()).collect::<Vec<_>>().join(", ")
        )
    } else {
        format!("**watertight leaks on a layout**: {}.", leaky.join("; "))
    })
}

/// False hits: per method x leaf, per offset d (false hits / rays the reference misses).
pub fn false_hits_table(report: &AccuracyReport) -> Table {
    let mut head = vec!["method".to_string(), "leaf".into()];
    head.extend(FALSE_HIT_OFFSETS.iter().map(|d| format!("d=1e{d}")));
    let mut t = Table::new(layout_head(report, head));
    for (m, leaf, l) in configurations(report) {
        {
            let rows: Vec<_> =
                report.false_hits.iter().filter(|r| r.method == m && r.leaf_size == leaf && r.layout == l).collect();
            if rows.is_empty() {
                continue;
            }
            let mut cells = first_cells(report, m, leaf, l);
            for &d in &FALSE_HIT_OFFSETS {
                let s = sum_tallies(rows.iter().filter(|r| r.d_exp == d).map(|r| &r.tally));
                cells.push(format!("{}/{}", s.false_hits, s.rays));
            }
            t.row(cells);
        }
    }
    t
}

/// t and barycentric error per method x leaf over every leak ray both hit on the same triangle.
pub fn errors_table(report: &AccuracyReport) -> Table {
    let head = [
        "method",
        "leaf",
        "compared",
        "t ULP median",
        "t ULP p99",
        "t ULP max",
        "bary median",
        "bary p99",
        "bary max",
        "different triangle",
        "NaN",
    ];
    let mut t = Table::new(layout_head(report, head.map(String::from).to_vec()));
    for r in &report.errors {
        let e = &r.tally;
        let mut cells = first_cells(report, r.method, r.leaf_size, r.layout);
        cells.extend([
            e.t_ulps.n.to_string(),
            format!("{:.2}", e.t_ulps.median),
            format!("{:.2}", e.t_ulps.p99),
            format!("{:.1}", e.t_ulps.max),
            format!("{:.2e}", e.bary.median),
            format!("{:.2e}", e.bary.p99),
            format!("{:.2e}", e.bary.max),
            e.different_triangle.to_string(),
            e.nan.to_string(),
        ]);
        t.row(cells);
    }
    t
}

/// One row per method x offset scheme, one column per scale of the self-intersection study,
/// each cell `cell` of that (method, scheme, scale)'s row.
fn scheme_by_scale_table(report: &AccuracyReport, cell: impl Fn(&SelfHitRow) -> String) -> Table {
    let mut scales: Vec<i32> = report.self_hits.iter().map(|r| r.scale_exp).collect();
    scales.sort_unstable();
    scales.dedup();
    let mut head = vec!["method".to_string(), "scheme".into()];
    head.extend(scales.iter().map(|k| format!("1e{k}")));
    let mut t = Table::new(head);
    for m in methods(report) {
        for scheme in Offset::ALL {
            let rows: Vec<_> = report.self_hits.iter().filter(|r| r.method == m && r.scheme == scheme).collect();
            if rows.is_empty() {
                continue;
            }
            let mut cells = vec![m.to_string(), scheme.name().to_string()];
            for k in &scales {
                cells.push(rows.iter().find(|r| r.scale_exp == *k).map_or_else(|| "-".into(), |r| cell(r)));
            }
            t.row(cells);
        }
    }
    t
}

/// Self-hits (near hits) per method x scheme, one column per scale.
pub fn self_hits_table(report: &AccuracyReport) -> Table {
    scheme_by_scale_table(report, |r| {
        if r.near_hits > r.self_hits {
            format!("{} ({})", r.self_hits, r.near_hits)
        } else {
            r.self_hits.to_string()
        }
    })
}

/// Escaped secondary rays (spawned inside the closed icosphere, hit nothing) per method x
/// scheme and scale: the offset pushed the origin through the surface.
pub fn escaped_table(report: &AccuracyReport) -> Table {
    scheme_by_scale_table(report, |r| r.escaped.to_string())
}

/// One extremes table for `kind`.
pub fn extremes_table(report: &AccuracyReport, kind: &str) -> Table {
    let mut t = Table::new([
        "case",
        "method",
        "rays",
        "ref hits",
        "GPU hits",
        "leaks",
        "false hits",
        "other tri",
        "NaN",
        "degenerate hits",
        "t ULP median",
        "t ULP max",
        "unrepresentable",
    ]);
    for r in report.extremes.iter().filter(|r| r.kind == kind) {
        let e = &r.tally;
        t.row([
            r.param.clone(),
            r.method.to_string(),
            e.rays.to_string(),
            e.reference_hits.to_string(),
            e.gpu_hits.to_string(),
            e.leaks.to_string(),
            e.false_hits.to_string(),
            e.different_triangle.to_string(),
            e.nan.to_string(),
            e.degenerate_hits.to_string(),
            format!("{:.2}", e.t_ulps.median),
            format!("{:.1}", e.t_ulps.max),
            r.unrepresentable.to_string(),
        ]);
    }
    t
}

/// `frontier.csv`: per method, speed and accuracy on the centred closed meshes (the columns
/// `analyze::Frontier` reads).
pub fn frontier_csv(report: &AccuracyReport) -> Result<String> {
    #[derive(Serialize)]
    struct Row {
        method: &'static str,
        mrays_median: String,
        mrays_min: String,
        mrays_max: String,
        leaks_per_million: String,
        false_hits_per_million: String,
        t_ulps_median: String,
        t_ulps_p99: String,
        device: String,
        commit: String,
    }
    let rows = report.frontier.iter().filter_map(|r| {
        let s = r.mrays_per_s?;
        Some(Row {
            method: r.method.name(),
            mrays_median: format!("{:.4}", s.median),
            mrays_min: format!("{:.4}", s.min),
            mrays_max: format!("{:.4}", s.max),
            leaks_per_million: format!("{:.3}", r.leaks_per_million),
            false_hits_per_million: format!("{:.3}", r.false_hits_per_million),
            t_ulps_median: format!("{:.4}", r.t_ulps_median),
            t_ulps_p99: format!("{:.4}", r.t_ulps_p99),
            device: report.provenance.device.clone(),
            commit: report.provenance.commit.clone(),
        })
    });
    csv_text("frontier.csv", rows)
}

/// `translation.csv`: per method and translation of the closed mesh, how far from the origin it
/// sat (largest |coordinate| over extent) and the leaks and t error there; `analyze` looks up a
/// scene's own ratio in it.
pub fn translation_csv(report: &AccuracyReport) -> Result<String> {
    #[derive(Serialize)]
    struct Row<'a> {
        method: &'static str,
        translation: &'a str,
        magnitude_over_extent: String,
        leaks_per_million: String,
        t_ulps_median: String,
        t_ulps_p99: String,
    }
    let rows = report.extremes.iter().filter(|r| r.kind == "translate").map(|r| Row {
        method: r.method.name(),
        translation: &r.param,
        magnitude_over_extent: format!("{:.6e}", r.magnitude_over_extent),
        leaks_per_million: format!("{:.3}", per_million(r.tally.leaks, r.tally.rays)),
        t_ulps_median: format!("{:.4}", r.tally.t_ulps.median),
        t_ulps_p99: format!("{:.4}", r.tally.t_ulps.p99),
    });
    csv_text("translation.csv", rows)
}

pub fn frontier_table(report: &AccuracyReport) -> Table {
    let mut t = Table::new([
        "method",
        "Mrays/s",
        "min..max",
        "leaks per 1e6",
        "false hits per 1e6",
        "t ULP median",
        "t ULP p99",
    ]);
    for r in &report.frontier {
        let (m, range) = match r.mrays_per_s {
            Some(s) => (format!("{:.2}", s.median), format!("{:.2}..{:.2}", s.min, s.max)),
            None => ("-".into(), r.note.clone().unwrap_or_default()),
        };
        t.row([
            r.method.to_string(),
            m,
            range,
            format!("{:.1}", r.leaks_per_million),
            format!("{:.1}", r.false_hits_per_million),
            format!("{:.2}", r.t_ulps_median),
            format!("{:.2}", r.t_ulps_p99),
        ]);
    }
    t
}

pub fn float_controls_table(report: &AccuracyReport) -> Table {
    let f = &report.device.float_controls;
    let mut t = Table::new(["property", "value"]);
    let yn = |b: bool| if b { "yes" } else { "no" }.to_string();
    t.row(["denormBehaviorIndependence".into(), f.denorm_behavior_independence.clone()]);
    t.row(["roundingModeIndependence".into(), f.rounding_mode_independence.clone()]);
    t.row(["shaderSignedZeroInfNanPreserveFloat32".into(), yn(f.signed_zero_inf_nan_preserve_f32)]);
    t.row(["shaderSignedZeroInfNanPreserveFloat64".into(), yn(f.signed_zero_inf_nan_preserve_f64)]);
    t.row(["shaderDenormPreserveFloat32".into(), yn(f.denorm_preserve_f32)]);
    t.row(["shaderDenormFlushToZeroFloat32".into(), yn(f.denorm_flush_to_zero_f32)]);
    t.row(["shaderRoundingModeRTEFloat32".into(), yn(f.rounding_mode_rte_f32)]);
    t.row(["shaderRoundingModeRTZFloat32".into(), yn(f.rounding_mode_rtz_f32)]);
    t.row(["shaderFloat64".into(), yn(report.device.shader_float64)]);
    t
}

/// `accuracy.md`.
pub fn markdown(report: &AccuracyReport, plots: &[Plot]) -> String {
    let mut s = header(report);
    if !report.meshes.is_empty() {
        s += &meshes_sections(report);
    }
    if !report.self_hits.is_empty() {
        s += &self_hits_section(report);
    }
    if !report.extremes.is_empty() {
        s += &extremes_section(report);
    }
    if !report.frontier.is_empty() {
        s += &frontier_section(report);
    }
    for plot in plots {
        let name = plot.path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let _ = writeln!(s, "![{}]({name})\n", plot.title);
    }
    s
}

/// The title, the run (provenance, workload, layouts, methods unsupported) and the device's
/// float controls.
fn header(report: &AccuracyReport) -> String {
    let p = &report.provenance;
    let o = &report.options;
    let mut s = String::new();
    let _ = writeln!(s, "# Intersection accuracy on {}\n", p.device);
    if let Some(note) = super::partial(report) {
        let _ = writeln!(s, "**{note}.**\n");
    }
    let _ = writeln!(
        s,
        "Driver {}; commit {}; {}; host {}; LP_NUM_THREADS {}; preset {:?}; {:.0} s.\n",
        p.driver,
        p.commit,
        p.date,
        p.host.label(),
        p.lp_num_threads.as_deref().unwrap_or("unset"),
        o.preset,
        report.seconds
    );
    let _ = writeln!(
        s,
        "Workload: {} leak rays per closed mesh and kind from {} proven-inside origins; {} silhouette rays per \
         offset; {} secondary rays per (scale, method, scheme); {} rays per extreme case; the frontier's speed \
         from {} bunny diffuse rays (leaf {FIXED_LEAF}, validated, median of {} runs). The extremes, the \
         self-intersection study and the frontier use leaf size {FIXED_LEAF} only: the intersector decides them, \
         the tree only decides which triangles are tested.\n",
        o.leak_rays, o.origins, o.silhouette_rays, o.self_rays, o.extreme_rays, report.frontier_rays, o.repeat
    );
    if names_layouts(report) {
        let ls: Vec<String> = layouts(report).iter().map(|l| format!("`{l}`")).collect();
        let _ = writeln!(
            s,
            "Node layouts: {} for the leaks, false hits and errors (each method on each); the extremes and the \
             self-intersection study on `{}`, the frontier on `{}`.\n",
            ls.join(", "),
            Layout::DEFAULT,
            report.frontier.first().map_or(Layout::DEFAULT, |f| f.layout)
        );
    }
    for (m, why) in &report.unsupported {
        let _ = writeln!(s, "- **{m}: unsupported** on this device ({why}); not measured.");
    }
    let _ = writeln!(s, "\n## Float controls of the device\n\n{}", float_controls_table(report).to_markdown());
    s
}

/// The closed meshes, then the leaks, leaks per layout, false hits and errors measured on them.
fn meshes_sections(report: &AccuracyReport) -> String {
    let mut s = String::new();
    let mut t = Table::new(["mesh", "triangles", "closed (proof)", "origins", "rejected origins"]);
    for m in &report.meshes {
        let closed = m.closed.as_ref().map_or_else(|e| format!("no: {e}"), |_| "yes".into());
        t.row([m.name.clone(), m.triangles.to_string(), closed, m.origins.to_string(), m.rejected_origins.to_string()]);
    }
    let _ = writeln!(s, "## Closed meshes\n\nEvery undirected edge in exactly two triangles with opposite orientation; origins proven inside by the f64 winding number on the rounded mesh.\n\n{}", t.to_markdown());
    for (name, tris, closed) in &report.real_scenes {
        let _ = writeln!(
            s,
            "- {name} ({tris} triangles): {}",
            closed.as_ref().map_or_else(
                |e| format!("not closed, not used for leaks: {e}"),
                |_| "proven closed, used for leaks".into()
            )
        );
    }
    let _ = writeln!(
        s,
        "\n## Leaks per 10^6 rays\n\nA leak is a ray from a proven-inside origin that hits nothing.\n\n{}",
        leaks_table(report).to_markdown()
    );
    if names_layouts(report) {
        let _ = writeln!(
            s,
            "## Leaks per node layout\n\nThe same leak rays traced with each layout's kernels (same leaves, \
             only the nodes and their traversal differ); every leaf size, mesh and kind together. A \
             watertight triangle test stays leak-free only if the layout's box test never culls a box the \
             ray touches (its conservative test).\n\n{}",
            layouts_table(report).to_markdown()
        );
        if let Some(w) = watertight_on_layouts(report) {
            let _ = writeln!(s, "{w}\n");
        }
    }
    let _ = writeln!(
        s,
        "## False hits\n\nRays aimed at points d x edge length outside silhouette edges, across the line of \
         sight (from a viewpoint outside), kept where the f64 reference misses; cells are GPU hits / rays.\n\n{}",
        false_hits_table(report).to_markdown()
    );
    let _ = writeln!(
        s,
        "## t and barycentric error against the f64 reference\n\nOver every leak ray where GPU and reference \
         hit the same triangle; t error in f32 ULPs of t_ref, barycentric error max(|du|, |dv|).\n\n{}",
        errors_table(report).to_markdown()
    );
    s
}

/// The self-intersection study: self-hits and escapes per scheme and scale.
fn self_hits_section(report: &AccuracyReport) -> String {
    let mut s = String::new();
    let rays = report.self_hits.iter().map(|r| r.rays).min().unwrap_or(0);
    let _ = writeln!(
        s,
        "## Self-intersection\n\nSecondary rays (cosine hemisphere, tmin = 0) from hit points reconstructed in \
         f32 from the barycentrics on an icosphere scaled by 10^k; at least {rays} rays per cell. Cells: rays \
         that hit the triangle they left (in parentheses, when more: rays that hit anything within 1e-4 of \
         the scene's extent). Recommended scheme: **{}** (`offset::RECOMMENDED`).\n\n{}",
        RECOMMENDED.name(),
        self_hits_table(report).to_markdown()
    );
    let inside = report.self_hits.iter().map(|r| r.inside_rays).min().unwrap_or(0);
    let _ = writeln!(
        s,
        "Escaped: of the secondary rays spawned on the inside of the closed icosphere (at least {inside} per \
         cell), those that hit nothing, so the offset moved the origin out through the surface.\n\n{}",
        escaped_table(report).to_markdown()
    );
    s
}

/// The extreme cases, a table per kind measured.
fn extremes_section(report: &AccuracyReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "## Extremes (leaf {FIXED_LEAF})\n");
    for (kind, what) in [
        ("scale", "Icosphere (closed) scaled by 10^k; leak rays (random, vertex, edge) must all hit."),
        ("translate", "Icosphere (closed) translated by 10^k x (1, 0.7, 0.3); leak rays must all hit."),
        ("grazing", "A 16 x 16 grid (rotated), rays at the given angle to its plane; the reference judges."),
        ("sliver", "A strip of 64 slivers (long edge 1, aspect ratio 10^k) covering a rectangle; rays aimed into it."),
        ("size", "A 4 x 4 grid scaled by 10^k (tiny and huge triangles), rays at 0.5 rad."),
        ("degenerate", "A grid with zero-area (collinear, repeated-index, repeated-position) triangles mixed in; rays aimed at them. They must never be hit."),
    ] {
        if report.extremes.iter().any(|r| r.kind == kind) {
            let _ = writeln!(s, "### {kind}\n\n{what}\n\n{}", extremes_table(report, kind).to_markdown());
        }
    }
    s
}

/// The frontier: speed against leaks, false hits and t error.
fn frontier_section(report: &AccuracyReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "## Frontier\n\nSpeed on {} bunny diffuse rays (leaf {FIXED_LEAF}) against leaks and false hits per 10^6 and \
         t error (leaf {FIXED_LEAF}, closed meshes).\n\n{}",
        report.frontier_rays,
        frontier_table(report).to_markdown()
    );
    s
}
