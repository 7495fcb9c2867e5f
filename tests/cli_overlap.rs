//! Issue 24, defect 3 and part of 7, through the binary: `trilab bvh` on copies of one triangle
//! (every triangle overlaps every other) finishes in seconds with the EPO its tree has by hand;
//! `--threads` is bounded in every command that takes it, refused before any work naming the
//! option; `rays random` on a scene whose every vertex is one point says so instead of blaming
//! f32's range. Every run has a wall-clock limit (tests/common/cli.rs).

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::cli::{expect_error, ok, s, trilab};

/// An OBJ of `n` copies of the triangle (0,0,0), (1,0,0), (0,1,0), of area 1/2.
fn copies(dir: &Path, n: usize) -> PathBuf {
    let p = dir.join(format!("copies{n}.obj"));
    std::fs::write(&p, format!("v 0 0 0\nv 1 0 0\nv 0 1 0\n{}", "f 1 2 3\n".repeat(n))).unwrap();
    p
}

/// Before: the EPO clipped every copy at every node (2^17 nodes x 2^16 copies here; 32,000
/// copies took 20 s per tree, `bvh` builds 12, 100,000 did not finish).
#[test]
fn bvh_of_copies_of_one_triangle_finishes_with_the_epo_of_its_tree() {
    let dir = tempfile::tempdir().unwrap();
    let scene = copies(dir.path(), 1 << 16);
    let args = ["bvh", "--scene", &s(&scene), "--leaf-sizes", "1,4", "--json"];
    let (o, took) = common::cli::run(&args, None, &[], 120);
    ok(&o);
    let rows: Vec<serde_json::Value> = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(rows.len(), 4, "two leaf sizes x two builders");
    for r in &rows {
        let epo = r["stats"]["epo"].as_f64();
        assert!(epo.is_some_and(|e| e > 0.0), "every tree's EPO is computed: {r}");
    }
    // All copies share one centroid, so the binned builder splits at the object median: at leaf
    // size 1 the tree is complete, 2^d nodes of 2^(16-d) copies at each depth d = 1..16. Every
    // box is the triangle's, so a node's foreign area is that of the 2^16 - 2^(16-d) copies
    // outside it, and its cost is 1 (an inner node, or a leaf of one triangle):
    // EPO = sum over d of 2^d (2^16 - 2^(16-d)) / 2^16 = sum of (2^d - 1) = 2^17 - 2 - 16.
    let binned = rows
        .iter()
        .find(|r| r["stats"]["max_leaf_size"] == 1 && r["stats"]["builder"].as_str().unwrap().starts_with("binned"))
        .unwrap();
    assert_eq!(binned["stats"]["nodes"], (1 << 17) - 1, "{binned}");
    let epo = binned["stats"]["epo"].as_f64().unwrap();
    let by_hand = f64::from((1 << 17) - 2 - 16);
    assert!((epo - by_hand).abs() <= 1e-9 * by_hand, "EPO {epo}, by hand {by_hand}");
    assert!(took < Duration::from_secs(60), "took {took:?}");
}

/// Before: `bvh --threads 100000` ran past two minutes (4,096 threads: 12 s) and `profile`
/// took any count. Every command with `--threads` refuses 0 and more than its bound (4 per
/// logical CPU, at least 64) before any work, naming the option, the value and the bound.
#[test]
fn thread_counts_are_bounded_in_every_command_that_takes_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("out"));
    let bunny = s(&common::root().join("scenes/bunny.obj"));
    let cpus = std::thread::available_parallelism().unwrap().get();
    // The bound, as the refusal of 100,000 names it.
    let (o, _) = common::cli::run(&["bvh", "--scene", &bunny, "--threads", "100000"], None, &[], 60);
    let e = expect_error(&o, &["--threads 100000", "logical CPU"]);
    let max: usize = e.split("1..=").nth(1).and_then(|t| t.split(' ').next()).and_then(|n| n.parse().ok()).unwrap();
    assert!(max >= 64 && max >= 4 * cpus && max < 100_000, "bound {max} on {cpus} CPUs: {e}");
    let over = (max + 1).to_string();
    for bad in ["100000", over.as_str(), "0"] {
        let list = format!("1,{bad}");
        for args in [
            vec!["bvh", "--scene", &bunny, "--threads", bad],
            // The whole list is checked before the first build.
            vec!["bvh", "--scene", &bunny, "--threads", &list],
            vec!["build-bench", "--scenes", &bunny, "--threads", bad, "--out", &out],
            vec!["profile", "--scene", &bunny, "--threads", bad, "--out", &out, "--methods", "mt"],
        ] {
            let (o, took) = common::cli::run(&args, None, &[], 60);
            let needle = format!("--threads {bad}");
            expect_error(&o, &[&needle, &format!("1..={max}")]);
            assert!(o.stdout.is_empty(), "nothing built before the refusal: {args:?}");
            assert!(took < Duration::from_secs(30), "{args:?} took {took:?}");
        }
    }
    assert!(!dir.path().join("out").exists(), "nothing written");
    // The bound itself is accepted, and finishes.
    let scene = s(&copies(dir.path(), 8));
    let (o, took) = common::cli::run(
        &["bvh", "--scene", &scene, "--leaf-sizes", "4", "--threads", &max.to_string()],
        None,
        &[],
        60,
    );
    ok(&o);
    assert!(took < Duration::from_secs(30), "took {took:?}");
}

/// Before: 3,000 triangles with every vertex at one point were refused as "too large for rays
/// around it (f32 ends at 3.4e38)". The box is a point: nothing to aim random rays into.
#[test]
fn random_rays_for_a_scene_at_one_point_name_the_point() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("point.obj");
    std::fs::write(&scene, format!("v 1 2 3\n{}", "f 1 1 1\n".repeat(3000))).unwrap();
    let out = dir.path().join("r.rays");
    let o = trilab(&["rays", "random", "--scene", &s(&scene), "--out", &s(&out)], 60);
    let e = expect_error(&o, &["point.obj", "3000 triangles", "single point [1.0, 2.0, 3.0]", "no direction"]);
    assert!(!e.contains("f32"), "not a matter of f32's range: {e}");
    assert!(!out.exists());
}

/// Issue 39: `bench`, `profile`, `study` and `scale` generate their ray sets themselves; the
/// random set of a scene at one point is refused as `trilab rays` refuses it, before any ray
/// is cast or any row written (before, they skipped the check).
#[test]
fn every_command_that_makes_random_rays_checks_them() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("point.obj");
    std::fs::write(&scene, format!("v 1 2 3\n{}", "f 1 1 1\n".repeat(30))).unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let sc = s(&scene);
    let o = s(&out);
    for args in [
        vec!["bench", "--scenes", &sc, "--out", &o],
        vec!["profile", "--scene", &sc],
        vec!["study", "--scenes", &sc, "--preset", "smoke", "--out", &o],
        vec!["scale", "--scenes", &sc, "--ray-set", "random"],
    ] {
        let r = trilab(&args, 120);
        let e = expect_error(&r, &["random rays cannot be made", "single point [1.0, 2.0, 3.0]", "no direction"]);
        assert!(!e.contains("panicked"), "{args:?}: {e}");
        assert!(!out.join("rows.jsonl").exists(), "{args:?} wrote rows");
    }
}
