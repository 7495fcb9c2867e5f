//! `trilab ab`: one workload under two driver environments, A and B, in one run, and what
//! changed between them with confidence (after gpu-trace-perf's A/B runs and the helped/hurt
//! reports of Mesa's shader-db).
//!
//! Each side is its own child process ([`worker`]): a driver is loaded once per process, and a
//! side is named by the ICD file the Vulkan loader is given (`VK_DRIVER_FILES`) and the
//! environment it runs in, and may run another trilab executable (two builds of the kernels).
//! In each round the parent times every cell on both sides back to back, one side running at a
//! time, which side first alternating from cell to cell and round to round, so the moment's load
//! on the host lands on both alike and each cell's ratio is paired round by round (a worker of
//! protocol 1 times whole rounds only: then rounds go A B B A and the intervals are unpaired);
//! every run of every cell is validated against the f64 reference before its time counts.
//! Rounds go on past the minimum until every judged interval ([`interval`]; each cell's, or each
//! kernel's over its cells) is narrower than the target, or the maximum rounds, or the time cap.
//! Then per cell and per kernel: the ratio B/A of kernel time with its 95 % interval and a
//! verdict, the hits of A and B compared ray by ray, and each side's agreement with the
//! reference. Cells are matched by what they are (scene, set, method, layout, traversal), so a
//! build that added or dropped a kernel is still compared on the cells both run.
//!
//! `run` is a plan, rounds and a verdict, one file each: [`options`] (what it is given, checked
//! before any side starts), [`sides`] (each side's worker started, ready and ended), [`plan`]
//! (the cells both sides ran, matched, and their kernels), [`rounds`] (the interleaved rounds and
//! when they stop; an older worker's whole rounds in [`whole_rounds`]) into [`measured`], then
//! [`verdict`] (each cell and kernel judged) into [`report`] (the report and its text), which
//! [`results`] writes. [`progress`] tells a stop handler where the run is.

pub mod compiled;
pub mod interval;
mod measured;
mod options;
mod plan;
mod progress;
pub mod repro;
mod report;
mod results;
mod rounds;
mod sides;
mod verdict;
mod whole_rounds;
pub mod worker;

use std::path::Path;
use std::time::Instant;

use crate::error::{Error, Result};
use options::{check_options, resolved_workload};
use plan::Plan;
use progress::{set_stage, ProgressGuard};
use verdict::{judged_cells, judged_kernels};

pub use crate::services::worker::{set_session_timeout as set_worker_timeout, MAX_LINE};
pub use options::{AbOptions, Judge, Side};
pub use progress::{remove_temp, stop_requested, stopping};
pub use report::{AbCell, AbKernel, AbReport, SideCell, SideReport};
pub use results::{rows, side_rows, write, SIDE_SETTING};
pub use verdict::LEVEL;

/// How long `ab` waits for one message of a worker by default ([`set_worker_timeout`]).
pub const DEFAULT_WORKER_TIMEOUT_S: f64 = crate::services::worker::DEFAULT_TIMEOUT_S;

/// Runs the two sides and compares them. An error means they could not be compared (a side
/// that does not start, a missing ICD file or executable, no cell in common): exit 2.
pub fn run(o: &AbOptions, mut progress: impl FnMut(&str)) -> Result<AbReport> {
    check_options(o, &mut progress)?;
    o.workload.sizes.check_memory()?;
    let workload = resolved_workload(&o.workload)?;
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let _progress = ProgressGuard::new(o.rounds, o.max_rounds, tmp.path());
    let start = Instant::now();
    let [a, b] = sides::start_both(o, &workload, tmp.path(), &mut progress)?;
    let protocols = [a.report.protocol, b.report.protocol];
    let plan = Plan::new([&a.cells, &b.cells], protocols)?;
    let mut workers = [a.worker, b.worker];
    let rounds = rounds::run(o, &plan, &mut workers, start, &mut progress)?;
    let [dir_a, dir_b] = sides::finish_both(workers);
    // The compilers' output, after the rounds: its compiles would time them otherwise.
    set_stage("the driver statistics, after the rounds".into());
    let stats = o.driver_stats.then(|| driver_stats(o, &plan, protocols, tmp.path(), &mut progress));
    let judging = crate::timeline::span("ab", "cells judged (hits compared ray by ray)");
    let invocations = [&a.invocations, &b.invocations].map(Vec::as_slice);
    let cells = judged_cells(o, &plan, &rounds.measured, [&dir_a, &dir_b], stats.as_ref(), invocations)?;
    drop(judging);
    let kernels = judged_kernels(o, &plan, &rounds.measured.times, &cells);
    let repros = match &o.repro {
        Some(dir) => {
            set_stage("the repros, after the rounds".into());
            repro::make(o, &workload, &cells, dir, &mut progress)?
        }
        None => vec![],
    };
    Ok(AbReport {
        a: SideReport { rounds: rounds.done[0], ..a.report },
        b: SideReport { rounds: rounds.done[1], ..b.report },
        workload: workload.args(),
        level: LEVEL,
        threshold: o.threshold,
        target: o.target,
        judge: o.judge,
        paired: plan.paired,
        stopped_by: rounds.stopped_by.into(),
        seconds: start.elapsed().as_secs_f64(),
        cells,
        kernels,
        only_in: plan.only_in(),
        mismatched: plan.matching.mismatched,
        driver_stats: stats.as_ref().map(|s| s.clone().map(|x| x.note)),
        pipeline_stats: o.workload.pipeline_stats.then_some([a.invocations_note, b.invocations_note]),
        driver_stats_rows: stats.map(|s| s.map(|x| x.rows)).unwrap_or_default(),
        repros,
    })
}

/// Each side's driver statistics of the kernels of its matched cells (`--driver-stats`), by a
/// worker that speaks its `protocols`, each into its own folder in `tmp`.
fn driver_stats(
    o: &AbOptions,
    plan: &Plan,
    protocols: [u32; 2],
    tmp: &Path,
    progress: &mut impl FnMut(&str),
) -> [compiled::SideStats; 2] {
    let matched = plan.matched();
    [("A", &o.a), ("B", &o.b)].map(|(name, side)| {
        let _span = crate::timeline::span_on(sides::side_track(name), "ab", "driver statistics");
        progress(&format!("side {name}: driver statistics"));
        let s = usize::from(name == "B");
        compiled::collect(o, name, side, protocols[s], &matched[s], &tmp.join(format!("driver-stats-{name}")))
    })
}
