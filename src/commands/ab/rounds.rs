//! The interleaved rounds: in each, every matched cell on both sides back to back, the cell
//! that opens the round rotating and which side goes first alternating from cell to cell and
//! round to round, so the moment's load on the host lands on both alike and each cell's ratio is
//! paired round by round (a worker of protocol 1 times whole rounds: [`super::whole_rounds`]).
//! Rounds go on past the minimum until every judged interval is narrower than the target, or
//! the maximum rounds, or the time cap.

use std::time::Instant;

use super::measured::Measured;
use super::options::{AbOptions, Judge};
use super::plan::Plan;
use super::progress::{in_round, set_rounds, set_stage};
use super::sides::{side_track, Worker};
use super::verdict::{cell_ratio, kernel_ratio};
use super::whole_rounds;
use super::worker::{CellInfo, CellRound};
use crate::error::Result;

/// What the rounds measured, how many each side ran and why they stopped.
pub(super) struct Rounds {
    pub(super) measured: Measured,
    /// Rounds side A ran, and side B.
    pub(super) done: [usize; 2],
    /// `target`, `max rounds` or `time cap`.
    pub(super) stopped_by: &'static str,
}

/// Runs `plan`'s rounds on the two sides' `workers` until one of `o`'s limits stops them
/// (`start`: when the run started, for the time cap); `progress` hears of each round past the
/// minimum.
pub(super) fn run(
    o: &AbOptions,
    plan: &Plan,
    workers: &mut [Worker; 2],
    start: Instant,
    progress: &mut impl FnMut(&str),
) -> Result<Rounds> {
    let mut measured = Measured::new(plan);
    let mut done = [0usize; 2];
    let stopped_by = loop {
        if plan.paired {
            paired_round(workers, plan, &mut measured, &mut done)?;
        } else {
            whole_rounds::block(workers, plan, &mut measured, &mut done)?;
        }
        set_rounds(done);
        let n = done[0].min(done[1]);
        if n < o.rounds {
            continue;
        }
        // The intervals the verdict is given by must be narrow enough.
        let widest = widest(o.judge, plan, &measured);
        progress(&format!("{n} rounds a side: widest {} interval +-{:.1} %", o.judge.unit(), widest * 100.0));
        let stop = [
            ("target", widest <= o.target),
            ("max rounds", n + if plan.paired { 1 } else { 2 } > o.max_rounds),
            ("time cap", start.elapsed().as_secs_f64() > o.time_cap_s),
        ];
        if let Some((why, _)) = stop.into_iter().find(|&(_, stop)| stop) {
            break why;
        }
    };
    Ok(Rounds { measured, done, stopped_by })
}

/// One paired round: every matched cell's two sides back to back.
fn paired_round(workers: &mut [Worker; 2], plan: &Plan, measured: &mut Measured, done: &mut [usize; 2]) -> Result<()> {
    let round = done[0];
    set_stage(format!("round {}", round + 1));
    let _round_span = crate::timeline::span_with("round", || format!("round {}", round + 1));
    let pairs = plan.pairs();
    let cells_b = plan.cells[1];
    for k in 0..pairs.len() {
        // The cell that opens a round rotates, and which side goes first alternates
        // from cell to cell and from round to round.
        let p = (k + round) % pairs.len();
        let order = if (k + round).is_multiple_of(2) { [0usize, 1] } else { [1, 0] };
        for (nth, side) in order.into_iter().enumerate() {
            let i = if side == 0 { pairs[p].0 } else { pairs[p].1 };
            let span = trace_side_cell(side, &cells_b[pairs[p].1], round, nth == 0);
            let r = workers[side].cell(i, &in_round(round, Some(&cells_b[pairs[p].1]), *done))?;
            trace_answer(&span, &r);
            measured.record(side, p, &r);
        }
    }
    *done = [round + 1, round + 1];
    Ok(())
}

/// The widest interval (half-width, log scale) of what the verdict judges: each cell's, or each
/// kernel's over its cells; infinite where one has none yet.
fn widest(judge: Judge, plan: &Plan, measured: &Measured) -> f64 {
    let times = &measured.times;
    match judge {
        Judge::Cells => (0..plan.pairs().len())
            .map(|p| cell_ratio(times, p, plan.paired).map_or(f64::INFINITY, |r| r.half_width()))
            .fold(0.0, f64::max),
        Judge::Kernels => plan
            .groups
            .iter()
            .map(|g| kernel_ratio(times, &g.members, plan.paired).map_or(f64::INFINITY, |r| r.half_width()))
            .fold(0.0, f64::max),
    }
}

/// One side's run of one cell in a paired round, as a span on that side's track of the trace
/// (`side`: 0 for A): the cell, the round (from 1) and whether the side went first.
fn trace_side_cell(side: usize, cell: &CellInfo, round: usize, first: bool) -> crate::timeline::Span {
    let name = ["A", "B"][side];
    if !crate::timeline::on() {
        return crate::timeline::span("ab", "");
    }
    let span = crate::timeline::span_on(side_track(name), "ab", format!("{name}: {}", cell.label()));
    if span.records() {
        span.arg("side", name);
        span.arg("cell", cell.label());
        span.arg("round", round + 1);
        span.arg("first_in_pair", first);
    }
    span
}

/// What the side's worker answered for the cell, in its span's args.
fn trace_answer(span: &crate::timeline::Span, r: &CellRound) {
    if !span.records() {
        return;
    }
    match r.ms {
        Some(ms) => span.arg("kernel_ms", ms),
        None => span.arg("validated", false),
    }
    span.arg("agree", r.agree);
}
