//! trilab on SwiftShader, Google's Vulkan driver (its own JIT, Subzero; not Mesa), unpacked from
//! Debian 12's `chromium-common` beside lavapipe by `scripts/swiftshader.sh` and chosen with the
//! loader's VK_DRIVER_FILES (the script's `env` file). What it offers and what it lacks, named by
//! `devices`; a small bench on a scene that fits its texel buffers, every ray checked against the
//! f64 reference; the provenance naming the package the driver came from (issue 38, first step:
//! what SwiftShader cannot run is not yet left out by name).
//!
//! Each run has the validation layer on and a wall-clock limit (tests/common/cli.rs). Without the
//! unpacked driver these tests fail, saying to run the script; they never skip.

mod common;

use common::cli::ok;
use common::unpacked::SWIFTSHADER;
use serde_json::Value;

fn on_swiftshader(args: &[&str], timeout_s: u64) -> std::process::Output {
    SWIFTSHADER.run(args, timeout_s)
}

#[test]
fn devices_names_swiftshader_and_what_it_lacks() {
    let o = on_swiftshader(&["devices"], 60);
    let err = ok(&o);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(text.contains("SwiftShader Device"), "not SwiftShader:\n{text}\n{err}");
    assert!(text.contains("GOOGLE_SWIFTSHADER"), "{text}");
    assert!(text.contains("shaderFloat64/Int64:      no/no"), "{text}");
    assert!(text.contains("maxTexelBufferElements:   65536"), "{text}");
    assert!(text.contains("subgroup size:            4"), "{text}");
}

#[test]
fn a_small_bench_on_a_scene_within_its_texel_limit_agrees_with_the_reference_and_names_the_package() {
    // 2,000 triangles fit SwiftShader's 65,536 texels (the bunny does not, and its address path
    // needs 64-bit integers SwiftShader lacks: issue 38).
    let args = [
        "bench",
        "--scenes",
        "synth:soup:2000",
        "--methods",
        "mt,unit,quad-unit,watertight",
        "--width",
        "48",
        "--height",
        "36",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "2000",
        "--json",
    ];
    let o = on_swiftshader(&args, 300);
    let err = ok(&o);
    let v: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {err}"));
    let rows = v["rows"].as_array().unwrap_or_else(|| panic!("no rows: {v}"));
    assert_eq!(rows.len(), 4 * 3, "4 methods x 3 ray sets: {v}");
    for r in rows {
        assert_eq!(r["agreement"].as_f64(), Some(1.0), "every ray agrees with the f64 reference: {r}");
    }
    assert!(v.to_string().contains("SwiftShader"), "{v}");
    let version = std::fs::read_to_string(SWIFTSHADER.dir().join("version")).unwrap();
    assert_eq!(v["driver_package"].as_str(), Some(version.trim()), "the provenance names the package: {v}");
}
