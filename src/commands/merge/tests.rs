//! The merge's unit tests: synthetic study reports of two devices merged, refused and written.

use std::path::PathBuf;

use super::*;
use crate::commands::study::claims;
use crate::commands::study::testing::synthetic;
use crate::commands::study::{self, StudyReport};
use crate::encoding::Layout;
use crate::encoding::Method;
use crate::error::Result;
use crate::report::Summary;
use crate::rows::{self, Cell, Figure, Plan, Row, Shard, Source};

/// The paper's shape (leaf 4 fastest, MT 3 % faster than unit, Quad unit 12 % faster than
/// MT) on "gpu-a", the contrary (leaf 16 fastest, unit faster, Quad unit slower) on "gpu-b".
fn report(device: &str, paper: bool) -> StudyReport {
    let t = move |_: &str, leaf: u32, m: Method, _: Layout| {
        let f = |mt: f64, unit: f64, quad_unit: f64| match m {
            Method::Mt => mt,
            Method::Unit => unit,
            Method::QuadUnit => quad_unit,
            _ => 1.0,
        };
        if paper {
            (1.0 + 0.05 * (leaf as f64 - 4.0).abs()) * f(1.0, 1.03, 1.0 / 1.12)
        } else {
            (20.0 - leaf as f64) * f(1.0, 0.9, 1.1)
        }
    };
    let mut r = synthetic(&["bunny", "dragon"], &[Layout::Bvh2], t, 0.001);
    r.provenance.device = device.into();
    r
}

/// The plan of a synthetic report (its options name no scene files): its rows' cells.
fn plan(r: &StudyReport, shard: Option<Shard>) -> Plan {
    Plan { shard, cells: study::rows(r).into_iter().map(|row| row.cell).collect(), ..study::plan(r) }
}

fn file(name: &str) -> PathBuf {
    PathBuf::from(format!("runs/{name}/rows.jsonl"))
}

fn merged(parts: &[(&str, &StudyReport, Option<Shard>)]) -> Result<MergeReport> {
    let mut rows = vec![];
    let mut plans = vec![];
    for (name, r, shard) in parts {
        rows.extend(study::rows(r).into_iter().map(|row| (row, file(name))));
        plans.push((plan(r, *shard), file(name)));
    }
    merge(vec![], parts.iter().map(|p| file(p.0)).collect(), rows, plans)
}

#[test]
fn claims_per_device_are_the_claims_of_a_study_report_of_the_same_numbers() {
    let (a, b) = (report("gpu-a", true), report("gpu-b", false));
    let m = merged(&[("a", &a, None), ("b", &b, None)]).unwrap();
    assert_eq!(m.devices.iter().map(|d| d.label.as_str()).collect::<Vec<_>>(), ["gpu-a", "gpu-b"]);
    assert_eq!(m.claims.len(), 2);
    for (d, r) in m.claims.iter().zip([&a, &b]) {
        let want = claims::all(r);
        assert_eq!(serde_json::to_value(&d.claims).unwrap(), serde_json::to_value(&want).unwrap(), "{}", d.device);
        assert_eq!((d.measured, d.planned, d.repeat), (r.rows.len(), r.rows.len(), 3));
    }
    // The paper's numbers hold on gpu-a, the contrary ones fail on gpu-b: one column each.
    let table = m.claims_table().to_markdown();
    assert!(table.contains("| (a) | holds | does not hold |"), "{table}");
    assert!(table.contains("| (c) | holds | does not hold |"), "{table}");
    assert!(m.missing.is_empty(), "{:?}", m.missing);
    // The speed table has every cell once with a figure for both devices.
    assert_eq!(m.speed.len(), a.rows.len());
    assert!(m.speed.iter().all(|r| r.figure == "render_s" && r.per_device.iter().all(Option::is_some)));
}

#[test]
fn a_cell_no_runner_of_a_device_measured_is_listed_and_its_claims_say_partial() {
    let a = report("gpu-a", true);
    let mut b = report("gpu-b", true);
    // gpu-b lost the cell (dragon, leaf 4, quad-unit).
    let lost = b.rows.iter().position(|r| r.scene == "dragon" && r.leaf_size == 4 && r.method == Method::QuadUnit);
    let lost = b.rows.remove(lost.unwrap());
    let mut m = merged(&[("a", &a, None), ("b", &b, None)]).unwrap();
    // gpu-b's own plan is taken from its rows here, so it lacks the cell: the cell is in
    // gpu-a's plan only.
    assert_eq!(m.missing.len(), 1, "{:?}", m.missing);
    let miss = &m.missing[0];
    assert_eq!((miss.device.as_str(), miss.planned_by_device), ("gpu-b", false));
    let dragon = [("layout", "bvh2"), ("leaf", "4"), ("method", "quad-unit"), ("scene", "dragon")];
    assert_eq!(miss.cell, rows::cell(dragon));
    // With gpu-b's full plan (its run planned the cell), the cell is missing from its own plan.
    let full = plan(&a, Some(Shard { index: 1, count: 2 }));
    let full = Plan { source: b.provenance.source(), ..full };
    let mut rows: Vec<(Row, PathBuf)> = study::rows(&a).into_iter().map(|r| (r, file("a"))).collect();
    rows.extend(study::rows(&b).into_iter().map(|r| (r, file("b"))));
    m = merge(vec![], vec![], rows, vec![(plan(&a, None), file("a")), (full, file("b"))]).unwrap();
    assert_eq!(m.missing.len(), 1);
    assert!(m.missing[0].planned_by_device);
    let md = m.markdown(&[]);
    assert!(md.contains("| gpu-b | study scene=dragon leaf=4 method=quad-unit layout=bvh2 | own plan |"), "{md}");
    assert!(md.contains("partial: 47 of 48 planned cells measured"), "{md}");
    // Its plan names shard 1/2; shard 2/2 never reported.
    let b_dev = m.devices.iter().find(|d| d.label == "gpu-b").unwrap();
    assert_eq!(b_dev.shards[0].missing, vec![Shard { index: 2, count: 2 }]);
    assert!(md.contains("study: 1/2 (missing 2/2)"), "{md}");
    assert!(m.speed.iter().any(|r| r.cell == lost_cell(&lost) && r.per_device[1].is_none()));
    assert!(md.contains("| missing |"), "{md}");
}

fn lost_cell(r: &study::StudyRow) -> Cell {
    r.cell().coordinates()
}

#[test]
fn a_cell_measured_twice_for_one_device_is_refused_naming_both_files() {
    let a = report("gpu-a", true);
    let e = merged(&[("a1", &a, None), ("a2", &a, None)]).unwrap_err().to_string();
    assert!(e.contains("measured twice") && e.contains("gpu-a"), "{e}");
    assert!(e.contains("runs/a1/rows.jsonl") && e.contains("runs/a2/rows.jsonl"), "{e}");
    assert!(e.contains("study scene=bunny leaf=1 method=mt"), "{e}");
    // The same numbers from another device are another column, not a duplicate.
    assert!(merged(&[("a", &a, None), ("b", &report("gpu-b", true), None)]).is_ok());
}

/// Two drivers that name their device alike (Debian's lavapipe 22.3.6 and 25.0.7 are both
/// "llvmpipe (LLVM 15.0.6, 256 bits)") are two columns, told apart by the driver; one
/// driver's runs stay one column.
#[test]
fn two_drivers_of_one_device_are_two_columns() {
    let mut new = report("llvmpipe", true);
    new.provenance.driver = "llvmpipe Mesa 25.0.7".into();
    let mut old = report("llvmpipe", false);
    old.provenance.driver = "llvmpipe Mesa 22.3.6".into();
    let m = merged(&[("new", &new, None), ("old", &old, None)]).unwrap();
    let labels: Vec<&str> = m.devices.iter().map(|d| d.label.as_str()).collect();
    assert_eq!(labels, ["llvmpipe, driver=llvmpipe Mesa 25.0.7", "llvmpipe, driver=llvmpipe Mesa 22.3.6"]);
    assert_eq!(m.claims_table().to_markdown().lines().next().map(|l| l.matches("driver=").count()), Some(2));
    // One driver twice is still a cell measured twice.
    let e = merged(&[("a", &new, None), ("b", &new, None)]).unwrap_err().to_string();
    assert!(e.contains("measured twice") && !e.contains("driver="), "{e}");
}

#[test]
fn one_device_at_two_driver_settings_is_two_columns() {
    let mut w8 = report("llvmpipe", true);
    w8.provenance.settings.insert("LP_NATIVE_VECTOR_WIDTH".into(), "256".into());
    // LP_NUM_THREADS changes speed but not the device a row belongs to.
    w8.provenance.settings.insert("LP_NUM_THREADS".into(), "2".into());
    let mut w4 = report("llvmpipe", false);
    w4.provenance.settings.insert("LP_NATIVE_VECTOR_WIDTH".into(), "128".into());
    let m = merged(&[("w8", &w8, None), ("w4", &w4, None)]).unwrap();
    let labels: Vec<&str> = m.devices.iter().map(|d| d.label.as_str()).collect();
    assert_eq!(labels, ["llvmpipe, LP_NATIVE_VECTOR_WIDTH=256", "llvmpipe, LP_NATIVE_VECTOR_WIDTH=128"]);
    assert_eq!(series_names(&m.devices), ["D1: WIDTH=256", "D2: WIDTH=128"]);
    // The width alone tells them apart; the subgroup size that follows it is left out.
    let mut both = m.devices.clone();
    for (d, sg) in both.iter_mut().zip(["8", "4"]) {
        d.settings.insert("subgroup_size".into(), sg.into());
    }
    assert_eq!(series_names(&both), ["D1: WIDTH=256", "D2: WIDTH=128"]);
    both[1].settings.insert("LP_NATIVE_VECTOR_WIDTH".into(), "256".into());
    // Equal widths: the subgroup size is what differs.
    assert_eq!(series_names(&both), ["D1: subgroup_size=8", "D2: subgroup_size=4"]);
    // Devices told apart by name only: the words that differ.
    let mut gpus = m.devices.clone();
    gpus[0].device = "NVIDIA GeForce RTX 4090".into();
    gpus[1].device = "NVIDIA GeForce RTX 3060".into();
    for d in &mut gpus {
        d.settings.clear();
    }
    assert_eq!(series_names(&gpus), ["D1: 4090", "D2: 3060"]);
    assert_eq!(series_names(&gpus[..1]), ["D1: NVIDIA GeForce RTX 4…"]);
}

#[test]
fn reads_each_file_once_and_writes_the_report_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (report("gpu-a", true), report("gpu-b", false));
    for (name, r) in [("a", &a), ("b/shard1", &b)] {
        let d = dir.path().join(name);
        std::fs::create_dir_all(&d).unwrap();
        rows::write(&d, Some(&plan(r, None)), &study::rows(r)).unwrap();
    }
    // b/ and b/shard1/ reach the same file: read once, not a duplicate.
    let inputs = [dir.path().join("a"), dir.path().join("b"), dir.path().join("b/shard1")];
    let m = run(&inputs).unwrap();
    assert_eq!(m.files.len(), 2);
    let out = dir.path().join("merged");
    let written = write(&m, &out).unwrap();
    for f in ["merge.md", "merge.json", "merge-time-vs-leaf-bunny.png", "merge-methods-vs-mt.png"] {
        assert!(written.contains(&out.join(f)), "{f} not in {written:?}");
    }
    let img = image::open(out.join("merge-time-vs-leaf-bunny.png")).unwrap();
    assert!(img.width() >= 4 * 640, "a panel per method");
    let md = std::fs::read_to_string(out.join("merge.md")).unwrap();
    assert!(md.contains("![") && md.contains("merge-methods-vs-mt.png"), "{md}");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("merge.json")).unwrap()).unwrap();
    assert_eq!(json["devices"].as_array().unwrap().len(), 2);
    // A folder without rows is refused by name.
    let empty = dir.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let e = run(std::slice::from_ref(&empty)).unwrap_err().to_string();
    assert!(e.contains("empty") && e.contains("rows.jsonl"), "{e}");
    // Rows files without a measured row (empty, or a plan only) are nothing to merge (issue
    // 24: an empty report and exit 0), refused naming the file, or each file.
    let (blank, planned) = (dir.path().join("blank"), dir.path().join("planned"));
    std::fs::create_dir_all(&blank).unwrap();
    std::fs::write(blank.join("rows.jsonl"), "").unwrap();
    std::fs::create_dir_all(&planned).unwrap();
    rows::write(&planned, Some(&plan(&a, None)), &[]).unwrap();
    let e = run(std::slice::from_ref(&blank)).unwrap_err().to_string();
    assert!(e.contains("blank/rows.jsonl") && e.contains("no measured row"), "{e}");
    let e = run(&[blank.clone(), planned.clone()]).unwrap_err().to_string();
    assert!(e.contains("blank/rows.jsonl") && e.contains("planned/rows.jsonl") && e.contains("nothing"), "{e}");
    // Beside a folder with rows they are merely empty.
    assert!(run(&[dir.path().join("a"), blank]).is_ok());
}

#[test]
fn headline_prefers_the_papers_metric() {
    let s = Source::default();
    let t = Figure::timing(Summary { median: 1.0, min: 1.0, max: 1.0, runs: 1 }, "s", rows::Better::Lower);
    let r1 = Row::new("x", Cell::new(), &s).with("zeta_ms", t.clone()).with("alpha_ms", t.clone());
    assert_eq!(headline([&r1]).as_deref(), Some("alpha_ms"));
    let r2 = Row::new("x", Cell::new(), &s).with("render_s", t.clone());
    assert_eq!(headline([&r1, &r2]).as_deref(), Some("render_s"));
    assert_eq!(
        cell_label(&rows::cell([("layout", "bvh2"), ("leaf", "4"), ("scene", "bunny"), ("x", "1")])),
        "scene=bunny leaf=4 layout=bvh2 x=1"
    );
}

/// Two Mesa builds' driver statistics of one chip merged (issue 50): each cell's subgroups
/// per SIMD side by side, the best by the figure's direction (higher), equal cells said.
#[test]
fn counts_of_two_driver_builds_name_the_better_by_direction() {
    let row = |build: &str, method: &str, subgroups: f64, vgprs: f64| {
        let mut src =
            Source { device: "Null hardware (RADV NAVI21)".into(), driver: "radv".into(), ..Source::default() };
        src.settings.insert(rows::DRIVER_BUILD.into(), build.into());
        let c = rows::cell([("kernel", "raycast"), ("method", method), ("chip", "navi21")]);
        (
            Row::new("driver-stats", c, &src)
                .with("subgroups_per_simd", Figure::count_toward(subgroups, "subgroups", rows::Better::Higher))
                .with("vgprs", Figure::count(vgprs, "registers")),
            PathBuf::from(format!("{build}/rows.jsonl")),
        )
    };
    let rows = vec![
        row("22.3.6", "mt", 20.0, 48.0),
        row("22.3.6", "quad-unit", 12.0, 80.0),
        row("25.0.7", "mt", 24.0, 40.0),
        row("25.0.7", "quad-unit", 12.0, 80.0),
    ];
    let r = merge(vec![], vec![], rows, vec![]).unwrap();
    assert_eq!(r.counts.len(), 2, "{:?}", r.counts);
    assert!(r.counts.iter().all(|c| c.figure == "subgroups_per_simd"));
    let mt = r.counts.iter().find(|c| c.cell.get("method").map(String::as_str) == Some("mt")).unwrap();
    assert_eq!(mt.best.len(), 1);
    assert!(mt.best[0].contains("25.0.7"), "{:?}", mt.best);
    let q = r.counts.iter().find(|c| c.cell.get("method").map(String::as_str) == Some("quad-unit")).unwrap();
    assert!(q.best.is_empty(), "equal: {:?}", q.best);
    let md = r.markdown(&[]);
    assert!(md.contains("## Counts per cell: `driver-stats`, `subgroups_per_simd`"), "{md}");
    assert!(md.contains("higher is better. Best: D2 in 1; equal in 1 of 2 cells."), "{md}");
}
