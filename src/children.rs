//! The processes trilab starts and waits for (trilab itself run again in another environment,
//! through `services::worker`: `ab`'s sides, a bench per LP_NUM_THREADS, the driver statistics'
//! child; the peers; the build benchmark's peers): each in a process group of its own and listed
//! here while it runs, so that a stop signal trilab catches reaches them and whatever they
//! started ([`signal_all`]) instead of leaving them running after trilab has gone. Ground floor:
//! it imports nothing of trilab.
//!
//! A process group of their own also keeps a terminal's Ctrl-C from reaching them directly:
//! the command that catches it forwards it (`trilab suite`, `study`, `ab`), and one that does
//! not ends, closing the pipes its children write to.

use std::io;
use std::process::{Child, Command, Output, Stdio};
use std::sync::Mutex;

/// Process ids (each its group's id) of the children running now.
static RUNNING: Mutex<Vec<u32>> = Mutex::new(Vec::new());

fn running() -> std::sync::MutexGuard<'static, Vec<u32>> {
    RUNNING.lock().unwrap_or_else(|e| e.into_inner())
}

/// A started child, listed until it is waited for or dropped.
pub struct Running {
    child: Option<Child>,
    pid: u32,
}

impl Running {
    /// The child, for its pipes.
    pub fn child(&mut self) -> &mut Child {
        self.child.as_mut().expect("a Running holds its child until it is consumed")
    }

    /// Waits for it with its output collected ([`Child::wait_with_output`]).
    pub fn wait_with_output(mut self) -> io::Result<Output> {
        self.child.take().expect("a Running holds its child until it is consumed").wait_with_output()
    }

    /// Waits for it to end.
    pub fn wait(&mut self) -> io::Result<std::process::ExitStatus> {
        self.child().wait()
    }

    pub fn id(&self) -> u32 {
        self.pid
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        running().retain(|&p| p != self.pid);
    }
}

/// Starts `cmd` in a process group of its own, listed until the returned [`Running`] is
/// waited for or dropped.
pub fn spawn(cmd: &mut Command) -> io::Result<Running> {
    #[cfg(unix)]
    std::os::unix::process::CommandExt::process_group(cmd, 0);
    // Listed under the lock it was started under, so a signal_all that comes between the two
    // cannot miss it.
    let mut list = running();
    let child = cmd.spawn()?;
    let pid = child.id();
    list.push(pid);
    Ok(Running { child: Some(child), pid })
}

/// [`Command::output`] through [`spawn`]: stdin closed, stdout and stderr collected.
pub fn output(cmd: &mut Command) -> io::Result<Output> {
    cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    spawn(cmd)?.wait_with_output()
}

/// Sends `signal` to every listed child's process group (the child and what it started);
/// returns how many were sent one. For a stop handler, before it exits.
pub fn signal_all(signal: i32) -> usize {
    let list = running();
    #[cfg(unix)]
    {
        // SAFETY: kill(2) with a negative pid signals that process group; it touches no memory.
        list.iter().filter(|&&p| unsafe { libc::kill(-(p as libc::pid_t), signal) } == 0).count()
    }
    #[cfg(not(unix))]
    {
        let _ = signal;
        list.len()
    }
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    #[test]
    fn a_listed_child_and_its_own_child_get_the_signal_and_leave_the_list() {
        // A shell that starts a sleeper and waits: SIGTERM to the group ends both.
        let mut r = spawn(Command::new("sh").args(["-c", "sleep 30 & wait"])).unwrap();
        let pid = r.id();
        assert!(running().contains(&pid));
        std::thread::sleep(std::time::Duration::from_millis(200));
        assert!(signal_all(libc::SIGTERM) >= 1);
        let status = r.wait().unwrap();
        assert!(!status.success(), "{status:?}");
        drop(r);
        assert!(!running().contains(&pid));
        // The sleeper (the shell's child) went with its group: no live process of it is left.
        std::thread::sleep(std::time::Duration::from_millis(300));
        assert_eq!(live_in_group(pid), Vec::<u32>::new(), "the child's group outlived the signal");
    }

    /// Processes of group `pgrp` that are not zombies, from /proc.
    fn live_in_group(pgrp: u32) -> Vec<u32> {
        let mut live = vec![];
        for e in std::fs::read_dir("/proc").unwrap().flatten() {
            let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else { continue };
            let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else { continue };
            // pid (comm) state ppid pgrp ...: fields after the last ')'.
            let rest: Vec<&str> =
                stat.rsplit_once(')').map(|(_, r)| r.split_whitespace().collect()).unwrap_or_default();
            if rest.len() > 2 && rest[2] == pgrp.to_string() && rest[0] != "Z" {
                live.push(pid);
            }
        }
        live
    }

    #[test]
    fn output_collects_and_unlists() {
        let o = output(Command::new("sh").args(["-c", "echo out; echo err >&2"])).unwrap();
        assert_eq!((o.stdout.as_slice(), o.stderr.as_slice()), (&b"out\n"[..], &b"err\n"[..]));
        assert!(o.status.success());
    }
}
