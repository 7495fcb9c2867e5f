//! `trilab driver-stats` and the profile's driver statistics on the device: lavapipe's machine
//! code per kernel (GALLIVM_DEBUG=asm in a re-executed child), as rows `trilab compare` reads.
//! Each run has the validation layer on (the child inherits TRILAB_VALIDATION) and a wall-clock
//! limit (tests/common/cli.rs); without a device the commands fail, and so do these tests.

mod common;

use std::collections::BTreeMap;

use common::cli::{expect_error, ok, run, s};
use trilab::rows::{self, Class, Row};

fn is_lavapipe() -> bool {
    let out = ok(&run(&["devices", "--json"], None, &[], 120).0);
    out.contains("MESA_LLVMPIPE")
}

/// The driver-stats rows of `dir/rows.jsonl`, by `method/layout`.
fn driver_rows(dir: &std::path::Path) -> BTreeMap<String, Row> {
    let set = rows::read(&dir.join(rows::FILE)).unwrap();
    set.rows
        .into_iter()
        .filter(|r| r.command == "driver-stats")
        .map(|r| (format!("{}/{}/{}", r.cell["method"], r.cell["layout"], r.cell["variant"]), r))
        .collect()
}

fn figure(r: &Row, name: &str) -> f64 {
    let f = &r.figures[name];
    assert_eq!(f.class, Class::Count, "{name} is a count");
    assert_eq!((f.min, f.max), (f.median, f.median), "{name}: a count is exact");
    f.median
}

#[test]
fn driver_stats_count_each_kernels_machine_code() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("ds"));
    let asm = s(&dir.path().join("asm"));
    let args = [
        "driver-stats",
        "--methods",
        "mt,quad-unit",
        "--layouts",
        "bvh2,cwbvh",
        "--variants",
        "closest,closest_address",
        "--out",
        &out,
        "--asm-dir",
        &asm,
    ];
    let (o, _) = run(&args, None, &[], 600);
    if !is_lavapipe() {
        // A driver without statistics is refused, naming why; one with them gives figures.
        if !o.status.success() {
            expect_error(&o, &["not available on this driver"]);
            return;
        }
        let rows = driver_rows(&dir.path().join("ds"));
        assert!(rows.values().all(|r| !r.figures.is_empty()));
        return;
    }
    ok(&o);
    let rows = driver_rows(&dir.path().join("ds"));
    assert_eq!(rows.len(), 8, "{:?}", rows.keys().collect::<Vec<_>>());
    for (k, r) in &rows {
        assert!(figure(r, "instructions") > 100.0, "{k}");
        assert_eq!(r.cell["kernel"], "raycast");
        assert!(r.source.device.contains("llvmpipe"));
        // The texel path reads the scene through llvmpipe's per-descriptor helpers; the
        // address path reads memory directly.
        let helpers = figure(r, "helper_calls");
        if k.ends_with("_address") {
            assert_eq!(helpers, 0.0, "{k}");
        } else {
            assert!(helpers > 0.0, "{k}");
        }
        assert!(figure(r, "calls") >= helpers);
    }
    let ins = |k: &str| figure(&rows[k], "instructions");
    assert_ne!(ins("mt/bvh2/closest"), ins("quad-unit/bvh2/closest"), "two intersectors compiled alike");
    assert_ne!(ins("mt/bvh2/closest"), ins("mt/cwbvh/closest"), "two layouts compiled alike");
    // Quad Unit tests four triangles per leaf slot: more texel fetches than Moller-Trumbore.
    assert!(figure(&rows["quad-unit/bvh2/closest"], "helper_calls") > figure(&rows["mt/bvh2/closest"], "helper_calls"));
    // The kept dump holds the kernel's functions, and its instruction lines add up to at least
    // the count (the dump also holds the descriptors' helper functions).
    let dump = std::fs::read_to_string(dir.path().join("asm/raycast.mt.closest.txt")).unwrap();
    assert!(dump.contains("\ncs_co_variant:\n"));
    let lines = dump.lines().filter(|l| l.starts_with(' ') && l.contains(":\t")).count() as f64;
    assert!(lines >= ins("mt/bvh2/closest"));
    let md = std::fs::read_to_string(dir.path().join("ds/driver-stats.md")).unwrap();
    assert!(md.contains("GALLIVM_DEBUG=asm") && md.contains("| raycast | closest | mt | bvh2 |"));
}

#[test]
fn profile_writes_timing_and_driver_statistics_rows() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("p"));
    let args = [
        "profile",
        "--scene",
        "cornell",
        "--methods",
        "mt,quad-unit",
        "--width",
        "32",
        "--height",
        "24",
        "--random-rays",
        "2000",
        "--repeat",
        "2",
        "--workgroup-sizes",
        "64",
        "--no-threads",
        "--out",
        &out,
    ];
    ok(&run(&args, None, &[], 600).0);
    let set = rows::read(&dir.path().join("p").join(rows::FILE)).unwrap();
    let timings: Vec<&Row> = set.rows.iter().filter(|r| r.command == "profile" && r.cell.len() == 6).collect();
    assert_eq!(timings.len(), 2 * 3, "two methods x three ray sets");
    for r in &timings {
        assert_eq!(r.figures["kernel_ms"].class, Class::Timing);
        assert_eq!(r.figures["kernel_ms"].runs, 2);
        assert!(r.figures["kernel_ms"].min <= r.figures["kernel_ms"].max);
        assert!(r.figures["agreement"].median >= trilab::commands::profile::MIN_AGREEMENT);
        assert_eq!(r.cell["layout"], "bvh2");
    }
    let md = std::fs::read_to_string(dir.path().join("p/profile.md")).unwrap();
    assert!(md.contains("## 8. Driver statistics"));
    let ds = driver_rows(&dir.path().join("p"));
    if !is_lavapipe() {
        assert!(md.contains("not available on this driver") || !ds.is_empty());
        return;
    }
    assert_eq!(ds.keys().collect::<Vec<_>>(), ["mt/bvh2/closest", "quad-unit/bvh2/closest"]);
    let (mt, quad) =
        (figure(&ds["mt/bvh2/closest"], "instructions"), figure(&ds["quad-unit/bvh2/closest"], "instructions"));
    assert!(mt > 100.0 && quad > 100.0 && mt != quad, "{mt} {quad}");
}
