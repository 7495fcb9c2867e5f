//! The verdict of an `ab` run: each matched cell's ratio B/A with its interval, its hits
//! compared ray by ray and its correctness on both sides; each kernel's ratio over its cells.

use std::path::Path;

use super::compiled;
use super::interval::Ratio;
use super::measured::{Measured, Times};
use super::options::AbOptions;
use super::plan::Plan;
use super::report::{AbCell, AbKernel};
use super::worker::{self, CellKind};
use crate::error::{Error, Result};

/// The interval's level.
pub const LEVEL: f64 = 0.95;

/// Each matched cell's two sides after the rounds: their validated times, worst correctness,
/// the rays (or pixels) whose answers differ, the compiled-code changes and invocations, and the
/// cell's verdict.
pub(super) fn judged_cells(
    o: &AbOptions,
    plan: &Plan,
    measured: &Measured,
    [dir_a, dir_b]: [&Path; 2],
    stats: Option<&[compiled::SideStats; 2]>,
    [inv_a, inv_b]: [&[Option<u64>]; 2],
) -> Result<Vec<AbCell>> {
    let [cells_a, cells_b] = plan.cells;
    let Measured { times, worst } = measured;
    let mut out = vec![];
    for (p, &(ia, ib)) in plan.pairs().iter().enumerate() {
        let c = cells_b[ib].clone();
        let ratio = cell_ratio(times, p, plan.paired);
        let mut a = worst[0][p].clone();
        let mut b = worst[1][p].clone();
        a.ms = times[0][p].iter().flatten().copied().collect();
        b.ms = times[1][p].iter().flatten().copied().collect();
        // A worker that did not write a cell's hits (another build's bug, or not trilab) is
        // named with the file.
        let recorded = |side: &str, r: Result<_>| {
            r.map_err(|e| Error::Usage(format!("side {side}: cell `{}`: its first round's output: {e}", c.label())))
        };
        let rays_differing = match c.kind {
            CellKind::Raycast => crate::rays::differing_hits(
                &recorded("A", crate::rays::read_hits(&dir_a.join(format!("{ia}.hits"))))?,
                &recorded("B", crate::rays::read_hits(&dir_b.join(format!("{ib}.hits"))))?,
            ),
            CellKind::Pathtrace => {
                worker::differing_pixels(&dir_a.join(format!("{ia}.image")), &dir_b.join(format!("{ib}.image")))?
            }
        };
        let compiled = stats.as_ref().and_then(|[sa, sb]| compiled::diff([sa, sb], [&cells_a[ia], &c]));
        let invocations = o.workload.pipeline_stats.then(|| [inv_a.get(ia).copied().flatten(), inv_b[ib]]);
        let correctness_worse = b.agree < a.agree || b.unexplained > a.unexplained || b.invalid > a.invalid;
        out.push(AbCell {
            cell: c,
            a,
            b,
            verdict: ratio.map(|r| r.verdict(o.threshold)),
            ratio,
            rays_differing,
            correctness_worse,
            compiled,
            invocations,
        });
    }
    Ok(out)
}

/// Each kernel of the plan over its matched cells (`cells`, judged): its ratio B/A round by
/// round, its verdict, and whether any of its cells' correctness got worse on B.
pub(super) fn judged_kernels(o: &AbOptions, plan: &Plan, times: &Times, cells: &[AbCell]) -> Vec<AbKernel> {
    plan.groups
        .iter()
        .map(|g| {
            let ratio = kernel_ratio(times, &g.members, plan.paired);
            AbKernel {
                kernel: g.kernel.clone(),
                kind: g.first.kind,
                method: g.first.method.clone(),
                layout: g.first.layout.clone(),
                traversal: g.first.traversal.clone(),
                cells: g.members.len(),
                ratio,
                verdict: ratio.map(|r| r.verdict(o.threshold)),
                correctness_worse: g.members.iter().any(|&p| cells[p].correctness_worse),
            }
        })
        .collect()
}

/// B/A for one matched cell, from its validated rounds: paired round by round when the two
/// sides ran each round's cell back to back, else Welch's interval on the two sides' rounds.
pub(super) fn cell_ratio(times: &Times, p: usize, paired: bool) -> Option<Ratio> {
    if paired {
        let d: Vec<f64> = times[0][p]
            .iter()
            .zip(&times[1][p])
            .filter_map(|(a, b)| Some(b.as_ref()?.ln() - a.as_ref()?.ln()))
            .collect();
        return Ratio::paired(&d, LEVEL);
    }
    let ok = |side: usize| times[side][p].iter().flatten().copied().collect::<Vec<f64>>();
    Ratio::welch(&ok(0), &ok(1), LEVEL)
}

/// B/A for one kernel over its cells, round by round (a round counts only when all its cells
/// validated on both sides). Paired: each round's figure is the mean over its cells of ln(b) -
/// ln(a), each cell's two sides timed back to back, and the interval is Student's t on those.
/// Unpaired (whole rounds apart): each side's round figure is the geometric mean of its cells'
/// times, and Welch's interval is taken over those. The cells of one round share that round's
/// moment on the host, so they are not independent samples: pooling them per round keeps a
/// burst that slowed one round from passing for several agreeing cells. Over its scenes and ray
/// sets a kernel's interval is narrower than any one cell's, so a smaller slowdown of it can be
/// told from noise.
pub(super) fn kernel_ratio(times: &Times, members: &[usize], paired: bool) -> Option<Ratio> {
    let rounds = |side: usize| members.iter().map(|&p| times[side][p].len()).min().unwrap_or(0);
    let log_mean = |side: usize, r: usize| -> Option<f64> {
        let logs: Option<Vec<f64>> = members.iter().map(|&p| times[side][p][r].map(f64::ln)).collect();
        logs.map(|l| l.iter().sum::<f64>() / l.len() as f64)
    };
    if paired {
        let d: Vec<f64> =
            (0..rounds(0).min(rounds(1))).filter_map(|r| Some(log_mean(1, r)? - log_mean(0, r)?)).collect();
        return Ratio::paired(&d, LEVEL);
    }
    let per_round =
        |side: usize| -> Vec<f64> { (0..rounds(side)).filter_map(|r| log_mean(side, r).map(f64::exp)).collect() };
    Ratio::welch(&per_round(0), &per_round(1), LEVEL)
}

#[cfg(test)]
mod tests {
    use super::super::interval::Verdict;
    use super::*;

    #[test]
    fn a_kernel_pools_its_cells_round_by_round() {
        // Two cells of one kernel, five rounds a side; B takes 1.2x A, and each round moves
        // both cells of a side together (the host's moment), by up to +-10 %, in another order
        // on each side. Per round, ln of the geometric mean of the cells moves by ln(moment),
        // so the interval is Welch's on those: exp(ln 1.2 +- t(0.975, 8) sqrt(2 s^2 / 5)), with
        // s^2 = 0.006291 the moments' log variance: [1.0689, 1.3472].
        let moment = [1.0, 1.1, 0.9, 1.05, 0.95];
        let side = |k: f64, order: &[usize]| -> Vec<Vec<Option<f64>>> {
            [2.0, 8.0].iter().map(|&ms| order.iter().map(|&i| Some(ms * moment[i] * k)).collect()).collect()
        };
        let mut times = [side(1.0, &[0, 1, 2, 3, 4]), side(1.2, &[4, 2, 0, 3, 1])];
        let r = kernel_ratio(&times, &[0, 1], false).unwrap();
        assert!((r.ratio - 1.2).abs() < 1e-9, "{r:?}");
        assert!((r.low - 1.0689).abs() < 0.001 && (r.high - 1.3472).abs() < 0.001, "{r:?}");
        assert_eq!((r.verdict(0.05), r.verdict(0.1)), (Verdict::HurtBeyondThreshold, Verdict::Hurt));
        // A round in which one cell did not validate does not count for the kernel.
        times[1][1][2] = None;
        let r = kernel_ratio(&times, &[0, 1], false).unwrap();
        assert_eq!((r.rounds_a, r.rounds_b), (5, 4));
        // Each cell alone: the same ratio, from its own rounds.
        let c = cell_ratio(&times, 0, false).unwrap();
        assert!((c.ratio - 1.2).abs() < 1e-9 && c.rounds_b == 5, "{c:?}");
        // Paired (each cell's sides back to back, sharing the moment): the moment cancels and
        // B/A is 1.2 in every round, so the interval closes on it; a round in which one side of
        // one cell did not validate is left out.
        let both = |k: f64| -> Vec<Vec<Option<f64>>> {
            [2.0, 8.0].iter().map(|&ms| moment.iter().map(|m| Some(ms * m * k)).collect()).collect()
        };
        let mut times = [both(1.0), both(1.2)];
        let r = kernel_ratio(&times, &[0, 1], true).unwrap();
        assert!((r.ratio - 1.2).abs() < 1e-9 && r.half_width() < 1e-9, "{r:?}");
        times[0][0][3] = None;
        let r = kernel_ratio(&times, &[0, 1], true).unwrap();
        assert_eq!((r.rounds_a, r.rounds_b), (4, 4));
        assert_eq!(cell_ratio(&times, 1, true).unwrap().rounds_a, 5);
        // Fewer than two usable rounds: no interval.
        let one = [vec![vec![Some(1.0)]], vec![vec![Some(1.0), Some(2.0)]]];
        assert!(kernel_ratio(&one, &[0], false).is_none());
    }
}
