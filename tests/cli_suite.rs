//! `trilab suite` at its smoke sizes: every part runs and validates, summary.md names the device
//! and driver, holds the headline speed table, the claims' verdicts and the frontier, and every
//! file it links exists; bad options are refused before any work. Validation is on and every run
//! has a wall-clock limit (tests/common/cli.rs).

mod common;

use common::cli::{expect_error, ok, s, trilab};

#[test]
fn smoke_suite_writes_a_summary_whose_links_all_exist() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("suite");
    let o = trilab(&["suite", "--size", "0", "--no-threads", "--budget-minutes", "5", "--out", &s(&out)], 600);
    let err = ok(&o);
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap_or_else(|e| panic!("no summary.md: {e}\n{err}"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("suite.json")).unwrap()).unwrap();
    let device = report["provenance"]["device"].as_str().unwrap();
    assert!(!device.is_empty() && md.contains(device), "summary names the device: {md}");
    for section in [
        "## Speed (bench)",
        "## The paper's claims (study)",
        "## Speed and accuracy (accuracy)",
        "## Kernels (profile)",
    ] {
        assert!(md.contains(section), "summary lacks `{section}`:\n{md}");
    }
    // Every part ran at its smoke size (step 1 of its ladder), as --size 0 asks.
    let parts = report["parts"].as_array().unwrap();
    assert_eq!(parts.len(), 4, "{report}");
    for p in parts {
        assert_eq!(p["size"], 0, "{p}");
        assert!(p["took_s"].as_f64().unwrap() > 0.0, "{p}");
    }
    // The headline table's agreement column: the bench validated every row it reports.
    let headline: Vec<&str> =
        md.split("## Speed (bench)").nth(1).unwrap().lines().filter(|l| l.starts_with("| bunny |")).collect();
    assert_eq!(headline.len(), 3, "one row per ray set:\n{md}");
    for line in headline {
        let agreement: f64 = line.trim_end_matches('|').rsplit('|').next().unwrap().trim().parse().unwrap();
        assert!(agreement >= 0.999, "{line}");
    }
    // The claims' verdicts: one row per claim, each with a verdict word.
    for claim in ["| (a) |", "| (b) |", "| (c) |"] {
        assert!(md.contains(claim), "summary lacks claim {claim}:\n{md}");
    }
    // Every relative link resolves to a file the suite wrote.
    let mut links = 0;
    for piece in md.split("](").skip(1) {
        let target = piece.split(')').next().unwrap();
        assert!(out.join(target).is_file(), "summary links {target}, which does not exist");
        links += 1;
    }
    assert!(links >= 10, "{links} links:\n{md}");
}

#[test]
fn bad_options_are_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("o"));
    let o = trilab(&["suite", "--budget-minutes", "0", "--out", &out], 60);
    expect_error(&o, &["--budget-minutes"]);
    let o = trilab(&["suite", "--embree", "/nonexistent/embree_rays", "--out", &out], 60);
    expect_error(&o, &["/nonexistent/embree_rays"]);
    let o = trilab(&["suite", "--parts", "bench,nope", "--out", &out], 60);
    expect_error(&o, &["nope"]);
    assert!(!dir.path().join("o").exists(), "nothing is written for a refused command");
}

/// A part that cannot run on the device (here the bench, whose tinybvh peer is broken: a
/// peer built for another CPU fails so on a lent GPU) is reported in its summary section while
/// the other parts complete and are summarised; the exit status says not all did.
#[test]
fn a_failing_part_is_summarised_and_the_others_complete() {
    let dir = tempfile::tempdir().unwrap();
    let peer = dir.path().join("broken_peer.sh");
    std::fs::write(&peer, "#!/bin/sh\necho 'illegal instruction' >&2\nexit 132\n").unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&peer, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let out = dir.path().join("suite");
    let args = ["suite", "--size", "0", "--no-threads", "--no-driver-stats", "--parts", "bench,study"];
    let o = trilab(&[&args[..], &["--tinybvh", &s(&peer), "--out", &s(&out)]].concat(), 600);
    let err = expect_error(&o, &["1 of 2 parts did not complete", "bench", "illegal instruction"]);
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap_or_else(|e| panic!("no summary.md: {e}\n{err}"));
    let failed = md.split("## Speed (bench) (did not complete)").nth(1).unwrap_or_else(|| panic!("{md}"));
    assert!(failed.lines().nth(2).unwrap().contains("illegal instruction"), "the section says why:\n{md}");
    assert!(md.contains("## The paper's claims (study)\n") && md.contains("| (a) |"), "the study completed:\n{md}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("suite.json")).unwrap()).unwrap();
    let parts = report["parts"].as_array().unwrap();
    assert!(parts[0]["failed"].as_str().unwrap().contains("exit status: 132"), "{}", parts[0]);
    assert!(parts[1]["failed"].is_null(), "{}", parts[1]);
}
