//! Issue 24, defect 7: SIGTERM (what `timeout`, CI runners and containers send) is Ctrl-C.
//! `render` finishes the pass in flight, writes the image so far and exits 143 (128 + SIGTERM),
//! where it used to die and lose the passes since its last checkpoint; `suite` says what it
//! kept, which parts completed and where, and exits 128 + the signal, where it used to die
//! silently. Each run has a wall-clock limit and runs under the validation layer.

mod common;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use common::cli::s;

/// A running trilab whose stderr lines arrive on a channel (and are kept).
struct Running {
    child: Child,
    lines: mpsc::Receiver<String>,
    seen: Vec<String>,
}

impl Running {
    fn start(args: &[&str]) -> Running {
        let mut child = Command::new(env!("CARGO_BIN_EXE_trilab"))
            .args(args)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .env("TRILAB_VALIDATION", "1")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (tx, lines) = mpsc::channel();
        let stderr = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(|l| l.ok()) {
                let _ = tx.send(line);
            }
        });
        Running { child, lines, seen: vec![] }
    }

    /// Waits up to `limit` for a stderr line that starts with `prefix` (killing the process and
    /// failing past it, or if it ends first).
    fn wait_for_line(&mut self, prefix: &str, limit: Duration) {
        let start = Instant::now();
        while !self.seen.iter().any(|l| l.starts_with(prefix)) {
            match self.lines.recv_timeout(Duration::from_millis(100)) {
                Ok(line) => self.seen.push(line),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    panic!("trilab ended before `{prefix}`:\n{}", self.seen.join("\n"))
                }
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("no `{prefix}` within {limit:?}:\n{}", self.seen.join("\n"));
            }
        }
    }

    /// Waits up to `limit` for a file (failing as above).
    fn wait_for_file(&mut self, path: &Path, limit: Duration) {
        let start = Instant::now();
        while !path.exists() {
            assert!(self.child.try_wait().unwrap().is_none(), "trilab ended early");
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("no {} within {limit:?}", path.display());
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Sends `signal`, then waits up to `limit` for the exit; the status and all of stderr.
    fn signal_and_wait(mut self, signal: i32, limit: Duration) -> (ExitStatus, String) {
        // SAFETY: signals a child this test started and has not reaped.
        assert_eq!(unsafe { libc::kill(self.child.id() as i32, signal) }, 0);
        let start = Instant::now();
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status;
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("trilab did not stop within {limit:?} of signal {signal}");
            }
            std::thread::sleep(Duration::from_millis(50));
        };
        // The reader thread ends with the pipe.
        self.seen.extend(self.lines.iter());
        (status, self.seen.join("\n"))
    }
}

/// Before: SIGTERM ended the render at once (no exit code: killed by the signal), leaving only
/// the last checkpoint, `"interrupted": false`.
#[test]
fn sigterm_during_render_saves_the_image_and_exits_143() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("r.exr");
    let json = dir.path().join("r.json");
    let bunny = s(&common::root().join("scenes/bunny.obj"));
    let mut r = Running::start(&[
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
    Running::start(&[
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
