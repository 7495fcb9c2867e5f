//! `trilab ab` (issue 25): the same environment on both sides passes and calls no cell hurt
//! beyond the threshold (the CI check: smoke cells, under a minute); a planted slowdown of one
//! method's kernel on side B (`TRILAB_INJECT_SLOWDOWN`, every dispatch recorded 8 times) is
//! found in that method's cells only and fails the run; a side that cannot start is exit 2,
//! naming it. The optional parts: driver statistics equal on A against A and different where B
//! compiles for 128-bit vectors, compute-shader invocations counted on both sides, path-trace
//! cells with identical pixels, and `merge` reading the output. Every run has a wall-clock
//! limit and the validation layer on.

mod common;

use common::cli::s;
use serde_json::Value;

/// The smoke cells: the bunny, two methods, three small ray sets.
const SMOKE: &[&str] = &["ab", "--methods", "mt,unit", "--width", "96", "--height", "72", "--random-rays", "8000"];

/// The tests' runs one at a time: each is a timing, and two at once on a 2-core host would
/// time each other.
static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn ab(extra: &[&str], timeout_s: u64) -> (std::process::Output, Value) {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let args: Vec<&str> = [SMOKE, extra, &["--json"]].concat();
    let (o, _) = common::cli::run(&args, None, &[], timeout_s);
    let v = serde_json::from_slice(&o.stdout).unwrap_or(Value::Null);
    (o, v)
}

#[test]
fn a_against_a_passes_and_nothing_is_hurt_beyond_the_threshold() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab");
    // A threshold no A/A can cross unless the pairing is broken (a side's rounds credited to the
    // other, say): a test judges no timing on a shared host, where one small cell under load has
    // read 2.2 ms in one round and 4.7 ms in the next (how often ab cries wolf at its real
    // thresholds is measured, not tested: results/lavapipe/ab/sensitivity/, docs/gate.md).
    let (o, r) = ab(&["--rounds", "4", "--max-rounds", "8", "--threshold", "50", "--out", &s(&out)], 120);
    let e = common::cli::stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{e}\n{r}");
    let cells = r["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 6, "2 methods x 3 ray sets: {r}");
    for c in cells {
        assert_ne!(c["verdict"], "hurt-beyond-threshold", "{c}");
        // The same driver traces the same rays to the same hits, all validated.
        assert_eq!(c["rays_differing"], 0, "{c}");
        assert_eq!(c["correctness_worse"], false, "{c}");
        assert!(c["a"]["ms"].as_array().unwrap().len() >= 4, "{c}");
        assert_eq!(c["a"]["unexplained"], 0, "{c}");
    }
    assert_eq!(r["a"]["provenance"]["driver"], r["b"]["provenance"]["driver"]);
    // The files `merge` and `compare` read: both sides' bench rows and the ratios.
    let rows = std::fs::read_to_string(out.join("rows.jsonl")).unwrap();
    assert_eq!(rows.lines().filter(|l| l.contains("\"command\":\"ab\"")).count(), 6, "{rows}");
    for side in ["a", "b"] {
        let rows = std::fs::read_to_string(out.join(side).join("rows.jsonl")).unwrap();
        assert_eq!(rows.lines().filter(|l| l.contains("\"command\":\"bench\"")).count(), 6, "{rows}");
    }
    // `compare` reads the two sides as two runs of one binary on one host.
    let (o, _) = common::cli::run(&["compare", &s(&out.join("a")), &s(&out.join("b"))], None, &[], 60);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(matches!(o.status.code(), Some(0 | 1)) && text.contains("bench"), "{text}{}", common::cli::stderr(&o));
    assert!(std::fs::read_to_string(out.join("ab.md")).unwrap().contains("totals:"));
    // A side's cells are bench's: `compare` matches a `trilab bench` run of the same workload
    // with side A cell for cell.
    let bench = dir.path().join("bench");
    std::fs::create_dir(&bench).unwrap();
    let args = [
        "bench",
        "--scenes",
        "bunny",
        "--methods",
        "mt,unit",
        "--width",
        "96",
        "--height",
        "72",
        "--random-rays",
        "8000",
        "--diffuse-per-hit",
        "2",
        "--seed",
        "7",
        "--leaf-size",
        "4",
        "--repeat",
        "1",
        "--out",
        &s(&bench),
    ];
    let (o, _) = common::cli::run(&args, None, &[], 120);
    assert_eq!(o.status.code(), Some(0), "{}", common::cli::stderr(&o));
    let (o, _) = common::cli::run(&["compare", &s(&bench), &s(&out.join("a")), "--json"], None, &[], 60);
    let c: Value = serde_json::from_slice(&o.stdout).unwrap_or(Value::Null);
    let t = &c["totals"];
    assert_eq!((t["cells_compared"].as_u64(), t["only_in_base"].as_array().map(Vec::len)), (Some(6), Some(0)), "{c}");
    assert_eq!(t["only_in_new"].as_array().map(Vec::len), Some(0), "{c}");
}

#[test]
fn a_planted_slowdown_is_found_in_its_cells_and_fails_the_run() {
    // Every mt dispatch recorded 8 times on side B: far beyond any host's noise. The verdict is
    // judged per kernel over its three cells at a 100 % threshold (hurt only when the whole
    // interval is past 2x): on a host with ten times more work than cores (the soak of issue 40
    // ran beside four builds), one cell's 95 % interval from 4 rounds has spanned 0.9x-50x and an
    // unchanged kernel's 1.4x-1.9x, so a per-cell verdict at 5 % judged the host, not the kernel.
    let (o, r) = ab(
        &[
            "--rounds",
            "4",
            "--max-rounds",
            "4",
            "--judge",
            "kernels",
            "--threshold",
            "100",
            "--b-env",
            "TRILAB_INJECT_SLOWDOWN=.mt.:8",
        ],
        120,
    );
    let e = common::cli::stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}\n{r}");
    let kernels = r["kernels"].as_array().unwrap();
    assert_eq!(kernels.len(), 2, "{r}");
    for k in kernels {
        let hurt = k["verdict"] == "hurt-beyond-threshold";
        assert_eq!(hurt, k["method"] == "mt", "only the slowed kernel is hurt: {k}");
    }
    for c in r["cells"].as_array().unwrap().iter().filter(|c| c["cell"]["method"] == "mt") {
        // 8 recorded dispatches for one: the ratio of medians is near 8, and never below 3 (a
        // recorded dispatch lost) nor past 40 (one counted many more times).
        let ratio = c["ratio"]["ratio"].as_f64().unwrap();
        assert!((3.0..40.0).contains(&ratio), "every dispatch recorded 8 times: B/A {ratio}: {c}");
    }
}

#[test]
fn sides_that_cannot_be_compared_are_exit_2_naming_why() {
    let (o, _) = ab(&["--b-icd", "/nonexistent/icd.json"], 60);
    assert_eq!(o.status.code(), Some(2));
    common::cli::expect_error(&o, &["--b-icd", "/nonexistent/icd.json"]);
    // A driver file that names no driver: the loader finds no device for side B.
    let dir = tempfile::tempdir().unwrap();
    let icd = dir.path().join("none.json");
    std::fs::write(&icd, r#"{"file_format_version": "1.0.0", "ICD": {"library_path": "/nonexistent/libvulkan_none.so", "api_version": "1.3.0"}}"#).unwrap();
    let (o, _) = ab(&["--b-icd", &s(&icd)], 60);
    assert_eq!(o.status.code(), Some(2), "{}", common::cli::stderr(&o));
    common::cli::expect_error(&o, &["side B"]);
}

#[test]
fn driver_statistics_invocations_and_a_path_trace_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab");
    let optional = ["--rounds", "2", "--max-rounds", "2", "--pathtrace", "--pipeline-stats", "--driver-stats"];
    let (o, r) = ab(&[&optional[..], &["--out", &s(&out)]].concat(), 180);
    // Two rounds a side say little about time: it is shown, not judged, and the run says so
    // (issue 39). What this test holds is everything else.
    let err = common::cli::stderr(&o);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{err}\n{r}");
    assert!(err.contains("--max-rounds 2: fewer than 4 rounds a side"), "{err}");
    let cells = r["cells"].as_array().unwrap();
    assert!(cells.iter().all(|c| c["verdict"] == "too-few-rounds" || c["ratio"].is_null()), "{r}");
    assert_eq!(cells.len(), 8, "2 methods x (3 ray sets + a path trace): {r}");
    for c in cells {
        assert_eq!(c["correctness_worse"], false, "{c}");
        let rays = c["cell"]["rays"].as_u64().unwrap();
        match c["cell"]["kind"].as_str().unwrap() {
            "raycast" => {
                // The same driver compiles the same code: every statistic equal, none missing.
                assert_eq!(c["compiled"], serde_json::json!([]), "{c}");
                let [a, b] = [&c["invocations"][0], &c["invocations"][1]].map(|v| v.as_u64().unwrap());
                assert_eq!(a, b, "{c}");
                // One invocation a ray, rounded up to whole workgroups (at most 1024 lanes).
                assert!(a >= rays && a < rays + 1024, "{rays} rays, {a} invocations: {c}");
            }
            "pathtrace" => {
                assert_eq!(c["cell"]["set"], "pathtrace");
                assert_eq!(c["rays_differing"], 0, "the same driver renders the same pixels: {c}");
                assert_eq!((c["a"]["invalid"].as_u64(), c["a"]["agree"].as_u64()), (Some(0), Some(rays)), "{c}");
                assert!(c["a"]["ms"].as_array().unwrap().len() == 2, "{c}");
            }
            other => panic!("cell kind {other}: {c}"),
        }
    }
    // Each side's rows hold its bench, bench-render and driver-stats rows, and `merge` reads
    // the folder (the two sides' rows are apart by their `ab_side` setting).
    let rows = std::fs::read_to_string(out.join("b").join("rows.jsonl")).unwrap();
    for (command, n) in [("bench", 6), ("bench-render", 2), ("driver-stats", 2)] {
        let count = rows.lines().filter(|l| l.contains(&format!("\"command\":\"{command}\""))).count();
        assert_eq!(count, n, "{command} rows in b/rows.jsonl:\n{rows}");
    }
    let merged = dir.path().join("merged");
    let (o, _) = common::cli::run(&["merge", &s(&out), "--out", &s(&merged)], None, &[], 60);
    assert_eq!(o.status.code(), Some(0), "{}", common::cli::stderr(&o));
    let md = std::fs::read_to_string(merged.join("merge.md")).unwrap();
    assert!(md.contains("ab_side=A") && md.contains("ab_side=B") && md.contains("bench-render"), "{md}");

    // B compiles for another SIMD width than A: the same kernels, other machine code, named per
    // kernel. 128 bits, or 256 where A already runs 4 lanes (a CPU without AVX, or the matrix's
    // GALLIUM_OVERRIDE_CPU_CAPS=sse4.1): the test holds what the width changes, on any host.
    let devices = common::cli::trilab(&["devices", "--json"], 60);
    let lanes = serde_json::from_slice::<Value>(&devices.stdout).unwrap()[0]["subgroup_size"].as_u64().unwrap();
    let b_width = format!("LP_NATIVE_VECTOR_WIDTH={}", if lanes == 4 { 256 } else { 128 });
    let out = dir.path().join("width");
    let (o, r) = ab(&[&optional[..], &["--b-env", &b_width, "--out", &s(&out)]].concat(), 180);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}\n{r}", common::cli::stderr(&o));
    let changed: Vec<&Value> = r["cells"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["compiled"].as_array().is_some_and(|v| v.iter().any(|f| f["figure"] == "instructions")))
        .collect();
    assert_eq!(changed.len(), 6, "every ray-casting cell's kernel compiles to other code: {r}");
    let text = std::fs::read_to_string(out.join("ab.md")).unwrap();
    assert!(text.contains("raycast.mt.closest: ") && text.contains("2 kernels compared, 2 changed"), "{text}");
}

#[test]
fn another_build_on_side_a_reads_the_scenes_the_parent_resolved_and_kernels_are_judged_over_their_cells() {
    // A copy of this executable in a folder with no `scenes/` near it, as the gate keeps its
    // base build: the parent resolves `cornell` and gives both sides the same file.
    let dir = tempfile::tempdir().unwrap();
    let bin = dir.path().join("base/bin/trilab");
    std::fs::create_dir_all(bin.parent().unwrap()).unwrap();
    std::fs::copy(env!("CARGO_BIN_EXE_trilab"), &bin).unwrap();
    // The threshold no A/A can cross (as in the A/A test): what is tested is the scenes and the
    // judging over cells, not this host's noise.
    let extra = [
        "--a-bin",
        &s(&bin),
        "--scenes",
        "cornell",
        "--rounds",
        "4",
        "--max-rounds",
        "4",
        "--judge",
        "kernels",
        "--threshold",
        "50",
    ];
    let (o, r) = ab(&extra, 120);
    assert_eq!(o.status.code(), Some(0), "{}\n{r}", common::cli::stderr(&o));
    assert_eq!(r["a"]["exe"], s(&bin), "{}", r["a"]);
    assert_eq!(r["a"]["protocol"], r["b"]["protocol"]);
    let workload: Vec<&str> = r["workload"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
    let scene = workload[workload.iter().position(|a| *a == "--scenes").unwrap() + 1];
    assert!(std::path::Path::new(scene).is_absolute() && scene.ends_with("scenes/cornell.obj"), "{workload:?}");
    // Two kernels (mt, unit), each over its three ray sets, judged as kernels.
    assert_eq!(r["judge"], "kernels");
    let kernels = r["kernels"].as_array().unwrap();
    let names: Vec<&str> = kernels.iter().map(|k| k["kernel"].as_str().unwrap()).collect();
    assert_eq!(names, ["raycast mt bvh2", "raycast unit bvh2"], "{r}");
    assert!(kernels.iter().all(|k| k["cells"] == 3 && k["ratio"]["rounds_a"] == 4), "{r}");
    assert!(r["cells"].as_array().unwrap().iter().all(|c| c["rays_differing"] == 0), "{r}");
    // A build that is not there: refused before any work, naming the option.
    let (o, _) = ab(&["--b-bin", "/nonexistent/trilab"], 60);
    assert_eq!(o.status.code(), Some(2));
    common::cli::expect_error(&o, &["--b-bin", "/nonexistent/trilab", "no such file"]);
}

/// `--b-layout`: side B runs another layout of the same build in A's cells, so two kernels get
/// ab's paired interval. qbvh4 is bvh4's tree with conservative boxes, so every hit is the same
/// ray for ray; each cell names the kernel B ran, B's side names its layout, and each side's
/// driver statistics are of its own kernel. A workload of two layouts is refused before any side
/// starts.
#[test]
fn side_b_runs_another_layout_in_side_a_cells() {
    let args =
        ["--layouts", "bvh4", "--b-layout", "qbvh4", "--sets", "primary,random", "--driver-stats", "--pathtrace"];
    let (o, r) = ab(&args, 300);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", common::cli::stderr(&o));
    let cells = r["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 6, "mt and unit on the bunny's two sets and its path trace: {r}");
    for c in cells {
        assert_eq!(c["cell"]["layout"], "bvh4", "named by A's layout: {c}");
        assert!(c["cell"]["kernel"].as_str().unwrap().ends_with("_qbvh4"), "{c}");
        // qbvh4 is bvh4's tree with boxes rounded outwards: the same hits, so the same pixels.
        assert_eq!(c["rays_differing"], 0, "{c}");
        assert_eq!(c["a"]["agree"], c["cell"]["rays"], "{c}");
        assert_eq!(c["b"]["agree"], c["cell"]["rays"], "{c}");
        assert!(c["ratio"]["ratio"].as_f64().unwrap() > 0.0, "{c}");
        if c["cell"]["kind"] == "pathtrace" {
            continue;
        }
        // Each side's compiled kernel is its own: qbvh4's node is 4 texel fetches, bvh4's 8.
        let calls = c["compiled"].as_array().unwrap().iter().find(|f| f["figure"] == "helper_calls").unwrap();
        assert_eq!(calls["a"].as_f64().unwrap() - calls["b"].as_f64().unwrap(), 4.0, "{c}");
    }
    assert_eq!(cells.iter().filter(|c| c["cell"]["kind"] == "pathtrace").count(), 2, "{r}");
    assert_eq!(r["b"]["given"]["layout"], "qbvh4", "{}", r["b"]);
    assert!(r["a"]["given"]["layout"].is_null(), "{}", r["a"]);
    let (o, _) = ab(&["--layouts", "bvh2,bvh4", "--b-layout", "qbvh4"], 60);
    assert_eq!(o.status.code(), Some(2));
    common::cli::expect_error(&o, &["--b-layout qbvh4", "one layout"]);
}
