//! Timings as a whole: each command's time factor over its cells, the host calibration that
//! takes a host's speed out of it, and the kernels whose cells slowed together.

use std::collections::BTreeMap;

use serde::Serialize;

use super::judge::{time_factor, Verdict};
use super::{Matched, Side, TimingRule};
use crate::error::{Error, Result};
use crate::host::Host;
use crate::rows::{Cell, Class, Figure, Row};
use crate::services::calibration::{self, CalibrationCell};

/// One command's matched cells that carry timings: each cell's time factor NEW/BASE (log of the
/// geometric mean over its timings with a spread on both sides).
#[derive(Default)]
pub(super) struct Timed {
    pub(super) figures: usize,
    pub(super) cells: Vec<(Cell, f64)>,
}

impl Timed {
    /// The command's mean log time factor over its cells.
    pub(super) fn mean(&self) -> f64 {
        self.cells.iter().map(|(_, l)| l).sum::<f64>() / self.cells.len() as f64
    }
}

/// The host calibration of one command's timings on both sides ([`calibration`]).
#[derive(Clone, Debug, Serialize)]
pub struct HostCalibration {
    pub command: String,
    pub workload: String,
    /// The calibration workload's time per pass on each side, ms (median, min-max).
    pub base: Figure,
    pub new: Figure,
    /// NEW's calibration time over BASE's: > 1 when NEW's host was the slower (or busier).
    pub factor: f64,
}

/// The cell coordinates that name a kernel (its intersector, node layout, traversal, variant, and
/// the workgroup and subgroup sizes its pipeline was made with); the others (scene, ray set, leaf
/// size) name the work it was given.
pub const KERNEL_COORDINATES: &[&str] =
    &["kernel", "method", "layout", "traversal", "variant", "local_size", "subgroup_size"];

/// Under the calibrated rule: one kernel's cells of a command (those that agree on every
/// [`KERNEL_COORDINATES`] value), their time factors against the command's mean change.
#[derive(Clone, Debug, Serialize)]
pub struct KernelChange {
    pub command: String,
    /// `method=unit layout=bvh2`.
    pub kernel: String,
    pub cells: usize,
    /// The geometric mean of its cells' time factors over the command's (> 1: slower than the
    /// command's other cells moved), and its 95 % Student-t interval over the cells.
    pub factor: f64,
    pub low: f64,
    pub high: f64,
    /// Its cells whose every timing was slower (faster) than the command's mean change with the
    /// min-max ranges so scaled apart.
    pub cells_slower: usize,
    pub cells_faster: usize,
    /// `slower`/`faster` when the interval lies above/below 1 and more than half of its cells
    /// were slower/faster in every round (ranges apart), else `within spread`. A burst of load
    /// moves one kernel's medians together now and then, but rarely every round of most of its
    /// cells (measured: 0-1 of 3 cells under load, 2-3 of 3 and 6 of 6 for a kernel slowed 2x).
    pub verdict: Verdict,
    pub beyond_threshold: bool,
    pub regression: bool,
}

/// Confidence of a kernel group's interval.
pub(super) const KERNEL_CONFIDENCE: f64 = 0.95;

/// The kernel groups of one command's cells ([`KernelChange`]): groups of two cells or more that
/// are not the whole command.
pub(super) fn kernel_changes(
    command: &str,
    t: &Timed,
    cell_verdicts: &BTreeMap<(String, Cell), Verdict>,
    threshold_pct: f64,
) -> Vec<KernelChange> {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    let mean = t.mean();
    // Per kernel: its cells' log factors against the command's mean, and their verdicts.
    let mut groups: BTreeMap<String, (Vec<f64>, Vec<Verdict>)> = BTreeMap::new();
    for (cell, log) in &t.cells {
        let key: Vec<String> =
            KERNEL_COORDINATES.iter().filter_map(|k| cell.get(*k).map(|v| format!("{k}={v}"))).collect();
        if !key.is_empty() {
            let g = groups.entry(key.join(" ")).or_default();
            g.0.push(log - mean);
            g.1.push(cell_verdicts.get(&(command.to_owned(), cell.clone())).copied().unwrap_or(Verdict::WithinSpread));
        }
    }
    groups
        .into_iter()
        .filter(|(_, (r, _))| r.len() >= 2 && r.len() < t.cells.len())
        .map(|(kernel, (r, verdicts))| {
            let count = |v: Verdict| verdicts.iter().filter(|x| **x == v).count();
            let (cells_slower, cells_faster) = (count(Verdict::Slower), count(Verdict::Faster));
            let n = r.len() as f64;
            let mu = r.iter().sum::<f64>() / n;
            let sd = (r.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
            let q = StudentsT::new(0.0, 1.0, n - 1.0)
                .expect("n >= 2 gives a positive number of degrees of freedom")
                .inverse_cdf(0.5 + KERNEL_CONFIDENCE / 2.0);
            let half = q * sd / n.sqrt();
            let (factor, low, high) = (mu.exp(), (mu - half).exp(), (mu + half).exp());
            let verdict = if low > 1.0 && 2 * cells_slower > r.len() {
                Verdict::Slower
            } else if high < 1.0 && 2 * cells_faster > r.len() {
                Verdict::Faster
            } else {
                Verdict::WithinSpread
            };
            let beyond = verdict != Verdict::WithinSpread && factor.max(1.0 / factor) - 1.0 > threshold_pct / 100.0;
            KernelChange {
                command: command.to_owned(),
                kernel,
                cells: r.len(),
                factor,
                low,
                high,
                cells_slower,
                cells_faster,
                verdict,
                beyond_threshold: beyond,
                regression: beyond && verdict == Verdict::Slower,
            }
        })
        .collect()
}

/// Per command: its timings NEW/BASE as a whole.
#[derive(Clone, Debug, Serialize)]
pub struct CommandSpeed {
    pub command: String,
    pub timings: usize,
    /// Geometric mean over its timings of the speed NEW/BASE as measured (> 1: NEW faster).
    pub geomean_speed: f64,
    /// Under the calibrated rule: the host's speed NEW/BASE by the calibration (> 1: NEW's host
    /// faster), and `geomean_speed` over it: the speed with the host's part taken out.
    pub host_speed: Option<f64>,
    pub calibrated_speed: Option<f64>,
    /// Under the calibrated rule: `faster`/`slower` when even the calibration's min-max leaves
    /// the calibrated speed on one side of 1, else `within spread`.
    pub verdict: Option<Verdict>,
    /// A real command-wide change beyond the command threshold.
    pub beyond_threshold: bool,
    pub regression: bool,
}

/// The calibration rows of one side with their cells, by the command they calibrate; the other
/// rows.
pub(super) fn split_calibration(rows: &[Row]) -> (BTreeMap<String, (CalibrationCell, &Row)>, Vec<&Row>) {
    let (cal, rest): (Vec<&Row>, Vec<&Row>) = rows.iter().partition(|r| r.command == calibration::COMMAND);
    let by_command = cal.into_iter().filter_map(|r| {
        let c = CalibrationCell::try_from(&r.cell).ok()?;
        Some((c.command.clone(), (c, r)))
    });
    (by_command.collect(), rest)
}

/// The calibration pair of `command`, or why there is none.
pub(super) fn calibration_pair(
    command: &str,
    base: &BTreeMap<String, (CalibrationCell, &Row)>,
    new: &BTreeMap<String, (CalibrationCell, &Row)>,
) -> std::result::Result<HostCalibration, String> {
    let (Some((bc, b)), Some((nc, n))) = (base.get(command), new.get(command)) else {
        let missing: Vec<&str> =
            [("BASE", base), ("NEW", new)].iter().filter(|(_, m)| !m.contains_key(command)).map(|(s, _)| *s).collect();
        return Err(format!(
            "{} {} no host calibration of `{command}` (`trilab suite` measures one)",
            missing.join(" and "),
            if missing.len() == 1 { "has" } else { "have" }
        ));
    };
    if bc.workload != nc.workload {
        return Err(format!(
            "the calibration workloads of `{command}` differ (BASE {}, NEW {}): their times cannot be set against each other",
            bc.workload, nc.workload
        ));
    }
    let same =
        ["hits", "checksum"].iter().all(|k| b.figures.get(*k).map(|f| f.median) == n.figures.get(*k).map(|f| f.median));
    let (Some(bt), Some(nt), true) = (b.figures.get("cpu_ms"), n.figures.get("cpu_ms"), same) else {
        return Err(format!(
            "the calibration rows of `{command}` disagree on their hits or lack `cpu_ms`: one of them is not the workload `{}`",
            bc.workload
        ));
    };
    if !(bt.median > 0.0 && nt.median > 0.0) {
        return Err(format!("the calibration of `{command}` has a zero time"));
    }
    Ok(HostCalibration {
        command: command.to_owned(),
        workload: bc.workload.clone(),
        base: bt.clone(),
        new: nt.clone(),
        factor: nt.median / bt.median,
    })
}

/// Each matched cell's time factor (the geometric mean of its timings with a spread on both
/// sides), per command.
pub(super) fn time_factors(matched: &[Matched]) -> BTreeMap<String, Timed> {
    let mut timed: BTreeMap<String, Timed> = BTreeMap::new();
    for (k, br, nr) in matched {
        let logs: Vec<f64> = br
            .figures
            .iter()
            .filter_map(|(name, bf)| {
                let nf = nr.figures.get(name)?;
                let comparable = bf.class == Class::Timing
                    && nf.class == Class::Timing
                    && bf.unit == nf.unit
                    && bf.better == nf.better
                    && bf.runs >= 2
                    && nf.runs >= 2;
                comparable.then(|| time_factor(bf, nf)).flatten().filter(|f| *f > 0.0 && f.is_finite()).map(f64::ln)
            })
            .collect();
        if !logs.is_empty() {
            let t = timed.entry(k.0.clone()).or_default();
            t.figures += logs.len();
            t.cells.push((k.1.clone(), logs.iter().sum::<f64>() / logs.len() as f64));
        }
    }
    timed
}

/// The rule the timings are judged by: `auto` is calibrated when every timed command has a
/// calibration pair, else raw; `calibrated` without one is an error naming why.
pub(super) fn timing_rule(
    asked: TimingRule,
    pairs: &BTreeMap<String, std::result::Result<HostCalibration, String>>,
) -> Result<TimingRule> {
    Ok(match asked {
        TimingRule::Auto if !pairs.is_empty() && pairs.values().all(|p| p.is_ok()) => TimingRule::Calibrated,
        TimingRule::Auto => TimingRule::Raw,
        TimingRule::Calibrated => {
            if let Some(why) = pairs.values().find_map(|p| p.as_ref().err()) {
                return Err(Error::Usage(format!("--timings calibrated: {why}")));
            }
            TimingRule::Calibrated
        }
        TimingRule::Raw => TimingRule::Raw,
        TimingRule::Ignore => TimingRule::Ignore,
    })
}

/// The warning when the sides ran on different hosts (saying how timings are judged then), or
/// why `auto` fell back to raw timings.
pub(super) fn host_warning(
    base: &Side,
    new: &Side,
    rule: TimingRule,
    asked: TimingRule,
    no_timing: bool,
    pairs: &BTreeMap<String, std::result::Result<HostCalibration, String>>,
) -> Option<String> {
    let different_hosts = !base.hosts.is_empty()
        && !new.hosts.is_empty()
        && !base.hosts.iter().all(|h| new.hosts.iter().any(|g| g.same_machine(h)));
    if different_hosts {
        return Some(format!(
            "the sides ran on different hosts (BASE {}; NEW {}): {}",
            base.hosts.iter().map(Host::label).collect::<Vec<_>>().join(" | "),
            new.hosts.iter().map(Host::label).collect::<Vec<_>>().join(" | "),
            match rule {
                TimingRule::Calibrated => "timings are judged by the host calibration",
                TimingRule::Ignore => "timings are not judged (--timings ignore)",
                _ if no_timing => "no timing is compared",
                _ => "timings are compared raw, and a host's speed reads as a change (`trilab suite` writes the calibration that takes it out)",
            }
        ));
    }
    if rule == TimingRule::Raw && asked == TimingRule::Auto && !no_timing {
        if let Some(why) = pairs.values().find_map(|p| p.as_ref().err()) {
            return Some(format!("timings compared raw: {why}"));
        }
    }
    None
}

/// Each timed command's speed as a whole, calibrated by the host where the rule is (with its
/// verdict), or only shown beside the host's speed under `--timings ignore`; and the
/// calibrations used.
pub(super) fn command_speeds(
    log_speed: &BTreeMap<String, (usize, f64)>,
    rule: TimingRule,
    pairs: &BTreeMap<String, std::result::Result<HostCalibration, String>>,
    command_threshold_pct: f64,
) -> (Vec<CommandSpeed>, Vec<HostCalibration>) {
    let mut calibrations = vec![];
    let mut speed = vec![];
    for (command, &(timings, mean_log_factor)) in log_speed {
        let geomean_speed = (-mean_log_factor).exp();
        let mut c = CommandSpeed {
            command: command.clone(),
            timings,
            geomean_speed,
            host_speed: None,
            calibrated_speed: None,
            verdict: None,
            beyond_threshold: false,
            regression: false,
        };
        if let (TimingRule::Calibrated, Some(Ok(cal))) = (rule, pairs.get(command)) {
            let calibrated = geomean_speed * cal.factor;
            // The calibration's own spread: the most and least favourable host factors.
            let (lo, hi) = (cal.new.min / cal.base.max, cal.new.max / cal.base.min);
            let verdict = if geomean_speed * hi < 1.0 {
                Verdict::Slower
            } else if geomean_speed * lo > 1.0 {
                Verdict::Faster
            } else {
                Verdict::WithinSpread
            };
            let t = command_threshold_pct / 100.0;
            c.beyond_threshold = verdict != Verdict::WithinSpread && calibrated.max(1.0 / calibrated) - 1.0 > t;
            c.regression = verdict == Verdict::Slower && c.beyond_threshold;
            c.host_speed = Some(1.0 / cal.factor);
            c.calibrated_speed = Some(calibrated);
            c.verdict = Some(verdict);
            calibrations.push(cal.clone());
        } else if let (TimingRule::Ignore, Some(Ok(cal))) = (rule, pairs.get(command)) {
            // Shown, not judged: how the two hosts' speeds compared while each ran the command.
            c.host_speed = Some(1.0 / cal.factor);
            calibrations.push(cal.clone());
        }
        speed.push(c);
    }
    (speed, calibrations)
}
