//! The command line under bad input (issue 14, defects 1, 2, 6 and part of 11): never a panic
//! (exit 101), an empty ray set refused or reported empty, outputs checked before any work with
//! errors naming the user's path, Ctrl-C during `render` saving the image and exiting 130, and
//! `analyze` and the smoke study saying what they cannot judge. Every run has a wall-clock
//! limit; commands that use a device run with the validation layer (`--validation`).

mod common;

use common::cli::s;

use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj");

fn trilab(args: &[&str], timeout_s: u64) -> (Output, Duration) {
    common::cli::run(args, None, &[], timeout_s)
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Never a panic: exit 0 (an empty set reported as empty), 1 or 2, and the output names every
/// needle (the option or file at fault).
fn no_panic(args: &[&str], needles: &[&str]) -> Output {
    let (o, _) = trilab(args, 240);
    let t = text(&o);
    let code = o.status.code();
    assert!(matches!(code, Some(0..=2)), "trilab {args:?}: exit {code:?} (101 is a panic):\n{t}");
    assert!(!t.contains("panicked"), "trilab {args:?} panicked:\n{t}");
    for n in needles {
        assert!(t.contains(n), "trilab {args:?} should mention `{n}`:\n{t}");
    }
    o
}

fn refused(args: &[&str], needles: &[&str]) {
    let o = no_panic(args, needles);
    assert!(matches!(o.status.code(), Some(1 | 2)), "trilab {args:?} should be refused:\n{}", text(&o));
}

#[test]
fn empty_ray_sets_never_panic() {
    let small = ["--methods", "mt", "--repeat", "1", "--validation"];
    let bench = |extra: &[&str]| {
        let mut a = vec!["bench", "--scenes", BUNNY, "--height", "12"];
        for (opt, default) in [("--width", "16"), ("--random-rays", "500")] {
            if !extra.contains(&opt) {
                a.extend_from_slice(&[opt, default]);
            }
        }
        a.extend_from_slice(&small);
        a.extend_from_slice(extra);
        a.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    // bench: an empty set is skipped with a note naming the option; the others still run.
    for (extra, needle) in [
        (&["--random-rays", "0"][..], "--random-rays 0"),
        (&["--width", "0"][..], "--width 0"),
        (&["--diffuse-per-hit", "0"][..], "--diffuse-per-hit 0"),
    ] {
        let a = bench(extra);
        let args: Vec<&str> = a.iter().map(String::as_str).collect();
        let o = no_panic(&args, &[needle, "skipped"]);
        assert!(o.status.success(), "{}", text(&o));
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(out.contains("primary") || out.contains("random"), "the other sets still run:\n{out}");
    }
    // profile times every set: refused at once, naming the option.
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("profile"));
    for (opt, needle) in
        [("--random-rays", "--random-rays 0"), ("--width", "--width 0"), ("--diffuse-per-hit", "--diffuse-per-hit 0")]
    {
        refused(
            &["profile", "--scene", BUNNY, opt, "0", "--out", &out, "--no-threads", "--methods", "mt", "--validation"],
            &[needle],
        );
    }
}

#[test]
fn bad_values_are_refused_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rays = s(&d.join("p.rays"));
    let (o, _) = trilab(&["rays", "primary", "--scene", BUNNY, "--out", &rays, "--width", "8", "--height", "8"], 60);
    assert!(o.status.success(), "{}", text(&o));
    let hits = s(&d.join("o.hits"));
    let empty_rays = d.join("zero.rays");
    std::fs::write(&empty_rays, b"").unwrap();
    let no_tris = d.join("notri.obj");
    std::fs::write(&no_tris, "v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    let empty_obj = d.join("empty.obj");
    std::fs::write(&empty_obj, "").unwrap();
    let exr = s(&d.join("r.exr"));
    let raycast = |extra: &[&str], needles: &[&str]| {
        let mut a =
            vec!["raycast", "--scene", BUNNY, "--rays", &rays, "--out", &hits, "--method", "mt", "--validation"];
        a.extend_from_slice(extra);
        refused(&a, needles);
    };
    raycast(&["--leaf-size", "0"], &["--leaf-size 0"]);
    raycast(&["--leaf-size", "17"], &["--leaf-size 17"]);
    raycast(&["--batch-rays", "0"], &["--batch-rays 0"]);
    raycast(&["--device", "99"], &["99"]);
    refused(&["raycast", "--scene", &s(&no_tris), "--rays", &rays, "--out", &hits], &["notri.obj", "no triangles"]);
    refused(&["raycast", "--scene", &s(&empty_obj), "--rays", &rays, "--out", &hits], &["empty.obj", "no triangles"]);
    refused(&["raycast", "--scene", BUNNY, "--rays", &s(&empty_rays), "--out", &hits], &["zero.rays", "no rays"]);
    let render = |extra: &[&str], needles: &[&str]| {
        let mut a = vec!["render", "--scene", BUNNY, "--out", &exr, "--height", "8", "--quiet", "--validation"];
        if !extra.contains(&"--width") {
            a.extend_from_slice(&["--width", "8"]);
        }
        a.extend_from_slice(extra);
        refused(&a, needles);
    };
    render(&["--spp", "0"], &["--spp"]);
    render(&["--spp", "1", "--submit-ms", "0"], &["--submit-ms 0"]);
    render(&["--spp", "1", "--leaf-size", "0"], &["--leaf-size 0"]);
    render(&["--spp", "1", "--width", "0"], &["--width 0", "empty"]);
    // Generators refuse to write a ray file with no rays (which every reader refuses).
    let x = s(&d.join("x.rays"));
    refused(&["rays", "random", "--scene", BUNNY, "--out", &x, "--random-rays", "0"], &["--random-rays 0"]);
    refused(&["rays", "primary", "--scene", BUNNY, "--out", &x, "--width", "0"], &["--width"]);
    assert!(!d.join("x.rays").exists());
    refused(&["accuracy", "--preset", "smoke", "--leak-rays", "0", "--out", &s(&d.join("acc"))], &["--leak-rays 0"]);
    refused(&["study", "--preset", "smoke", "--leaf-sizes", "0", "--out", &s(&d.join("st"))], &["--leaf-size 0"]);
    refused(&["bvh", "--scene", BUNNY, "--threads", "0"], &["--threads"]);
    refused(&["analyze", "--scene", &s(&empty_obj)], &["empty.obj"]);
}

#[test]
fn outputs_are_checked_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let file = d.join("a-file");
    std::fs::write(&file, "keep").unwrap();
    let file_s = s(&file);
    // Thousands of samples per pixel would take minutes: the missing folder must fail first.
    let (o, took) = trilab(&["render", "--scene", BUNNY, "--out", "/nodir/x.exr", "--spp", "2000", "--quiet"], 60);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(1), "{t}");
    assert!(took < Duration::from_secs(5), "render --out /nodir/x.exr took {took:?} before failing:\n{t}");
    assert!(t.contains("/nodir/x.exr") && !t.contains(".trilab-"), "the error names the user's path only:\n{t}");
    // Folders that cannot be one: an existing file, a folder under /proc (unwritable even for
    // root), a folder under a file.
    let unwritable = "/proc/trilab-no-such-dir/out";
    let under_file = s(&file.join("sub"));
    for out in [file_s.as_str(), unwritable, under_file.as_str()] {
        for cmd in [&["study", "--preset", "smoke"][..], &["accuracy", "--preset", "smoke"][..]] {
            let mut a = cmd.to_vec();
            a.extend_from_slice(&["--out", out, "--validation"]);
            let (o, took) = trilab(&a, 60);
            let t = text(&o);
            assert_eq!(o.status.code(), Some(1), "trilab {a:?}:\n{t}");
            assert!(took < Duration::from_secs(10), "trilab {a:?} took {took:?} before failing:\n{t}");
            assert!(t.contains(out) && !t.contains(".trilab-"), "trilab {a:?}: the error names {out}:\n{t}");
        }
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
    // A file output that is an existing folder, or one of the inputs; a folder output that is a file.
    let folder = s(d);
    refused(&["bench", "--scenes", BUNNY, "--json-out", &folder], &["--json-out", &folder, "directory"]);
    refused(&["bench", "--scenes", BUNNY, "--md-out", BUNNY], &["--md-out", "input"]);
    refused(&["rays", "random", "--scene", BUNNY, "--out", "/nodir/r.rays"], &["/nodir/r.rays", "does not exist"]);
    // `--write` is the old spelling of `--out` (one output option, `OutArgs`): the refusal names
    // the option by its name today.
    refused(&["spirv", "--write", &file_s], &["--out", &file_s]);
    refused(&["build-bench", "--scenes", BUNNY, "--out", &file_s], &["--out", &file_s]);
    refused(&["profile", "--scene", BUNNY, "--out", &file_s, "--no-threads"], &["--out", &file_s]);
    refused(&["scale", "--scenes", BUNNY, "--out", &file_s], &["--out", &file_s]);
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "keep");
}

#[test]
fn ctrl_c_during_render_saves_the_image_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("r.exr");
    let json = dir.path().join("r.json");
    let mut child = Command::new(env!("CARGO_BIN_EXE_trilab"))
        .args(["render", "--scene", BUNNY, "--out", &s(&exr), "--width", "64", "--height", "48"])
        .args(["--spp", "100000", "--quiet", "--checkpoint-secs", "0.2", "--validation"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The first checkpoint shows the render is under way (and the Ctrl-C handler installed).
    let start = Instant::now();
    while !json.exists() {
        assert!(child.try_wait().unwrap().is_none(), "render ended early");
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint within 120 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    let kill = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
    assert!(kill.success());
    let stop = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if stop.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            panic!("render did not stop within 60 s of SIGINT");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "exit status after Ctrl-C:\n{}", text(&o));
    assert!(exr.exists(), "the partial image is kept");
    let sidecar = std::fs::read_to_string(&json).unwrap();
    assert!(sidecar.contains("\"interrupted\": true"), "{sidecar}");
}

#[test]
fn analyze_names_methods_the_frontier_lacks() {
    let dir = tempfile::tempdir().unwrap();
    let builtin =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/results/lavapipe/accuracy/frontier.csv"))
            .unwrap();
    // Only Möller-Trumbore, which leaks: no method in this frontier meets the default target.
    let frontier = dir.path().join("frontier.csv");
    std::fs::write(&frontier, builtin.lines().take(2).collect::<Vec<_>>().join("\n") + "\n").unwrap();
    let (o, _) = trilab(&["analyze", "--scene", BUNNY, "--frontier", &s(&frontier), "--device", "llvmpipe"], 60);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("lacks") && t.contains("watertight"), "names the missing methods:\n{t}");
    assert!(t.contains("recommendation: none"), "recommends nothing that misses the target:\n{t}");
    assert!(!t.contains("recommendation: --method mt"), "{t}");
}

#[test]
fn smoke_study_says_it_cannot_judge_the_claims() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let (o, _) = trilab(
        &["study", "--preset", "smoke", "--methods", "mt,unit,quad-unit", "--out", &s(&out), "--validation"],
        300,
    );
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    for (what, s) in [("report", &t), ("study.md", &md)] {
        assert!(s.contains("cannot judge the paper's claims"), "{what}:\n{s}");
        for verdict in ["holds", "does not hold", "inconclusive"] {
            assert!(!s.contains(&format!(": {verdict}")), "{what} gives a verdict `{verdict}`:\n{s}");
        }
        assert!(s.contains("not judged"), "{what}:\n{s}");
    }
}

/// Output into a pipe whose reader has gone (`trilab completions bash | head -1`) ends trilab
/// quietly, never with a panic (without the SIGPIPE reset in main.rs, `completions` panicked:
/// "failed to write completion file: Broken pipe", exit 101).
#[test]
fn a_closed_stdout_pipe_is_not_a_panic() {
    use std::process::{Command, Stdio};
    for args in [&["completions", "bash"][..], &["man", "--help"][..], &["methods", "--markdown"][..]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_trilab"))
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // the reader is gone before trilab writes
        let start = std::time::Instant::now();
        while child.try_wait().unwrap().is_none() {
            assert!(start.elapsed().as_secs() < 60, "trilab {args:?} did not finish within 60 s");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("panicked") && o.status.code() != Some(101), "trilab {args:?}: {:?} {err}", o.status);
    }
}
