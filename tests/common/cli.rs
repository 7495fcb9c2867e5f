//! Running the `trilab` binary from the tests: one runner for every CLI test. Each run has a
//! wall-clock limit (the test fails, naming the command, past it), the Khronos validation layer
//! on (`TRILAB_VALIDATION=1`; any message fails the command, so the test), stdin closed, and both
//! pipes drained while the process runs, so a command that prints more than a pipe holds never
//! stalls until the limit. Variables that change what trilab does (`TRILAB_SCENES`,
//! `TRILAB_TEST_LIMITS`, `TRILAB_INJECT_FAULT`, `TRILAB_INJECT_SLOWDOWN`, and lavapipe's
//! `GALLIVM_PERF`) are cleared unless the test sets them.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// `trilab args` in the source tree; panics past `timeout_s` seconds.
pub fn trilab(args: &[&str], timeout_s: u64) -> Output {
    run(args, None, &[], timeout_s).0
}

/// `trilab args` in `cwd` (default: the source tree) with `env` added; the output and the wall
/// time. Panics past `timeout_s` seconds, after killing the process.
pub fn run(args: &[&str], cwd: Option<&Path>, env: &[(&str, &str)], timeout_s: u64) -> (Output, Duration) {
    let mut cmd = command(args, cwd, env);
    let start = Instant::now();
    let out = output_within(&mut cmd, None, Duration::from_secs(timeout_s), &format!("trilab {args:?}"));
    (out, start.elapsed())
}

/// `trilab args` as every test runs it: in `cwd` (default: the source tree), the validation layer
/// on, the variables that change what trilab does cleared, then `env` added.
pub fn command(args: &[&str], cwd: Option<&Path>, env: &[(&str, &str)]) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_trilab"));
    cmd.args(args)
        .current_dir(cwd.unwrap_or(Path::new(env!("CARGO_MANIFEST_DIR"))))
        .env("TRILAB_VALIDATION", "1")
        .env_remove("TRILAB_SCENES")
        .env_remove("TRILAB_TEST_LIMITS")
        .env_remove("TRILAB_INJECT_FAULT")
        .env_remove("TRILAB_INJECT_SLOWDOWN")
        .env_remove("GALLIVM_PERF");
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd
}

/// Any command, `stdin` fed to it (`None`: closed) and both pipes drained while it runs; panics,
/// naming `what`, past `limit` (after killing it).
pub fn output_within(cmd: &mut Command, stdin: Option<&[u8]>, limit: Duration, what: &str) -> Output {
    cmd.stdin(if stdin.is_some() { Stdio::piped() } else { Stdio::null() })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let start = Instant::now();
    let mut child = cmd.spawn().unwrap_or_else(|e| panic!("cannot start {what}: {e}"));
    let feed = stdin.map(|input| {
        let input = input.to_vec();
        let mut pipe = child.stdin.take().expect("piped stdin");
        // A command that exits without reading its input closes the pipe: not an error here.
        std::thread::spawn(move || {
            let _ = std::io::Write::write_all(&mut pipe, &input);
        })
    });
    let drain = |mut pipe: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let _ = pipe.read_to_end(&mut buf);
            buf
        })
    };
    let stdout = drain(Box::new(child.stdout.take().expect("piped stdout")));
    let stderr = drain(Box::new(child.stderr.take().expect("piped stderr")));
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for a subprocess") {
            break status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what} did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    if let Some(f) = feed {
        f.join().unwrap();
    }
    Output { status, stdout: stdout.join().unwrap(), stderr: stderr.join().unwrap() }
}

/// A command's stderr, as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Fails unless the command succeeded without a validation message; its stderr.
pub fn ok(o: &Output) -> String {
    let e = stderr(o);
    assert!(o.status.success() && !e.contains("validation:"), "should succeed: {e}");
    e
}

/// Fails unless the command failed cleanly (no panic) with a message containing every needle;
/// its stderr.
pub fn expect_error(o: &Output, needles: &[&str]) -> String {
    let e = stderr(o);
    assert!(!o.status.success(), "should fail: {e}");
    assert!(!e.contains("panicked"), "panicked instead of reporting an error: {e}");
    for n in needles {
        assert!(e.contains(n), "error should mention `{n}`: {e}");
    }
    e
}

/// A path as a command-line argument.
pub fn s(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}
