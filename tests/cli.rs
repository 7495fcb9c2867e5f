//! The command line as a user meets it: bad input gets a clear error naming the file and the
//! problem (never a panic), outputs never overwrite inputs, and `raycast --json` reports what
//! the issue promises. Every run has a wall-clock limit.

mod common;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use trilab::rays::{read_hits, write_rays, Ray};

fn trilab(args: &[&str], timeout_s: u64) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_trilab"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > Duration::from_secs(timeout_s) {
            let _ = child.kill();
            panic!("trilab {args:?} did not finish within {timeout_s} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Fails unless the command failed cleanly with a message containing every needle.
fn expect_error(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert!(!o.status.success(), "should fail: {e}");
    assert!(!e.contains("panicked"), "panicked instead of reporting an error: {e}");
    for n in needles {
        assert!(e.contains(n), "error should mention `{n}`: {e}");
    }
}

fn tiny_scene(dir: &Path) -> String {
    let p = dir.join("tri.obj");
    std::fs::write(&p, "v 0 0 1\nv 1 0 1\nv 0 1 1\nv 1 1 1\nf 1 2 3\nf 2 4 3\n").unwrap();
    p.to_string_lossy().into_owned()
}

fn s(p: &Path) -> String {
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
        ("mtllib nowhere.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", &["nowhere.mtl", "cannot open"]),
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
