//! trilab on Debian 12's own lavapipe (Mesa 22.3.6, `mesa-vulkan-drivers` from bookworm, not
//! backports), unpacked beside the installed driver by `scripts/stock-mesa.sh` and chosen with
//! the loader's VK_DRIVER_FILES (the script's `env` file). What a user with only stock Mesa
//! meets: `devices` names the driver and what it lacks, a small `bench` runs and validates,
//! `driver-stats` refuses after one kernel naming why (that release build reads no
//! GALLIVM_DEBUG), the ray-query peer is refused naming the feature, and `suite --size 0`
//! completes with the profile's summary saying which sections this driver cannot measure.
//!
//! Each run has the validation layer on (the system's layer works with either driver) and a
//! wall-clock limit (tests/common/cli.rs). Without the unpacked driver these tests fail, saying
//! to run the script; they never skip.

mod common;

use common::cli::{expect_error, ok, run, s};
use common::unpacked::STOCK_MESA;

/// `trilab args` on the stock driver; panics past `timeout_s`.
fn on_stock(args: &[&str], timeout_s: u64) -> std::process::Output {
    STOCK_MESA.run(args, timeout_s)
}

#[test]
fn devices_names_mesa_22_3_6_and_what_it_lacks() {
    let text = STOCK_MESA.devices("Mesa 22.3.6");
    assert!(text.contains("ray query:                no"), "{text}");
    assert!(text.contains("pipeline executable info: no"), "{text}");
}

#[test]
fn a_small_bench_runs_and_validates() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(dir.path());
    let args = [
        "bench",
        "--scenes",
        "bunny",
        "--width",
        "48",
        "--height",
        "36",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "2000",
        "--repeat",
        "2",
        "--methods",
        "mt,quad-unit,watertight",
        "--ray-query",
        "on",
        "--out",
        &out,
    ];
    let err = ok(&on_stock(&args, 120));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("bench.json")).unwrap()).unwrap();
    assert_eq!(report["mesa_version"], "22.3.6", "{}", report["driver"]);
    let rows = report["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 9, "3 methods x 3 ray sets: {err}");
    // Asked for, the ray-query row is not faked: the report says the driver lacks it.
    let notes = report["driver_notes"].to_string();
    assert!(notes.contains("ray query: unsupported on"), "{notes}");
}

#[test]
fn driver_stats_refuses_naming_why() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ds");
    let (o, took) = {
        let vars = STOCK_MESA.env();
        let env: Vec<(&str, &str)> = vars.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
        run(&["driver-stats", "--out", &s(&out)], None, &env, 120)
    };
    expect_error(&o, &["not available on this driver", "Mesa 22.3.6", "GALLIVM_DEBUG"]);
    // Refused after the one-kernel probe, not after compiling all 64 variants.
    assert!(took.as_secs_f64() < 30.0, "took {took:?}");
    assert!(!out.exists(), "nothing is written for a refused command");
}

#[test]
fn the_ray_query_peer_is_refused_naming_the_feature() {
    let dir = tempfile::tempdir().unwrap();
    let rays = s(&dir.path().join("r.rays"));
    ok(&on_stock(&["rays", "random", "--scene", "cornell", "--random-rays", "64", "--out", &rays], 60));
    let hits = s(&dir.path().join("h.hits"));
    let o = on_stock(&["raycast", "--scene", "cornell", "--rays", &rays, "--out", &hits, "--peer", "ray-query"], 60);
    expect_error(&o, &["ray query: unsupported on", "Mesa 22.3.6"]);
}

#[test]
fn the_smoke_suite_completes_and_says_what_this_driver_cannot_measure() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("suite");
    let o = on_stock(&["suite", "--size", "0", "--no-threads", "--budget-minutes", "5", "--out", &s(&out)], 300);
    let err = ok(&o);
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap_or_else(|e| panic!("no summary.md: {e}\n{err}"));
    assert!(md.contains("Mesa 22.3.6"), "summary names the driver:\n{md}");
    assert!(!md.contains("did not complete"), "every part completes on 22.3.6:\n{md}");
    for section in [
        "## Speed (bench)",
        "## The paper's claims (study)",
        "## Speed and accuracy (accuracy)",
        "## Kernels (profile)",
    ] {
        assert!(md.contains(section), "summary lacks `{section}`:\n{md}");
    }
    let kernels = md.split("## Kernels (profile)").nth(1).unwrap();
    assert!(kernels.contains("Not measured on this driver"), "{kernels}");
    assert!(kernels.contains("- Driver statistics (unsupported): not available on this driver"), "{kernels}");
    assert!(kernels.contains("GALLIVM_DEBUG"), "{kernels}");
    let profile = std::fs::read_to_string(out.join("profile/profile.md")).unwrap();
    assert!(profile.contains("## 8. Driver statistics\n\nStatus: **unsupported**"), "{profile}");
}

#[test]
fn ab_of_the_stock_driver_against_the_installed_one_names_what_the_stock_one_lacks() {
    let vars = STOCK_MESA.env();
    let icd = vars.iter().find(|(k, _)| k == "VK_DRIVER_FILES").map(|(_, v)| v.clone()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ab");
    let args = [
        "ab",
        "--methods",
        "mt",
        "--sets",
        "primary",
        "--width",
        "64",
        "--height",
        "48",
        "--rounds",
        "2",
        "--max-rounds",
        "2",
        "--pathtrace",
        "--driver-stats",
        "--a-icd",
        &icd,
        "--out",
        &s(&out),
        "--json",
    ];
    // Side A is the stock driver; the test's own environment is the installed one (B).
    let (o, _) = run(&args, None, &[], 120);
    let err = common::cli::stderr(&o);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{err}");
    let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(r["a"]["provenance"]["mesa_version"], "22.3.6", "{r}");
    assert_ne!(r["b"]["provenance"]["mesa_version"], "22.3.6", "{r}");
    // The stock driver has no statistics: named, and no cell compared on them.
    let note = r["driver_stats"][0].as_str().unwrap();
    assert!(note.contains("GALLIVM_DEBUG") && note.contains("22.3.6"), "{note}");
    assert!(r["cells"].as_array().unwrap().iter().all(|c| c.get("compiled").is_none()), "{r}");
    let md = std::fs::read_to_string(out.join("ab.md")).unwrap();
    assert!(md.contains("side A has none"), "{md}");
    // Both drivers' hits and pixels were validated before their times counted.
    for c in r["cells"].as_array().unwrap() {
        assert_eq!((c["a"]["failed_rounds"].as_u64(), c["b"]["failed_rounds"].as_u64()), (Some(0), Some(0)), "{c}");
    }
}
