//! Scenes as a user outside the repository meets them (issue 14, defects 3, 4, 5 and 11): scene
//! names resolve from any working directory, missing or wrong materials are warnings with file
//! and line, ray sets of huge scenes are made in f64 or refused naming the bounds, ray files get
//! a sidecar that catches casting them against another scene, and `accuracy --scene` measures
//! leaks on a user's closed mesh. Every command runs the binary from a temporary directory, with
//! the validation layer on (`TRILAB_VALIDATION=1`) and a wall-clock limit.

mod common;

use common::cli::{expect_error, ok, s};

use std::path::Path;
use std::process::Output;
use std::time::{Duration, Instant};

use trilab::commands::accuracy::closed::{icosphere, Placement};
use trilab::scene::Mesh;

/// Runs `trilab args` in `cwd` with `env`, killed after `timeout_s`.
fn trilab_in(cwd: &Path, env: &[(&str, &str)], args: &[&str], timeout_s: u64) -> Output {
    common::cli::run(args, Some(cwd), env, timeout_s).0
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

/// The spec -> source entries of a report's provenance (flattened into bench's report).
fn scene_sources(report: &serde_json::Value) -> Vec<(String, String)> {
    let provenance = if report["provenance"].is_object() { &report["provenance"] } else { report };
    provenance["scenes"]
        .as_array()
        .unwrap_or_else(|| panic!("provenance names no scenes: {}", report["provenance"]))
        .iter()
        .map(|s| (s["spec"].as_str().unwrap().to_owned(), s["found"].as_str().unwrap().to_owned()))
        .collect()
}

fn write_obj(path: &Path, mesh: &Mesh) {
    let mut text = String::new();
    for p in &mesh.positions {
        text += &format!("v {:e} {:e} {:e}\n", p[0], p[1], p[2]);
    }
    for t in &mesh.triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

/// A tetrahedron with coordinates of magnitude `s`.
fn tetra(path: &Path, s: &str) {
    std::fs::write(
        path,
        format!("v -{s} -{s} -{s}\nv {s} -{s} -{s}\nv 0 {s} -{s}\nv 0 0 {s}\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n"),
    )
    .unwrap();
}

/// Rays of a ray file (origin, direction).
fn read_rays(path: &Path) -> Vec<trilab::rays::Ray> {
    let bytes = std::fs::read(path).unwrap();
    bytes.chunks_exact(32).map(bytemuck::pod_read_unaligned).collect()
}

#[test]
fn bench_runs_from_any_folder_with_the_built_in_bunny() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "bench",
        "--methods",
        "mt",
        "--width",
        "16",
        "--height",
        "12",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "500",
        "--repeat",
        "1",
        "--json-out",
        "bench.json",
    ];
    let o = trilab_in(dir.path(), &[], &args, 300);
    ok(&o);
    let sources = scene_sources(&json(&dir.path().join("bench.json")));
    assert!(sources.iter().any(|(spec, _)| spec == "bunny"), "{sources:?}");
    // bench's list takes names too, and names the bundled scenes' folder when asked.
    let o = trilab_in(dir.path(), &[], &[&args[..13], &["--scenes", "cornell", "--json-out", "c.json"]].concat(), 300);
    ok(&o);
    let sources = scene_sources(&json(&dir.path().join("c.json")));
    assert!(sources.iter().any(|(spec, found)| spec == "cornell" && found != "path"), "{sources:?}");
}

#[test]
fn study_smoke_runs_from_any_folder() {
    let dir = tempfile::tempdir().unwrap();
    for (args, out) in [
        (&["study", "--preset", "smoke", "--out", "default"][..], "default"),
        (&["study", "--preset", "smoke", "--scenes", "bunny", "--out", "named"][..], "named"),
    ] {
        let o = trilab_in(dir.path(), &[], args, 300);
        ok(&o);
        let report = json(&dir.path().join(out).join("study.json"));
        assert!(scene_sources(&report).iter().any(|(spec, _)| spec == "bunny"), "{}", report["provenance"]);
        assert!(report["rows"].as_array().is_some_and(|r| !r.is_empty()));
    }
}

#[test]
fn accuracy_smoke_runs_from_any_folder() {
    let dir = tempfile::tempdir().unwrap();
    let o = trilab_in(dir.path(), &[], &["accuracy", "--preset", "smoke", "--out", "acc"], 300);
    ok(&o);
    let report = json(&dir.path().join("acc/accuracy.json"));
    assert!(scene_sources(&report).iter().any(|(spec, _)| spec == "bunny"), "{}", report["provenance"]);
}

#[test]
fn scene_names_come_from_trilab_scenes_and_scene_dir_and_a_miss_lists_the_places() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().unwrap();
    let lib = dir.path().join("lib");
    std::fs::create_dir(&lib).unwrap();
    // A name that exists nowhere else: only the folder given can supply it.
    std::fs::copy(root.join("scenes/cornell.obj"), lib.join("mybox.obj")).unwrap();
    std::fs::copy(root.join("scenes/cornell.mtl"), lib.join("cornell.mtl")).unwrap();
    let work = dir.path().join("work");
    std::fs::create_dir(&work).unwrap();
    let rays = ["rays", "random", "--scene", "mybox", "--count", "100", "--out", "r.rays"];
    let o = trilab_in(&work, &[("TRILAB_SCENES", &s(&lib))], &rays, 60);
    ok(&o);
    let side = json(&work.join("r.rays.json"));
    assert_eq!(side["scene"], "mybox");
    assert_eq!(side["scene_source"], s(&lib.join("mybox.obj")));
    let o = trilab_in(&work, &[], &[&["--scene-dir", &s(&lib)][..], &rays].concat(), 60);
    ok(&o);
    let o = trilab_in(&work, &[], &[&rays[..], &["--scene-dir", &s(&lib)]].concat(), 60);
    ok(&o);

    let o = trilab_in(&work, &[], &rays, 60);
    expect_error(
        &o,
        &["mybox", "--scene-dir", "TRILAB_SCENES", "beside the executable", "built into trilab", "source tree"],
    );
    let o = trilab_in(&work, &[], &["--scene-dir", "/no/such/dir", "bvh", "--scene", "bunny"], 60);
    expect_error(&o, &["--scene-dir", "/no/such/dir"]);
}

#[test]
fn a_missing_mtllib_is_a_warning_for_geometry_and_shading() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("a.obj"), "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n")
        .unwrap();
    for args in [
        &["bvh", "--scene", "a.obj"][..],
        &["analyze", "--scene", "a.obj"],
        &["render", "--scene", "a.obj", "--out", "a.exr", "--width", "8", "--height", "6", "--spp", "1", "--quiet"],
    ] {
        let o = trilab_in(dir.path(), &[], args, 120);
        let e = ok(&o);
        assert!(e.contains("gone.mtl") && e.contains("default material"), "{args:?}: {e}");
    }
    assert!(dir.path().join("a.exr").is_file());
}

#[test]
fn mtl_mistakes_name_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\nNs shiny\n").unwrap();
    std::fs::write(dir.path().join("a.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let o = trilab_in(dir.path(), &[], &["bvh", "--scene", "a.obj"], 60);
    expect_error(&o, &["m.mtl:3:", "`Ns`"]);

    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
    std::fs::write(
        dir.path().join("b.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\nusemtl bleu\nf 1 2 3\n",
    )
    .unwrap();
    let o = trilab_in(dir.path(), &[], &["bvh", "--scene", "b.obj"], 60);
    let e = ok(&o);
    assert!(e.contains("b.obj:7: usemtl `bleu`") && e.contains("default material"), "{e}");
}

#[test]
fn ray_sets_of_huge_scenes_are_made_in_f64_or_refused_naming_the_bounds() {
    let dir = tempfile::tempdir().unwrap();
    tetra(&dir.path().join("big.obj"), "1e20");
    let o =
        trilab_in(dir.path(), &[], &["rays", "random", "--scene", "big.obj", "--count", "1000", "--out", "r.rays"], 60);
    ok(&o);
    let rays = read_rays(&dir.path().join("r.rays"));
    assert_eq!(rays.len(), 1000);
    assert!(rays.iter().all(|r| r.problem().is_none()), "{:?}", rays.iter().find(|r| r.problem().is_some()));

    tetra(&dir.path().join("huge.obj"), "3e38");
    for kind in [&["random", "--count", "1000"][..], &["diffuse", "--width", "8", "--height", "6"]] {
        let o = trilab_in(
            dir.path(),
            &[],
            &[&["rays"][..], kind, &["--scene", "huge.obj", "--out", "h.rays"]].concat(),
            60,
        );
        expect_error(&o, &[]);
        assert!(!dir.path().join("h.rays").exists(), "{kind:?}: a refused set writes nothing");
        if kind[0] == "random" {
            expect_error(&o, &["cannot be represented", "bounds", "3e38"]);
        }
    }
}

#[test]
fn ray_files_carry_a_sidecar_and_another_scene_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = trilab_in(
        d,
        &[],
        &["rays", "random", "--scene", "bunny", "--random-rays", "2000", "--seed", "3", "--out", "b.rays"],
        60,
    );
    ok(&o);
    let side = json(&d.join("b.rays.json"));
    assert_eq!(side["format"], "trilab-rays-sidecar/1");
    assert_eq!(side["scene"], "bunny");
    assert_eq!(side["scene_triangles"], 69451);
    assert_eq!(side["generator"], "random");
    assert_eq!(side["settings"]["count"], 2000);
    assert_eq!(side["seed"], 3);
    assert_eq!(side["count"], 2000);
    assert_eq!(side["scene_sha256"].as_str().unwrap().len(), 64);
    let _ = side["trilab_version"].as_str().unwrap();

    let mesh = icosphere(2).to_mesh(Placement::IDENTITY);
    write_obj(&d.join("ball.obj"), &mesh);
    let cast = |scene: &str, rays: &str| {
        trilab_in(d, &[], &["raycast", "--scene", scene, "--rays", rays, "--out", "h.hits", "--method", "mt"], 120)
    };
    let e = ok(&cast("ball.obj", "b.rays"));
    assert!(e.contains("made for scene `bunny`") && e.contains("`ball`"), "{e}");
    // `hits check` reads the same sidecar (its exit code is the check's, not the warning's).
    let o = trilab_in(d, &[], &["hits", "check", "--scene", "ball.obj", "--rays", "b.rays", "h.hits"], 120);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(e.contains("made for scene `bunny`") && e.contains("`ball`"), "{e}");
    let e = ok(&cast("bunny", "b.rays"));
    assert!(!e.contains("made for scene"), "{e}");
    let o = trilab_in(d, &[], &["steps", "--scene", "ball.obj", "--rays", "b.rays"], 120);
    let e = ok(&o);
    assert!(e.contains("made for scene `bunny`"), "{e}");
    // No sidecar (a file from another tool): no warning.
    std::fs::copy(d.join("b.rays"), d.join("plain.rays")).unwrap();
    let e = ok(&cast("ball.obj", "plain.rays"));
    assert!(!e.contains("made for scene"), "{e}");
}

#[test]
fn accuracy_measures_leaks_on_a_users_closed_mesh_and_refuses_an_open_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = icosphere(2).to_mesh(Placement::IDENTITY);
    write_obj(&d.join("ball.obj"), &mesh);
    let mut open = mesh.clone();
    open.triangles.pop();
    write_obj(&d.join("open.obj"), &open);

    let start = Instant::now();
    let o = trilab_in(d, &[], &["accuracy", "--preset", "smoke", "--scene", "open.obj", "--out", "acc-open"], 60);
    expect_error(&o, &["open.obj", "not proven closed", "edge"]);
    assert!(start.elapsed() < Duration::from_secs(20), "refused at once, not after the run");
    assert!(!d.join("acc-open/accuracy.json").exists());

    let o = trilab_in(d, &[], &["accuracy", "--preset", "smoke", "--scene", "ball.obj", "--out", "acc"], 300);
    ok(&o);
    let report = json(&d.join("acc/accuracy.json"));
    let leaks: Vec<&serde_json::Value> =
        report["leaks"].as_array().unwrap().iter().filter(|r| r["mesh"] == "ball").collect();
    assert!(!leaks.is_empty(), "no leak rows for the user's mesh");
    assert!(leaks.iter().all(|r| r["tally"]["rays"].as_u64().unwrap() > 0), "{leaks:?}");
    assert!(report["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .any(|m| m["name"] == "ball" && m["closed"].get("Ok").is_some()));
}
