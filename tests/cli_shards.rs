//! `--shard I/N` on the matrix commands besides the study (`bench`, `accuracy`, `build-bench`) and
//! `trilab merge` of their shards, end to end (bench under the validation layer): shards 1/2 and
//! 2/2 of a tiny matrix measure disjoint cells whose union is exactly the unsharded run's cells,
//! every shard plans the unsharded run's whole matrix, each shard's report says it is partial,
//! the merge of both shards misses no cell while one shard alone misses the other's cells, and a
//! bad shard is refused before any work, naming `--shard`. Timings are not compared.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::time::Instant;

use common::cli::{expect_error, ok, trilab};

type Cell = BTreeMap<String, String>;

/// A rows file: its rows' cells (each once), its plan's cells and its shard, and per cell the
/// figures that are not timings (counts and correctness: exact, so the same in every run).
struct Rows {
    cells: BTreeSet<Cell>,
    exact: BTreeMap<Cell, BTreeMap<String, f64>>,
    plan: Vec<Cell>,
    shard: serde_json::Value,
}

fn cell(v: &serde_json::Value) -> Cell {
    v.as_object().unwrap().iter().map(|(k, v)| (k.clone(), v.as_str().unwrap().to_owned())).collect()
}

fn rows(dir: &Path, command: &str) -> Rows {
    let text = std::fs::read_to_string(dir.join("rows.jsonl")).unwrap();
    let mut r = Rows { cells: BTreeSet::new(), exact: BTreeMap::new(), plan: vec![], shard: serde_json::Value::Null };
    let mut plans = 0;
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["schema"], "trilab-rows/1");
        assert_eq!(v["command"], command, "{v}");
        assert!(v["source"]["device"].as_str().is_some_and(|d| !d.is_empty()), "{v}");
        if v["type"] == "plan" {
            plans += 1;
            r.plan = v["cells"].as_array().unwrap().iter().map(cell).collect();
            r.shard = v["shard"].clone();
        } else {
            assert!(r.cells.insert(cell(&v["cell"])), "a cell twice: {v}");
            let exact = v["figures"].as_object().unwrap().iter().filter(|(_, f)| f["class"] != "timing");
            r.exact.insert(cell(&v["cell"]), exact.map(|(n, f)| (n.clone(), f["median"].as_f64().unwrap())).collect());
        }
    }
    assert_eq!(plans, 1, "one plan line in {}", dir.display());
    r
}

/// The planned cell a row's cell fills: the one whose every coordinate the row has (a row may
/// add measured coordinates, such as bench's `rays`); exactly one must.
fn planned<'a>(plan: &'a [Cell], c: &Cell) -> &'a Cell {
    let fits: Vec<&Cell> = plan.iter().filter(|p| p.iter().all(|(k, v)| c.get(k) == Some(v))).collect();
    assert_eq!(fits.len(), 1, "{c:?} fills {} planned cells: {fits:?}", fits.len());
    fits[0]
}

fn merge(dirs: &[&Path], out: &Path) -> serde_json::Value {
    let mut args = vec!["merge".to_owned()];
    args.extend(dirs.iter().map(|d| d.to_str().unwrap().to_owned()));
    args.extend(["--out".into(), out.to_str().unwrap().into(), "--json".into()]);
    let o = trilab(&args.iter().map(String::as_str).collect::<Vec<_>>(), 120);
    ok(&o);
    serde_json::from_slice(&o.stdout).unwrap()
}

fn cells_of(v: &serde_json::Value) -> BTreeSet<Cell> {
    v.as_array().unwrap().iter().map(|r| cell(&r["cell"])).collect()
}

/// Runs `args` whole and as shards 1/2 and 2/2 into `dir/{whole,shards/1,shards/2}`, checks the
/// cells, plans, partial notes (in the file `report` of each shard's folder) and merges; `unit`:
/// the coordinates of the groups a shard takes whole (no such group is split over the shards).
/// Returns the unsharded run's rows and the two shards'.
fn check_sharded(dir: &Path, command: &str, args: &[&str], report: &str, unit: &[&str]) -> (Rows, Rows, Rows) {
    let run = |out: &Path, shard: Option<&str>| {
        std::fs::create_dir_all(out).unwrap(); // bench writes into an existing folder
        let mut a: Vec<&str> = args.to_vec();
        a.extend(["--out", out.to_str().unwrap()]);
        if let Some(s) = shard {
            a.extend(["--shard", s]);
        }
        ok(&trilab(&a, 600))
    };
    let (whole, s1, s2) = (dir.join("whole"), dir.join("shards/1"), dir.join("shards/2"));
    run(&whole, None);
    run(&s1, Some("1/2"));
    run(&s2, Some("2/2"));
    let w = rows(&whole, command);
    let (r1, r2) = (rows(&s1, command), rows(&s2, command));

    // The unsharded run: one row per planned cell, no shard.
    assert!(w.shard.is_null());
    let filled: BTreeSet<&Cell> = w.cells.iter().map(|c| planned(&w.plan, c)).collect();
    assert_eq!(filled.len(), w.cells.len(), "two rows fill one planned cell");
    assert_eq!(filled, w.plan.iter().collect(), "the unsharded run measures every planned cell");

    // The shards: the whole matrix planned, disjoint cells, together exactly the unsharded run's.
    assert_eq!((&r1.plan, &r2.plan), (&w.plan, &w.plan), "every shard plans the unsharded run's matrix");
    assert_eq!(
        (&r1.shard, &r2.shard),
        (&serde_json::json!({"index": 1, "count": 2}), &serde_json::json!({"index": 2, "count": 2}))
    );
    assert!(!r1.cells.is_empty() && !r2.cells.is_empty());
    assert!(r1.cells.is_disjoint(&r2.cells), "{:?} {:?}", r1.cells, r2.cells);
    assert_eq!(
        r1.cells.union(&r2.cells).cloned().collect::<BTreeSet<_>>(),
        w.cells,
        "the shards' union is the whole run"
    );
    // A shard measures its cells as the whole run does: the same counts and correctness figures
    // (the same rays, from the same seeds, wherever the shard's share starts).
    for r in [&r1, &r2] {
        for (c, figures) in &r.exact {
            assert_eq!(figures, &w.exact[c], "{c:?}");
        }
    }
    // A shard takes whole groups.
    let groups = |r: &Rows| -> BTreeSet<Vec<String>> {
        r.cells.iter().filter_map(|c| unit.iter().map(|k| c.get(*k).cloned()).collect()).collect()
    };
    assert!(!groups(&r1).is_empty() && groups(&r1).is_disjoint(&groups(&r2)), "a {unit:?} group split over shards");
    for (d, r, i) in [(&s1, &r1, 1), (&s2, &r2, 2)] {
        let text = std::fs::read_to_string(d.join(report)).unwrap();
        let note = format!("partial: shard {i}/2, {} of {} cells", r.cells.len(), w.plan.len());
        assert!(text.contains(&note), "`{note}` in {report}: {text}");
    }
    assert!(!std::fs::read_to_string(whole.join(report)).unwrap().contains("partial"));

    // Both shards merged: nothing missing, every planned cell in the speed table once.
    let m = merge(&[&dir.join("shards")], &dir.join("merged"));
    assert!(m["missing"].as_array().unwrap().is_empty(), "{}", m["missing"]);
    assert_eq!(m["devices"].as_array().unwrap().len(), 1);
    let speed = m["speed"].as_array().unwrap();
    assert!(speed.iter().all(|r| r["per_device"][0]["median"].as_f64().is_some()), "{}", m["speed"]);
    let sped = cells_of(&m["speed"]);
    assert_eq!(sped.len(), speed.len(), "a cell twice in the speed table");
    assert!(sped.iter().all(|c| w.plan.contains(c)), "speed cells are planned cells: {sped:?}");

    // One shard alone: exactly the other shard's cells are missing, from the device's own plan.
    let lone = merge(&[&s1], &dir.join("lone"));
    let other: BTreeSet<Cell> = r2.cells.iter().map(|c| planned(&w.plan, c).clone()).collect();
    assert_eq!(cells_of(&lone["missing"]), other);
    assert!(lone["missing"].as_array().unwrap().iter().all(|r| r["planned_by_device"] == true));
    assert_eq!(lone["devices"][0]["shards"][0]["missing"], serde_json::json!([{"index": 2, "count": 2}]));
    (w, r1, r2)
}

/// Three tiny scenes (round-robin: shard 1 takes the first and third), two methods on two
/// layouts, every ray set a few hundred rays, one timed round.
const BENCH: [&str; 20] = [
    "bench",
    "--scenes",
    "cornell,synth:terrain:2k,synth:spheres:1k",
    "--methods",
    "mt,unit",
    "--layouts",
    "bvh2,bvh4",
    "--width",
    "16",
    "--height",
    "12",
    "--diffuse-per-hit",
    "1",
    "--random-rays",
    "300",
    "--repeat",
    "1",
    "--ray-query",
    "off",
    "--validation",
];

#[test]
fn bench_shards_take_whole_scenes_and_merge_to_the_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    let (w, _, _) = check_sharded(dir.path(), "bench", &BENCH, "bench.md", &["scene"]);
    // 3 scenes x 3 sets x 2 methods x 2 layouts, each row naming its ray count.
    assert_eq!(w.plan.len(), 3 * 3 * 2 * 2);
    assert!(w.cells.iter().all(|c| c["rays"].parse::<usize>().is_ok_and(|n| n > 0)), "{:?}", w.cells);
    assert!(w.plan.iter().all(|c| !c.contains_key("rays")), "a ray count is measured, not planned");
    let primary: BTreeSet<&str> =
        w.cells.iter().filter(|c| c["set"] == "primary").map(|c| c["rays"].as_str()).collect();
    assert_eq!(primary, BTreeSet::from(["192"]), "16 x 12 primary rays");
}

#[test]
fn build_bench_shards_take_whole_scenes_and_merge_to_the_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    // The sweep runs on scenes of at most 400 triangles: a shard plans it for scenes it does not
    // build (the soup of 300 and the spheres of 200, not the terrain of 600).
    let args = [
        "build-bench",
        "--scenes",
        "synth:soup:300,synth:terrain:600,synth:spheres:200",
        "--threads",
        "1,2",
        "--repeat",
        "1",
        "--layouts",
        "bvh2,bvh4",
        "--sweep-max",
        "400",
    ];
    let (w, _, _) = check_sharded(dir.path(), "build-bench", &args, "build.md", &["scene"]);
    let sweeps: BTreeSet<&str> = w
        .plan
        .iter()
        .filter(|c| c.get("builder").is_some_and(|b| b == "trilab-sweep"))
        .map(|c| c["scene"].as_str())
        .collect();
    assert_eq!(sweeps.len(), 2, "{sweeps:?}");
    assert!(sweeps.iter().all(|s| !s.contains("terrain")), "{sweeps:?}");
    // Per scene: binned at 1 and 2 threads, serial, the sweep where small, two layouts.
    assert_eq!(w.plan.len(), 3 * (2 + 1 + 2) + 2);
}

/// The smoke preset at three leaf sizes on two layouts (six groups; round-robin, leaf size major:
/// shard 1 takes bvh2 at every leaf size, shard 2 bvh4), two methods.
const ACCURACY: [&str; 10] = [
    "accuracy",
    "--preset",
    "smoke",
    "--leaf-sizes",
    "1,2,4",
    "--layouts",
    "bvh2,bvh4",
    "--methods",
    "mt,unit",
    "--validation",
];

#[test]
fn accuracy_shards_take_whole_leaf_and_layout_groups_and_merge_to_the_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    let (w, r1, r2) = check_sharded(dir.path(), "accuracy", &ACCURACY, "accuracy.md", &["leaf", "layout"]);
    let parts = |r: &Rows| r.cells.iter().map(|c| c["part"].clone()).collect::<BTreeSet<_>>();
    let all = BTreeSet::from(["extremes", "frontier", "leaks", "self-intersection"].map(String::from));
    assert_eq!(parts(&w), all);
    // The extremes, self-intersection and frontier run once, in the shard owning leaf 4 on bvh2.
    assert_eq!((parts(&r1), parts(&r2)), (all, BTreeSet::from(["leaks".to_owned()])));
    let leaks = |r: &Rows| {
        r.cells.iter().filter(|c| c["part"] == "leaks").map(|c| c["layout"].clone()).collect::<BTreeSet<String>>()
    };
    assert_eq!(leaks(&r1), BTreeSet::from(["bvh2".to_owned()]));
    assert_eq!(leaks(&r2), BTreeSet::from(["bvh4".to_owned()]));
    // Per method: 3 x 2 leak groups, 6 extreme kinds, the offset schemes, one frontier cell.
    let schemes = w.plan.iter().filter(|c| c["part"] == "self-intersection").count() / 2;
    assert!(schemes > 0);
    assert_eq!(w.plan.len(), 2 * (6 + 6 + schemes + 1));
}

#[test]
fn bad_shards_are_refused_before_any_work() {
    for cmd in [&BENCH[..], &ACCURACY[..], &["build-bench", "--scenes", "synth:soup:300,synth:terrain:600"][..]] {
        for bad in ["0/2", "3/2", "1/0", "x"] {
            let mut a = cmd.to_vec();
            a.extend(["--shard", bad]);
            expect_error(&trilab(&a, 60), &["--shard", bad, "I/N"]);
        }
    }
    // More shards than scenes: refused, naming the option and the scene count, before any work.
    let t = Instant::now();
    let mut a = BENCH.to_vec();
    a.extend(["--shard", "4/4"]);
    expect_error(&trilab(&a, 60), &["--shard 4/4", "3 scene(s)"]);
    let o = trilab(&["build-bench", "--scenes", "synth:soup:300,synth:terrain:600", "--shard", "3/3"], 60);
    expect_error(&o, &["--shard 3/3", "2 scene(s)"]);
    let o = trilab(&["accuracy", "--preset", "smoke", "--leaf-sizes", "1,4", "--shard", "3/3"], 60);
    expect_error(&o, &["--shard 3/3", "2 (2 leaf size(s) x 1 layout(s))"]);
    assert!(t.elapsed().as_secs() < 30, "refusals took {:?}", t.elapsed());
}
