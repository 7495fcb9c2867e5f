//! The rounds of a side whose worker speaks ab protocol 1, an older build's: it times whole
//! rounds only (every cell once, in its own order), so the rounds go in balanced blocks A B B A
//! and each side's times are a whole round apart from the other's: the intervals are unpaired
//! (Welch's). Both sides of protocol 2 or later run each cell's two sides back to back
//! ([`super::rounds`]).

use super::measured::Measured;
use super::plan::Plan;
use super::progress::{in_round, set_stage};
use super::sides::{side_track, Worker};
use super::worker::{CellRound, Message, Request};
use crate::error::Result;
use crate::services::worker::quote;

/// One balanced block of whole rounds, A B B A, each recorded into `measured`; `rounds` counts
/// the rounds each side has done.
pub(super) fn block(
    workers: &mut [Worker; 2],
    plan: &Plan,
    measured: &mut Measured,
    rounds: &mut [usize; 2],
) -> Result<()> {
    for side in [0usize, 1, 1, 0] {
        set_stage(format!("round {}", rounds[side] + 1));
        let w = &mut workers[side];
        let when = in_round(rounds[side], None, *rounds);
        let span = crate::timeline::span_on(side_track(["A", "B"][side]), "ab", "whole round")
            .with("round", rounds[side] + 1)
            .with("side", ["A", "B"][side]);
        let res = round(w, &when)?;
        drop(span);
        rounds[side] += 1;
        for (p, &(ia, ib)) in plan.pairs().iter().enumerate() {
            let Some(r) = res.get(if side == 0 { ia } else { ib }) else {
                let what = format!("a round answered {} cells, fewer than it said it had", res.len());
                return Err(w.fail(&what, &when));
            };
            measured.record(side, p, r);
        }
    }
    Ok(())
}

/// Asks `w` for one round.
fn round(w: &mut Worker, when: &str) -> Result<Vec<CellRound>> {
    match w.session.ask(&Request::Round, when)? {
        Message::Round { cells } => Ok(cells),
        other => Err(w.fail(&format!("expected a round, got {}", quote(&format!("{other:?}"))), when)),
    }
}
