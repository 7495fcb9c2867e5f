//! What the rounds measured: for each side and each matched cell, every round's kernel time
//! (when the round validated), and the cell's worst correctness over the rounds.

use super::plan::Plan;
use super::report::SideCell;
use super::worker::CellRound;

/// Per side, per matched cell, one entry per round: the validated time, or `None`.
pub(super) type Times = [Vec<Vec<Option<f64>>>; 2];

/// The rounds' figures so far.
pub(super) struct Measured {
    pub(super) times: Times,
    /// Per side, per matched cell: the rounds that did not validate, and the worst agreement,
    /// unexplained and invalid counts.
    pub(super) worst: [Vec<SideCell>; 2],
}

impl Measured {
    /// Nothing measured yet for `plan`'s matched cells.
    pub(super) fn new(plan: &Plan) -> Measured {
        let pairs = plan.pairs();
        let times = [vec![vec![]; pairs.len()], vec![vec![]; pairs.len()]];
        let worst = std::array::from_fn(|side| {
            pairs
                .iter()
                .map(|&(ia, ib)| {
                    let rays = if side == 0 { plan.cells[0][ia].rays } else { plan.cells[1][ib].rays };
                    SideCell { ms: vec![], failed_rounds: 0, agree: rays, unexplained: 0, invalid: 0 }
                })
                .collect()
        });
        Measured { times, worst }
    }

    /// Side `side`'s (0: A) answer `r` for matched cell `p` in its next round.
    pub(super) fn record(&mut self, side: usize, p: usize, r: &CellRound) {
        let s = &mut self.worst[side][p];
        if r.ms.is_none() {
            s.failed_rounds += 1;
        }
        self.times[side][p].push(r.ms);
        s.agree = s.agree.min(r.agree);
        s.unexplained = s.unexplained.max(r.unexplained);
        s.invalid = s.invalid.max(r.invalid);
    }
}
