//! Issue 24, defect 7: SIGTERM (what `timeout`, CI runners and containers send) is Ctrl-C.
//! `render` finishes the pass in flight, writes the image so far and exits 143 (128 + SIGTERM),
//! where it used to die and lose the passes since its last checkpoint; `suite` says what it
//! kept, which parts completed and where, and exits 128 + the signal, where it used to die
//! silently. Each run has a wall-clock limit and runs under the validation layer.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::cli::s;
use common::running::{alive, Running};

/// `trilab args` in the source tree, running.
fn start(args: &[&str]) -> Running {
    Running::start(common::cli::command(args, None, &[]))
}

/// Before: SIGTERM ended the render at once (no exit code: killed by the signal), leaving only
/// the last checkpoint, `"interrupted": false`.
#[test]
fn sigterm_during_render_saves_the_image_and_exits_143() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("r.exr");
    let json = dir.path().join("r.json");
    let bunny = s(&common::root().join("scenes/bunny.obj"));
    let mut r = start(&[
        "render",
        "--scene",
        &bunny,
        "--out",
        &s(&exr),
        "--width",
        "64",
        "--height",
        "48",
        "--spp",
        "100000",
        "--quiet",
        "--submit-ms",
        "50",
        "--checkpoint-secs",
        "0.2",
        "--validation",
    ]);
    // The first checkpoint: the render is under way and its handler installed.
    r.wait_for_file(&json, Duration::from_secs(180));
    let checkpoint: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    let (status, err) = r.signal_and_wait(libc::SIGTERM, Duration::from_secs(60));
    assert_eq!(status.code(), Some(128 + libc::SIGTERM), "exit status after SIGTERM:\n{err}");
    assert!(err.contains("stopped by SIGTERM; the partial output was saved"), "{err}");
    assert!(!err.contains("validation:"), "{err}");
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(j["interrupted"], true, "{j}");
    assert_eq!(j["checkpoint"], false, "the final write, not a checkpoint: {j}");
    let done = j["spp_done"].as_u64().unwrap();
    assert!(done >= checkpoint["spp_done"].as_u64().unwrap() && done < 100_000, "spp_done {done}");
    assert!(std::fs::read(&exr).unwrap().len() > 1000);
    assert!(dir.path().join("r.png").exists());
}

fn suite(out: &Path) -> Running {
    start(&[
        "suite",
        "--size",
        "0",
        "--parts",
        "bench,study",
        "--no-threads",
        "--no-driver-stats",
        "--validation",
        "--out",
        &s(out),
    ])
}

/// Before: the suite died at once on SIGTERM or Ctrl-C, saying nothing (SIGINT: 130 from the
/// shell, no word of what was kept). Now it names the completed parts, the part it stopped in
/// and the folder, and exits 128 + the signal.
#[test]
fn a_stopped_suite_says_what_it_kept() {
    let dir = tempfile::tempdir().unwrap();
    // SIGTERM once the bench is done and the study under way.
    let out = dir.path().join("term");
    let mut r = suite(&out);
    r.wait_for_line("suite: study:", Duration::from_secs(400));
    let (status, err) = r.signal_and_wait(libc::SIGTERM, Duration::from_secs(30));
    assert_eq!(status.code(), Some(128 + libc::SIGTERM), "{err}");
    let d = out.display();
    for needle in [
        "suite: stopped by SIGTERM".to_owned(),
        format!("kept in {d}: devices.txt and devices.json"),
        format!("completed parts: bench ({d}/bench)"),
        format!("stopped during study: {d}/study"),
        "summary.md and suite.json are written only when every part has run: not written".to_owned(),
    ] {
        assert!(err.contains(&needle), "should say `{needle}`:\n{err}");
    }
    assert!(out.join("bench/rows.jsonl").is_file(), "the completed bench is kept");
    assert!(!out.join("summary.md").exists());

    // Ctrl-C before any part: nothing completed, and it says so; 130.
    let out = dir.path().join("int");
    let mut r = suite(&out);
    r.wait_for_line("suite: probe:", Duration::from_secs(120));
    let (status, err) = r.signal_and_wait(libc::SIGINT, Duration::from_secs(30));
    assert_eq!(status.code(), Some(128 + libc::SIGINT), "{err}");
    assert!(err.contains("stopped by SIGINT (Ctrl-C)") && err.contains("no part completed"), "{err}");
    assert!(err.contains("stopped before the first part"), "{err}");
}

/// Issue 39: SIGTERM to the suite while its profile part runs `trilab bench` per LP_NUM_THREADS
/// reaches that child too (before, the child ran on after the suite had gone).
#[test]
fn a_stopped_suite_stops_the_processes_it_started() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("suite");
    let mut r =
        start(&["suite", "--size", "0", "--parts", "profile", "--no-driver-stats", "--validation", "--out", &s(&out)]);
    r.wait_for_text("LP_NUM_THREADS=", Duration::from_secs(400));
    let start = Instant::now();
    let kids = loop {
        let kids = r.children();
        if !kids.is_empty() {
            break kids;
        }
        assert!(start.elapsed() < Duration::from_secs(60), "no child process appeared:\n{}", r.seen.join("\n"));
        std::thread::sleep(Duration::from_millis(20));
    };
    let (status, err) = r.signal_and_wait(libc::SIGTERM, Duration::from_secs(30));
    assert_eq!(status.code(), Some(128 + libc::SIGTERM), "{err}");
    assert!(err.contains("child process(es)"), "the signal was forwarded: {err}");
    let start = Instant::now();
    while kids.iter().any(|&k| alive(k)) {
        assert!(start.elapsed() < Duration::from_secs(20), "children {kids:?} outlived the suite by 20 s:\n{err}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Issue 39: `study` stopped by SIGTERM finishes the (scene, leaf size) group under way, writes
/// the groups it finished (study.md says it stopped early) and exits 143; before, it died
/// with nothing written.
#[test]
fn a_stopped_study_writes_the_groups_it_finished() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let mut r = start(&[
        "study",
        "--preset",
        "smoke",
        "--methods",
        "mt",
        "--leaf-sizes",
        "1,2,4,8,16",
        "--validation",
        "--out",
        &s(&out),
    ]);
    // The first group's render is done: the signal comes during the first or second group.
    r.wait_for_line("  bunny leaf 1 ", Duration::from_secs(300));
    let (status, err) = r.signal_and_wait(libc::SIGTERM, Duration::from_secs(300));
    assert_eq!(status.code(), Some(128 + libc::SIGTERM), "{err}");
    assert!(err.contains("finishing the group under way"), "{err}");
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    assert!(md.contains("Stopped early: stopped before bunny leaf"), "{md}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).unwrap()).unwrap();
    let rows = json["rows"].as_array().unwrap();
    assert!(!rows.is_empty() && rows.len() < 5, "{} rows: only the finished groups", rows.len());
    assert!(rows.iter().all(|r| r["leaf_size"] != 16), "the last group never ran");
}
