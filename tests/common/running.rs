//! A trilab process a test stops while it runs: its stderr lines arrive on a channel (and are
//! kept), the test waits for a line or a file, reads which processes it started, then signals
//! it and waits for its exit, each wait with a wall-clock limit.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

pub struct Running {
    pub child: Child,
    lines: mpsc::Receiver<String>,
    pub seen: Vec<String>,
}

impl Running {
    /// Starts `cmd` (see `super::cli::command`) with stdin closed, stdout dropped and stderr read.
    pub fn start(mut cmd: Command) -> Running {
        let mut child = cmd.stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
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
    pub fn wait_for_line(&mut self, prefix: &str, limit: Duration) {
        self.wait_until(|l| l.starts_with(prefix), prefix, limit)
    }

    /// Waits up to `limit` for a stderr line containing `needle` (failing as wait_for_line).
    pub fn wait_for_text(&mut self, needle: &str, limit: Duration) {
        self.wait_until(|l| l.contains(needle), needle, limit)
    }

    fn wait_until(&mut self, found: impl Fn(&str) -> bool, what: &str, limit: Duration) {
        let start = Instant::now();
        while !self.seen.iter().any(|l| found(l)) {
            match self.lines.recv_timeout(Duration::from_millis(100)) {
                Ok(line) => self.seen.push(line),
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    panic!("trilab ended before `{what}`:\n{}", self.seen.join("\n"))
                }
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("no `{what}` within {limit:?}:\n{}", self.seen.join("\n"));
            }
        }
    }

    /// Waits up to `limit` for a file (failing as above).
    pub fn wait_for_file(&mut self, path: &Path, limit: Duration) {
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

    /// The processes this one started that run now (from /proc: its threads' children).
    pub fn children(&self) -> Vec<u32> {
        let mut out = vec![];
        let tasks = format!("/proc/{}/task", self.child.id());
        for t in std::fs::read_dir(tasks).into_iter().flatten().flatten() {
            let text = std::fs::read_to_string(t.path().join("children")).unwrap_or_default();
            out.extend(text.split_whitespace().filter_map(|p| p.parse::<u32>().ok()));
        }
        out
    }

    /// Sends `signal`, then waits up to `limit` for the exit; the status and all of stderr.
    pub fn signal_and_wait(mut self, signal: i32, limit: Duration) -> (ExitStatus, String) {
        // SAFETY: signals a child this test started and has not reaped.
        assert_eq!(unsafe { libc::kill(self.child.id() as i32, signal) }, 0);
        let start = Instant::now();
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status;
            }
            if start.elapsed() > limit {
                let _ = self.child.kill();
                panic!("trilab did not stop within {limit:?} of signal {signal}:\n{}", self.seen.join("\n"));
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        // The reader thread ends with the pipe.
        self.seen.extend(self.lines.iter());
        (status, self.seen.join("\n"))
    }
}

/// Whether process `pid` runs (exists and is not a zombie).
pub fn alive(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| s.rsplit_once(')').map(|(_, r)| r.split_whitespace().next() != Some("Z")))
        .unwrap_or(false)
}
