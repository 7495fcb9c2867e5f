//! The command line as a user meets it: bad input gets a clear error naming the file and the
//! problem (never a panic), outputs never overwrite inputs, and `raycast --json` reports what
//! the issue promises. Every run has a wall-clock limit.

mod common;

use common::cli::{expect_error, s, stderr};

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use trilab::rays::{read_hits, write_rays, Ray};

fn trilab(args: &[&str], timeout_s: u64) -> Output {
    common::cli::trilab(args, timeout_s)
}

fn tiny_scene(dir: &Path) -> String {
    let p = dir.join("tri.obj");
    std::fs::write(&p, "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\nf 1 2 3\nf 2 4 3\n").unwrap();
    p.to_string_lossy().into_owned()
}

#[test]
fn bad_scene_files_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let rays = dir.path().join("r.rays");
    write_rays(&rays, &[Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 1.0])]).unwrap();
    let out = dir.path().join("h.hits");
    let cases: &[(&str, &[&str])] = &[
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", &["bad.obj:4", "out of range"]),
        ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", &["bad.obj:2", "vertex position"]),
        ("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", &["bad.obj:2", "NaN or infinite"]),
        ("v 0 0 0\nv 1 0 0\n", &["bad.obj", "no triangles"]),
        // A missing MTL is a warning now (tests/cli_scenes.rs); a malformed one is still an error.
    ];
    for (text, needles) in cases {
        let obj = dir.path().join("bad.obj");
        std::fs::write(&obj, text).unwrap();
        let o = trilab(&["raycast", "--scene", &s(&obj), "--rays", &s(&rays), "--out", &s(&out)], 60);
        expect_error(&o, needles);
        assert!(!out.exists(), "no output on error");
    }
    let o = trilab(&["raycast", "--scene", "/no/such/scene.obj", "--rays", &s(&rays), "--out", &s(&out)], 60);
    expect_error(&o, &["/no/such/scene.obj"]);
}

#[test]
fn bad_ray_files_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let rays = dir.path().join("r.rays");
    let out = dir.path().join("h.hits");
    let mut bad = vec![Ray::new([0.0; 3], [0.0, 0.0, 1.0]); 5];
    bad[3].dir[1] = f32::NAN;
    write_rays(&rays, &bad).unwrap();
    let o = trilab(&["raycast", "--scene", &scene, "--rays", &s(&rays), "--out", &s(&out)], 60);
    expect_error(&o, &["r.rays", "ray 3", "direction.y is NaN"]);
    std::fs::write(&rays, [0u8; 40]).unwrap();
    let o = trilab(&["raycast", "--scene", &scene, "--rays", &s(&rays), "--out", &s(&out)], 60);
    expect_error(&o, &["r.rays", "not a multiple of 32"]);
}

#[test]
fn outputs_never_overwrite_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let rays = dir.path().join("r.rays");
    write_rays(&rays, &[Ray::new([0.2, 0.2, 0.0], [0.0, 0.0, 1.0])]).unwrap();
    let before = std::fs::read(&rays).unwrap();
    let o = trilab(&["raycast", "--scene", &scene, "--rays", &s(&rays), "--out", &s(&rays)], 60);
    expect_error(&o, &["refusing to overwrite"]);
    assert_eq!(std::fs::read(&rays).unwrap(), before);
    let o = trilab(&["rays", "random", "--scene", &scene, "--out", &scene, "--count", "10"], 60);
    expect_error(&o, &["refusing to overwrite"]);
}

#[test]
fn raycast_json_reports_the_promised_fields_and_writes_hits() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let rays = dir.path().join("r.rays");
    let o = trilab(&["rays", "random", "--scene", &scene, "--out", &s(&rays), "--count", "5000", "--seed", "3"], 120);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::metadata(&rays).unwrap().len(), 5000 * 32);
    for method in ["mt", "unit", "quad-mt", "quad-unit"] {
        let hits = dir.path().join(format!("{method}.hits"));
        let o = trilab(
            &[
                "raycast",
                "--scene",
                &scene,
                "--rays",
                &s(&rays),
                "--out",
                &s(&hits),
                "--method",
                method,
                "--leaf-size",
                "4",
                "--repeat",
                "2",
                "--json",
                "--validate",
                "--validation",
            ],
            300,
        );
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
        for key in ["method", "leaf_size", "rays", "hits", "kernel_ms", "mrays_per_s", "device", "driver"] {
            assert!(v.get(key).is_some(), "{method}: JSON lacks `{key}`: {v}");
        }
        assert_eq!(v["method"], method);
        assert_eq!(v["rays"], 5000);
        assert_eq!(v["validation"]["passes"], true, "{v}");
        let h = read_hits(&hits).unwrap();
        assert_eq!(h.len(), 5000);
        assert_eq!(v["hits"], h.iter().filter(|x| x.is_hit()).count());
        assert!(v["kernel_ms"].as_f64().unwrap() > 0.0);
    }
}

#[test]
fn devices_lists_at_least_one_device_with_its_driver() {
    let o = trilab(&["devices"], 60);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("driver:") && text.contains("maxStorageBufferRange"), "{text}");
    assert!(text.contains("(default choice)"), "{text}");
}

#[test]
fn render_writes_exr_png_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bunny.exr");
    let scene = common::root().join("scenes/bunny.obj");
    let o = trilab(
        &["render", "--scene", &s(&scene), "--width", "24", "--height", "18", "--spp", "2", "--quiet", "--validation"]
            .iter()
            .copied()
            .chain(["--method", "quad-unit", "--out", &s(&out)])
            .collect::<Vec<_>>(),
        120,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let exr = std::fs::read(&out).unwrap();
    assert_eq!(&exr[..4], &[0x76, 0x2f, 0x31, 0x01], "OpenEXR magic");
    let png = image::open(dir.path().join("bunny.png")).unwrap();
    assert_eq!((png.width(), png.height()), (24, 18));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("bunny.json")).unwrap()).unwrap();
    assert_eq!(j["kernel"], "pathtrace.quad-unit.lambert");
    assert_eq!(j["spp_done"], 2);
    assert_eq!(j["interrupted"], false);
    assert_eq!(j["dropped_samples_nan_or_inf"], 0);
    assert_eq!(j["scene_sha256"].as_str().unwrap().len(), 64);
    for key in ["device", "driver", "gpu_ms", "samples_per_second", "mrays_per_second", "ray_definition", "settings"] {
        assert!(!j[key].is_null(), "JSON sidecar lacks {key}: {j}");
    }
    assert!(j["closest_rays"].as_u64().unwrap() >= 24 * 18 * 2, "every sample traces a camera ray");
}

#[test]
fn render_refuses_bad_requests() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::root().join("scenes/bunny.obj");
    let base = ["render", "--scene", &s(&scene), "--width", "8", "--height", "8", "--spp", "1", "--quiet"];
    let run = |extra: &[&str]| trilab(&base.iter().copied().chain(extra.iter().copied()).collect::<Vec<_>>(), 60);
    expect_error(&run(&["--out", &s(&dir.path().join("x.png"))]), &["x.png", "must be an .exr"]);
    expect_error(&run(&["--out", &s(&dir.path().join("x.exr")), "--camera", "0,0,1,0,0,0,0,1"]), &["--camera", "10"]);
    expect_error(&run(&["--out", &s(&dir.path().join("x.exr")), "--camera", "0,0,1,0,0,1,0,1,0,45"]), &["camera"]);
    expect_error(&run(&["--out", &s(&dir.path().join("x.exr")), "--spp", "0"]), &["--spp"]);
    // A scene whose name is the JSON sidecar's: refused before anything is written.
    let sneaky = dir.path().join("r.json");
    std::fs::copy(common::root().join("scenes/bunny.obj"), &sneaky).unwrap();
    std::fs::copy(common::root().join("scenes/bunny.mtl"), dir.path().join("bunny.mtl")).unwrap();
    let before = std::fs::read(&sneaky).unwrap();
    let o = trilab(
        &["render", "--scene", &s(&sneaky), "--spp", "1", "--quiet", "--out", &s(&dir.path().join("r.exr"))],
        60,
    );
    expect_error(&o, &["r.json", "refusing to overwrite an input"]);
    assert_eq!(std::fs::read(&sneaky).unwrap(), before);
    assert!(!dir.path().join("r.exr").exists());
}

/// Ctrl-C (SIGINT) during a long render: the pass in flight finishes, and what accumulated is
/// written (EXR, PNG, JSON saying how many samples it holds), and the exit status is 130.
#[test]
fn ctrl_c_writes_what_has_accumulated() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("long.exr");
    let scene = common::root().join("scenes/bunny.obj");
    let mut child = Command::new(env!("CARGO_BIN_EXE_trilab"))
        .args(["render", "--scene", &s(&scene), "--width", "64", "--height", "48", "--spp", "100000", "--quiet"])
        .args(["--submit-ms", "50", "--out", &s(&out)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(3));
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("render did not stop within 60 s of SIGINT");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    // Saved, then the interrupted process's status (issue 14): 130, as `study` exits.
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("long.json")).unwrap()).unwrap();
    assert_eq!(j["interrupted"], true);
    let done = j["spp_done"].as_u64().unwrap();
    assert!(done > 0 && done < 100_000, "spp_done {done}");
    assert!(std::fs::read(&out).unwrap().len() > 1000);
}

#[test]
fn steps_gpu_reports_kernel_counts_beside_the_mirror_and_bvh_reports_epo() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let rays = dir.path().join("r.rays");
    let o = trilab(&["rays", "random", "--scene", &scene, "--out", &s(&rays), "--count", "3000", "--seed", "5"], 120);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = trilab(&["steps", "--scene", &scene, "--rays", &s(&rays), "--gpu", "--json", "--validation"], 300);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    let cpu_nodes = v["cpu_summary"]["nodes"]["mean"].as_f64().unwrap();
    assert!(cpu_nodes > 5.0, "{v}");
    let gpu = v["gpu"].as_array().unwrap();
    assert_eq!(gpu.len(), trilab::encoding::Method::ALL.len(), "every method by default: {v}");
    for g in gpu {
        let nodes = g["summary"]["nodes"]["mean"].as_f64().unwrap();
        assert!((nodes - cpu_nodes).abs() <= 0.005 * cpu_nodes, "{g}");
        assert!(g["rays_differing_from_cpu"].as_u64().unwrap() <= 3, "{g}");
        assert!(g["summary"]["slots"]["max"].as_u64().unwrap() >= g["summary"]["triangles"]["max"].as_u64().unwrap());
    }
    let text = trilab(&["steps", "--scene", &scene, "--rays", &s(&rays), "--gpu", "--methods", "quad-unit"], 300);
    let out = String::from_utf8_lossy(&text.stdout);
    assert!(text.status.success() && out.contains("GPU quad-unit") && out.contains("CPU mirror"), "{out}");
    expect_error(&trilab(&["steps", "--scene", &scene, "--rays", &s(&rays), "--methods", "mt"], 60), &["--gpu"]);

    let o = trilab(&["bvh", "--scene", &scene, "--leaf-size", "4", "--json"], 120);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for row in v.as_array().unwrap() {
        let epo = row["stats"]["epo"].as_f64().unwrap();
        assert!(epo > 0.0 && epo < row["stats"]["sah_cost"].as_f64().unwrap(), "{row}");
    }
}

#[test]
fn analyze_reports_conditioning_and_a_recommendation() {
    let dir = tempfile::tempdir().unwrap();
    // A 1x1 quad centred on the origin, and the same quad 1e5 away: the second should be recentred.
    let near = dir.path().join("near.obj");
    std::fs::write(&near, "v -0.5 -0.5 0\nv 0.5 -0.5 0\nv -0.5 0.5 0\nv 0.5 0.5 0\nf 1 2 3\nf 2 4 3\n").unwrap();
    let near = s(&near);
    let far = dir.path().join("far.obj");
    std::fs::write(&far, "v 1e5 1e5 1e5\nv 100001 1e5 1e5\nv 1e5 100001 1e5\nv 100001 100001 1e5\nf 1 2 3\nf 2 4 3\n")
        .unwrap();
    let o = trilab(&["analyze", "--scene", &near, "--json"], 60);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    assert_eq!(v["conditioning"]["triangles"], 2);
    assert_eq!(v["conditioning"]["edge_min"], 1.0);
    assert_eq!(v["recommendation"]["recentre"], false);
    let method = v["recommendation"]["method"].as_str().unwrap().to_owned();
    assert!(v["available_methods"].as_array().unwrap().iter().any(|m| m == method.as_str()), "{v}");
    let o = trilab(&["analyze", "--scene", &s(&far), "--json"], 60);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["recommendation"]["recentre"], true, "{v}");
    // ULP at 1e5 is 2^-7: 7 bits across a unit edge; recentred (magnitude 0.5): 24.
    assert_eq!(v["conditioning"]["edge_bits"], 7.0);
    assert_eq!(v["conditioning"]["edge_bits_recentred"], 24.0);
    // The text form names the method and the reasons.
    let o = trilab(&["analyze", "--scene", &s(&far)], 60);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("recommendation: --method") && text.contains("recentre"), "{text}");
}

#[test]
fn analyze_refuses_bad_frontiers_and_targets() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let bad = dir.path().join("frontier.csv");
    std::fs::write(&bad, "method,mrays_median,leaks_per_million,t_ulps_p99\nnot-a-method,1,0,0\n").unwrap();
    expect_error(
        &trilab(&["analyze", "--scene", &scene, "--frontier", &s(&bad)], 60),
        &["frontier.csv:2", "not-a-method"],
    );
    expect_error(
        &trilab(&["analyze", "--scene", &scene, "--frontier", &s(&dir.path().join("none.csv"))], 60),
        &["none.csv"],
    );
    expect_error(&trilab(&["analyze", "--scene", &scene, "--max-t-ulps=-1"], 60), &["--max-t-ulps"]);
    expect_error(
        &trilab(&["raycast", "--scene", &scene, "--rays", "x", "--out", "y", "--method", "fastest"], 60),
        &["fastest", "auto"],
    );
}

#[test]
fn raycast_and_render_method_auto_say_what_they_picked() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let rays = dir.path().join("r.rays");
    let o = trilab(&["rays", "random", "--scene", &scene, "--out", &s(&rays), "--count", "2000", "--seed", "5"], 120);
    assert!(o.status.success(), "{}", stderr(&o));
    let hits = dir.path().join("auto.hits");
    let args = [
        "raycast",
        "--scene",
        &scene,
        "--rays",
        &s(&rays),
        "--out",
        &s(&hits),
        "--method",
        "auto",
        "--json",
        "--validate",
    ];
    let o = trilab(&[&args[..], &["--validation", "--repeat", "1"]].concat(), 300);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["method_choice"], "auto");
    assert_eq!(v["method"], v["auto"]["method"], "{v}");
    assert_eq!(v["validation"]["passes"], true, "{v}");
    assert!(stderr(&o).contains("--method auto picked"), "{}", stderr(&o));
    // The recentred run: same rays moved with the scene, still validated against the reference.
    let o = trilab(&[&args[..], &["--validation", "--repeat", "1", "--recentre"]].concat(), 300);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["recentred"], true);
    assert_eq!(v["validation"]["passes"], true, "{v}");

    let out = dir.path().join("auto.exr");
    let o = trilab(
        &[
            "render",
            "--scene",
            &scene,
            "--out",
            &s(&out),
            "--method",
            "auto",
            "--width",
            "32",
            "--height",
            "24",
            "--spp",
            "2",
            "--quiet",
            "--validation",
        ],
        300,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("--method auto picked"), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("auto.json")).unwrap()).unwrap();
    assert_eq!(j["method_choice"], "auto");
    assert_eq!(j["method"], j["auto"]["method"], "{j}");
}

/// A render whose buffers cannot fit is refused by its placement before anything is encoded or
/// allocated, naming the buffer and the limit; nothing is written.
#[test]
fn a_render_that_cannot_fit_is_refused_before_upload() {
    let dir = tempfile::tempdir().unwrap();
    let scene = tiny_scene(dir.path());
    let out = dir.path().join("big.exr");
    // The device's limit, not the host's memory (41.7 GiB of pixels on the host is refused first
    // on a machine with less: tests/hostile_inputs.rs): a host as large as the pixels need.
    let args = ["render", "--scene", &scene, "--out", &s(&out), "--width", "40000", "--height", "40000"];
    let (o, _) = common::cli::run(&args, None, &[("TRILAB_MAX_MEMORY", "1000000000000000")], 60);
    expect_error(&o, &["does not fit", "accumulation image", "maxStorageBufferRange"]);
    assert!(!out.exists(), "nothing may be written");
}
