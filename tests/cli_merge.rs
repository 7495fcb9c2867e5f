//! `trilab study --shard I/N` and `trilab merge` end to end under the validation layer: a tiny
//! study sharded two ways and merged has the same cells as the unsharded run (timings are not
//! compared), each shard's report says it is partial, a lone shard's merge lists the other
//! shard's cells as missing, and a cell measured twice for one device is refused.

mod common;

use std::collections::BTreeSet;
use std::path::Path;

use common::cli::{expect_error, ok, trilab};

/// A tiny matrix: the smoke preset's bunny at three leaf sizes and two methods.
const TINY: [&str; 7] = ["study", "--preset", "smoke", "--leaf-sizes", "1,2,4", "--methods", "mt,unit"];

fn study(out: &Path, extra: &[&str]) -> String {
    let mut args: Vec<&str> = TINY.to_vec();
    args.extend(["--validation", "--out", out.to_str().unwrap()]);
    args.extend(extra);
    let err = ok(&trilab(&args, 600));
    assert!(!err.contains("validation:"), "validation messages: {err}");
    err
}

/// The cells of a rows file's rows, and its plan's cells and shard.
fn rows(dir: &Path) -> (BTreeSet<String>, BTreeSet<String>, serde_json::Value) {
    let text = std::fs::read_to_string(dir.join("rows.jsonl")).unwrap();
    let (mut cells, mut plan, mut shard) = (BTreeSet::new(), BTreeSet::new(), serde_json::Value::Null);
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(v["schema"], "trilab-rows/1");
        if v["type"] == "plan" {
            plan.extend(v["cells"].as_array().unwrap().iter().map(|c| c.to_string()));
            shard = v["shard"].clone();
        } else {
            assert_eq!(v["command"], "study");
            let f = &v["figures"];
            for name in ["render_s", "primary_mrays_per_s", "random_agreement", "sah_cost"] {
                assert!(f[name]["median"].as_f64().is_some(), "{name} in {v}");
            }
            assert_eq!(f["render_s"]["class"], "timing");
            assert_eq!(f["primary_agreement"]["class"], "correctness");
            assert!(f["primary_agreement"]["median"].as_f64().unwrap() >= 0.9999);
            assert_eq!(f["bvh_nodes"]["class"], "count");
            assert!(v["source"]["device"].as_str().is_some_and(|d| !d.is_empty()));
            cells.insert(v["cell"].to_string());
        }
    }
    (cells, plan, shard)
}

fn merge_json(dirs: &[&Path], out: &Path) -> serde_json::Value {
    let mut args = vec!["merge".to_owned()];
    args.extend(dirs.iter().map(|d| d.to_str().unwrap().to_owned()));
    args.extend(["--out".into(), out.to_str().unwrap().into(), "--json".into()]);
    let o = trilab(&args.iter().map(String::as_str).collect::<Vec<_>>(), 120);
    ok(&o);
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn two_shards_merge_to_the_cells_of_the_unsharded_study() {
    let dir = tempfile::tempdir().unwrap();
    let (whole, s1, s2) = (dir.path().join("whole"), dir.path().join("shards/1"), dir.path().join("shards/2"));
    study(&whole, &[]);
    let err = study(&s1, &["--shard", "1/2"]);
    assert!(err.contains("shard 1/2: 2 of 3 (scene, leaf size) groups"), "{err}");
    study(&s2, &["--shard", "2/2"]);

    let (all, plan, shard) = rows(&whole);
    assert_eq!(all.len(), 3 * 2, "leaf sizes x methods");
    assert_eq!(plan, all, "the unsharded plan is its rows' cells");
    assert!(shard.is_null());
    let (c1, p1, sh1) = rows(&s1);
    let (c2, p2, sh2) = rows(&s2);
    assert_eq!((p1.clone(), p2), (all.clone(), all.clone()), "every shard plans the whole matrix");
    assert_eq!((sh1, sh2), (serde_json::json!({"index": 1, "count": 2}), serde_json::json!({"index": 2, "count": 2})));
    assert!(c1.is_disjoint(&c2) && c1.union(&c2).cloned().collect::<BTreeSet<_>>() == all, "{c1:?} {c2:?}");
    // A shard takes whole leaf sizes: both methods of each of its leaves.
    assert_eq!((c1.len(), c2.len()), (4, 2));
    let md = std::fs::read_to_string(s1.join("study.md")).unwrap();
    assert!(md.contains("**Partial: shard 1/2 of the matrix.**") && md.contains("4 of the matrix's 6"), "{md}");

    let out = dir.path().join("merged");
    let m = merge_json(&[&dir.path().join("shards")], &out);
    assert_eq!(m["devices"].as_array().unwrap().len(), 1);
    let merged: BTreeSet<String> = m["speed"].as_array().unwrap().iter().map(|r| r["cell"].to_string()).collect();
    assert_eq!(merged, all, "the merged shards have the unsharded study's cells");
    assert!(m["missing"].as_array().unwrap().is_empty(), "{}", m["missing"]);
    assert_eq!(m["claims"][0]["measured"], 6);
    for f in ["merge.md", "merge.json", "merge-time-vs-leaf-bunny.png", "merge-methods-vs-mt.png"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let md = std::fs::read_to_string(out.join("merge.md")).unwrap();
    assert!(md.contains("study: 1/2, 2/2") && md.contains("## Missing cells\n\nNone"), "{md}");

    // One shard alone: the other's cells are missing, from the device's own plan.
    let lone = merge_json(&[&s1], &dir.path().join("lone"));
    let missing: BTreeSet<String> = lone["missing"].as_array().unwrap().iter().map(|r| r["cell"].to_string()).collect();
    assert_eq!(missing, c2);
    assert!(lone["missing"].as_array().unwrap().iter().all(|r| r["planned_by_device"] == true));
    assert_eq!(lone["devices"][0]["shards"][0]["missing"], serde_json::json!([{"index": 2, "count": 2}]));

    // The unsharded run and the shards measured the same cells on one device: refused.
    let o = trilab(
        &["merge", whole.to_str().unwrap(), s1.to_str().unwrap(), "--out", dir.path().join("x").to_str().unwrap()],
        120,
    );
    expect_error(&o, &["measured twice", "rows.jsonl"]);
    assert!(!dir.path().join("x/merge.md").exists(), "nothing written after a refusal");
}

#[test]
fn bad_shards_and_merge_inputs_are_refused_before_any_work() {
    expect_error(&trilab(&["study", "--preset", "smoke", "--shard", "3/2"], 60), &["3/2", "I/N"]);
    expect_error(&trilab(&["study", "--preset", "smoke", "--shard", "0/2"], 60), &["0/2"]);
    // Three leaf sizes of one scene are three groups: four shards would leave one empty.
    expect_error(
        &trilab(&["study", "--preset", "smoke", "--leaf-sizes", "1,2,4", "--shard", "4/4"], 60),
        &["--shard 4/4", "3"],
    );
    let dir = tempfile::tempdir().unwrap();
    expect_error(&trilab(&["merge", dir.path().to_str().unwrap()], 60), &["rows.jsonl"]);
    expect_error(&trilab(&["merge", "no/such/folder"], 60), &["no/such/folder"]);
    let bad = dir.path().join("bad");
    std::fs::create_dir_all(&bad).unwrap();
    std::fs::write(bad.join("rows.jsonl"), "{\"schema\":\"trilab-rows/1\",\"type\":\"row\"}\n").unwrap();
    expect_error(&trilab(&["merge", bad.to_str().unwrap()], 60), &["rows.jsonl", "1"]);
}

/// Issue 24, defect 7: merge exited 1 on a malformed row where compare exits 2 (it could not
/// compare), and 0 with an empty report on an empty rows file. Whatever keeps merge from merging
/// exits 2 and names the file, with `--json` too.
#[test]
fn merge_exits_2_naming_the_file_when_it_cannot_merge() {
    let dir = tempfile::tempdir().unwrap();
    let folder = |name: &str, text: &str| {
        let d = dir.path().join(name);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("rows.jsonl"), text).unwrap();
        d.to_str().unwrap().to_owned()
    };
    let malformed = folder("malformed", "{\"schema\":\"trilab-rows/1\",\"type\":\"row\"}\nnot json\n");
    let empty = folder("empty", "");
    let cases: [(Vec<&str>, Vec<String>); 4] = [
        (vec!["merge", &malformed], vec!["malformed/rows.jsonl:1".into()]),
        (vec!["merge", &empty], vec!["empty/rows.jsonl".into(), "no measured row".into()]),
        (vec!["merge", &empty, "--json"], vec!["empty/rows.jsonl".into()]),
        (vec!["merge", "no/such/folder"], vec!["no/such/folder".into()]),
    ];
    for (args, needles) in &cases {
        let o = trilab(args, 60);
        let needles: Vec<&str> = needles.iter().map(String::as_str).collect();
        expect_error(&o, &needles);
        assert_eq!(o.status.code(), Some(2), "trilab {args:?}");
        if args.contains(&"--json") {
            let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            assert_eq!(j["error"]["kind"], "bad-input", "{j}");
        }
    }
    // The same malformed file stops compare with the same status.
    let o = trilab(&["compare", &malformed, &malformed], 60);
    expect_error(&o, &["malformed/rows.jsonl:1"]);
    assert_eq!(o.status.code(), Some(2));
    let out = dir.path().join("out");
    let o = trilab(&["merge", &empty, "--out", out.to_str().unwrap()], 60);
    assert_eq!(o.status.code(), Some(2));
    assert!(!out.join("merge.md").exists(), "no report of nothing");
}
