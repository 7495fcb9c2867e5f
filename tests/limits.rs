//! One scene pipeline for every command: with the device's limits lowered for tests
//! (`TRILAB_TEST_LIMITS`), the bunny no longer fits one texel binding per buffer, and every command
//! that uploads a scene reads it through buffer device addresses, or without 64-bit integers
//! (SwiftShader) through storage buffers, and its results still agree with the f64 reference.
//! The path tracer, which has no address path, takes storage buffers, and beyond those refuses
//! the scene before any work with the same "does not fit" error in every command, naming the
//! scene, the method, the buffer, what it needs and what the device allows.

mod common;

use common::cli::s;

use std::path::Path;
use std::process::Output;

/// 4096 texels per binding: every buffer of the bunny's encodings (69,451 triangles) is larger.
const LIMITS: &str = "max_texel_buffer_elements=4096";

/// A bench of the bunny small enough for a test: 48x36 camera, one diffuse ray per hit, 3,000
/// random rays, one timed round.
const SMALL_BENCH: [&str; 11] =
    ["bench", "--width", "48", "--height", "36", "--diffuse-per-hit", "1", "--random-rays", "3000", "--repeat", "1"];

fn trilab(args: &[&str], limits: bool) -> Output {
    trilab_with(args, if limits { Some(LIMITS) } else { None })
}

fn trilab_with(args: &[&str], limits: Option<&str>) -> Output {
    let env: Vec<(&str, &str)> = limits.map(|l| ("TRILAB_TEST_LIMITS", l)).into_iter().collect();
    common::cli::run(args, None, &env, 600).0
}

fn ok(o: &Output, what: &str) -> String {
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{what} failed: {err}");
    assert!(!err.contains("validation:"), "{what}: validation messages: {err}");
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The paths every row of `rows` read its scene through (`key` names the field).
fn paths(rows: &serde_json::Value, key: &str) -> Vec<String> {
    rows.as_array().unwrap().iter().filter_map(|r| r[key].as_str().map(str::to_owned)).collect()
}

fn all_address(p: &[String], what: &str) {
    all_on(p, "address", what);
}

fn all_on(p: &[String], path: &str, what: &str) {
    assert!(!p.is_empty() && p.iter().all(|a| a == path), "{what}: {p:?}");
}

/// A device like SwiftShader (issue 38): small texel buffers and no 64-bit integers, so the
/// address path is out too, and `auto` takes storage buffers; the results still agree with the
/// f64 reference, and asking for the address path is refused with the missing feature named.
#[test]
fn without_64_bit_integers_a_scene_beyond_one_texel_binding_is_read_through_storage_buffers() {
    let limits = Some("max_texel_buffer_elements=4096,shader_int64=0");
    let dir = tempfile::tempdir().unwrap();
    let d = |f: &str| s(&dir.path().join(f));
    ok(
        &trilab_with(
            &["rays", "random", "--scene", "scenes/bunny.obj", "--count", "3000", "--out", &d("r.rays")],
            None,
        ),
        "rays",
    );
    let raycast = ["raycast", "--scene", "scenes/bunny.obj", "--rays", &d("r.rays"), "--out", &d("h.hits")];
    for method in ["mt", "quad-unit", "watertight"] {
        let o = trilab_with(
            &[&raycast[..], &["--method", method, "--validate", "--json", "--repeat", "1"]].concat(),
            limits,
        );
        let v: serde_json::Value = serde_json::from_str(&ok(&o, "raycast")).unwrap();
        assert_eq!(v["scene_access"], "storage", "raycast {method}");
        assert_eq!(v["validation"]["passes"], true, "raycast {method}: {}", v["validation"]);
    }
    let o = trilab_with(&[&raycast[..], &["--method", "mt", "--scene-access", "address"]].concat(), limits);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("shaderInt64") && err.contains("--scene-access storage"), "{err}");
    let layouts = ["--methods", "mt,unit,quad-mt", "--layouts", "bvh2,bvh4,cwbvh", "--json-out", &d("bench.json")];
    ok(&trilab_with(&[&SMALL_BENCH[..], &layouts].concat(), limits), "bench");
    let bench = json(&dir.path().join("bench.json"));
    all_on(&paths(&bench["rows"], "scene_access"), "storage", "bench");
    assert_eq!(bench["rows"].as_array().unwrap().len(), 27);
    assert!(bench["rows"].as_array().unwrap().iter().all(|r| r["agreement"].as_f64().unwrap() > 0.999), "{bench}");
    let o = trilab_with(
        &["steps", "--scene", "scenes/bunny.obj", "--rays", &d("r.rays"), "--gpu", "--methods", "mt,quad-mt", "--json"],
        limits,
    );
    let steps: serde_json::Value = serde_json::from_str(&ok(&o, "steps")).unwrap();
    all_on(&paths(&steps["gpu"], "access"), "storage", "steps");
    // The path tracer too: the storage kernel renders the texel kernel's image bit for bit.
    let render = |out: &str, limits| {
        let args = ["render", "--scene", "scenes/bunny.obj", "--width", "24", "--height", "16", "--spp", "4"];
        let o = trilab_with(&[&args[..], &["--kernel", "general", "--json", "--out", &d(out)]].concat(), limits);
        serde_json::from_str::<serde_json::Value>(&ok(&o, "render")).unwrap()
    };
    let (texel, storage) = (render("t.exr", None), render("s.exr", limits));
    assert_eq!(
        (texel["kernel"].as_str(), storage["kernel"].as_str()),
        (Some("pathtrace.mt.all"), Some("pathtrace.mt.all_storage"))
    );
    let image = |f: &str| std::fs::read(dir.path().join(f)).unwrap();
    assert!(image("t.exr") == image("s.exr"), "the storage path's image differs from the texel path's");
    for r in steps["gpu"].as_array().unwrap() {
        assert!(r["rays_differing_from_cpu"].as_u64().unwrap() <= 3, "steps: {r}");
    }
}

#[test]
fn every_command_reads_a_scene_beyond_one_binding_through_addresses() {
    let dir = tempfile::tempdir().unwrap();
    let d = |f: &str| s(&dir.path().join(f));
    ok(
        &trilab(&["rays", "random", "--scene", "scenes/bunny.obj", "--count", "3000", "--out", &d("r.rays")], false),
        "rays",
    );

    // raycast: as the device is, the texel path; lowered, the address path, validated.
    for (limits, want) in [(false, "texel"), (true, "address")] {
        for method in ["mt", "quad-unit", "watertight"] {
            let args = ["raycast", "--scene", "scenes/bunny.obj", "--rays", &d("r.rays"), "--out", &d("h.hits")];
            let o =
                trilab(&[&args[..], &["--method", method, "--validate", "--json", "--repeat", "1"]].concat(), limits);
            let v: serde_json::Value = serde_json::from_str(&ok(&o, "raycast")).unwrap();
            assert_eq!(v["scene_access"], want, "raycast {method}, limits {limits}");
            assert_eq!(v["validation"]["passes"], true, "raycast {method}: {}", v["validation"]);
        }
    }

    // bench: every row on the address path, each validated before it has a speed.
    let extra = ["--ray-query", "off", "--methods", "mt,unit,quad-mt", "--json-out", &d("bench.json")];
    let o = trilab(&[&SMALL_BENCH[..], &extra].concat(), true);
    ok(&o, "bench");
    let bench = json(&dir.path().join("bench.json"));
    all_address(&paths(&bench["rows"], "scene_access"), "bench");
    assert_eq!(bench["rows"].as_array().unwrap().len(), 9);

    // scale: the placement's choice is in each row, and the sample agrees with the reference.
    let o = trilab(
        &[
            "scale",
            "--scenes",
            "scenes/bunny.obj",
            "--methods",
            "mt,quad-unit",
            "--rays",
            "3000",
            "--validate",
            "500",
            "--repeat",
            "1",
            "--out",
            &d("scale"),
        ],
        true,
    );
    ok(&o, "scale");
    let scale = json(&dir.path().join("scale/scale.json"));
    all_address(&paths(&scale["rows"], "access"), "scale");
    assert!(scale["rows"].as_array().unwrap().iter().all(|r| r["validation_passes"] == true), "{scale}");

    // steps --gpu: the stats kernels on the address path count what the CPU mirror counts.
    let o = trilab(
        &["steps", "--scene", "scenes/bunny.obj", "--rays", &d("r.rays"), "--gpu", "--methods", "mt,quad-mt", "--json"],
        true,
    );
    let steps: serde_json::Value = serde_json::from_str(&ok(&o, "steps")).unwrap();
    all_address(&paths(&steps["gpu"], "access"), "steps");
    for r in steps["gpu"].as_array().unwrap() {
        assert!(r["rays_differing_from_cpu"].as_u64().unwrap() <= 3, "steps: {r}");
    }

    // profile: timings, clock and sweeps, every one validated.
    let o = trilab(
        &[
            "profile",
            "--scene",
            "scenes/bunny.obj",
            "--methods",
            "unit",
            "--width",
            "32",
            "--height",
            "24",
            "--diffuse-per-hit",
            "1",
            "--random-rays",
            "2000",
            "--repeat",
            "1",
            "--no-threads",
            "--workgroup-sizes",
            "64",
            "--out",
            &d("profile"),
        ],
        true,
    );
    ok(&o, "profile");
    let profile = json(&dir.path().join("profile/profile.json"));
    all_address(&paths(&profile["timestamps"]["rows"], "scene_access"), "profile");

    // accuracy: its small closed meshes fit; the bunny of the frontier takes the address path.
    let o = trilab(&["accuracy", "--preset", "smoke", "--methods", "mt,watertight", "--out", &d("accuracy")], true);
    ok(&o, "accuracy");
    let accuracy = json(&dir.path().join("accuracy/accuracy.json"));
    all_address(&paths(&accuracy["frontier"], "scene_access"), "accuracy frontier");
    assert!(accuracy["frontier"].as_array().unwrap().iter().all(|r| r["mrays_per_s"].is_object()), "{accuracy}");
}

#[test]
fn the_path_tracer_refuses_a_scene_beyond_one_storage_binding_in_every_command_the_same_way() {
    let dir = tempfile::tempdir().unwrap();
    let d = |f: &str| s(&dir.path().join(f));
    let commands: [Vec<String>; 3] = [
        [
            "render",
            "--scene",
            "scenes/bunny.obj",
            "--out",
            &d("x.exr"),
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
        ]
        .map(String::from)
        .to_vec(),
        [
            "bench-render",
            "--scenes",
            "scenes/bunny.obj",
            "--methods",
            "mt",
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
        ]
        .map(String::from)
        .to_vec(),
        ["study", "--preset", "smoke", "--methods", "mt", "--leaf-sizes", "4", "--out", &d("study")]
            .map(String::from)
            .to_vec(),
    ];
    let mut messages = vec![];
    for args in &commands {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        // Beyond one texel binding the path tracer takes storage buffers (issue 38); beyond one
        // storage binding too, it has nowhere to go.
        let o = trilab_with(&args, Some("max_texel_buffer_elements=4096,max_storage_buffer_range=65536"));
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(!o.status.success(), "{}: should refuse: {err}", args[0]);
        assert!(!err.contains("panicked"), "{}: {err}", args[0]);
        let line = err.lines().find(|l| l.starts_with("trilab: error:")).unwrap_or_else(|| panic!("{err}")).to_owned();
        for want in [
            "scene `bunny` does not fit",
            "method mt",
            "needs",
            "65536",
            "maxStorageBufferRange",
            "not device addresses",
        ] {
            assert!(line.contains(want), "{}: `{want}` missing from: {line}", args[0]);
        }
        messages.push(line);
    }
    // One placement, one message: every command refuses in the same words.
    assert!(messages.windows(2).all(|w| w[0] == w[1]), "{messages:#?}");
    // Nothing was written: the refusal comes before any work.
    assert!(!dir.path().join("x.exr").exists() && !dir.path().join("study/study.json").exists());
}
