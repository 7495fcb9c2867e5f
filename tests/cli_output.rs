//! One output option for every command that writes files: `--out DIR` is declared once
//! (`OutArgs` in src/cli/mod.rs, each command naming its files in its help), and so are
//! `--shard I/N` (`ShardArg`) and `--timeline FILE` (`TimelineArg`); every command makes its `--out`
//! folder when it is missing, and refuses a file given as the folder before any work.

mod common;

use std::path::Path;

use common::cli::{stderr, trilab};

/// The command-line files declare neither option themselves: they flatten the shared groups.
#[test]
fn out_and_shard_are_declared_once() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/cli");
    let mut own = vec![];
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        let path = e.path();
        if path.file_name().unwrap() == "mod.rs" {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        for (n, line) in text.lines().enumerate() {
            let l = line.trim();
            let declares = |field: &str| {
                l.starts_with(&format!("{field}: Option<")) || l.starts_with(&format!("pub {field}: Option<"))
            };
            if declares("out") || declares("shard") || declares("trace") || l.contains("json_out: Option<") {
                own.push(format!("{}:{}: {l}", path.display(), n + 1));
            }
        }
    }
    assert!(
        own.is_empty(),
        "declare --out through OutArgs/ReportOutArgs, --shard through ShardArg and --timeline through TimelineArg:\n{}",
        own.join("\n")
    );
    let text = std::fs::read_to_string(dir.join("mod.rs")).unwrap();
    assert_eq!(text.matches("pub struct OutArgs").count(), 1);
    assert_eq!(text.matches("pub struct ShardArg").count(), 1);
    assert_eq!(text.matches("pub struct TimelineArg").count(), 1);
}

/// Every command that writes a folder of files makes `--out` when it is missing, parents too.
#[test]
fn every_command_makes_a_missing_out_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let cases: &[(&str, &[&str], &str)] = &[
        (
            "bench",
            &[
                "bench",
                "--scenes",
                "cornell",
                "--methods",
                "mt",
                "--width",
                "16",
                "--height",
                "16",
                "--diffuse-per-hit",
                "1",
                "--random-rays",
                "64",
                "--repeat",
                "1",
            ],
            "bench.json",
        ),
        ("spirv", &["spirv"], "instruction_counts.csv"),
        ("man", &["man"], "trilab.1"),
        ("scale", &["scale", "--placement-only"], "scale.json"),
        (
            "roofline",
            &["roofline", "--sizes", "16K", "--rounds", "1", "--invocations", "4096", "--steps", "8"],
            "roofline.json",
        ),
        (
            "driver-stats",
            &["driver-stats", "--kernels", "raycast", "--methods", "mt", "--layouts", "bvh2"],
            "rows.jsonl",
        ),
    ];
    for (name, args, file) in cases {
        let out = tmp.path().join(name).join("not/there/yet");
        let mut argv: Vec<&str> = args.to_vec();
        argv.extend(["--out", out.to_str().unwrap()]);
        let o = trilab(&argv, 600);
        assert!(o.status.success(), "{name} --out {}: {}", out.display(), stderr(&o));
        assert!(out.join(file).is_file(), "{name} wrote no {file} into the folder it was given");
    }
}

/// A file given as the folder is refused by name before any work, and left as it was.
#[test]
fn a_file_as_out_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("a-file");
    std::fs::write(&file, "keep me").unwrap();
    for args in [&["bench", "--scenes", "cornell", "--methods", "mt"][..], &["spirv"], &["scale", "--placement-only"]] {
        let mut argv: Vec<&str> = args.to_vec();
        argv.extend(["--out", file.to_str().unwrap()]);
        let o = trilab(&argv, 120);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?}: a file as --out was accepted");
        assert!(
            err.contains("--out") && err.contains("a-file"),
            "{args:?}: the refusal names the option and the path: {err}"
        );
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep me", "{args:?} wrote over the file");
    }
}
