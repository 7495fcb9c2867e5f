//! Issue 39 item 4: a hostile pass over `trilab ab`. Driver files that are missing, a folder,
//! not JSON, empty or naming a library that does not exist; a side's worker that crashes in a
//! round, hangs (before it is ready, or in a round), or prints what is not one of its messages
//! (not JSON, JSON of the wrong shape, one enormous line); Ctrl-C and SIGTERM between rounds.
//! Each is refused with exit 2 ("could not be compared"; 128 + the signal for a stop), naming
//! the side and what happened, within a bounded time, never a panic; nothing is written outside
//! the output folder (the run's working folder and its TMPDIR are left empty), and no worker, nor
//! anything a worker started, outlives `ab`.
//!
//! Side B's "trilab" is a shell script written here (`--b-bin`): one that runs the real trilab
//! for its `ready` message, then dies or hangs; one that forwards two commands to a real worker
//! and then kills itself with SIGSEGV. Every run has a wall-clock limit and the validation layer
//! on.

mod common;

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Output;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use common::cli::s;
use common::running::{alive, Running};

/// The cheapest workload: one scene, one method, one ray set of 2000 rays.
const WORKLOAD: &[&str] =
    &["ab", "--scenes", "cornell", "--methods", "mt", "--sets", "random", "--random-rays", "2000"];

/// Four rounds a side.
const ROUNDS: &[&str] = &["--rounds", "4", "--max-rounds", "4"];

/// The variable every process of one test's `ab` carries (its workers, and what they start):
/// how survivors are found in /proc.
const MARKER: &str = "TRILAB_AB_HOSTILE_MARKER";

/// One test's folders: the run's working folder and its TMPDIR (both must stay empty), and
/// where its scripts and inputs go.
struct Place {
    dir: tempfile::TempDir,
    marker: String,
}

impl Place {
    fn new() -> Place {
        static N: AtomicUsize = AtomicUsize::new(0);
        let dir = tempfile::tempdir().unwrap();
        for sub in ["cwd", "tmp", "in"] {
            std::fs::create_dir(dir.path().join(sub)).unwrap();
        }
        let marker = format!("{}-{}", std::process::id(), N.fetch_add(1, Ordering::SeqCst));
        Place { dir, marker }
    }

    fn cwd(&self) -> PathBuf {
        self.dir.path().join("cwd")
    }

    fn tmp(&self) -> PathBuf {
        self.dir.path().join("tmp")
    }

    /// A path for an input of this test.
    fn input(&self, name: &str) -> PathBuf {
        self.dir.path().join("in").join(name)
    }

    fn env(&self) -> Vec<(&'static str, String)> {
        vec![("TMPDIR", s(&self.tmp())), (MARKER, self.marker.clone())]
    }

    /// `trilab ab WORK extra` in the working folder; the output and the wall time.
    fn ab(&self, extra: &[&str], timeout_s: u64) -> (Output, Duration) {
        let args: Vec<&str> = [WORKLOAD, ROUNDS, extra].concat();
        let env = self.env();
        let env: Vec<(&str, &str)> = env.iter().map(|(k, v)| (*k, v.as_str())).collect();
        common::cli::run(&args, Some(&self.cwd()), &env, timeout_s)
    }

    /// An executable script `name` with `body` after the shebang.
    fn script(&self, name: &str, body: &str) -> PathBuf {
        let path = self.input(name);
        std::fs::write(&path, format!("#!/bin/bash\n{body}\n")).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        path
    }

    /// Nothing left behind: the working folder and TMPDIR are empty, and within 10 s no process
    /// of this run (one carrying its marker) is alive.
    fn assert_clean(&self, context: &str) {
        for d in [self.cwd(), self.tmp()] {
            let left: Vec<String> = std::fs::read_dir(&d)
                .unwrap()
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect();
            assert!(left.is_empty(), "{} holds {left:?} after the run:\n{context}", d.display());
        }
        let start = Instant::now();
        loop {
            let live = survivors(&self.marker);
            if live.is_empty() {
                break;
            }
            assert!(start.elapsed() < Duration::from_secs(10), "processes {live:?} outlived ab by 10 s:\n{context}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// Processes alive (not zombies) whose environment carries `marker`.
fn survivors(marker: &str) -> Vec<u32> {
    let needle = format!("{MARKER}={marker}");
    let me = std::process::id();
    let mut live = vec![];
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else { continue };
        if pid == me {
            continue;
        }
        let Ok(env) = std::fs::read(e.path().join("environ")) else { continue };
        if env.split(|&b| b == 0).any(|v| v == needle.as_bytes()) && alive(pid) {
            live.push(pid);
        }
    }
    live
}

/// Fails unless `o` is exit 2 without a panic and its stderr holds every needle; its stderr.
fn refused(o: &Output, needles: &[&str]) -> String {
    let e = common::cli::stderr(o);
    assert_eq!(o.status.code(), Some(2), "exit 2, the sides could not be compared:\n{e}");
    assert!(!e.contains("panicked"), "panicked:\n{e}");
    for n in needles {
        assert!(e.contains(n), "should say `{n}`:\n{e}");
    }
    e
}

// ---- Driver files ----------------------------------------------------------------------------

/// Each side given `icd` in turn: refused before either side starts, naming the side, the
/// option, the file and `why`; the file is left as it was.
fn refuses_icd(p: &Place, icd: &Path, why: &str) {
    let before = std::fs::read(icd).ok();
    for (side, flag) in [("A", "--a-icd"), ("B", "--b-icd")] {
        let (o, took) = p.ab(&[flag, &s(icd)], 60);
        let e = refused(&o, &[&format!("side {side}: {flag} {}: {why}", icd.display())]);
        assert!(!e.contains("starting"), "refused before any side starts:\n{e}");
        assert!(took < Duration::from_secs(20), "took {took:?}:\n{e}");
        assert_eq!(std::fs::read(icd).ok(), before, "the driver file is not changed");
        p.assert_clean(&e);
    }
}

#[test]
fn a_missing_driver_file_is_refused_naming_the_side_and_file() {
    let p = Place::new();
    refuses_icd(&p, &p.input("no-such-icd.json"), "no such file");
}

#[test]
fn a_folder_as_driver_file_is_refused() {
    let p = Place::new();
    let d = p.input("icd.d");
    std::fs::create_dir(&d).unwrap();
    std::fs::write(d.join("lvp.json"), "{}").unwrap();
    refuses_icd(&p, &d, "a directory, not an ICD JSON file");
}

#[test]
fn a_driver_file_that_is_not_json_is_refused() {
    let p = Place::new();
    let f = p.input("icd.json");
    std::fs::write(&f, "this is not JSON\n").unwrap();
    refuses_icd(&p, &f, "not JSON (");
}

#[test]
fn an_empty_driver_file_is_refused() {
    let p = Place::new();
    let f = p.input("empty.json");
    std::fs::write(&f, "").unwrap();
    refuses_icd(&p, &f, "the file is empty");
}

#[test]
fn a_driver_file_naming_a_missing_library_is_refused() {
    let p = Place::new();
    let f = p.input("nolib.json");
    std::fs::write(
        &f,
        r#"{"file_format_version":"1.0.0","ICD":{"library_path":"/nonexistent/libvk.so","api_version":"1.3.0"}}"#,
    )
    .unwrap();
    refuses_icd(&p, &f, "its driver library /nonexistent/libvk.so does not exist");
    // JSON that names no driver at all.
    let f = p.input("nodriver.json");
    std::fs::write(&f, r#"{"file_format_version":"1.0.0","layers":[]}"#).unwrap();
    refuses_icd(&p, &f, "names no driver");
    // A library that exists but is no driver: the loader's refusal, from the side's worker as it
    // sets up, named with the side.
    let f = p.input("notadriver.json");
    std::fs::write(&f, r#"{"file_format_version":"1.0.0","ICD":{"library_path":"/bin/true","api_version":"1.3.0"}}"#)
        .unwrap();
    let (o, _) = p.ab(&["--b-icd", &s(&f)], 60);
    let e = refused(&o, &["side B: the worker ended with exit status", "while it set up", "Vulkan error"]);
    p.assert_clean(&e);
}

// ---- Workers that crash, hang or print garbage ------------------------------------------------

/// A script that prints the real worker's `ready` message (the real trilab, run with no
/// commands), then runs `then`.
fn ready_then(p: &Place, name: &str, then: &str) -> PathBuf {
    let trilab = env!("CARGO_BIN_EXE_trilab");
    p.script(name, &format!("ulimit -c 0\n\"{trilab}\" \"$@\" </dev/null | head -n 1\n{then}"))
}

#[test]
fn a_worker_that_crashes_in_the_first_round_is_named_with_its_signal() {
    let p = Place::new();
    let b = ready_then(&p, "segv.sh", "kill -SEGV $$");
    let (o, took) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(
        &o,
        &[
            "side B: the worker was killed by signal 11 (SIGSEGV) in round 1, cell `cornell random mt bvh2`",
            "not compared",
        ],
    );
    assert!(took < Duration::from_secs(60), "took {took:?}");
    p.assert_clean(&e);
}

#[test]
fn a_worker_that_crashes_after_two_rounds_is_named_with_the_rounds_done() {
    let p = Place::new();
    let trilab = env!("CARGO_BIN_EXE_trilab");
    // A real worker behind a relay that forwards two commands, then dies on the third.
    let b = p.script(
        "relay.sh",
        &format!(
            r#"ulimit -c 0
coproc W {{ exec "{trilab}" "$@"; }}
IFS= read -r line <&"${{W[0]}}" || exit 3
printf '%s\n' "$line"
n=0
while IFS= read -r cmd; do
  n=$((n + 1))
  if [ "$n" -gt 2 ]; then kill -SEGV $$; fi
  printf '%s\n' "$cmd" >&"${{W[1]}}"
  IFS= read -r line <&"${{W[0]}}" || exit 3
  printf '%s\n' "$line"
done"#
        ),
    );
    let (o, _) = p.ab(&["--b-bin", &s(&b)], 120);
    refused(&o, &["side B: the worker was killed by signal 11 (SIGSEGV) in round 3", "after 2 rounds a side"]);
    p.assert_clean(&common::cli::stderr(&o));
    // One that exits with a status of its own.
    let b = ready_then(&p, "exit.sh", "echo 'worker: giving up' >&2; exit 7");
    let (o, _) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(&o, &["side B: the worker ended with exit status 7 in round 1", "worker: giving up"]);
    p.assert_clean(&e);
}

#[test]
fn a_worker_that_hangs_is_killed_and_named_within_the_timeout() {
    let p = Place::new();
    // Silent after its `ready`: killed in round 1, with the `sleep` it started.
    let b = ready_then(&p, "hang.sh", "sleep 1000000");
    let (o, took) = p.ab(&["--b-bin", &s(&b), "--worker-timeout", "3"], 120);
    let e = refused(
        &o,
        &["side B: the worker said nothing for 3 s (--worker-timeout) and was killed in round 1", "not compared"],
    );
    assert!(took < Duration::from_secs(60), "a 3 s timeout took {took:?}:\n{e}");
    p.assert_clean(&e);
    // Silent from the start, on side A: named while it sets up, before side B starts.
    let a = p.script("mute.sh", "sleep 1000000");
    let (o, took) = p.ab(&["--a-bin", &s(&a), "--worker-timeout", "2"], 120);
    let e = refused(&o, &["side A: the worker said nothing for 2 s (--worker-timeout) and was killed while it set up"]);
    assert!(!e.contains("side B: starting"), "{e}");
    assert!(took < Duration::from_secs(60), "took {took:?}:\n{e}");
    p.assert_clean(&e);
    // A timeout that is no number of seconds is refused naming the option.
    let (o, _) = p.ab(&["--worker-timeout", "0"], 30);
    refused(&o, &["--worker-timeout 0: must be a positive number"]);
}

#[test]
fn a_worker_that_prints_garbage_is_refused_quoting_it() {
    let p = Place::new();
    // Not JSON, before its `ready`.
    let b = p.script("words.sh", "echo 'hello, I am not JSON'; sleep 1000000");
    let (o, _) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(
        &o,
        &["side B: the worker printed what is not an ab message", "`hello, I am not JSON`", "while it set up"],
    );
    p.assert_clean(&e);
    // JSON of the wrong shape: no `message`, then a round where `ready` belongs.
    let b = p.script("shape.sh", r#"echo '{"hello": "world"}'"#);
    let (o, _) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(&o, &["side B: the worker printed what is not an ab message", r#"`{"hello": "world"}`"#]);
    p.assert_clean(&e);
    let b = p.script("round.sh", r#"echo '{"message": "round", "cells": []}'; sleep 1000000"#);
    let (o, _) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(&o, &["side B: the worker's first message was not `ready` but `Round { cells: [] }`"]);
    p.assert_clean(&e);
    // A long line of garbage in a round: quoted, cut at 200 bytes, with its length.
    let b = ready_then(&p, "long.sh", "read -r cmd; printf 'z%.0s' $(seq 1000); echo; sleep 1000000");
    let (o, _) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(&o, &["side B: the worker printed what is not an ab message", "... (1000 bytes) in round 1"]);
    assert!(e.contains(&format!("`{}`...", "z".repeat(200))) && !e.contains(&"z".repeat(201)), "{e}");
    p.assert_clean(&e);
}

#[test]
fn an_enormous_line_is_refused_without_reading_it_all() {
    let p = Place::new();
    // 64 MiB without a newline, then the worker hangs: refused at 16 MiB, the message short.
    let b = p.script("flood.sh", "head -c 67108864 /dev/zero | tr '\\0' x; sleep 1000000");
    let (o, took) = p.ab(&["--b-bin", &s(&b)], 120);
    let e = refused(&o, &["side B: the worker printed a line of more than 16 MiB (not an ab message), starting `xxxx"]);
    assert!(e.len() < 4000, "the message quotes only the line's start: {} bytes", e.len());
    assert!(took < Duration::from_secs(60), "took {took:?}");
    p.assert_clean(&e);
}

#[test]
fn a_worker_binary_that_is_a_folder_or_missing_is_refused() {
    let p = Place::new();
    let (o, _) = p.ab(&["--b-bin", &s(&p.input("no-such-trilab"))], 30);
    refused(&o, &["side B: --b-bin", "no-such-trilab: no such file"]);
    let (o, _) = p.ab(&["--a-bin", &s(&p.dir.path().join("in"))], 30);
    refused(&o, &["side A: --a-bin", "a directory, not a trilab executable"]);
    // A file that is not executable: named with the OS's reason.
    let f = p.input("not-executable");
    std::fs::write(&f, "#!/bin/sh\n").unwrap();
    let (o, _) = p.ab(&["--b-bin", &s(&f)], 30);
    let e = refused(&o, &["side B: cannot run", "not-executable", "ermission denied"]);
    p.assert_clean(&e);
}

/// The child's side of the worker service: `trilab __worker` answers what is not one of its
/// requests, and an `ab` side's request, with a typed `failed` message and a failing exit, never a
/// panic; an `ab` side (`__ab-worker ... --hits-dir`, the name older parents use) reads typed
/// requests and the words of protocols 1 and 2 alike.
#[test]
fn the_worker_answers_what_is_not_its_request_with_a_typed_failure() {
    let p = Place::new();
    let worker = |args: &[&str], input: &str| {
        let env = p.env();
        let env: Vec<(&str, &str)> = env.iter().map(|(k, v)| (*k, v.as_str())).collect();
        let mut cmd = common::cli::command(args, Some(&p.cwd()), &env);
        let o = common::cli::output_within(&mut cmd, Some(input.as_bytes()), Duration::from_secs(120), "the worker");
        let messages: Vec<serde_json::Value> =
            String::from_utf8_lossy(&o.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        (o, messages)
    };
    for (input, needle) in [
        ("hello\n", "unknown command `hello`"),
        ("{\"request\": \"bench-threads\"}\n", "is not a request"),
        ("{\"request\": \"cell\", \"index\": 0}\n", "rounds and cells are an ab side's"),
    ] {
        let (o, m) = worker(&["__worker"], input);
        let e = common::cli::expect_error(&o, &[needle]);
        assert_eq!(m.len(), 1, "one answer: {m:?}\n{e}");
        assert_eq!(m[0]["message"], "failed", "{m:?}");
        assert!(m[0]["error"].as_str().unwrap().contains(needle), "{m:?}");
    }
    let hits = p.input("hits");
    std::fs::create_dir(&hits).unwrap();
    let hits_arg = s(&hits);
    let side = [&["__ab-worker"], &WORKLOAD[1..], &["--hits-dir", &hits_arg]].concat();
    let (o, m) = worker(&side, "round\n{\"request\": \"cell\", \"index\": 0}\ncell 0\n{\"request\": \"quit\"}\n");
    common::cli::ok(&o);
    let kinds: Vec<&str> = m.iter().map(|x| x["message"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["ready", "round", "round", "round"], "{m:?}");
    assert_eq!(m[0]["protocol"], trilab::services::worker::PROTOCOL, "{m:?}");
    // A one-shot request is not an ab side's.
    let (o, m) = worker(&side, "{\"request\": \"dispatch-kernels\", \"kernels\": []}\n");
    common::cli::expect_error(&o, &["an ab side answers round, cell and quit"]);
    assert_eq!(m.last().unwrap()["message"], "failed", "{m:?}");
    std::fs::remove_dir_all(&hits).unwrap();
    p.assert_clean("the worker");
}

// ---- Stop signals -----------------------------------------------------------------------------

/// `ab` with the test workload and `extra`, in `p`'s folder and environment, running.
fn start(p: &Place, extra: &[&str]) -> Running {
    let env = p.env();
    let env: Vec<(&str, &str)> = env.iter().map(|(k, v)| (*k, v.as_str())).collect();
    Running::start(common::cli::command(&[WORKLOAD, extra].concat(), Some(&p.cwd()), &env))
}

/// `ab` stopped by `signal` once its fourth round is done: it says what it had measured, exits
/// 128 + the signal, writes nothing, and its workers end with it.
fn stop_between_rounds(signal: i32, name: &str) {
    let p = Place::new();
    let out = p.dir.path().join("out");
    // Rounds until the time cap: the signal comes long before.
    let rounds = ["--rounds", "4", "--max-rounds", "1000000", "--target", "0.0001", "--time-cap", "600"];
    let mut r = start(&p, &[&rounds[..], &["--out", &s(&out)]].concat());
    // The fourth round's line ("  4 rounds a side", not 14): the rounds are under way.
    r.wait_for_text("  4 rounds a side: widest cell interval", Duration::from_secs(120));
    let workers = r.children();
    assert_eq!(workers.len(), 2, "two workers run: {workers:?}");
    let (status, err) = r.signal_and_wait(signal, Duration::from_secs(30));
    let code = status.code();
    assert_eq!(code, Some(128 + signal), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for needle in [
        format!("ab: stopped by {name} (and its 2 worker(s)); stopped during round "),
        "rounds a side done (at least 4 were to run, at most 1000000); no verdict".to_owned(),
        format!("nothing written to {}", out.display()),
    ] {
        assert!(err.contains(&needle), "should say `{needle}`:\n{err}");
    }
    // The rounds it names as done are at least the four it reported.
    let done: usize = err
        .split("stopped during round ")
        .nth(1)
        .and_then(|t| t.split(": ").nth(1))
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count of rounds done:\n{err}"));
    assert!(done >= 4, "{done} rounds done:\n{err}");
    let start = Instant::now();
    while workers.iter().any(|&w| alive(w)) {
        assert!(start.elapsed() < Duration::from_secs(10), "workers {workers:?} outlived ab by 10 s:\n{err}");
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(!out.join("ab.json").exists() && !out.join("rows.jsonl").exists(), "nothing is written");
    p.assert_clean(&err);
}

#[test]
fn ctrl_c_between_rounds_says_what_was_measured_and_ends_the_workers() {
    stop_between_rounds(libc::SIGINT, "SIGINT (Ctrl-C)");
}

#[test]
fn sigterm_between_rounds_says_what_was_measured_and_ends_the_workers() {
    stop_between_rounds(libc::SIGTERM, "SIGTERM");
}
