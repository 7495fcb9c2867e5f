//! `trilab bench --embree/--tinybvh` with fake peer programs (shell scripts written here): a
//! peer's line is read and set beside trilab's best row with the ratios and the speed target; a
//! peer whose hits disagree with the f64 reference is reported as failing, never timed; an
//! OpenCL layout without OpenCL is skipped with a note; a missing program, a garbage line or a
//! crash is an error naming the program and layout before the long work. The correct fakes get
//! their hits from `trilab raycast` itself, so they are right by construction, not by copying a
//! value from the code under test. Every run has a wall-clock limit and validation on.

mod common;

use std::path::{Path, PathBuf};

use common::cli::{expect_error, ok, s};
use serde_json::Value;

/// The small bench every test runs: the bunny, one method, tiny ray sets, one timed run.
const SMALL: &[&str] = &[
    "bench",
    "--scenes",
    "bunny",
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
];

/// Writes an executable shell script `name` into `dir`.
fn script(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, format!("#!/bin/sh\nset -e\n{body}")).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    p
}

/// `trilab raycast` as a peer would trace: the right hits for `$rays` on `$scene` into `$hits`.
fn raycast_line(scene: &str, rays: &str, hits: &str) -> String {
    format!(
        "'{}' raycast --scene \"{scene}\" --rays \"{rays}\" --out \"{hits}\" --method mt >/dev/null 2>&1\n",
        env!("CARGO_BIN_EXE_trilab")
    )
}

/// A fake `embree_rays trace OBJ RAYS HITS REPEAT`: right hits, Embree's line at 3.25 Mrays/s.
fn fake_embree(dir: &Path) -> PathBuf {
    let body = format!(
        "n=$(( $(wc -c < \"$3\") / 32 ))\n{}\
         echo \"embree3 default threads=2 tris=1 rays=$n hits=0 build_ms=1.0 best_s=0.001 mrays_per_s=3.25\"\n",
        raycast_line("$2", "$3", "$4")
    );
    script(dir, "embree_rays", &body)
}

/// A fake `tinybvh_rays trace LAYOUT OBJ RAYS HITS REPEATS`: `cpu-bvh8` right at 2.50 Mrays/s,
/// `ocl-bvh2` wrong (every ray "hits" triangle 0 at t = 0), `ocl-cwbvh` without OpenCL.
fn fake_tinybvh(dir: &Path) -> PathBuf {
    let body = format!(
        "n=$(( $(wc -c < \"$4\") / 32 ))\n\
         case \"$2\" in\n\
         ocl-cwbvh) echo 'no OpenCL device' >&2; exit 3 ;;\n\
         ocl-bvh2) head -c $(( n * 16 )) /dev/zero > \"$5\" ;;\n\
         *) {} ;;\n\
         esac\n\
         echo \"layout=$2 scene=x rays=$n build_ms=1.0 trace_ms=0.4 mrays_per_s=2.50 threads=2 hits=0 median_ms=0.5 repeats=1 builder=BuildHQ\"\n",
        raycast_line("$3", "$4", "$5").trim_end()
    );
    script(dir, "tinybvh_rays", &body)
}

fn bench(extra: &[&str], timeout_s: u64) -> std::process::Output {
    let mut args = SMALL.to_vec();
    args.extend(extra);
    common::cli::trilab(&args, timeout_s)
}

#[test]
fn peers_are_validated_then_timed_beside_trilabs_best() {
    let dir = tempfile::tempdir().unwrap();
    let (embree, tinybvh) = (s(&fake_embree(dir.path())), s(&fake_tinybvh(dir.path())));
    let out = s(dir.path());
    let layouts = "cpu-bvh8,ocl-bvh2,ocl-cwbvh";
    let o = bench(
        &["--embree", &embree, "--tinybvh", &tinybvh, "--tinybvh-layouts", layouts, "--json", "--out", &out],
        300,
    );
    let err = ok(&o);
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let notes: Vec<&str> = j["notes"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
    assert!(
        notes.iter().any(|n| n.contains("tinybvh ocl-cwbvh: skipped") && n.contains("no OpenCL device")),
        "the OpenCL layout without OpenCL is skipped with its reason: {notes:?}"
    );
    let rows = j["rows"].as_array().unwrap();
    let comparisons = j["peers"].as_array().unwrap();
    assert_eq!(comparisons.len(), 3, "one comparison per ray set");
    for c in comparisons {
        let set = c["ray_set"].as_str().unwrap();
        // trilab's best is the fastest of its own rows on this set, named.
        let mine: Vec<&Value> = rows.iter().filter(|r| r["ray_set"] == set && r["method"] == "mt").collect();
        let best = mine.iter().map(|r| r["mrays_per_s"].as_f64().unwrap()).fold(0.0, f64::max);
        assert!(best > 0.0);
        assert_eq!(c["trilab"]["mrays_per_s"].as_f64().unwrap(), best, "{set}");
        assert_eq!(c["trilab"]["method"], "mt");
        assert_eq!(c["trilab"]["layout"], "bvh2");
        let peers = c["peers"].as_array().unwrap();
        let names: Vec<&str> = peers.iter().map(|p| p["peer"].as_str().unwrap()).collect();
        assert_eq!(names, ["embree3", "tinybvh cpu-bvh8", "tinybvh ocl-bvh2"], "{set}");
        // The right peers are timed at the rate their line gives, after passing the f64 check.
        assert_eq!(peers[0]["status"], "timed");
        assert_eq!(peers[0]["mrays_per_s"], 3.25);
        assert_eq!(peers[0]["agreement"], 1.0, "{set}: raycast's hits agree with the reference");
        assert_eq!(peers[1]["status"], "timed");
        assert_eq!(peers[1]["mrays_per_s"], 2.5);
        let n = c["rays"].as_f64().unwrap();
        let median = peers[1]["median_mrays_per_s"].as_f64().unwrap();
        assert!((median - n / 0.5e3).abs() < 1e-9, "median from median_ms=0.5: {median}");
        // The wrong peer is reported as failing validation, with no speed.
        assert_eq!(peers[2]["status"], "wrong-hits", "{set}: a peer with wrong hits is not timed: {}", peers[2]);
        assert!(peers[2].get("mrays_per_s").is_none());
        assert!(peers[2]["reason"].as_str().unwrap().contains("disagree with the f64 reference"));
        assert!(peers[2]["agreement"].as_f64().unwrap() < 0.5);
        // Ratios and the target, from the figures above.
        let t = &c["target"];
        let e = t["vs_embree"]["ratio"].as_f64().unwrap();
        assert!((e - best / 3.25).abs() < 1e-9 && t["vs_embree"]["met"] == (best / 3.25 >= 0.6), "{t}");
        assert!((t["vs_cpu_bvh8"]["ratio"].as_f64().unwrap() - best / 2.5).abs() < 1e-9, "{t}");
        assert!(t["vs_best_opencl"].is_null(), "no OpenCL layout passed: no OpenCL target cell: {t}");
        for r in mine {
            assert_eq!(r["embree_mrays_per_s"], 3.25);
        }
    }
    assert!(err.contains("tinybvh ocl-bvh2: failed validation"), "{err}");
    // The Markdown file carries the same tables and says why a peer failed.
    let md = std::fs::read_to_string(Path::new(&out).join("bench.md")).unwrap();
    for needle in
        ["| trilab mt bvh2 |", "| embree3 | 3.25 |", "wrong hits", "Speed target", "failed validation, not timed"]
    {
        assert!(md.contains(needle), "bench.md lacks `{needle}`:\n{md}");
    }
    let line = md.lines().find(|l| l.contains("| random |") && l.contains("tinybvh cpu-bvh8")).unwrap();
    assert!(
        line.contains(&format!("{:.2}", comparisons[2]["trilab"]["mrays_per_s"].as_f64().unwrap() / 2.5)),
        "{line}"
    );
}

#[test]
fn a_peer_that_cannot_report_is_an_error_naming_it_before_the_long_work() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("garbage", "echo hello\n", vec!["no result line", "`hello`"]),
        ("crash", "echo 'Segmentation fault' >&2; exit 139\n", vec!["failed", "Segmentation fault"]),
        ("short", "echo \"layout=$2 rays=3 mrays_per_s=1.0\"\n", vec!["traced 3 rays"]),
        ("nohits", "n=$(( $(wc -c < \"$4\") / 32 ))\necho \"layout=$2 rays=$n mrays_per_s=1.0\"\n", vec!["hit file"]),
    ];
    for (name, body, needles) in cases {
        let p = s(&script(dir.path(), name, body));
        for layout in ["cpu-bvh8", "ocl-bvh2"] {
            let o = bench(&["--tinybvh", &p, "--tinybvh-layouts", layout], 120);
            let mut all = vec![p.as_str(), layout];
            all.extend(needles.iter().copied());
            let e = expect_error(&o, &all);
            assert!(!e.contains("ray sets ready"), "{name} {layout}: found before any scene work: {e}");
        }
    }
    // The same for Embree: its program named.
    let p = s(&script(dir.path(), "embree_garbage", "echo 'mrays_per_s=fast'\n"));
    let e = expect_error(&bench(&["--embree", &p], 120), &["Embree peer", &p, "`mrays_per_s=fast` is not a number"]);
    assert!(!e.contains("ray sets ready"), "{e}");
}

#[test]
fn missing_or_unrunnable_peer_programs_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let missing = s(&dir.path().join("tinybvh_rays"));
    let e =
        expect_error(&bench(&["--tinybvh", &missing], 60), &["--tinybvh", &missing, "no such file", "tinybvh-peer.sh"]);
    assert!(!e.contains("ray sets ready"), "{e}");
    let plain = dir.path().join("embree_rays");
    std::fs::write(&plain, "#!/bin/sh\n").unwrap();
    expect_error(&bench(&["--embree", &s(&plain)], 60), &["--embree", &s(&plain), "not executable"]);
    expect_error(&bench(&["--tinybvh", &s(dir.path())], 60), &["--tinybvh", "not a file"]);
    // Layouts without the program is a usage error from the command line.
    let o = bench(&["--tinybvh-layouts", "cpu-bvh8"], 60);
    assert_eq!(o.status.code(), Some(2), "{}", common::cli::stderr(&o));
    expect_error(&o, &["--tinybvh"]);
    let o = bench(&["--tinybvh", &missing, "--tinybvh-layouts", "gpu-magic"], 60);
    expect_error(&o, &["gpu-magic", "cpu-bvh8"]);
}
