//! `trilab bench --traversals`, `--scene-access texel,address` and `--orders` (issue 27 items 2, 3
//! and 5): every method x layout x traversal x access path that has a kernel is timed with every
//! ray order in one run, each validated against
//! the f64 reference before it counts (bench refuses a speed otherwise); a combination without a
//! kernel is a note, not an error; the rows carry the traversal and the order as coordinates
//! only where they are not the defaults. Validation layers on; a wall-clock limit.

mod common;

use serde_json::Value;

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj");

#[test]
fn bench_times_every_traversal_and_ray_order_side_by_side() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("bench")).unwrap();
    let out = dir.path().join("bench").to_string_lossy().into_owned();
    let args = [
        "bench",
        "--scenes",
        BUNNY,
        "--methods",
        "unit",
        "--layouts",
        "bvh2,bvh4",
        "--traversals",
        "while-if,while-while",
        "--orders",
        "given,octant-origin",
        "--scene-access",
        "texel,address",
        "--width",
        "48",
        "--height",
        "32",
        "--random-rays",
        "3000",
        "--repeat",
        "1",
        "--validation",
        "--json",
        "--out",
        &out,
    ];
    let o = common::cli::trilab(&args, 600);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let rows = j["rows"].as_array().unwrap();
    // While-if on both layouts and both paths, while-while on bvh2's texel path only: 5 kernels
    // x 2 orders x 3 sets.
    let mut seen: Vec<(String, String, String, String, String)> = rows
        .iter()
        .map(|r| {
            let s = |k: &str| r[k].as_str().unwrap_or_default().to_owned();
            (s("ray_set"), s("layout"), s("traversal"), s("scene_access"), s("order"))
        })
        .collect();
    seen.sort();
    seen.dedup();
    assert_eq!(seen.len(), 30, "{seen:?}");
    let kernels = [
        ("bvh2", "while-if", "texel"),
        ("bvh2", "while-if", "address"),
        ("bvh2", "while-while", "texel"),
        ("bvh4", "while-if", "texel"),
        ("bvh4", "while-if", "address"),
    ];
    for set in ["primary", "diffuse", "random"] {
        for (layout, traversal, access) in kernels {
            for order in ["given", "octant-origin"] {
                let want = [set, layout, traversal, access, order].map(str::to_owned);
                let want = (want[0].clone(), want[1].clone(), want[2].clone(), want[3].clone(), want[4].clone());
                assert!(seen.contains(&want), "no row {want:?}");
            }
        }
    }
    for note in [
        "while-while traversal on bvh4 (texel path): not run",
        "while-while traversal on bvh2 (address path): not run",
        "while-while traversal on bvh4 (address path): not run",
    ] {
        assert!(stderr.contains(note), "{note}: {stderr}");
    }
    for r in rows {
        // Each row agreed with the reference (bench refuses a speed otherwise) ...
        assert!(r["agreement"].as_f64().unwrap() >= 0.9999, "{r}");
        // ... and a reordered row's time holds its reordering.
        let kernel = r["kernel_ms"]["median"].as_f64().unwrap();
        match r["order"].as_str().unwrap() {
            "given" => assert!(r["reorder_ms"].is_null(), "{r}"),
            _ => {
                let reorder = r["reorder_ms"]["median"].as_f64().unwrap();
                assert!(reorder > 0.0 && reorder < kernel, "{r}");
            }
        }
    }
    // rows.jsonl: the coordinates appear only where they are not the defaults.
    let text = std::fs::read_to_string(dir.path().join("bench").join("rows.jsonl")).unwrap();
    let cells: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|l| l["type"] == "row")
        .map(|l| l["cell"].clone())
        .collect();
    assert_eq!(cells.len(), 30);
    let count = |k: &str, v: &str| cells.iter().filter(|c| c[k] == v).count();
    assert_eq!(count("traversal", "while-while"), 6);
    assert_eq!(count("order", "octant-origin"), 15);
    assert_eq!(count("access", "address"), 12);
    assert!(cells.iter().all(|c| c["traversal"] != "while-if" && c["order"] != "given" && c["access"] != "texel"));
}

/// `--orders tiles` (issue 53): packets on primary rays traced in screen tiles. Each order's row
/// passes the f64 check (the hits are put back in the set's order before it), the tiled row's
/// time holds its sort. (That the tiles are compact is src/rays/order.rs's unit test.)
#[test]
fn tiles_order_traces_primary_rays_in_screen_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_string_lossy().into_owned();
    let args = [
        "bench",
        "--scenes",
        BUNNY,
        "--methods",
        "mt",
        "--layouts",
        "bvh4",
        "--traversals",
        "packet",
        "--orders",
        "given,tiles",
        "--width",
        "96",
        "--height",
        "64",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "2000",
        "--repeat",
        "1",
        "--validation",
        "--json",
        "--out",
        &out,
    ];
    let o = common::cli::trilab(&args, 600);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let rows = j["rows"].as_array().unwrap();
    let cells: Vec<(&str, &str)> =
        rows.iter().map(|r| (r["ray_set"].as_str().unwrap(), r["order"].as_str().unwrap())).collect();
    for set in ["primary", "diffuse", "random"] {
        for order in ["given", "tiles"] {
            assert!(cells.contains(&(set, order)), "no {set} {order} row: {cells:?}");
        }
    }
    for r in rows {
        assert!(r["agreement"].as_f64().unwrap() >= 0.9999, "{r}");
        assert_eq!(r["traversal"], "packet", "{r}");
        match r["order"].as_str().unwrap() {
            "given" => assert!(r["reorder_ms"].is_null(), "{r}"),
            _ => assert!(r["reorder_ms"]["median"].as_f64().unwrap() > 0.0, "{r}"),
        }
    }
}
