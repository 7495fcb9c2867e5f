//! Running trilab again, in another environment: the one way trilab does it.
//!
//! A driver reads its environment once, when it loads, so work under another environment
//! (another ICD file, `LP_NUM_THREADS`, `GALLIVM_DEBUG=asm`, another trilab build) runs in a
//! child process: `ab`'s sides, `profile`'s LP_NUM_THREADS section (and the suite's, through
//! it), the driver statistics' `GALLIVM_DEBUG=asm` child and an `ab` side's driver statistics.
//! Each is this module's: a [`Launch`] names the executable and its environment, the child is
//! started in a process group of its own ([`crate::children`]), and the two speak the typed
//! JSON lines of [`protocol`]: [`Request`]s on the child's stdin, [`Message`]s on its stdout.
//!
//! Two shapes: a [`Session`] (an `ab` side: it says `ready`, then answers many requests) and a
//! one-shot [`call`] (one request, one answer, and the child's stderr, where a driver prints its
//! own dumps). Either way a child that crashes, hangs past its timeout, prints what is not a
//! message (or a line longer than [`MAX_LINE`]) or fails is an error naming it (`side B`,
//! `LP_NUM_THREADS=2`), what it was doing and the last lines of its stderr, and it is killed
//! with whatever it started.
//!
//! The child's side, the executor of these requests, is a command's: `commands::worker`.

pub mod protocol;

use std::ffi::OsString;
use std::io::{BufRead, BufReader, Seek, Write};
use std::path::{Path, PathBuf};
use std::process::{ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use crate::error::{Error, Result};
pub use protocol::{Message, Request, PROTOCOL};

/// The trilab executable running now: what a [`Launch`] runs unless it is given another build.
pub fn this_exe() -> Result<PathBuf> {
    std::env::current_exe().map_err(|e| Error::io(Path::new("the trilab executable"), e))
}

/// A trilab process to start: which executable, in which environment, and how long it may be
/// silent.
#[derive(Clone, Debug)]
pub struct Launch {
    pub exe: PathBuf,
    /// Variables set for the child only, in order (a later one wins).
    pub env: Vec<(OsString, OsString)>,
    /// Variables the child does not inherit.
    pub unset: Vec<String>,
    /// Options after the command (`__worker --repro DIR`: the worker's context is a repro's).
    pub args: Vec<OsString>,
    /// `--device N`: the device the child opens (`None`: its own choice).
    pub device: Option<usize>,
    /// `--validation`: the child loads the validation layer.
    pub validation: bool,
    /// The longest wait for one message (`None`: as long as the work takes).
    pub timeout: Option<Duration>,
    /// Keep the whole of the child's stderr (a driver's dump), not only its last MiBs (enough
    /// for an error's tail).
    pub whole_stderr: bool,
}

impl Launch {
    /// `exe` in this process's environment, on its default device, without a timeout.
    pub fn new(exe: impl Into<PathBuf>) -> Launch {
        Launch {
            exe: exe.into(),
            env: vec![],
            unset: vec![],
            args: vec![],
            device: None,
            validation: false,
            timeout: None,
            whole_stderr: false,
        }
    }

    /// Sets `key` to `value` for the child.
    pub fn env(mut self, key: impl Into<OsString>, value: impl Into<OsString>) -> Launch {
        self.env.push((key.into(), value.into()));
        self
    }

    pub fn device(mut self, index: usize) -> Launch {
        self.device = Some(index);
        self
    }

    pub fn validation(mut self, on: bool) -> Launch {
        self.validation = on;
        self
    }

    /// `exe args...` with the environment, the device and the validation layer.
    fn command(&self, args: &[OsString]) -> Command {
        let mut cmd = Command::new(&self.exe);
        cmd.args(args).args(&self.args);
        if let Some(d) = self.device {
            cmd.arg("--device").arg(d.to_string());
        }
        if self.validation {
            cmd.arg("--validation");
        }
        for k in &self.unset {
            cmd.env_remove(k);
        }
        for (k, v) in &self.env {
            cmd.env(k, v);
        }
        cmd
    }

    /// Runs another build's own command line (`args`: a command and its options), stdin closed,
    /// its output collected: for a build older than the typed requests ([`protocol::PROTOCOL_TYPED`]).
    pub fn run_command(&self, args: &[OsString]) -> std::io::Result<std::process::Output> {
        crate::children::output(&mut self.command(args))
    }
}

/// The longest line a worker may print: a `ready` message of thousands of cells is a few MiB,
/// and a longer line is not one of its messages (read whole, it would only fill memory).
pub const MAX_LINE: usize = 16 << 20;

/// How long a session waits for one message by default ([`set_session_timeout`]).
pub const DEFAULT_TIMEOUT_S: f64 = 600.0;

/// The longest wait for one message of a session, in ms (process-wide: `ab` and `gate` set it
/// from `--worker-timeout` before their sides start).
static SESSION_TIMEOUT_MS: AtomicU64 = AtomicU64::new((DEFAULT_TIMEOUT_S * 1e3) as u64);

/// Sets how long a session's worker may stay silent (setting up, or in one run of one cell, or
/// one round) before it is killed and named.
pub fn set_session_timeout(t: Duration) {
    SESSION_TIMEOUT_MS.store(t.as_millis().clamp(1, u64::MAX as u128) as u64, Ordering::Relaxed);
}

/// The session timeout now ([`set_session_timeout`]).
pub fn session_timeout() -> Duration {
    Duration::from_millis(SESSION_TIMEOUT_MS.load(Ordering::Relaxed))
}

/// One thing a worker's stdout gave.
enum Line {
    Text(String),
    /// A line past [`MAX_LINE`]: its first bytes.
    TooLong(String),
    Unreadable(std::io::Error),
}

/// The next line of `r` (without its newline), at most `max` bytes; `None` at the end.
fn read_line(r: &mut impl BufRead, max: usize) -> Option<Line> {
    let mut acc: Vec<u8> = vec![];
    loop {
        let buf = match r.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Some(Line::Unreadable(e)),
        };
        if buf.is_empty() {
            return (!acc.is_empty()).then(|| Line::Text(String::from_utf8_lossy(&acc).into_owned()));
        }
        let (take, end) = match buf.iter().position(|&c| c == b'\n') {
            Some(i) => (i, true),
            None => (buf.len(), false),
        };
        if acc.len() + take > max {
            acc.extend_from_slice(&buf[..take.min(QUOTE)]);
            acc.truncate(QUOTE);
            return Some(Line::TooLong(String::from_utf8_lossy(&acc).into_owned()));
        }
        acc.extend_from_slice(&buf[..take]);
        r.consume(take + usize::from(end));
        if end {
            return Some(Line::Text(String::from_utf8_lossy(&acc).into_owned()));
        }
    }
}

/// Bytes of a worker's line an error quotes.
const QUOTE: usize = 200;

/// `line` for an error message: at most [`QUOTE`] bytes of it, and its length when longer.
pub fn quote(line: &str) -> String {
    if line.len() <= QUOTE {
        return format!("`{line}`");
    }
    let mut end = QUOTE;
    while !line.is_char_boundary(end) {
        end -= 1;
    }
    format!("`{}`... ({} bytes)", &line[..end], line.len())
}

/// How a process ended, in words: `was killed by signal 11 (SIGSEGV)`, `ended with exit
/// status 3`.
fn ended(status: std::process::ExitStatus) -> String {
    #[cfg(unix)]
    if let Some(s) = std::os::unix::process::ExitStatusExt::signal(&status) {
        let name = match s {
            libc::SIGSEGV => " (SIGSEGV)",
            libc::SIGABRT => " (SIGABRT)",
            libc::SIGKILL => " (SIGKILL)",
            libc::SIGTERM => " (SIGTERM)",
            libc::SIGINT => " (SIGINT)",
            libc::SIGBUS => " (SIGBUS)",
            libc::SIGILL => " (SIGILL)",
            libc::SIGFPE => " (SIGFPE)",
            libc::SIGPIPE => " (SIGPIPE)",
            _ => "",
        };
        return format!("was killed by signal {s}{name}");
    }
    match status.code() {
        Some(c) => format!("ended with exit status {c}"),
        None => format!("ended ({status})"),
    }
}

/// Whether `child` has ended, without reaping it.
fn exited(child: &mut crate::children::Running) -> bool {
    #[cfg(unix)]
    {
        // SAFETY: waitid(2) with WNOWAIT | WNOHANG only reads the child's state into a zeroed
        // siginfo_t it is given; si_pid stays 0 while the child runs.
        unsafe {
            let mut info: libc::siginfo_t = std::mem::zeroed();
            let flags = libc::WEXITED | libc::WNOWAIT | libc::WNOHANG;
            libc::waitid(libc::P_PID, child.id() as libc::id_t, &mut info, flags) != 0 || info.si_pid() != 0
        }
    }
    #[cfg(not(unix))]
    child.child().try_wait().map_or(true, |s| s.is_some())
}

/// The last lines of a worker's stderr, for an error message; `skip_indented`: lines that start
/// with white space are left out (a driver's dump: machine code, not the error).
fn tail(stderr: &str, skip_indented: bool) -> String {
    let lines: Vec<&str> = stderr
        .lines()
        .filter(|l| !(l.trim().is_empty() || skip_indented && l.starts_with(char::is_whitespace)))
        .collect();
    if lines.is_empty() {
        String::new()
    } else {
        format!("\n{}", lines[lines.len().saturating_sub(8)..].join("\n"))
    }
}

/// `3 s`, `0.5 s`.
fn show_seconds(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s.fract() == 0.0 {
        format!("{s:.0} s")
    } else {
        format!("{s} s")
    }
}

/// A running worker: requests go to its stdin, its messages are read from its stdout on a
/// thread of their own (so a silent one is waited for a bounded time), its stderr is kept for
/// errors. Dropped, it is killed with its process group.
pub struct Session {
    /// How errors name it: `side B`.
    who: String,
    /// What its lines should be: `an ab message`.
    speaks: &'static str,
    /// The protocol its requests are written in ([`Request::line`]).
    protocol: u32,
    /// `None` once it has been waited for.
    child: Option<crate::children::Running>,
    /// `None` when it reads its requests from a file, or has been told to end.
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<Line>,
    /// Its stderr so far, and a message when the whole of it has been read.
    stderr: Arc<Mutex<Vec<u8>>>,
    stderr_done: mpsc::Receiver<()>,
    timeout: Option<Duration>,
    whole_stderr: bool,
}

/// Where a worker's requests come from.
enum Input {
    /// A pipe the parent writes to as it goes.
    Pipe,
    /// The requests, all of them, in a file: nothing is written to a pipe the child may have
    /// closed.
    Requests(Vec<u8>),
}

impl Session {
    /// Starts `launch.exe args...` (a command and its options; `args` come before the device
    /// and validation options), named `who` in errors. Its messages are read as [`Message`]s;
    /// requests are written for the newest protocol until [`Session::speaks_protocol`].
    pub fn start(launch: &Launch, who: impl Into<String>, args: &[OsString]) -> Result<Session> {
        Session::spawn(launch, who.into(), args, Input::Pipe)
    }

    fn spawn(launch: &Launch, who: String, args: &[OsString], input: Input) -> Result<Session> {
        let mut cmd = launch.command(args);
        let stdin = match input {
            Input::Pipe => Stdio::piped(),
            Input::Requests(bytes) => {
                // An unnamed file: nothing is left behind, whatever happens.
                let mut f = tempfile::tempfile().map_err(|e| Error::io(Path::new("temporary file"), e))?;
                f.write_all(&bytes).and_then(|_| f.rewind()).map_err(|e| Error::io(Path::new("temporary file"), e))?;
                Stdio::from(f)
            }
        };
        let mut child = crate::children::spawn(cmd.stdin(stdin).stdout(Stdio::piped()).stderr(Stdio::piped()))
            .map_err(|e| Error::Usage(format!("{who}: cannot run {}: {e}", launch.exe.display())))?;
        let stdin = child.child().stdin.take();
        let mut out = BufReader::new(child.child().stdout.take().expect("piped"));
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            while let Some(line) = read_line(&mut out, MAX_LINE) {
                let last = !matches!(line, Line::Text(_));
                if tx.send(line).is_err() || last {
                    return;
                }
            }
        });
        let mut err = child.child().stderr.take().expect("piped");
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let (done, stderr_done) = mpsc::channel();
        let kept = stderr.clone();
        let whole = launch.whole_stderr;
        std::thread::spawn(move || {
            let mut buf = [0u8; 8192];
            loop {
                match std::io::Read::read(&mut err, &mut buf) {
                    Ok(0) => break,
                    Ok(n) => {
                        let mut k = kept.lock().unwrap_or_else(|e| e.into_inner());
                        // The last MiB or two are plenty for the message's tail.
                        if !whole && k.len() > 2 << 20 {
                            k.drain(..1 << 20);
                        }
                        k.extend_from_slice(&buf[..n]);
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                    Err(_) => break,
                }
            }
            let _ = done.send(());
        });
        Ok(Session {
            who,
            speaks: "a worker message",
            protocol: PROTOCOL,
            child: Some(child),
            stdin,
            lines,
            stderr,
            stderr_done,
            timeout: launch.timeout,
            whole_stderr: whole,
        })
    }

    /// Names what its lines should be in errors (`an ab message`).
    pub fn speaking(mut self, what: &'static str) -> Session {
        self.speaks = what;
        self
    }

    /// From now on its requests are written in `protocol` (what its `ready` said).
    pub fn speaks_protocol(&mut self, protocol: u32) {
        self.protocol = protocol;
    }

    /// Its stderr so far (all of it once it has ended, or after a second's wait).
    fn stderr_text(&self) -> String {
        let _ = self.stderr_done.recv_timeout(Duration::from_secs(1));
        String::from_utf8_lossy(&self.stderr.lock().unwrap_or_else(|e| e.into_inner())).into_owned()
    }

    /// Kills the worker's process group (the worker and whatever it started), then reaps the
    /// worker; its status. The group is signalled before the worker is reaped, so its id is
    /// still this group's.
    fn kill(&mut self) -> Option<std::process::ExitStatus> {
        let mut child = self.child.take()?;
        #[cfg(unix)]
        // SAFETY: kill(2) with a negative pid signals that process group: the worker's own,
        // which `children::spawn` made, its leader not yet reaped.
        unsafe {
            libc::kill(-(child.id() as libc::pid_t), libc::SIGKILL);
        }
        #[cfg(not(unix))]
        let _ = child.child().kill();
        child.wait().ok()
    }

    /// Waits up to `limit` for the worker to end, without reaping it (see [`Session::kill`]).
    fn wait_for_exit(&mut self, limit: Duration) -> bool {
        let start = Instant::now();
        loop {
            let Some(child) = self.child.as_mut() else { return true };
            if exited(child) {
                return true;
            }
            if start.elapsed() > limit {
                return false;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Its end, once its stdout or stdin has closed: how it ended (`was killed by signal 11
    /// (SIGSEGV)`, `ended with exit status 3`), or that it lingered and was killed.
    fn how_it_ended(&mut self) -> String {
        let exited = self.wait_for_exit(Duration::from_secs(5));
        match self.kill() {
            Some(status) if exited => ended(status),
            _ => "closed its output but did not end (killed)".into(),
        }
    }

    /// An error naming the worker, what happened and `when`, with the worker's last stderr
    /// lines; the worker is killed.
    pub fn fail(&mut self, what: &str, when: &str) -> Error {
        self.kill();
        let when = if when.is_empty() { String::new() } else { format!(" {when}") };
        Error::Usage(format!("{}: {what}{when}{}", self.who, tail(&self.stderr_text(), self.whole_stderr)))
    }

    /// The worker's next message (`when`: what it was doing, for an error); its failure, its
    /// end, a line that is not a message, or silence past the timeout as an error naming it.
    pub fn next(&mut self, when: &str) -> Result<Message> {
        let got = match self.timeout {
            Some(limit) => self.lines.recv_timeout(limit),
            None => self.lines.recv().map_err(|_| mpsc::RecvTimeoutError::Disconnected),
        };
        match got {
            Ok(Line::Text(line)) => match serde_json::from_str::<Message>(&line) {
                Ok(Message::Failed { error }) => Err(self.fail(&format!("the worker failed ({error})"), when)),
                Ok(m) => Ok(m),
                Err(e) => {
                    let what = format!("the worker printed what is not {} ({e}): {}", self.speaks, quote(&line));
                    Err(self.fail(&what, when))
                }
            },
            Ok(Line::TooLong(start)) => {
                let what = format!(
                    "the worker printed a line of more than {} MiB (not {}), starting `{start}`...",
                    MAX_LINE >> 20,
                    self.speaks,
                );
                Err(self.fail(&what, when))
            }
            Ok(Line::Unreadable(e)) => Err(self.fail(&format!("the worker's output could not be read ({e})"), when)),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                let limit = self.timeout.unwrap_or_default();
                let what =
                    format!("the worker said nothing for {} (--worker-timeout) and was killed", show_seconds(limit));
                Err(self.fail(&what, when))
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                let how = self.how_it_ended();
                Err(self.fail(&format!("the worker {how}"), when))
            }
        }
    }

    /// Writes `request` to the worker's stdin. The caller ignores SIGPIPE meanwhile (a worker
    /// that died then gives an error naming it, not the end of this process).
    pub fn send(&mut self, request: &Request, when: &str) -> Result<()> {
        let Some(line) = request.line(self.protocol) else {
            let what = format!("its worker speaks protocol {}, which has no `{request:?}` request", self.protocol);
            return Err(self.fail(&what, when));
        };
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(Error::Usage(format!("{}: the worker has ended", self.who)));
        };
        match writeln!(stdin, "{line}").and_then(|_| stdin.flush()) {
            Ok(()) => Ok(()),
            Err(e) => {
                // A worker that ended between two requests fails the write (a broken pipe) or the
                // next read, whichever comes first: both say the same, that it ended and how
                // (the soak of issue 40 saw the write lose that race). One that is still running
                // stopped reading its commands.
                let exited = self.wait_for_exit(Duration::from_secs(5));
                let how = self.how_it_ended();
                let what = match exited {
                    true => format!("the worker {how}"),
                    false => format!("the worker stopped reading its commands ({e}): it {how}"),
                };
                Err(self.fail(&what, when))
            }
        }
    }

    /// Sends `request` and reads its answer.
    pub fn ask(&mut self, request: &Request, when: &str) -> Result<Message> {
        self.send(request, when)?;
        self.next(when)
    }

    /// Asks the worker to end and waits for it (killing it past the session timeout); its
    /// stderr.
    pub fn finish(mut self) -> String {
        if let Some(mut stdin) = self.stdin.take() {
            if let Some(line) = Request::Quit.line(self.protocol) {
                let _ = writeln!(stdin, "{line}").and_then(|_| stdin.flush());
            }
        }
        // Reaped, and anything it left in its group ended with it.
        self.wait_for_exit(self.timeout.unwrap_or_else(session_timeout));
        self.kill();
        self.stderr_text()
    }
}

impl Drop for Session {
    /// A worker left behind by an error (the other side failed, a refusal) does not outlive it.
    fn drop(&mut self) {
        self.stdin.take();
        self.kill();
    }
}

/// A one-shot request's answer, and everything the worker printed on stderr (a driver's dump).
#[derive(Debug)]
pub struct Answered {
    pub message: Message,
    pub stderr: String,
}

/// Runs `launch.exe __worker` for one request (named `who` in errors) and returns its answer:
/// the request is in the child's stdin, and the child ends once it has answered. A failure, a
/// child that ends without an answer, crashes, prints what is not a message, is silent past
/// `launch.timeout`, or ends unsuccessfully after its answer (the validation layer's messages
/// at exit) is an error naming `who`, with the child's last stderr lines.
pub fn call(launch: &Launch, who: impl Into<String>, request: &Request) -> Result<Answered> {
    let line = request.line(PROTOCOL).expect("this build speaks its own protocol");
    let args = [OsString::from(protocol::COMMAND)];
    let mut s = Session::spawn(launch, who.into(), &args, Input::Requests(format!("{line}\n").into_bytes()))?;
    let message = s.next("")?;
    // The work is done: the child ends at the end of its requests.
    if !s.wait_for_exit(launch.timeout.unwrap_or(Duration::from_secs(DEFAULT_TIMEOUT_S as u64))) {
        return Err(s.fail("the worker answered but did not end (killed)", ""));
    }
    match s.kill() {
        Some(status) if status.success() => {}
        Some(status) => return Err(s.fail(&format!("the worker {} after its answer", ended(status)), "")),
        None => {}
    }
    let stderr = s.stderr_text();
    Ok(Answered { message, stderr })
}

/// The child's side: writes `m` as one line on `out` (its stdout) and flushes it.
pub fn say(out: &mut dyn Write, m: &Message) -> Result<()> {
    let line = serde_json::to_string(m).expect("messages serialise");
    writeln!(out, "{line}").and_then(|_| out.flush()).map_err(|e| Error::io(Path::new("stdout"), e))
}

/// An error for an answer of another kind than `expected`.
pub fn unexpected(who: &str, expected: &str, got: &Message) -> Error {
    Error::Usage(format!("{who}: expected a `{expected}` answer, got `{}`", got.kind()))
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    use std::os::unix::fs::PermissionsExt;

    /// An executable script with `body`, standing in for trilab.
    fn script(dir: &Path, name: &str, body: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, format!("#!/bin/bash\n{body}\n")).unwrap();
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
        path
    }

    fn launch(exe: &Path) -> Launch {
        Launch { timeout: Some(Duration::from_secs(20)), ..Launch::new(exe) }
    }

    #[test]
    fn a_call_gets_its_answer_with_the_request_on_stdin_and_the_whole_stderr() {
        let dir = tempfile::tempdir().unwrap();
        // Runs only as `__worker` in its environment, reads a dispatch-kernels request and prints
        // 3000 lines of a dump on stderr before its answer.
        let exe = script(
            dir.path(),
            "w.sh",
            r#"[ "$1" = __worker ] || exit 9
[ "$MY_SETTING" = on ] && [ -z "${HOME+set}" ] || exit 8
IFS= read -r req
case "$req" in *dispatch-kernels*) ;; *) exit 7 ;; esac
for i in $(seq 3000); do echo "  $i: some machine code line that is long enough" >&2; done
echo '{"message":"dispatched","kernels":2}'"#,
        );
        let l = Launch { whole_stderr: true, unset: vec!["HOME".into()], ..launch(&exe).env("MY_SETTING", "on") };
        let r =
            call(&l, "the test child", &Request::DispatchKernels { kernels: vec!["a".into(), "b".into()] }).unwrap();
        assert!(matches!(r.message, Message::Dispatched { kernels: 2 }), "{r:?}");
        assert_eq!(r.stderr.lines().count(), 3000, "the whole stderr is kept");
    }

    #[test]
    fn a_call_names_a_failure_a_crash_garbage_and_a_bad_exit() {
        let dir = tempfile::tempdir().unwrap();
        let err = |body: &str| {
            let exe = script(dir.path(), "w.sh", body);
            call(&launch(&exe), "LP_NUM_THREADS=3", &Request::Quit).unwrap_err().to_string()
        };
        let e = err(r#"echo 'worker: no device' >&2; echo '{"message":"failed","error":"no device"}'; exit 1"#);
        assert!(
            e.starts_with("LP_NUM_THREADS=3: the worker failed (no device)") && e.ends_with("worker: no device"),
            "{e}"
        );
        let e = err("echo 'dying' >&2; kill -SEGV $$");
        assert!(
            e.contains("LP_NUM_THREADS=3: the worker was killed by signal 11 (SIGSEGV)") && e.contains("dying"),
            "{e}"
        );
        let e = err("echo 'hello, not JSON'");
        assert!(
            e.contains("the worker printed what is not a worker message") && e.contains("`hello, not JSON`"),
            "{e}"
        );
        let e = err(r#"echo '{"message":"dispatched","kernels":1}'; echo 'validation: oops' >&2; exit 3"#);
        assert!(
            e.contains("the worker ended with exit status 3 after its answer") && e.contains("validation: oops"),
            "{e}"
        );
        let e = err("exit 4");
        assert!(e.contains("the worker ended with exit status 4"), "{e}");
        // A program that cannot be run at all.
        let e = call(&launch(&dir.path().join("nope")), "side A", &Request::Quit).unwrap_err().to_string();
        assert!(e.starts_with("side A: cannot run") && e.contains("nope"), "{e}");
    }

    #[test]
    fn a_silent_worker_is_killed_with_what_it_started_and_an_enormous_line_is_cut() {
        let dir = tempfile::tempdir().unwrap();
        let pidfile = dir.path().join("sleeper.pid");
        let exe = script(dir.path(), "mute.sh", &format!("sleep 1000 & echo $! > {}; wait", pidfile.display()));
        let l = Launch { timeout: Some(Duration::from_millis(500)), ..Launch::new(&exe) };
        let start = Instant::now();
        let e = call(&l, "side B", &Request::Quit).unwrap_err().to_string();
        assert!(e.contains("side B: the worker said nothing for 0.5 s (--worker-timeout) and was killed"), "{e}");
        assert!(start.elapsed() < Duration::from_secs(10));
        let pid: i32 = std::fs::read_to_string(&pidfile).unwrap().trim().parse().unwrap();
        std::thread::sleep(Duration::from_millis(200));
        // SAFETY: kill(2) with signal 0 only asks whether the process exists.
        let alive = unsafe { libc::kill(pid, 0) } == 0
            && !std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|s| s.contains(") Z "));
        assert!(!alive, "the worker's own child outlived it");
        // 20 MiB without a newline: refused at the cap, quoting only its start.
        let exe = script(dir.path(), "flood.sh", "head -c 20971520 /dev/zero | tr '\\0' x; sleep 1000");
        let e = call(&launch(&exe), "side B", &Request::Quit).unwrap_err().to_string();
        assert!(e.contains("a line of more than 16 MiB (not a worker message), starting `xxx"), "{e}");
        assert!(e.len() < 1000, "{} bytes", e.len());
    }

    #[test]
    fn a_session_writes_words_to_an_older_worker_and_json_to_a_newer_one() {
        let dir = tempfile::tempdir().unwrap();
        // Answers each line with a round whose one cell's `agree` is the line's length.
        let exe = script(
            dir.path(),
            "w.sh",
            r#"while IFS= read -r line; do
  [ "$line" = quit ] && exit 0
  echo "{\"message\":\"round\",\"cells\":[{\"ms\":1.0,\"agree\":${#line},\"unexplained\":0,\"invalid\":0}]}"
done"#,
        );
        let mut s = Session::start(&launch(&exe), "side A", &[]).unwrap().speaking("an ab message");
        let agree = |m: Message| match m {
            Message::Round { cells } => cells[0].agree,
            other => panic!("{other:?}"),
        };
        let json = Request::Cell { index: 3 }.line(PROTOCOL).unwrap();
        assert_eq!(agree(s.ask(&Request::Cell { index: 3 }, "in round 1").unwrap()), json.len());
        s.speaks_protocol(2);
        assert_eq!(agree(s.ask(&Request::Cell { index: 3 }, "in round 2").unwrap()), "cell 3".len());
        let e = s.send(&Request::DispatchKernels { kernels: vec![] }, "after the rounds").unwrap_err().to_string();
        assert!(e.contains("side A: its worker speaks protocol 2, which has no"), "{e}");
        let mut s = Session::start(&launch(&exe), "side A", &[]).unwrap().speaking("an ab message");
        s.speaks_protocol(2);
        s.send(&Request::Round, "").unwrap();
        s.finish();
    }
}
