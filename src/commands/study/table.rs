//! The study's tables: CSV (one row per scene x leaf size x method x layout, every figure with
//! its min/max and the row's provenance) and Markdown in the paper's table format (one table per
//! layout). With layouts other than bvh2 every other table gains a layout column.

use std::fmt::Write as _;

use super::claims;
use super::{cell, counts, layouts_of, names_layouts, scenes, StudyReport, StudyRow};
use crate::encoding::{Layout, Method};
use crate::error::Result;
use crate::report::Table;
use crate::services::plots::Plot;

use crate::named::Named;
use crate::services::rayset::RaySet;

const SETS: &[RaySet] = RaySet::ALL;

/// `study.csv`.
pub fn csv(report: &StudyReport) -> Result<String> {
    let mut header: Vec<String> = [
        "scene",
        "triangles",
        "leaf_size",
        "method",
        "layout",
        "scene_mb",
        "bvh_nodes",
        "sah_cost",
        "epo",
        "quad_padding",
        "render_s",
        "render_s_min",
        "render_s_max",
        "render_runs",
        "msamples_per_s",
        "render_mrays_per_s",
        "rays_per_sample",
        "image_mean",
    ]
    .map(String::from)
    .to_vec();
    for &s in SETS {
        for f in [
            "rays",
            "mrays_per_s",
            "mrays_per_s_min",
            "mrays_per_s_max",
            "agreement",
            "nodes_mean",
            "nodes_max",
            "triangles_mean",
            "triangles_max",
            "slots_mean",
            "boxes_mean",
        ] {
            header.push(format!("{s}_{f}"));
        }
    }
    header.extend(
        ["render_kernel", "raycast_kernel", "device", "driver", "mesa", "commit", "date", "timed_on_gpu"]
            .map(String::from),
    );
    let records = report.rows.iter().map(|r| {
        let s = r.render_seconds();
        let mut rec = vec![
            r.scene.clone(),
            r.triangles.to_string(),
            r.leaf_size.to_string(),
            r.method.to_string(),
            r.layout.to_string(),
            format!("{:.3}", r.scene_bytes as f64 / 1e6),
            r.bvh.nodes.to_string(),
            format!("{:.3}", r.bvh.sah_cost),
            if r.bvh.epo.is_finite() { format!("{:.4}", r.bvh.epo) } else { "-".into() },
            r.bvh.quad_padding.to_string(),
            format!("{:.5}", s.median),
            format!("{:.5}", s.min),
            format!("{:.5}", s.max),
            s.runs.to_string(),
            format!("{:.4}", r.render.msamples_per_s.median),
            format!("{:.4}", r.render.mrays_per_s.median),
            format!("{:.4}", r.render.rays_per_sample),
            format!("{:.6}", r.render.image_mean),
        ];
        for &set in SETS {
            match r.set(set) {
                Some(x) => rec.extend([
                    x.rays.to_string(),
                    format!("{:.4}", x.mrays_per_s.median),
                    format!("{:.4}", x.mrays_per_s.min),
                    format!("{:.4}", x.mrays_per_s.max),
                    format!("{:.7}", x.agreement),
                    format!("{:.3}", x.traversal.nodes.mean),
                    x.traversal.nodes.max.to_string(),
                    format!("{:.3}", x.traversal.triangles.mean),
                    x.traversal.triangles.max.to_string(),
                    format!("{:.3}", x.traversal.slots.mean),
                    format!("{:.3}", x.traversal.boxes.mean),
                ]),
                None => rec.extend(std::iter::repeat_n(String::new(), 11)),
            }
        }
        let p = &r.provenance;
        rec.extend([
            r.render_kernel.to_owned(),
            r.raycast_kernel.to_owned(),
            p.device.clone(),
            p.driver.clone(),
            p.mesa_version.clone().unwrap_or_default(),
            p.commit.clone(),
            p.date.clone(),
            p.timed_on_gpu.to_string(),
        ]);
        rec
    });
    crate::services::results::csv("study.csv", &header, records)
}

fn title(scene: &str) -> String {
    let mut c = scene.chars();
    c.next().map(|f| f.to_uppercase().collect::<String>() + c.as_str()).unwrap_or_default()
}

fn thousands(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, ch) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(ch);
    }
    out
}

/// The paper's table on `layout`: scene, triangles per leaf, GPU scene size, seconds per method.
pub fn paper_table(report: &StudyReport, layout: Layout) -> Table {
    let methods = &report.options.methods;
    let mut headers = vec!["Scene".to_owned(), "# Triangles per BVH leaf".into(), "GPU scene size, MB".into()];
    headers.extend(methods.iter().map(|m| format!("{}, s (min-max)", m.title())));
    let mut t = Table::new(headers);
    for scene in scenes(report) {
        for (i, &leaf) in report.options.leaf_sizes.iter().enumerate() {
            let rows: Vec<Option<&StudyRow>> = methods.iter().map(|&m| cell(report, &scene, leaf, m, layout)).collect();
            let Some(first) = rows.iter().flatten().next() else { continue };
            let label = if i == 0 {
                format!("{}, {} triangles", title(&scene), thousands(first.triangles))
            } else {
                String::new()
            };
            // The paper gives one size per row; ours differs per method, so all are listed.
            let sizes: Vec<String> = rows
                .iter()
                .map(|r| r.map(|r| format!("{:.2}", r.scene_bytes as f64 / 1e6)).unwrap_or("-".into()))
                .collect();
            let mut cells = vec![label, leaf.to_string(), sizes.join(" / ")];
            cells.extend(rows.iter().map(|r| match r {
                Some(r) => {
                    let s = r.render_seconds();
                    format!("{} ({}-{})", sig(s.median), sig(s.min), sig(s.max))
                }
                None => "-".into(),
            }));
            t.row(cells);
        }
    }
    t
}

/// Three significant figures, at least three decimals below 1.
fn sig(x: f64) -> String {
    if x >= 100.0 {
        format!("{x:.1}")
    } else if x >= 10.0 {
        format!("{x:.2}")
    } else {
        format!("{x:.3}")
    }
}

/// Mrays/s per ray set and for the path tracer's own rays.
pub fn rays_table(report: &StudyReport) -> Table {
    let mut t = Table::new(with_layout(
        report,
        3,
        [
            "scene",
            "leaf",
            "method",
            "primary Mrays/s",
            "diffuse Mrays/s",
            "random Mrays/s",
            "path-trace Mrays/s",
            "Msamples/s",
            "agree % (p/d/r)",
        ],
        None,
    ));
    for scene in scenes(report) {
        for &leaf in &report.options.leaf_sizes {
            for (m, l) in cells(report) {
                let Some(r) = cell(report, &scene, leaf, m, l) else { continue };
                let set = |s: RaySet| {
                    r.set(s)
                        .map(|x| {
                            format!("{:.2} ({:.2}-{:.2})", x.mrays_per_s.median, x.mrays_per_s.min, x.mrays_per_s.max)
                        })
                        .unwrap_or_else(|| "-".into())
                };
                let agree: Vec<String> = SETS
                    .iter()
                    .map(|&s| r.set(s).map(|x| format!("{:.3}", 100.0 * x.agreement)).unwrap_or("-".into()))
                    .collect();
                t.row(with_layout(
                    report,
                    3,
                    [
                        scene.clone(),
                        leaf.to_string(),
                        m.to_string(),
                        set(RaySet::Primary),
                        set(RaySet::Diffuse),
                        set(RaySet::Random),
                        format!("{:.2}", r.render.mrays_per_s.median),
                        format!("{:.3}", r.render.msamples_per_s.median),
                        agree.join(" / "),
                    ],
                    Some(l),
                ));
            }
        }
    }
    t
}

/// BVH quality per (scene, leaf size).
pub fn bvh_table(report: &StudyReport) -> Table {
    let mut t =
        Table::new(["scene", "leaf", "nodes", "leaves", "depth", "SAH cost", "EPO", "quad padding", "build ms"]);
    for scene in scenes(report) {
        for &leaf in &report.options.leaf_sizes {
            let Some(r) = report.rows.iter().find(|r| r.scene == scene && r.leaf_size == leaf) else { continue };
            let b = &r.bvh;
            t.row([
                scene.clone(),
                leaf.to_string(),
                b.nodes.to_string(),
                b.leaves.to_string(),
                b.depth.to_string(),
                format!("{:.2}", b.sah_cost),
                if b.epo.is_finite() { format!("{:.3}", b.epo) } else { "-".into() },
                b.quad_padding.to_string(),
                format!("{:.0}", b.build_ms),
            ]);
        }
    }
    t
}

/// Traversal work per ray from the statistics kernels: nodes visited and triangles tested
/// (mean, max) per ray set; the same for every method on one BVH and layout, except the slots a
/// Quad kernel evaluates (padding included), given for the Quad methods. With layouts other than
/// bvh2, one row per layout and the boxes slab-tested per ray beside them.
pub fn traversal_table(report: &StudyReport) -> Table {
    let named = names_layouts(report);
    let mut head: Vec<String> = ["scene", "leaf", "set", "nodes mean (max)", "triangles mean (max)", "Quad slots mean"]
        .map(String::from)
        .to_vec();
    if named {
        head.insert(2, "layout".into());
        head.push("boxes mean".into());
    }
    let mut t = Table::new(head);
    for scene in scenes(report) {
        for &leaf in &report.options.leaf_sizes {
            for l in layouts_of(report) {
                let rows: Vec<&StudyRow> =
                    report.rows.iter().filter(|r| r.scene == scene && r.leaf_size == leaf && r.layout == l).collect();
                let Some(first) = rows.first() else { continue };
                for &set in SETS {
                    let Some(x) = first.set(set) else { continue };
                    let quad = rows
                        .iter()
                        .find(|r| r.method.group_size() > 1)
                        .and_then(|r| r.set(set))
                        .map(|q| format!("{:.1}", q.traversal.slots.mean))
                        .unwrap_or_else(|| "-".into());
                    let tr = &x.traversal;
                    let mut cells = vec![
                        scene.clone(),
                        leaf.to_string(),
                        set.to_string(),
                        format!("{:.1} ({})", tr.nodes.mean, tr.nodes.max),
                        format!("{:.1} ({})", tr.triangles.mean, tr.triangles.max),
                        quad,
                    ];
                    if named {
                        cells.insert(2, l.to_string());
                        cells.push(format!("{:.1}", tr.boxes.mean));
                    }
                    t.row(cells);
                }
            }
        }
    }
    t
}

/// SPIR-V instruction counts of the kernels the study ran, beside their measured time at each
/// leaf size (geometric mean over scenes of time relative to Möller-Trumbore's on the same
/// layout).
pub fn spirv_table(report: &StudyReport) -> Table {
    let mut headers: Vec<String> = [
        "method",
        "path-trace kernel",
        "fn instr.",
        "arith",
        "mem",
        "image",
        "ctrl",
        "raycast fn instr.",
        "raycast image",
    ]
    .map(String::from)
    .to_vec();
    headers.extend(report.options.leaf_sizes.iter().map(|l| format!("time / MT, leaf {l}")));
    let mut t = Table::new(with_layout(report, 1, headers, None));
    for (m, l) in cells(report) {
        let Some(r) = report.rows.iter().find(|r| r.method == m && r.layout == l) else { continue };
        let pc = counts(r.render_kernel);
        let rc = counts(r.raycast_kernel);
        let mut cells = vec![
            m.to_string(),
            r.render_kernel.to_owned(),
            pc.functions.to_string(),
            pc.arithmetic.to_string(),
            pc.memory.to_string(),
            pc.image.to_string(),
            pc.control_flow.to_string(),
            rc.functions.to_string(),
            rc.image.to_string(),
        ];
        for &leaf in &report.options.leaf_sizes {
            cells.push(
                claims::relative_time(report, m, Method::Mt, leaf, l).map(|x| format!("{x:.3}")).unwrap_or("-".into()),
            );
        }
        t.row(with_layout(report, 1, cells, Some(l)));
    }
    t
}

/// `study.md`.
pub fn markdown(report: &StudyReport, plots: &[Plot]) -> String {
    let p = &report.provenance;
    let mut s = String::new();
    let _ = writeln!(s, "# trilab study ({:?} preset)\n", report.options.preset);
    if let Some(why) = &report.stopped {
        let _ = writeln!(s, "**Stopped early: {why}.** The tables hold the groups it finished.\n");
    }
    let _ = writeln!(s, "- device: {} ({})", p.device, p.driver);
    if let Some(m) = &p.mesa_version {
        let _ = writeln!(s, "- Mesa {m}");
    }
    let lp = p.lp_num_threads.as_deref().map(|n| format!(", LP_NUM_THREADS={n}")).unwrap_or_default();
    let _ = writeln!(s, "- host: {}{lp}", p.host.label());
    let _ = writeln!(s, "- commit {}, {}", p.commit, p.date);
    let _ = writeln!(s, "- workload: {}", report.scaling);
    let _ = writeln!(
        s,
        "- times: {}; the whole study took {:.0} s",
        if p.timed_on_gpu { "GPU timestamps" } else { "host wall clock (no timestamps on this queue)" },
        report.seconds
    );
    let _ = writeln!(
        s,
        "- every render validated (no NaN/Inf sample, image mean within 2 % of the scene's first render) and \
         every ray set validated against the f64 reference (>= 99.99 % agreement, every disagreement an edge, \
         vertex or tie case) before its time was kept\n"
    );
    let _ = writeln!(s, "## Path tracing, the paper's table format\n");
    let _ = writeln!(s, "GPU scene size lists each method's encoding ({}).\n", method_list(report));
    if names_layouts(report) {
        for l in layouts_of(report) {
            let _ = writeln!(s, "### {} (`{l}`): {}\n", l.title(), l.spec().about);
            s += &paper_table(report, l).to_markdown();
            s.push('\n');
        }
    } else {
        s += &paper_table(report, Layout::DEFAULT).to_markdown();
    }
    let _ = writeln!(s, "\n## Ray sets: Mrays/s, median (min-max)\n");
    s += &rays_table(report).to_markdown();
    let _ = writeln!(s, "\n## BVH quality\n");
    s += &bvh_table(report).to_markdown();
    let _ = writeln!(s, "\n## Traversal work per ray\n");
    let _ = writeln!(
        s,
        "Counted by each kernel's statistics variant (`raycast.<method>.stats`, same hits as the timed kernel): \
         nodes = inner-node plus leaf iterations of the traversal loop; triangles = real triangles tested; Quad \
         slots include padding.\n"
    );
    s += &traversal_table(report).to_markdown();
    let _ = writeln!(s, "\n## SPIR-V instructions against time\n");
    let _ = writeln!(
        s,
        "Function-body instruction counts of each method's kernels (`trilab spirv` lists every variant) \
         and its render time relative to Möller-Trumbore's (geometric mean over scenes; < 1 is faster).\n"
    );
    s += &spirv_table(report).to_markdown();
    s += &super::compiled::markdown(report);
    let _ = writeln!(s, "\n## The paper's claims on this device\n");
    s += &claims::markdown(report);
    if names_layouts(report) {
        let _ = writeln!(s, "\n## Does the best intersector, and the best leaf size, change with the layout?\n");
        s += &super::layouts::markdown(report);
    }
    if !plots.is_empty() {
        let _ = writeln!(s, "\n## Plots\n");
        for pl in plots {
            let file = pl.path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
            let _ = writeln!(s, "- [{}]({file})", pl.title);
        }
    }
    s
}

/// (method, layout) of every cell of a (scene, leaf size), in the order run.
fn cells(report: &StudyReport) -> Vec<(Method, Layout)> {
    let ls = layouts_of(report);
    report.options.methods.iter().flat_map(|&m| ls.iter().map(move |&l| (m, l))).collect()
}

/// `cells` with `layout`'s name inserted at `at` when the report names layouts (a header row
/// gets "layout").
fn with_layout<S: Into<String>>(
    report: &StudyReport,
    at: usize,
    cells: impl IntoIterator<Item = S>,
    layout: Option<Layout>,
) -> Vec<String> {
    let mut v: Vec<String> = cells.into_iter().map(Into::into).collect();
    if names_layouts(report) {
        v.insert(at, layout.map_or_else(|| "layout".to_owned(), |l| l.to_string()));
    }
    v
}

fn method_list(report: &StudyReport) -> String {
    report.options.methods.iter().map(|m| m.to_string()).collect::<Vec<_>>().join(" / ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::study::testing::synthetic;

    /// Layout-dependent times: bvh8 half of bvh2's, so a table that mixed them up shows it.
    fn t(_: &str, leaf: u32, m: Method, l: Layout) -> f64 {
        let base = 1.0 + 0.01 * leaf as f64 + if m == Method::Unit { 0.5 } else { 0.0 };
        if l == Layout::Bvh8 {
            base / 2.0
        } else {
            base
        }
    }

    #[test]
    fn one_paper_table_per_layout_each_with_its_own_times() {
        let r = synthetic(&["bunny"], &[Layout::Bvh2, Layout::Bvh8], t, 0.0);
        let cell = |l: Layout| paper_table(&r, l).to_markdown();
        // Leaf 4, MT: 1.04 s on bvh2, 0.52 s on bvh8.
        assert!(
            cell(Layout::Bvh2).contains("| 4 | 0.00 / 0.00 / 0.00 / 0.00 | 1.040 (1.040-1.040) |"),
            "{}",
            cell(Layout::Bvh2)
        );
        assert!(
            cell(Layout::Bvh8).contains("| 4 | 0.00 / 0.00 / 0.00 / 0.00 | 0.520 (0.520-0.520) |"),
            "{}",
            cell(Layout::Bvh8)
        );
        let md = markdown(&r, &[]);
        for needle in [
            "### BVH2 (`bvh2`)",
            "### BVH8 (`bvh8`)",
            "## Does the best intersector, and the best leaf size, change with the layout?",
            "| scene | leaf | method | layout | primary Mrays/s",
        ] {
            assert!(md.contains(needle), "study.md lacks `{needle}`:\n{md}");
        }
        // CSV: one row per cell, each naming its layout.
        let csv = csv(&r).unwrap();
        let layouts: Vec<&str> = csv.lines().skip(1).map(|l| l.split(',').nth(4).unwrap()).collect();
        assert_eq!(layouts.len(), 6 * 4 * 2);
        assert_eq!(layouts.iter().filter(|l| **l == "bvh8").count(), 6 * 4);
    }

    #[test]
    fn a_bvh2_study_names_no_layout_in_its_tables() {
        let r = synthetic(&["bunny"], &[Layout::Bvh2], t, 0.0);
        let md = markdown(&r, &[]);
        assert!(!md.contains("### BVH2") && !md.contains("change with the layout"), "{md}");
        assert!(md.contains("| scene | leaf | method | primary Mrays/s"), "{md}");
    }
}
