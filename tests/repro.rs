//! `trilab repro` (issue 41): a cell made into a folder a driver developer can act on without
//! trilab, and `repro --check` replaying it elsewhere. A repro made on lavapipe 25.0.7 holds a
//! GFXReconstruct capture whose device has only what the kernel needs; `gfxrecon-replay` replays
//! it, and the dispatch from the folder's files gives the expected hits ray for ray, on lavapipe
//! 25.0.7, on Debian 12's own lavapipe 22.3.6 and on SwiftShader (each unpacked by its script,
//! never installed). The expected hits themselves are checked against the f64 reference by
//! `trilab hits check`, a path that shares nothing with the GPU. A changed hit is found ray by
//! ray; a damaged folder is refused by file and problem before any device work.
//!
//! GFXReconstruct comes from scripts/gfxreconstruct.sh (install-deps.sh runs it): without it the
//! capture tests fail saying so (`--capture required`); they never skip.

mod common;

use std::path::{Path, PathBuf};

use common::cli::{expect_error, ok, run, s, trilab};
use common::unpacked::{STOCK_MESA, SWIFTSHADER};
use serde_json::Value;

/// 24 x 16 primary rays on the bunny, written into `dir`.
fn bunny_rays(dir: &Path) -> PathBuf {
    let rays = dir.join("p.rays");
    ok(&trilab(&["rays", "primary", "--scene", "bunny", "--width", "24", "--height", "16", "--out", &s(&rays)], 120));
    rays
}

/// A repro of the bunny's primary rays (`extra` options added), captured (GFXReconstruct
/// required) or not; its folder.
fn make(dir: &Path, name: &str, capture: bool, extra: &[&str]) -> PathBuf {
    let (rays, out) = (s(&bunny_rays(dir)), s(&dir.join(name)));
    let when = if capture { "required" } else { "off" };
    let mut args = vec!["repro", "--scene", "bunny", "--rays", &rays, "--capture", when, "--out", &out];
    args.extend_from_slice(extra);
    let o = trilab(&args, 300);
    ok(&o);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    if capture {
        assert!(text.contains("its dispatch returned the expected hits"), "{text}");
    } else {
        assert!(text.contains("capture:   none (not asked for"), "{text}");
    }
    dir.join(name)
}

fn manifest(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("cell.json")).unwrap()).unwrap()
}

/// `repro --check DIR --gfxrecon --json` with `env`; the report.
fn check(dir: &Path, env: &[(String, String)]) -> Value {
    let env: Vec<(&str, &str)> = env.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
    let (o, _) = run(&["repro", "--check", &s(dir), "--gfxrecon", "--json"], None, &env, 300);
    ok(&o);
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn a_repro_made_on_lavapipe_replays_and_checks_the_same_on_three_drivers() {
    let tmp = tempfile::tempdir().unwrap();
    // The storage path: the bunny's nodes are beyond SwiftShader's 65,536 texels.
    let dir = make(tmp.path(), "repro", true, &["--scene-access", "storage"]);
    let m = manifest(&dir);
    assert_eq!(m["format"], "trilab-repro 1");
    assert_eq!(m["kernel"]["name"], "raycast.mt.closest_storage");
    assert_eq!(m["kernel"]["features"], serde_json::json!([]), "{m}");
    assert_eq!(m["capture"]["differing"], 0);
    assert_eq!(m["expected"]["passes"], true);
    // Every file the manifest names is there, with its size.
    let mut files = vec![&m["kernel"]["spirv"], &m["rays"], &m["expected"], &m["capture"]["file"]];
    files.extend(m["bindings"].as_array().unwrap());
    for f in files {
        let path = dir.join(f["file"].as_str().unwrap());
        assert_eq!(std::fs::metadata(&path).unwrap().len(), f["bytes"].as_u64().unwrap(), "{}", path.display());
    }
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    assert!(readme.contains("gfxrecon-replay capture.gfxr") && readme.contains("`bindings/"), "{readme}");
    let asm = std::fs::read_to_string(dir.join("kernel.spvasm")).unwrap();
    assert!(asm.contains("OpEntryPoint GLCompute"), "{asm}");

    // The expected hits against the f64 reference, through `hits check` (no GPU).
    let hits = s(&dir.join("expected.hits"));
    let rays = s(&dir.join("cell.rays"));
    let o = trilab(&["hits", "check", "--scene", "bunny", "--rays", &rays, &hits], 120);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    ok(&o);
    assert!(text.contains("384/384 rays agree"), "{text}");

    let rays = 24 * 16;
    for (driver, env, names) in [
        ("lavapipe 25.0.7", vec![], "Mesa 25"),
        ("lavapipe 22.3.6", STOCK_MESA.env(), "Mesa 22.3.6"),
        ("SwiftShader", SWIFTSHADER.env(), "SwiftShader"),
    ] {
        let r = check(&dir, &env);
        let d = &r["differences"];
        assert!(
            r["driver"].as_str().unwrap().contains(names) || r["device"].as_str().unwrap().contains(names),
            "{driver}: {r}"
        );
        assert_eq!((d["rays"].as_u64(), d["identical"].as_u64()), (Some(rays), Some(rays)), "{driver}: {r}");
        let replay = &r["gfxrecon_replay"];
        assert_eq!(replay["success"], true, "{driver}: gfxrecon-replay: {replay}");
        // The hits gfxrecon-replay's own dispatch read back (trilab's read-back layer under it).
        let g = &r["gfxrecon_differences"];
        assert_eq!((g["rays"].as_u64(), g["identical"].as_u64()), (Some(rays), Some(rays)), "{driver}: {r}");
        assert!(!replay["output"].as_str().unwrap().contains("FATAL"), "{driver}: {replay}");
    }
}

#[test]
fn a_changed_hit_is_named_ray_by_ray_and_fails_the_check() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = make(tmp.path(), "repro", true, &[]);
    let path = dir.join("expected.hits");
    let mut bytes = std::fs::read(&path).unwrap();
    // The first two rays that hit: one given another triangle, one a t one ulp further.
    let hitting: Vec<usize> = (0..bytes.len() / 16)
        .filter(|&i| f32::from_le_bytes(bytes[i * 16..i * 16 + 4].try_into().unwrap()).is_finite())
        .collect();
    let (a, b) = (hitting[0], hitting[1]);
    let id = u32::from_le_bytes(bytes[a * 16 + 4..a * 16 + 8].try_into().unwrap());
    bytes[a * 16 + 4..a * 16 + 8].copy_from_slice(&(id ^ 1).to_le_bytes());
    let t = u32::from_le_bytes(bytes[b * 16..b * 16 + 4].try_into().unwrap());
    bytes[b * 16..b * 16 + 4].copy_from_slice(&(t + 1).to_le_bytes());
    std::fs::write(&path, &bytes).unwrap();
    let o = trilab(&["repro", "--check", &s(&dir)], 300);
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    expect_error(&o, &["2 of 384 rays differ"]);
    assert!(out.contains("2 of 384 rays differ: 1 hit another triangle"), "{out}");
    assert!(out.contains("1 hit the same triangle at another t, u or v (t up to 1 ulps apart)"), "{out}");
    assert!(out.contains(&format!("ray {a:>7}:")) && out.contains(&format!("ray {b:>7}:")), "{out}");
    // gfxrecon-replay's dispatch finds the same two rays changed.
    let o = trilab(&["repro", "--check", &s(&dir), "--gfxrecon", "--json"], 300);
    expect_error(&o, &["2 of 384 rays differ"]);
    let r: Value = serde_json::from_slice(&o.stdout).unwrap();
    for d in [&r["differences"], &r["gfxrecon_differences"]] {
        assert_eq!(
            (d["identical"].as_u64(), d["different_hit"].as_u64(), d["same_triangle"].as_u64()),
            (Some(382), Some(1), Some(1)),
            "{r}"
        );
    }
}

#[test]
fn a_kernel_that_needs_full_subgroups_gets_them_and_nothing_else() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = ["--leaf-policy", "sah", "--sah-group", "4"];
    let dir = make(tmp.path(), "coop", true, &[&["--traversal", "coop", "--layout", "bvh4"][..], &tree].concat());
    let m = manifest(&dir);
    assert_eq!(m["kernel"]["full_subgroups"], true, "{m}");
    assert_eq!(m["cell"]["traversal"], "coop");
    // The tree's build options, all of them, so trilab can build the same tree again.
    assert_eq!((m["cell"]["leaf_policy"].as_str(), m["cell"]["sah_group"].as_u64()), (Some("sah"), Some(4)), "{m}");
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    assert!(readme.contains("sah leaves, SAH priced in groups of 4"), "{readme}");
    let r = check(&dir, &[]);
    assert_eq!(r["differences"]["identical"], r["differences"]["rays"], "{r}");
    // A folder made before the build options were recorded (leaf size alone) still checks.
    let mut old = m.clone();
    for k in ["leaf_policy", "sah_group", "builder"] {
        old["cell"].as_object_mut().unwrap().remove(k);
    }
    std::fs::write(dir.join("cell.json"), old.to_string()).unwrap();
    let r = check(&dir, &[]);
    assert_eq!(r["differences"]["identical"], r["differences"]["rays"], "{r}");
}

#[test]
fn a_damaged_repro_is_refused_by_file_and_problem() {
    let tmp = tempfile::tempdir().unwrap();
    let good = make(tmp.path(), "good", false, &[]);
    let copy = |name: &str| {
        let d = tmp.path().join(name);
        let o = std::process::Command::new("cp").arg("-r").arg(&good).arg(&d).output().unwrap();
        assert!(o.status.success());
        d
    };
    let refused = |dir: &Path, needles: &[&str]| {
        let o = trilab(&["repro", "--check", &s(dir)], 60);
        expect_error(&o, needles);
    };
    // A cut scene buffer.
    let d = copy("cut");
    let m = manifest(&d);
    let first = d.join(m["bindings"][0]["file"].as_str().unwrap());
    let len = std::fs::metadata(&first).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&first).unwrap().set_len(len - 16).unwrap();
    refused(&d, &[&s(&first), "cell.json says", "a cut or changed file"]);
    // Another format.
    let d = copy("format");
    let text = std::fs::read_to_string(d.join("cell.json")).unwrap().replace("trilab-repro 1", "trilab-repro 9");
    std::fs::write(d.join("cell.json"), text).unwrap();
    refused(&d, &["cell.json", "format `trilab-repro 9`"]);
    // A file name that leaves the folder.
    let d = copy("escape");
    let text = std::fs::read_to_string(d.join("cell.json")).unwrap().replace("\"cell.rays\"", "\"../good/cell.rays\"");
    std::fs::write(d.join("cell.json"), text).unwrap();
    refused(&d, &["not a plain path inside the folder"]);
    // SPIR-V that is not this trilab's kernel.
    let d = copy("spirv");
    let mut spv = std::fs::read(d.join("kernel.spv")).unwrap();
    let n = spv.len();
    spv[n - 8] ^= 0xff;
    std::fs::write(d.join("kernel.spv"), &spv).unwrap();
    refused(&d, &["kernel.spv", "differs from this trilab's `raycast.mt.closest`"]);
    // Hits for fewer rays than the file holds.
    let d = copy("short");
    let hits = std::fs::read(d.join("expected.hits")).unwrap();
    std::fs::write(d.join("expected.hits"), &hits[..hits.len() - 16]).unwrap();
    let text = std::fs::read_to_string(d.join("cell.json")).unwrap();
    let m: Value = serde_json::from_str(&text).unwrap();
    let old = format!("\"bytes\": {}", m["expected"]["bytes"]);
    let text = text.replacen(&old, &format!("\"bytes\": {}", hits.len() - 16), 1);
    std::fs::write(d.join("cell.json"), text).unwrap();
    refused(&d, &["expected.hits", "383 hits for 384 rays"]);
    // No folder.
    refused(&tmp.path().join("none"), &["not a folder"]);
}

#[test]
fn an_existing_folder_and_the_address_path_are_refused_before_work() {
    let tmp = tempfile::tempdir().unwrap();
    let rays = bunny_rays(tmp.path());
    let exists = tmp.path().join("exists");
    std::fs::create_dir(&exists).unwrap();
    std::fs::write(exists.join("keep.txt"), "mine").unwrap();
    let o = trilab(&["repro", "--scene", "bunny", "--rays", &s(&rays), "--out", &s(&exists)], 60);
    expect_error(&o, &["exists", "nothing is overwritten"]);
    assert_eq!(std::fs::read_to_string(exists.join("keep.txt")).unwrap(), "mine");
    let out = tmp.path().join("new");
    let o =
        trilab(&["repro", "--scene", "bunny", "--rays", &s(&rays), "--scene-access", "address", "--out", &s(&out)], 60);
    expect_error(&o, &["--scene-access address", "texel or the storage path"]);
    assert!(!out.exists(), "a refused repro leaves no folder");
    // Nothing half-written beside it either.
    let left: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().flatten().map(|e| e.file_name()).collect();
    assert_eq!(left.len(), 3, "{left:?}"); // p.rays, its sidecar, exists/
}

#[test]
fn ab_makes_each_changed_cell_a_repro_of_both_sides_each_in_its_own_driver() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("repros");
    let b_icd = STOCK_MESA.env().into_iter().find(|(k, _)| k == "VK_DRIVER_FILES").unwrap().1;
    let args = [
        "ab",
        "--methods",
        "mt,unit",
        "--width",
        "32",
        "--height",
        "24",
        "--random-rays",
        "2000",
        "--threshold",
        "1",
        "--judge",
        "kernels",
        "--b-icd",
        &b_icd,
        "--b-env",
        "TRILAB_INJECT_SLOWDOWN=.mt.:8",
        "--repro",
        &s(&dir),
        "--json",
    ];
    let (o, _) = run(&args, None, &[], 300);
    // The planted slowdown fails the run (exit 1), and the repros are made all the same.
    assert_eq!(o.status.code(), Some(1), "{}", common::cli::stderr(&o));
    let r: Value = serde_json::from_slice(&o.stdout).unwrap();
    let repros = r["repros"].as_array().unwrap();
    // The three cells that moved most (at most three are made): mt's, 8 times slower on B on top
    // of whatever 22.3.6 itself changes, which unit's cells show alone.
    let mut cells: Vec<&str> = repros.iter().map(|x| x["cell"].as_str().unwrap()).collect();
    cells.sort();
    assert_eq!(cells, ["bunny diffuse mt bvh2", "bunny primary mt bvh2", "bunny random mt bvh2"], "{r}");
    for x in repros {
        let cell_dir = PathBuf::from(x["dir"].as_str().unwrap());
        assert!(cell_dir.starts_with(&dir), "{x}");
        assert_eq!(x["hits"]["identical"], x["hits"]["rays"], "the two drivers' hits: {x}");
        for (side, driver) in [("a", "Mesa 25"), ("b", "Mesa 22.3.6")] {
            let m = manifest(&cell_dir.join(side));
            assert!(m["made"]["driver"].as_str().unwrap().contains(driver), "side {side}: {m}");
            assert_eq!(m["capture"]["differing"], 0, "side {side}: {m}");
        }
        let readme = std::fs::read_to_string(cell_dir.join("README.md")).unwrap();
        assert!(readme.contains("verdict HURT beyond threshold"), "{readme}");
    }
    // A folder that exists is refused before any side starts.
    let (o, _) = run(&["ab", "--methods", "mt", "--repro", &s(&dir)], None, &[], 60);
    expect_error(&o, &["--repro", "exists"]);
}

/// `compare BASE NEW --repro DIR`: a changed bench cell of ours becomes a repro made here, its
/// rays made from the run's bench.json, and the README says which side this device is. One bench
/// run is both sides; NEW's copy has one cell's agreement worsened and names another driver, so
/// the change and the sides are known, whatever the timings did (not judged here).
#[test]
fn compare_makes_a_changed_bench_cell_a_repro_here_naming_the_side_this_device_is() {
    let tmp = tempfile::tempdir().unwrap();
    let (base, new, dir) = (tmp.path().join("base"), tmp.path().join("new"), tmp.path().join("repros"));
    let bench = ["bench", "--scenes", "bunny", "--methods", "mt,unit", "--width", "32", "--height", "24"];
    let mut args = bench.to_vec();
    args.extend(["--random-rays", "2000", "--repeat", "2", "--out", s(&base).leak()]);
    ok(&trilab(&args, 300));
    std::fs::create_dir(&new).unwrap();
    std::fs::copy(base.join("bench.json"), new.join("bench.json")).unwrap();
    let rows = std::fs::read_to_string(base.join("rows.jsonl")).unwrap();
    let mut planted = 0;
    let rows: Vec<String> = rows
        .lines()
        .map(|l| {
            let mut r: Value = serde_json::from_str(l).unwrap();
            if r["type"] == "row" {
                r["source"]["driver"] = "Mesa 22.3.6 (elsewhere)".into();
                if r["cell"]["method"] == "unit" && r["cell"]["set"] == "diffuse" {
                    for k in ["median", "min", "max"] {
                        r["figures"]["agreement"][k] = 0.99.into();
                    }
                    planted += 1;
                }
            }
            r.to_string()
        })
        .collect();
    assert_eq!(planted, 1);
    std::fs::write(new.join("rows.jsonl"), rows.join("\n") + "\n").unwrap();
    let compare = |dir: &Path| {
        run(&["compare", &s(&base), &s(&new), "--timings", "ignore", "--repro", &s(dir), "--json"], None, &[], 300).0
    };
    let o = compare(&dir);
    assert_eq!(o.status.code(), Some(1), "the worse agreement fails: {}", common::cli::stderr(&o));
    let r: Value = serde_json::from_slice(&o.stdout).unwrap();
    let repros = r["repros"].as_array().unwrap();
    assert_eq!(repros.len(), 1, "{r}");
    let x = &repros[0];
    assert_eq!(x["cell"], "layout=bvh2 leaf=4 method=unit rays=1560 scene=bunny set=diffuse", "{x}");
    let cell_dir = PathBuf::from(x["dir"].as_str().unwrap());
    assert_eq!(cell_dir, dir.join("bunny-diffuse-unit-bvh2-leaf4"));
    assert!(x["this_device"].as_str().unwrap().starts_with("BASE's device and driver"), "{x}");
    assert!(x["this_device"].as_str().unwrap().contains("NEW ran on llvmpipe"), "{x}");
    let m = manifest(&cell_dir);
    assert_eq!(m["rays"]["bytes"], 1560 * 32, "the run's diffuse set, made again: {m}");
    assert!(m["made"]["driver"].as_str().unwrap().contains("Mesa 25"), "{m}");
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    assert!(readme.contains("agreement: 1 fraction -> 0.9900 fraction (worse)"), "{readme}");
    // The folder replays here as made.
    let c = check(&cell_dir, &[]);
    assert_eq!(c["differences"]["identical"], 1560, "{c}");
    // A folder that exists is refused before anything is compared.
    let o = compare(&dir);
    expect_error(&o, &["--repro", "exists"]);
    // A run whose bench.json records no recipe: the cell is not made, and says why by file.
    let mut json: Value = serde_json::from_str(&std::fs::read_to_string(new.join("bench.json")).unwrap()).unwrap();
    json.as_object_mut().unwrap().remove("recipe");
    std::fs::write(new.join("bench.json"), json.to_string()).unwrap();
    let o = compare(&tmp.path().join("again"));
    let r: Value = serde_json::from_slice(&o.stdout).unwrap();
    let made = r["repros"][0]["made"].as_str().unwrap();
    assert!(made.starts_with("not made:") && made.contains("bench.json") && made.contains("no recipe"), "{made}");
}
