//! Where an `ab` run is: its stage and the rounds each side has done, for a stop handler (which
//! says so and removes the run's temporary folder) and for the error of a worker that fails in
//! the rounds.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use super::worker::CellInfo;

/// Where a run is, for a stop handler ([`stop_requested`]): the stage, the rounds done and the
/// temporary folder the workers write their hits to.
#[derive(Default)]
struct Progress {
    stage: String,
    rounds: [usize; 2],
    least: usize,
    most: usize,
    temp: Option<PathBuf>,
}

static PROGRESS: Mutex<Option<Progress>> = Mutex::new(None);

fn progress_state() -> std::sync::MutexGuard<'static, Option<Progress>> {
    PROGRESS.lock().unwrap_or_else(|e| e.into_inner())
}

/// What the run is doing now, for a stop handler: `round 3`, `side B's start`.
pub(super) fn set_stage(stage: String) {
    if let Some(p) = progress_state().as_mut() {
        p.stage = stage;
    }
}

/// Set once a stop handler has taken over ([`stop_requested`]).
static STOPPING: AtomicBool = AtomicBool::new(false);

/// For a stop handler, before it signals the workers: marks the run as stopping (a worker that
/// the signal ends is then no failure to report: [`stopping`]) and says where the run was and
/// what it had measured. `None` when no `ab` run is under way.
pub fn stop_requested() -> Option<String> {
    STOPPING.store(true, Ordering::SeqCst);
    let state = progress_state();
    let p = state.as_ref()?;
    let done = rounds_done(p.rounds);
    Some(format!(
        "stopped during {}: {done} done (at least {} were to run, at most {}); no verdict",
        p.stage, p.least, p.most
    ))
}

/// Whether a stop handler has taken over: the caller of [`super::run`] leaves the exit to it.
pub fn stopping() -> bool {
    STOPPING.load(Ordering::SeqCst)
}

/// For a stop handler, once the workers have ended: removes the run's temporary folder (the
/// workers' hits), which an exit from the handler would leave behind.
pub fn remove_temp() {
    if let Some(t) = progress_state().as_mut().and_then(|p| p.temp.take()) {
        let _ = std::fs::remove_dir_all(t);
    }
}

/// Clears the run's [`Progress`] when the run ends, however it ends.
pub(super) struct ProgressGuard;

impl ProgressGuard {
    pub(super) fn new(least: usize, most: usize, temp: &Path) -> ProgressGuard {
        *progress_state() =
            Some(Progress { stage: "the start".into(), rounds: [0, 0], least, most, temp: Some(temp.to_owned()) });
        ProgressGuard
    }
}

impl Drop for ProgressGuard {
    fn drop(&mut self) {
        *progress_state() = None;
    }
}

/// The rounds each side has done so far, for a stop handler.
pub(super) fn set_rounds(rounds: [usize; 2]) {
    if let Some(p) = progress_state().as_mut() {
        p.rounds = rounds;
    }
}

/// `3 rounds a side`, or `3 rounds on side A, 2 on side B`.
fn rounds_done([a, b]: [usize; 2]) -> String {
    if a == b {
        format!("{a} rounds a side")
    } else {
        format!("{a} rounds on side A, {b} on side B")
    }
}

/// What a worker's failure in the rounds says after what happened: when (the round, from 0, and
/// the cell, if one), and what had been measured (nothing is compared then).
pub(super) fn in_round(round: usize, cell: Option<&CellInfo>, done: [usize; 2]) -> String {
    let cell = cell.map(|c| format!(", cell `{}`", c.label())).unwrap_or_default();
    format!("in round {}{cell}, after {}; the sides were not compared", round + 1, rounds_done(done))
}
