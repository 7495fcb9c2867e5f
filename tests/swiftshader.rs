//! trilab on SwiftShader, Google's Vulkan driver (its own JIT, Subzero; not Mesa), unpacked from
//! Debian 12's `chromium-common` beside lavapipe by `scripts/swiftshader.sh` and chosen with the
//! loader's VK_DRIVER_FILES (the script's `env` file). Issue 38: what it offers and what it
//! cannot run, named by `devices` (`gpu::Capabilities`); a bench on both of its scene paths,
//! every ray checked against the f64 reference, the provenance naming the package; the bunny,
//! beyond its 65,536 texels and without 64-bit integers, through storage buffers; what it cannot
//! run left out by name while the rest runs; the path tracer's image against lavapipe's; and the
//! suite's smoke run (bench, study, accuracy, profile, driver statistics' reason) end to end.
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
    let text = SWIFTSHADER.devices("SwiftShader Device");
    assert!(text.contains("GOOGLE_SWIFTSHADER"), "{text}");
    assert!(text.contains("shaderFloat64/Int64:      no/no"), "{text}");
    assert!(text.contains("maxTexelBufferElements:   65536"), "{text}");
    assert!(text.contains("subgroup size:            4"), "{text}");
    // What it cannot run, and why (gpu::Capabilities): one line each.
    for want in [
        "cannot run method f64: its kernels need shaderFloat64 (SPIR-V capability Float64), not enabled\n",
        "cannot run access address: shaderInt64",
        "cannot run peer ray-query: unsupported\n",
        "cannot run shader clock:",
        "cannot run pipeline statistics:",
        "cannot run thread count (LP_NUM_THREADS): a lavapipe setting, not read",
    ] {
        assert!(text.contains(want), "`{want}` missing:\n{text}");
    }
    for runs in ["method mt", "access storage", "access texel", "traversal coop"] {
        assert!(!text.contains(&format!("cannot run {runs}:")), "{runs}:\n{text}");
    }
}

#[test]
fn a_small_bench_on_a_scene_within_its_texel_limit_agrees_with_the_reference_and_names_the_package() {
    // 2,000 triangles fit SwiftShader's 65,536 texels: both of its paths, texel and storage.
    let args = [
        "bench",
        "--scenes",
        "synth:soup:2000",
        "--methods",
        "mt,unit,quad-unit,watertight",
        "--scene-access",
        "texel,storage",
        "--width",
        "48",
        "--height",
        "36",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "2000",
    ];
    let v = SWIFTSHADER.json(&args, 300);
    let rows = v["rows"].as_array().unwrap_or_else(|| panic!("no rows: {v}"));
    assert_eq!(rows.len(), 4 * 2 * 3, "4 methods x 2 paths x 3 ray sets: {v}");
    for r in rows {
        assert_eq!(r["agreement"].as_f64(), Some(1.0), "every ray agrees with the f64 reference: {r}");
    }
    assert!(v.to_string().contains("SwiftShader"), "{v}");
    let version = std::fs::read_to_string(SWIFTSHADER.dir().join("version")).unwrap();
    assert_eq!(v["driver_package"].as_str(), Some(version.trim()), "the provenance names the package: {v}");
}

/// The bunny (69,451 triangles) is beyond SwiftShader's 65,536 texels, and the address path needs
/// shaderInt64: `auto` reads it through storage buffers (SwiftShader's fastest path, so its
/// preferred one). What SwiftShader cannot run is left out with its reason and the rest runs; a
/// run of nothing it can run is refused.
#[test]
fn the_bunny_runs_through_storage_buffers_and_what_cannot_run_is_left_out_by_name() {
    let args = [
        "bench",
        "--methods",
        "mt,f64,unit",
        "--scene-access",
        "auto,address",
        "--traversals",
        "while-if,coop",
        "--width",
        "40",
        "--height",
        "30",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "1000",
        "--repeat",
        "1",
    ];
    let v = SWIFTSHADER.json(&args, 300);
    let rows = v["rows"].as_array().unwrap_or_else(|| panic!("no rows: {v}"));
    // mt and unit, while-if, three sets. SwiftShader has coop's subgroup operations, but the
    // bunny needs the storage path here, where coop has no kernel: left out, named.
    assert_eq!(rows.len(), 2 * 3, "{v}");
    for r in rows {
        assert_eq!(r["scene_access"], "storage", "{r}");
        assert_eq!(r["unexplained_disagreements"], 0, "{r}");
        assert_eq!(r["invalid"], 0, "{r}");
        assert!(r["agreement"].as_f64().unwrap() > 0.999, "{r}");
    }
    let notes = v["notes"].to_string();
    assert!(notes.contains("method f64: its kernels need shaderFloat64"), "{notes}");
    assert!(notes.contains("--scene-access address: shaderInt64"), "{notes}");
    assert!(notes.contains("the coop traversal on bvh2 has no kernel on the storage path"), "{notes}");
    // Nothing asked for can run: refused before any work, every reason named.
    let o = on_swiftshader(&["bench", "--methods", "f64", "--random-rays", "100"], 60);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("none of the methods asked for can run on SwiftShader") && err.contains("shaderFloat64"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

fn exr_luminance(path: &std::path::Path) -> Vec<f64> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![0f64; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<f64>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = 0.2126 * f64::from(r) + 0.7152 * f64::from(g) + 0.0722 * f64::from(b)
        },
    )
    .unwrap();
    image.layer_data.channel_data.pixels.1
}

/// The path tracer on SwiftShader (storage buffers: the bunny is beyond its texel buffers) makes
/// lavapipe's image (texel buffers): the same sample sequence on the same tree, so every pixel
/// agrees to a small tolerance (a different JIT may round an operation differently and send a
/// path elsewhere, so not bit for bit), and the mean within 0.5 %.
#[test]
fn the_path_tracer_on_swiftshader_makes_lavapipes_image() {
    let dir = tempfile::tempdir().unwrap();
    let args = |out: &std::path::Path| {
        let out = out.to_str().unwrap().to_owned();
        ["render", "--scene", "bunny", "--width", "40", "--height", "30", "--spp", "16", "--json", "--out"]
            .iter()
            .map(|s| s.to_string())
            .chain([out])
            .collect::<Vec<String>>()
    };
    let (lp, ss) = (dir.path().join("lavapipe.exr"), dir.path().join("swiftshader.exr"));
    let a = args(&lp);
    let a: Vec<&str> = a.iter().map(String::as_str).collect();
    let o = common::cli::run(&a, None, &[], 300).0;
    let lavapipe: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", ok(&o)));
    let b = args(&ss);
    let b: Vec<&str> = b.iter().map(String::as_str).collect();
    let o = on_swiftshader(&b, 300);
    let swiftshader: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}: {}", ok(&o)));
    assert_eq!(swiftshader["kernel"], "pathtrace.mt.all_storage", "{swiftshader}");
    assert!(swiftshader["device"].as_str().unwrap().contains("SwiftShader"), "{swiftshader}");
    assert!(lavapipe["device"].as_str().unwrap().contains("llvmpipe"), "{lavapipe}");
    let (x, y) = (exr_luminance(&lp), exr_luminance(&ss));
    assert_eq!(x.len(), 40 * 30);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (mx, my) = (mean(&x), mean(&y));
    assert!(mx > 0.0 && ((my - mx) / mx).abs() < 0.005, "image means: lavapipe {mx}, SwiftShader {my}");
    let same = x.iter().zip(&y).filter(|(a, b)| (*a - *b).abs() <= 1e-3 * a.abs().max(1e-3)).count();
    assert!(same as f64 >= 0.95 * x.len() as f64, "{same} of {} pixels agree", x.len());
}

/// The suite's smoke run on SwiftShader, end to end: every part validated, the study's claims
/// judged, and driver statistics' reason given instead of a failure.
#[test]
fn the_suite_smoke_run_completes_on_swiftshader() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("suite");
    let o = on_swiftshader(&["suite", "--size", "0", "--out", out.to_str().unwrap()], 600);
    ok(&o);
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(summary.contains("# trilab suite: SwiftShader Device (Subzero)"), "{summary}");
    for part in ["bench", "study", "accuracy", "profile"] {
        assert!(out.join(part).join("rows.jsonl").is_file(), "{part} wrote no rows");
    }
    let profile = std::fs::read_to_string(out.join("profile/profile.md")).unwrap();
    assert!(profile.contains("machine code (GALLIVM_DEBUG=asm): printed only by lavapipe, not"), "{profile}");
}

/// Issue 53: packets and the hybrid at SwiftShader's 4 lanes (its own JIT, not Mesa's), on both
/// of its scene paths where they have kernels: every ray of every set passes the f64 check, and
/// each hybrid row says how many rays left the packet.
#[test]
fn packets_and_the_hybrid_pass_the_f64_check_at_four_lanes() {
    let args = [
        "bench",
        "--scenes",
        "synth:soup:2000",
        "--methods",
        "mt,unit",
        "--layouts",
        "bvh2,bvh4",
        "--traversals",
        "packet,hybrid",
        "--scene-access",
        "texel,storage",
        "--width",
        "48",
        "--height",
        "36",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "2000",
        "--repeat",
        "1",
    ];
    let v = SWIFTSHADER.json(&args, 300);
    assert_eq!(v["settings"]["subgroup_size"], "4", "{}", v["settings"]);
    let rows = v["rows"].as_array().unwrap_or_else(|| panic!("no rows: {v}"));
    // Packets on both paths, the hybrid on the texel path (its only one): 3 x 2 layouts x 2
    // methods x 3 sets.
    assert_eq!(rows.len(), 3 * 2 * 2 * 3, "{v}");
    for r in rows {
        assert_eq!(r["unexplained_disagreements"], 0, "{r}");
        assert_eq!(r["invalid"], 0, "{r}");
        assert!(r["agreement"].as_f64().unwrap() >= 0.999, "{r}");
        let switched = r["switched"].as_f64();
        match r["traversal"].as_str().unwrap() {
            "hybrid" => assert!(switched.is_some_and(|s| s > 0.0 && s <= 1.0), "{r}"),
            "packet" => assert!(switched.is_none(), "{r}"),
            t => panic!("{t} was not asked for: {r}"),
        }
    }
    assert!(v["notes"].to_string().contains("hybrid traversal on bvh2 (storage path): not run"), "{}", v["notes"]);
}
