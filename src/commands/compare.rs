//! `trilab compare BASE NEW`: two result folders (or rows files) cell by cell, the way Mesa's
//! shader-db and fossil-db reports compare two driver builds: only what changed is printed, then
//! the totals.
//!
//! Rows ([`crate::rows`]) are matched by command and cell. Each figure of a matched cell gets the
//! ratio NEW/BASE and a verdict by its class:
//! - **count** (instructions, bytes, SAH cost): exact, so any change is real and printed, with
//!   totals per figure over all cells ("spirv_instructions: 123456 -> 124000 (+0.44 %)"); an
//!   increase beyond the count threshold is a regression.
//! - **correctness** (agreement, leaks, NaN hits): every change is printed; any worsening is a
//!   regression, whatever the threshold.
//! - **timing**: `faster` or `slower` only when the two runs' min-max ranges over their timed
//!   rounds do not overlap (the rule of the study's claims, `study::claims::overlap`), else
//!   `within spread`; a figure of a single run on either side has no spread (`no spread`) and is
//!   never called a change. How the two sides' timings are set against each other is the
//!   [`TimingRule`]:
//!   - **raw**: each timing as measured. Right only when both runs shared one host and its load.
//!   - **calibrated** (when both sides carry calibration rows, which `trilab suite` writes:
//!     [`calibration`]): a command's timings are split into what moved them all and what moved
//!     one. *Command-wide*: the geometric mean of the command's NEW/BASE time factors, divided by
//!     the factor of the host calibration measured around the command in each run (a fixed CPU
//!     workload that does not go through the driver): a slower or busier host slows both alike
//!     and cancels; a slower driver or a slower everything does not. *Per figure*: each factor
//!     over its command's geometric mean (no calibration needed: the host's speed is common to
//!     every cell of one run), with the min-max rule on the ranges scaled alike; a kernel that
//!     slowed alone stands out against the rest of its command.
//!
//! Rates (Mrays/s, better higher) are judged as times (their inverse), so that "x1.30 slower"
//! means the same for a rate and a time: NEW takes 1.30 times as long.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::host::Host;
use crate::named::named_enum;
use crate::report::{Report, Table};
use crate::rows::{self, Better, Cell, Class, Figure, Row};
use crate::services::calibration::{self, CalibrationCell};

/// The threshold `trilab compare` gates on unless told: a real change of more than 10 %.
pub const DEFAULT_THRESHOLD_PCT: f64 = 10.0;

/// The command-wide threshold of the calibrated rule unless told: the calibrated speed of a
/// command's timings as a whole may move this much before it fails.
pub const DEFAULT_COMMAND_THRESHOLD_PCT: f64 = 40.0;

/// Cells only in one side listed by name in the text (the JSON lists them all).
const LIST_MAX: usize = 10;

named_enum! {
    /// How two sides' timings are set against each other.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum TimingRule: "timing rule" {
        /// calibrated where both sides carry a host calibration for every timed command, else raw (warning when the hosts differ)
        Auto = "auto" (default),
        /// each timing as measured: for two runs on one host under one load
        Raw = "raw",
        /// command-wide speed over the host calibration, and each figure against its command (fails when a side has no calibration)
        Calibrated = "calibrated",
        /// timings not judged, only counted (counts and correctness are): for two runs on different hosts, where a timing is no evidence about the code
        Ignore = "ignore",
    }
}

/// What `trilab compare` is asked.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct CompareOptions {
    /// Per figure: a real timing change (after the rule's normalisation) beyond it is printed,
    /// a slowdown beyond it fails.
    pub threshold_pct: f64,
    /// Counts (instructions, spills, bytes) gated apart: exact figures can be held tightly where
    /// timings on a noisy machine cannot (`None`: the timings' threshold).
    pub count_threshold_pct: Option<f64>,
    /// The calibrated rule's command-wide threshold.
    pub command_threshold_pct: f64,
    pub timings: TimingRule,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            threshold_pct: DEFAULT_THRESHOLD_PCT,
            count_threshold_pct: None,
            command_threshold_pct: DEFAULT_COMMAND_THRESHOLD_PCT,
            timings: TimingRule::Auto,
        }
    }
}

impl CompareOptions {
    /// Checks every threshold: a percentage, 0 or more.
    pub fn check(&self) -> Result<()> {
        check_pct("--threshold", self.threshold_pct)?;
        if let Some(c) = self.count_threshold_pct {
            check_pct("--count-threshold", c)?;
        }
        check_pct("--command-threshold", self.command_threshold_pct)
    }

    fn count_pct(&self) -> f64 {
        self.count_threshold_pct.unwrap_or(self.threshold_pct)
    }
}

/// What a figure's comparison found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// A timing whose ranges do not overlap, NEW the faster.
    Faster,
    /// A timing whose ranges do not overlap, NEW the slower.
    Slower,
    /// A timing whose ranges overlap: no real difference.
    WithinSpread,
    /// A timing of one run on a side: no range to judge by.
    NoSpread,
    /// A count or correctness figure that improved.
    Better,
    /// A count or correctness figure that got worse.
    Worse,
    /// A count or correctness figure that is equal.
    Unchanged,
}

impl std::fmt::Display for Verdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Verdict::Faster => "faster",
            Verdict::Slower => "slower",
            Verdict::WithinSpread => "within spread",
            Verdict::NoSpread => "no spread",
            Verdict::Better => "better",
            Verdict::Worse => "worse",
            Verdict::Unchanged => "unchanged",
        })
    }
}

/// One figure of one matched cell.
#[derive(Clone, Debug, Serialize)]
pub struct FigureChange {
    pub command: String,
    /// The cell's coordinates, `scene=bunny set=primary ...`.
    pub cell: String,
    pub figure: String,
    pub class: Class,
    pub unit: String,
    pub base: Figure,
    pub new: Figure,
    /// NEW's median over BASE's (`None` where BASE's is 0).
    pub ratio: Option<f64>,
    /// How many times worse NEW is (> 1) or better (< 1), oriented so that for a rate it is the
    /// inverse of `ratio` (a time's factor); `None` where a side is 0.
    pub factor: Option<f64>,
    /// Under the calibrated rule, a timing's factor over its command's geometric mean: what the
    /// verdict and the threshold judged (`None` under the raw rule and for other classes).
    pub relative_factor: Option<f64>,
    pub verdict: Verdict,
    /// A real change beyond the threshold (an improvement or a regression).
    pub beyond_threshold: bool,
    /// This change fails the comparison (exit status 1).
    pub regression: bool,
}

impl FigureChange {
    /// Whether the text prints it: real timing changes beyond the threshold, every count and
    /// correctness change.
    pub fn printed(&self) -> bool {
        match self.class {
            Class::Timing => self.beyond_threshold,
            Class::Count | Class::Correctness => self.verdict != Verdict::Unchanged,
        }
    }
}

/// One side of the comparison, as the header names it.
#[derive(Clone, Debug, Serialize)]
pub struct Side {
    pub path: PathBuf,
    pub files: Vec<PathBuf>,
    pub rows: usize,
    pub commands: Vec<String>,
    /// Every distinct device, driver, commit and settings its rows name.
    pub sources: Vec<String>,
    /// Every distinct host (CPU model and count) its rows name; empty where no row names one.
    pub hosts: Vec<Host>,
    /// The lowest and highest one-minute load average its rows recorded.
    pub load: Option<(f64, f64)>,
}

impl Side {
    /// Describes `rows` read from `path` (`files`).
    pub fn of(path: &Path, files: Vec<PathBuf>, rows: &[Row]) -> Side {
        let commands: BTreeSet<String> = rows.iter().map(|r| r.command.clone()).collect();
        let sources: BTreeSet<String> = rows.iter().map(|r| source_label(&r.source)).collect();
        let hosts: BTreeSet<Host> = rows.iter().filter_map(|r| r.source.host.clone()).map(|h| h.machine()).collect();
        let loads: Vec<f64> = rows.iter().filter_map(|r| r.source.host.as_ref()?.load_1m).map(|l| l.0).collect();
        let load = (!loads.is_empty())
            .then(|| (loads.iter().copied().fold(f64::INFINITY, f64::min), loads.iter().copied().fold(0.0, f64::max)));
        Side {
            path: path.to_owned(),
            files,
            rows: rows.len(),
            commands: commands.into_iter().collect(),
            sources: sources.into_iter().collect(),
            hosts: hosts.into_iter().collect(),
            load,
        }
    }

    /// `Intel Xeon ..., 2 CPUs; load 0.40-1.90`.
    fn host_label(&self) -> String {
        let mut s = match self.hosts.as_slice() {
            [] => "host not recorded".to_owned(),
            hosts => hosts.iter().map(Host::label).collect::<Vec<_>>().join(" | "),
        };
        if let Some((lo, hi)) = self.load {
            s.push_str(&format!("; load {lo:.2}-{hi:.2}"));
        }
        s
    }
}

/// One command's matched cells that carry timings: each cell's time factor NEW/BASE (log of the
/// geometric mean over its timings with a spread on both sides).
#[derive(Default)]
struct Timed {
    figures: usize,
    cells: Vec<(Cell, f64)>,
}

impl Timed {
    /// The command's mean log time factor over its cells.
    fn mean(&self) -> f64 {
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
const KERNEL_CONFIDENCE: f64 = 0.95;

/// The kernel groups of one command's cells ([`KernelChange`]): groups of two cells or more that
/// are not the whole command.
fn kernel_changes(
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

/// A count figure summed over every matched cell of a command.
#[derive(Clone, Debug, Serialize)]
pub struct CountTotal {
    pub command: String,
    pub figure: String,
    pub unit: String,
    pub base: f64,
    pub new: f64,
    pub cells: usize,
    pub cells_changed: usize,
}

/// The counts of what was compared.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Totals {
    pub cells_compared: usize,
    pub only_in_base: Vec<String>,
    pub only_in_new: Vec<String>,
    pub figures_compared: usize,
    pub faster: usize,
    pub slower: usize,
    pub within_spread: usize,
    pub no_spread: usize,
    /// Real timing changes beyond the threshold: improvements and regressions.
    pub faster_beyond_threshold: usize,
    pub slower_beyond_threshold: usize,
    pub counts_changed: usize,
    pub correctness_changed: usize,
    pub correctness_worse: usize,
    /// Figures in a cell on one side only (`command cell figure`).
    pub figures_only_in_one_side: usize,
    /// Counts not judged because a driver's JIT compiled them for different CPUs
    /// ([`rows::JIT_CPU`]: lavapipe's machine code on two hosts).
    pub counts_other_cpu: usize,
    /// Counts not judged because the two sides' SPIR-V came from different GLSL compilers
    /// ([`rows::SPIRV_COMPILER`], or one side does not name its compiler).
    pub counts_other_compiler: usize,
    /// Timing figures of matched cells left unjudged by the `ignore` rule.
    pub timings_not_judged: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    pub base: Side,
    pub new: Side,
    pub threshold_pct: f64,
    /// The counts' threshold (the timings' unless `--count-threshold` set it).
    pub count_threshold_pct: f64,
    pub command_threshold_pct: f64,
    /// The rule the timings were judged by (`auto` resolved to `raw` or `calibrated`).
    pub timing_rule: TimingRule,
    /// The calibration pairs, per command (calibrated rule).
    pub calibrations: Vec<HostCalibration>,
    /// Every kernel group of every timed command against its command (calibrated rule).
    pub kernels: Vec<KernelChange>,
    /// The printed changes (see [`FigureChange::printed`]), in cell order.
    pub changes: Vec<FigureChange>,
    pub totals: Totals,
    pub speed: Vec<CommandSpeed>,
    pub counts: Vec<CountTotal>,
    pub warnings: Vec<String>,
    pub regressions: usize,
    /// No regression: exit status 0.
    pub passed: bool,
}

/// Reads every rows file below `path` (or the file itself) with the file each row came from; a
/// side that holds no row, or one cell twice, is refused naming the files.
pub fn load(path: &Path) -> Result<(Side, Vec<Row>)> {
    let set = rows::read(path)?;
    let mut out: Vec<Row> = vec![];
    let mut seen: BTreeMap<(String, Cell), PathBuf> = BTreeMap::new();
    for file in &set.files {
        for row in rows::read_file(file)?.rows {
            if let Some(first) = seen.insert((row.command.clone(), row.cell.clone()), file.clone()) {
                return Err(Error::bad_input(
                    file,
                    None,
                    format!(
                        "`{}` is also in {}: a side holds one run of each cell (name one run's folder or rows file)",
                        row.key(),
                        first.display()
                    ),
                ));
            }
            out.push(row);
        }
    }
    if out.is_empty() {
        return Err(Error::bad_input(path, None, "its rows files hold no rows"));
    }
    Ok((Side::of(path, set.files, &out), out))
}

/// `device (driver), commit C, K=V ...` (the host is named apart, with what its JIT compiles
/// for: [`rows::JIT_CPU`] is the host's, not a setting of the run; [`rows::SPIRV_COMPILER`] is
/// the build's, named where counts are not judged for it).
fn source_label(s: &rows::Source) -> String {
    let mut label = format!("{} ({}), commit {}", s.device, s.driver, s.commit);
    for (k, v) in s.settings.iter().filter(|(k, _)| k.as_str() != rows::JIT_CPU && k.as_str() != rows::SPIRV_COMPILER) {
        label.push_str(&format!(", {k}={v}"));
    }
    label
}

/// Compares the rows files below `base` and `new`.
pub fn run(base: &Path, new: &Path, o: &CompareOptions) -> Result<CompareReport> {
    o.check()?;
    let (bs, br) = load(base)?;
    let (ns, nr) = load(new)?;
    compare_with(bs, &br, ns, &nr, o)
}

/// A threshold is a percentage, 0 or more.
pub fn check_threshold(pct: f64) -> Result<()> {
    check_pct("--threshold", pct)
}

fn check_pct(option: &str, pct: f64) -> Result<()> {
    if !(pct.is_finite() && pct >= 0.0) {
        return Err(Error::Usage(format!("{option} {pct}: a percentage, 0 or more")));
    }
    Ok(())
}

/// NEW's figure against BASE's (same class and unit).
pub fn judge(base: &Figure, new: &Figure, threshold_pct: f64) -> (Verdict, Option<f64>, bool, bool) {
    let t = threshold_pct / 100.0;
    let factor = time_factor(base, new);
    let worse = match base.better {
        Better::Lower => new.median > base.median,
        Better::Higher => new.median < base.median,
    };
    // Beyond the threshold either way (1/f for an improvement); a change from or to 0 always is.
    let beyond = match factor {
        Some(f) if f > 0.0 => f.max(1.0 / f) - 1.0 > t,
        _ => base.median != new.median,
    };
    match base.class {
        Class::Timing => {
            let verdict = if base.runs < 2 || new.runs < 2 {
                Verdict::NoSpread
            } else if base.overlaps(new) {
                Verdict::WithinSpread
            } else if worse {
                Verdict::Slower
            } else {
                Verdict::Faster
            };
            let real = matches!(verdict, Verdict::Faster | Verdict::Slower);
            (verdict, factor, real && beyond, real && worse && beyond)
        }
        Class::Count | Class::Correctness => {
            let verdict = if base.median == new.median {
                Verdict::Unchanged
            } else if worse {
                Verdict::Worse
            } else {
                Verdict::Better
            };
            let regression = worse && (base.class == Class::Correctness || beyond);
            (verdict, factor, verdict != Verdict::Unchanged && beyond, regression)
        }
    }
}

/// How many times worse NEW is: a time's (or count's) ratio, a rate's inverse; `None` where the
/// divisor is 0.
fn time_factor(base: &Figure, new: &Figure) -> Option<f64> {
    match base.better {
        Better::Lower => (base.median != 0.0).then(|| new.median / base.median),
        Better::Higher => (new.median != 0.0).then(|| base.median / new.median),
    }
}

/// `f` as if it took `factor` times less time: a time divided by it, a rate multiplied.
fn scaled(f: &Figure, factor: f64) -> Figure {
    let k = match f.better {
        Better::Lower => 1.0 / factor,
        Better::Higher => factor,
    };
    Figure { median: f.median * k, min: f.min * k, max: f.max * k, ..f.clone() }
}

/// Compares two sides' rows (each cell at most once per side, as [`load`] ensures) by the raw
/// rule at one threshold.
pub fn compare(base: Side, base_rows: &[Row], new: Side, new_rows: &[Row], threshold_pct: f64) -> CompareReport {
    let o = CompareOptions { threshold_pct, timings: TimingRule::Raw, ..CompareOptions::default() };
    compare_with(base, base_rows, new, new_rows, &o).expect("the raw rule needs no calibration")
}

/// The calibration rows of one side with their cells, by the command they calibrate; the other
/// rows.
fn split_calibration(rows: &[Row]) -> (BTreeMap<String, (CalibrationCell, &Row)>, Vec<&Row>) {
    let (cal, rest): (Vec<&Row>, Vec<&Row>) = rows.iter().partition(|r| r.command == calibration::COMMAND);
    let by_command = cal.into_iter().filter_map(|r| {
        let c = CalibrationCell::try_from(&r.cell).ok()?;
        Some((c.command.clone(), (c, r)))
    });
    (by_command.collect(), rest)
}

/// The calibration pair of `command`, or why there is none.
fn calibration_pair(
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

/// [`compare`] by the options' rule and thresholds. Fails (exit status 2) only when the
/// calibrated rule is asked for and a timed command has no calibration pair.
pub fn compare_with(
    mut base: Side,
    base_rows: &[Row],
    mut new: Side,
    new_rows: &[Row],
    o: &CompareOptions,
) -> Result<CompareReport> {
    let (base_cal, base_rows) = split_calibration(base_rows);
    let (new_cal, new_rows) = split_calibration(new_rows);
    for side in [&mut base, &mut new] {
        side.commands.retain(|c| c != calibration::COMMAND);
    }
    let key = |r: &Row| (r.command.clone(), r.cell.clone());
    let b: BTreeMap<(String, Cell), &Row> = base_rows.iter().map(|r| (key(r), *r)).collect();
    let n: BTreeMap<(String, Cell), &Row> = new_rows.iter().map(|r| (key(r), *r)).collect();
    let mut totals = Totals::default();
    let mut warnings = vec![];
    if base.commands != new.commands {
        warnings.push(format!(
            "the sides ran different commands: BASE {}, NEW {}; only the common cells are compared",
            base.commands.join(", "),
            new.commands.join(", ")
        ));
    }
    for (side, name, rows) in [(&base, "BASE", &base_rows), (&new, "NEW", &new_rows)] {
        // One command's rows from several devices, drivers, commits or settings (a side may
        // hold commands of different sources, such as the SPIR-V counts beside a device's run).
        let mut by_command: BTreeMap<&str, BTreeSet<String>> = BTreeMap::new();
        for r in rows.iter() {
            by_command.entry(r.command.as_str()).or_default().insert(source_label(&r.source));
        }
        for (command, sources) in by_command.iter().filter(|(_, s)| s.len() > 1) {
            warnings.push(format!(
                "{name}'s {command} rows mix {} devices, drivers, commits or settings ({})",
                sources.len(),
                side.path.display()
            ));
        }
    }

    totals.only_in_base = b.keys().filter(|k| !n.contains_key(*k)).map(|(c, cell)| rows::cell_key(c, cell)).collect();
    totals.only_in_new = n.keys().filter(|k| !b.contains_key(*k)).map(|(c, cell)| rows::cell_key(c, cell)).collect();

    // Pass 1: each matched cell's time factor (the geometric mean of its timings with a spread
    // on both sides), per command.
    let matched: Vec<(&(String, Cell), &Row, &Row)> =
        b.iter().filter_map(|(k, br)| n.get(k).map(|nr| (k, *br, *nr))).collect();
    let mut timed: BTreeMap<String, Timed> = BTreeMap::new();
    for (k, br, nr) in &matched {
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
    let log_speed: BTreeMap<String, (usize, f64)> =
        timed.iter().map(|(c, t)| (c.clone(), (t.figures, t.mean()))).collect();

    // The rule, and the calibration of every timed command.
    let pairs: BTreeMap<String, std::result::Result<HostCalibration, String>> =
        log_speed.keys().map(|c| (c.clone(), calibration_pair(c, &base_cal, &new_cal))).collect();
    let rule = match o.timings {
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
    };
    let different_hosts = !base.hosts.is_empty()
        && !new.hosts.is_empty()
        && !base.hosts.iter().all(|h| new.hosts.iter().any(|g| g.same_machine(h)));
    if different_hosts {
        warnings.push(format!(
            "the sides ran on different hosts (BASE {}; NEW {}): {}",
            base.hosts.iter().map(Host::label).collect::<Vec<_>>().join(" | "),
            new.hosts.iter().map(Host::label).collect::<Vec<_>>().join(" | "),
            match rule {
                TimingRule::Calibrated => "timings are judged by the host calibration",
                TimingRule::Ignore => "timings are not judged (--timings ignore)",
                _ if log_speed.is_empty() => "no timing is compared",
                _ => "timings are compared raw, and a host's speed reads as a change (`trilab suite` writes the calibration that takes it out)",
            }
        ));
    } else if rule == TimingRule::Raw && o.timings == TimingRule::Auto && !log_speed.is_empty() {
        if let Some(why) = pairs.values().find_map(|p| p.as_ref().err()) {
            warnings.push(format!("timings compared raw: {why}"));
        }
    }
    // A command's speed NEW/BASE: the geometric mean over its cells.
    let geomean = |c: &str| log_speed.get(c).map(|(_, mean_log_factor)| (-mean_log_factor).exp());

    // Pass 2: every figure.
    let mut changes = vec![];
    let mut counts: BTreeMap<(String, String), CountTotal> = BTreeMap::new();
    let mut regressions = 0;
    let mut mismatched = vec![];
    let mut other_cpus: BTreeSet<(String, String, String)> = BTreeSet::new();
    let mut other_compilers: BTreeSet<(String, String, String)> = BTreeSet::new();
    let mut cell_verdicts: BTreeMap<(String, Cell), Verdict> = BTreeMap::new();
    for (k, br, nr) in &matched {
        totals.cells_compared += 1;
        let names: BTreeSet<&String> = br.figures.keys().chain(nr.figures.keys()).collect();
        for name in names {
            let (Some(bf), Some(nf)) = (br.figures.get(name), nr.figures.get(name)) else {
                totals.figures_only_in_one_side += 1;
                continue;
            };
            if bf.class != nf.class || bf.unit != nf.unit || bf.better != nf.better {
                mismatched.push(format!("{} {name}", br.key()));
                continue;
            }
            if rule == TimingRule::Ignore && bf.class == Class::Timing {
                totals.timings_not_judged += 1;
                continue;
            }
            // A count is the same code's only where both rows name the same CPU the driver's JIT
            // compiled for and the same GLSL compiler (rows whose counts depend on neither, such
            // as bench's bytes and SAH cost, name neither: equal).
            let setting = |r: &Row, key: &str| r.source.settings.get(key).cloned().unwrap_or_default();
            if bf.class == Class::Count && setting(br, rows::JIT_CPU) != setting(nr, rows::JIT_CPU) {
                totals.counts_other_cpu += 1;
                other_cpus.insert((k.0.clone(), setting(br, rows::JIT_CPU), setting(nr, rows::JIT_CPU)));
                continue;
            }
            if bf.class == Class::Count && setting(br, rows::SPIRV_COMPILER) != setting(nr, rows::SPIRV_COMPILER) {
                totals.counts_other_compiler += 1;
                other_compilers.insert((
                    k.0.clone(),
                    setting(br, rows::SPIRV_COMPILER),
                    setting(nr, rows::SPIRV_COMPILER),
                ));
                continue;
            }
            totals.figures_compared += 1;
            let t = if bf.class == Class::Count { o.count_pct() } else { o.threshold_pct };
            // Under the calibrated rule a timing is judged against its command's mean change.
            let command_speed = geomean(&k.0).filter(|_| rule == TimingRule::Calibrated && bf.class == Class::Timing);
            let judged = command_speed.map(|s| scaled(nf, 1.0 / s));
            let (verdict, relative, beyond, regression) = judge(bf, judged.as_ref().unwrap_or(nf), t);
            // Under the calibrated rule one timing alone is printed, not failed: on a busy host one
            // sub-millisecond cell moves by itself far more than a kernel's slowdown (the kernels'
            // groups below judge that, over all their cells).
            let regression = regression && judged.is_none();
            if judged.is_some() && bf.runs >= 2 && nf.runs >= 2 {
                // A cell is slower (faster) when every timing of it is; one that disagrees with
                // itself is within spread.
                let e = cell_verdicts.entry((k.0.clone(), k.1.clone())).or_insert(verdict);
                if *e != verdict {
                    *e = Verdict::WithinSpread;
                }
            }
            let factor = time_factor(bf, nf);
            match verdict {
                Verdict::Faster => totals.faster += 1,
                Verdict::Slower => totals.slower += 1,
                Verdict::WithinSpread => totals.within_spread += 1,
                Verdict::NoSpread => totals.no_spread += 1,
                Verdict::Better | Verdict::Worse if bf.class == Class::Count => totals.counts_changed += 1,
                Verdict::Better | Verdict::Worse => totals.correctness_changed += 1,
                Verdict::Unchanged => {}
            }
            if bf.class == Class::Correctness && verdict == Verdict::Worse {
                totals.correctness_worse += 1;
            }
            if bf.class == Class::Timing && beyond {
                if verdict == Verdict::Faster {
                    totals.faster_beyond_threshold += 1;
                } else {
                    totals.slower_beyond_threshold += 1;
                }
            }
            if bf.class == Class::Count {
                let t = counts.entry((k.0.clone(), name.clone())).or_insert_with(|| CountTotal {
                    command: k.0.clone(),
                    figure: name.clone(),
                    unit: bf.unit.clone(),
                    base: 0.0,
                    new: 0.0,
                    cells: 0,
                    cells_changed: 0,
                });
                t.base += bf.median;
                t.new += nf.median;
                t.cells += 1;
                t.cells_changed += (verdict != Verdict::Unchanged) as usize;
            }
            regressions += regression as usize;
            let change = FigureChange {
                command: k.0.clone(),
                cell: rows::cell_key("", &k.1).trim_start().to_owned(),
                figure: name.clone(),
                class: bf.class,
                unit: bf.unit.clone(),
                base: bf.clone(),
                new: nf.clone(),
                ratio: (bf.median != 0.0).then(|| nf.median / bf.median),
                factor,
                relative_factor: judged.and(relative),
                verdict,
                beyond_threshold: beyond,
                regression,
            };
            if change.printed() {
                changes.push(change);
            }
        }
    }
    if !mismatched.is_empty() {
        warnings.push(format!(
            "{} figure(s) changed class, unit or direction and were not compared, e.g. {}",
            mismatched.len(),
            mismatched[0]
        ));
    }
    for (command, b_cpu, n_cpu) in &other_cpus {
        let name = |c: &String| if c.is_empty() { "not recorded".to_owned() } else { c.clone() };
        warnings.push(format!(
            "{command}: the driver compiled BASE's kernels for another CPU than NEW's ({} {} / {}): their machine \
             code differs by the CPU alone, so its counts are not judged",
            rows::JIT_CPU,
            name(b_cpu),
            name(n_cpu)
        ));
    }
    for (command, b, n) in &other_compilers {
        let name = |c: &String| if c.is_empty() { "not recorded".to_owned() } else { c.clone() };
        warnings.push(format!(
            "{command}: BASE's SPIR-V and NEW's come from different GLSL compilers (BASE: {}; NEW: {}): their \
             counts differ by the compiler alone, so they are not judged",
            name(b),
            name(n)
        ));
    }
    if totals.cells_compared == 0 {
        warnings.push("no cell is in both sides: nothing was compared".into());
    }

    // Command-wide: the calibrated speed of each command's timings as a whole.
    let mut calibrations = vec![];
    let mut speed = vec![];
    for (command, &(timings, mean_log_factor)) in &log_speed {
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
            let t = o.command_threshold_pct / 100.0;
            c.beyond_threshold = verdict != Verdict::WithinSpread && calibrated.max(1.0 / calibrated) - 1.0 > t;
            c.regression = verdict == Verdict::Slower && c.beyond_threshold;
            c.host_speed = Some(1.0 / cal.factor);
            c.calibrated_speed = Some(calibrated);
            c.verdict = Some(verdict);
            regressions += c.regression as usize;
            calibrations.push(cal.clone());
        } else if let (TimingRule::Ignore, Some(Ok(cal))) = (rule, pairs.get(command)) {
            // Shown, not judged: how the two hosts' speeds compared while each ran the command.
            c.host_speed = Some(1.0 / cal.factor);
            calibrations.push(cal.clone());
        }
        speed.push(c);
    }
    let kernels: Vec<KernelChange> = match rule {
        TimingRule::Calibrated => {
            timed.iter().flat_map(|(command, t)| kernel_changes(command, t, &cell_verdicts, o.threshold_pct)).collect()
        }
        _ => vec![],
    };
    regressions += kernels.iter().filter(|k| k.regression).count();
    Ok(CompareReport {
        base,
        new,
        threshold_pct: o.threshold_pct,
        count_threshold_pct: o.count_pct(),
        command_threshold_pct: o.command_threshold_pct,
        timing_rule: rule,
        calibrations,
        kernels,
        changes,
        totals,
        speed,
        counts: counts.into_values().collect(),
        warnings,
        regressions,
        passed: regressions == 0,
    })
}

/// A figure's value: whole numbers as they are, others to four significant digits.
fn value(x: f64) -> String {
    if x == x.trunc() && x.abs() < 1e15 {
        format!("{x:.0}")
    } else if x == 0.0 || !x.is_finite() {
        format!("{x}")
    } else {
        let decimals = (3 - x.abs().log10().floor() as i32).clamp(0, 12) as usize;
        format!("{x:.decimals$}")
    }
}

/// `median [min..max] unit` for a timing, `value unit` otherwise.
fn shown(f: &Figure) -> String {
    match f.class {
        Class::Timing => format!("{} [{}..{}] {}", value(f.median), value(f.min), value(f.max), f.unit),
        _ => format!("{} {}", value(f.median), f.unit),
    }
}

/// A signed percentage of `new` over `base`.
fn pct(base: f64, new: f64) -> String {
    if base == 0.0 {
        if new == 0.0 {
            "+0 %".into()
        } else {
            "new".into()
        }
    } else {
        format!("{:+.2} %", 100.0 * (new / base - 1.0))
    }
}

impl CompareReport {
    /// "10 %", or "10 % (timings), 1 % (counts)" when they differ; the command-wide threshold
    /// under the calibrated rule.
    pub fn thresholds(&self) -> String {
        let mut s = if self.count_threshold_pct == self.threshold_pct {
            format!("{} %", self.threshold_pct)
        } else {
            format!("{} % (timings), {} % (counts)", self.threshold_pct, self.count_threshold_pct)
        };
        if self.timing_rule == TimingRule::Calibrated {
            s = format!(
                "{s}; timings calibrated: {} % (a kernel against its command), {} % (a command over the host calibration)",
                self.threshold_pct, self.command_threshold_pct
            );
        }
        s
    }

    /// What failed, by kind: `2 commands' timings as a whole, 1 kernel, 47 counts`.
    pub fn failed(&self) -> String {
        let figures = |class: Class| self.changes.iter().filter(|c| c.regression && c.class == class).count();
        let kinds = [
            (
                self.speed.iter().filter(|c| c.regression).count(),
                "command's timings as a whole",
                "commands' timings as a whole",
            ),
            (
                self.kernels.iter().filter(|k| k.regression).count(),
                "kernel against its command",
                "kernels against their command",
            ),
            (figures(Class::Timing), "timing", "timings"),
            (figures(Class::Count), "count", "counts"),
            (figures(Class::Correctness), "correctness figure worse", "correctness figures worse"),
        ];
        kinds
            .iter()
            .filter(|(n, _, _)| *n > 0)
            .map(|(n, one, many)| format!("{n} {}", if *n == 1 { one } else { many }))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The exit status the rule gives: 1 when a regression exceeds the threshold (any
    /// correctness worsening), else 0.
    pub fn exit_code(&self) -> u8 {
        u8::from(!self.passed)
    }

    pub fn changes_table(&self) -> Table {
        let mut t = Table::new(["cell", "figure", "BASE", "NEW", "NEW/BASE", "verdict"]);
        for c in &self.changes {
            let verdict = match (c.class, c.relative_factor, c.factor) {
                (Class::Timing, Some(r), _) => format!("{} x{:.2} against its command", c.verdict, r.max(1.0 / r)),
                (Class::Timing, None, Some(f)) => format!("{} x{:.2}", c.verdict, f.max(1.0 / f)),
                _ => c.verdict.to_string(),
            };
            t.row([
                format!("{} {}", c.command, c.cell),
                c.figure.clone(),
                shown(&c.base),
                shown(&c.new),
                c.ratio.map_or_else(|| "-".into(), |r| format!("{r:.3}")),
                if c.regression { format!("{verdict} REGRESSION") } else { verdict },
            ]);
        }
        t
    }

    /// The kernel groups beyond the threshold (calibrated rule).
    pub fn kernels_table(&self) -> Table {
        let mut t = Table::new([
            "command",
            "kernel",
            "cells (slower, faster in every round)",
            "time factor against its command",
            "95 % interval",
            "verdict",
        ]);
        for k in self.kernels.iter().filter(|k| k.beyond_threshold) {
            t.row([
                k.command.clone(),
                k.kernel.clone(),
                format!("{} ({}, {})", k.cells, k.cells_slower, k.cells_faster),
                format!("x{:.3}", k.factor),
                format!("x{:.3}..x{:.3}", k.low, k.high),
                format!(
                    "{} x{:.2}{}",
                    k.verdict,
                    k.factor.max(1.0 / k.factor),
                    if k.regression { " REGRESSION" } else { "" }
                ),
            ]);
        }
        t
    }

    /// Per command: the timings as a whole, raw and (calibrated rule) over the host calibration.
    pub fn speed_table(&self) -> Table {
        let mut t = Table::new([
            "command",
            "timings",
            "speed NEW/BASE",
            "host speed NEW/BASE (calibration ms)",
            "calibrated speed",
            "verdict",
        ]);
        for c in &self.speed {
            let cal = self.calibrations.iter().find(|k| k.command == c.command);
            let verdict = match (c.verdict, c.calibrated_speed) {
                (Some(v), Some(s)) if v != Verdict::WithinSpread => {
                    format!("{v} x{:.2}{}", (1.0 / s).max(s), if c.regression { " REGRESSION" } else { "" })
                }
                (Some(v), _) => v.to_string(),
                _ => "-".into(),
            };
            t.row([
                c.command.clone(),
                c.timings.to_string(),
                format!("{:.3}", c.geomean_speed),
                match (c.host_speed, cal) {
                    (Some(h), Some(k)) => format!("{h:.3} ({} -> {})", shown(&k.base), shown(&k.new)),
                    _ => "-".into(),
                },
                c.calibrated_speed.map_or_else(|| "-".into(), |s| format!("{s:.3}")),
                verdict,
            ]);
        }
        t
    }
}

impl Report for CompareReport {
    fn to_text(&self) -> String {
        let mut s = String::new();
        for (name, side) in [("BASE", &self.base), ("NEW ", &self.new)] {
            s += &format!(
                "{name} {}: {} rows in {} file(s), commands {}\n",
                side.path.display(),
                side.rows,
                side.files.len(),
                side.commands.join(", ")
            );
            for src in &side.sources {
                s += &format!("     {src}\n");
            }
            s += &format!("     host: {}\n", side.host_label());
        }
        for w in &self.warnings {
            s += &format!("warning: {w}\n");
        }
        s += &match self.timing_rule {
            TimingRule::Calibrated => format!(
                "rule: timings calibrated: (1) a command's timings as a whole, by their speed over the host \
                 calibration's (a fixed CPU workload measured around them in each run), fail when slower beyond {c} %; \
                 (2) a kernel's cells (those sharing {keys}) against their command's mean change, slower or faster \
                 when the 95 % Student-t interval over its cells lies on one side of 1 and most of its cells were so in \
                 every round, fail when slower beyond {t} %; \
                 (3) one timing against its command's mean change, faster or slower when the ranges so scaled do \
                 not overlap, printed beyond {t} %, never failing alone; every count and correctness change is \
                 printed\n\n",
                c = self.command_threshold_pct,
                t = self.threshold_pct,
                keys = KERNEL_COORDINATES.join(", ")
            ),
            TimingRule::Ignore => "rule: timings not judged (a timing measured in another run, let alone on another \
                 host, is no evidence about the code: `trilab ab` times two builds side by side); every count and \
                 correctness change is printed and judged\n\n"
                .to_owned(),
            _ => format!(
                "rule: timings raw: a timing is faster or slower only when the two runs' min-max ranges do not \
                 overlap, and is printed beyond {} %; every count and correctness change is printed\n\n",
                self.threshold_pct
            ),
        };
        if self.changes.is_empty() {
            s += "no changes to print\n\n";
        } else {
            s += &format!("changed ({} figures):\n\n{}\n", self.changes.len(), self.changes_table().to_text());
        }
        let t = &self.totals;
        s += &format!(
            "cells compared: {}; only in BASE: {}; only in NEW: {}; figures compared: {}\n",
            t.cells_compared,
            t.only_in_base.len(),
            t.only_in_new.len(),
            t.figures_compared
        );
        for (name, list) in [("only in BASE", &t.only_in_base), ("only in NEW", &t.only_in_new)] {
            for k in list.iter().take(LIST_MAX) {
                s += &format!("  {name}: {k}\n");
            }
            if list.len() > LIST_MAX {
                s += &format!("  {name}: ... and {} more\n", list.len() - LIST_MAX);
            }
        }
        if self.timing_rule == TimingRule::Ignore {
            s += &format!("timings not judged: {}\n", t.timings_not_judged);
            for c in &self.speed {
                let cal = self.calibrations.iter().find(|k| k.command == c.command);
                s += &format!(
                    "  {}: {} timings, speed NEW/BASE {:.3}{} (information only)\n",
                    c.command,
                    c.timings,
                    c.geomean_speed,
                    match (c.host_speed, cal) {
                        (Some(h), Some(k)) =>
                            format!("; host calibration speed {h:.3} ({} -> {})", shown(&k.base), shown(&k.new)),
                        _ => String::new(),
                    }
                );
            }
        } else {
            s += &format!(
            "timings{}: {} faster ({} beyond {} %), {} slower ({} beyond), {} within spread, {} without spread (one run)\n",
            if self.timing_rule == TimingRule::Calibrated { " (each against its command)" } else { "" },
            t.faster,
            t.faster_beyond_threshold,
            self.threshold_pct,
            t.slower,
            t.slower_beyond_threshold,
            t.within_spread,
            t.no_spread
        );
            if self.timing_rule == TimingRule::Calibrated {
                s += &format!("commands' timings as a whole (> 1: NEW faster):\n\n{}\n", self.speed_table().to_text());
                let shown = self.kernels.iter().filter(|k| k.beyond_threshold).count();
                s += &format!(
                "kernels against their command: {} groups, {} slower and {} faster (interval and rounds agreeing), {shown} beyond {} %{}\n",
                self.kernels.len(),
                self.kernels.iter().filter(|k| k.verdict == Verdict::Slower).count(),
                self.kernels.iter().filter(|k| k.verdict == Verdict::Faster).count(),
                self.threshold_pct,
                if shown > 0 { ":" } else { "" }
            );
                if shown > 0 {
                    s += &format!("\n{}\n", self.kernels_table().to_text());
                }
            } else {
                for c in &self.speed {
                    s += &format!(
                        "speed NEW/BASE, geometric mean of {} timings of {} (> 1: NEW faster): {:.3}\n",
                        c.timings, c.command, c.geomean_speed
                    );
                }
            }
        }
        for c in &self.counts {
            s += &format!(
                "{} {}: {} -> {} {} ({}), {} of {} cells changed\n",
                c.command,
                c.figure,
                value(c.base),
                value(c.new),
                c.unit,
                pct(c.base, c.new),
                c.cells_changed,
                c.cells
            );
        }
        s += &format!("correctness: {} figures changed, {} worse\n", t.correctness_changed, t.correctness_worse);
        if t.figures_only_in_one_side > 0 {
            s += &format!("figures in one side only: {}\n", t.figures_only_in_one_side);
        }
        if t.counts_other_cpu > 0 {
            s += &format!("counts compiled for different CPUs, not judged: {}\n", t.counts_other_cpu);
        }
        if t.counts_other_compiler > 0 {
            s += &format!("counts of different GLSL compilers, not judged: {}\n", t.counts_other_compiler);
        }
        s += &if self.passed {
            format!("verdict: pass (no regression beyond {}, no correctness worse)\n", self.thresholds())
        } else {
            format!(
                "verdict: FAIL: {} regression(s): {} (thresholds {})\n",
                self.regressions,
                self.failed(),
                self.thresholds()
            )
        };
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Summary;
    use crate::rows::{cell, Source};

    fn source(commit: &str) -> Source {
        Source { device: "llvmpipe".into(), driver: "Mesa 25.0.7".into(), commit: commit.into(), ..Source::default() }
    }

    fn timing(median: f64, min: f64, max: f64) -> Figure {
        Figure::timing(Summary { median, min, max, runs: 5 }, "Mrays/s", Better::Higher)
    }

    /// Base: two bench cells with a rate, agreement and bytes; a spirv cell with a count.
    fn base_rows() -> Vec<Row> {
        let s = source("aaa");
        vec![
            Row::new("bench", cell([("scene", "bunny"), ("method", "mt")]), &s)
                .with("mrays_per_s", timing(10.0, 9.5, 10.5))
                .with("agreement", Figure::correctness(0.9999, "fraction", Better::Higher))
                .with("scene_bytes", Figure::count(1000.0, "bytes")),
            Row::new("bench", cell([("scene", "bunny"), ("method", "unit")]), &s)
                .with("mrays_per_s", timing(8.0, 7.5, 8.5))
                .with("agreement", Figure::correctness(0.9999, "fraction", Better::Higher)),
            Row::new("spirv", cell([("kernel", "raycast.mt.closest")]), &s)
                .with("spirv_instructions", Figure::count(500.0, "instructions")),
            Row::new("spirv", cell([("kernel", "raycast.unit.closest")]), &s)
                .with("spirv_instructions", Figure::count(600.0, "instructions")),
        ]
    }

    fn side(rows: &[Row], name: &str) -> Side {
        Side::of(Path::new(name), vec![], rows)
    }

    fn run(new: &[Row], threshold: f64) -> CompareReport {
        let base = base_rows();
        compare(side(&base, "base"), &base, side(new, "new"), new, threshold)
    }

    /// `base_rows` with `f` applied to the figure `figure` of the cell whose key contains `cell`.
    fn planted(cell: &str, figure: &str, f: impl Fn(&mut Figure)) -> Vec<Row> {
        let mut rows = base_rows();
        for r in rows.iter_mut().filter(|r| r.key().contains(cell)) {
            f(r.figures.get_mut(figure).unwrap());
        }
        rows
    }

    #[test]
    fn the_same_rows_compare_clean() {
        let r = run(&base_rows(), DEFAULT_THRESHOLD_PCT);
        assert!(r.passed && r.changes.is_empty(), "{}", r.to_text());
        assert_eq!(r.totals.cells_compared, 4);
        assert_eq!(r.totals.within_spread, 2);
        assert_eq!(r.exit_code(), 0);
        assert!(r.speed.iter().all(|c| (c.geomean_speed - 1.0).abs() < 1e-12));
    }

    #[test]
    fn a_real_slowdown_beyond_the_threshold_fails() {
        // 30 % more time: the rate divided by 1.3, ranges apart.
        let new = planted("method=mt", "mrays_per_s", |f| *f = timing(10.0 / 1.3, 7.5, 7.9));
        let r = run(&new, 10.0);
        assert_eq!(r.exit_code(), 1, "{}", r.to_text());
        assert_eq!(r.changes.len(), 1);
        let c = &r.changes[0];
        assert_eq!((c.verdict, c.regression), (Verdict::Slower, true));
        assert!((c.factor.unwrap() - 1.3).abs() < 1e-9);
        assert_eq!(r.totals.slower_beyond_threshold, 1);
        let text = r.to_text();
        assert!(text.contains("REGRESSION") && text.contains("method=mt") && !text.contains("method=unit"), "{text}");
        assert!(text.contains("FAIL"), "{text}");
        // Beyond 35 % it is a real slowdown, counted, but neither printed nor failing.
        let r = run(&new, 35.0);
        assert_eq!((r.exit_code(), r.totals.slower, r.changes.len()), (0, 1, 0), "{}", r.to_text());
    }

    #[test]
    fn counts_are_gated_apart_from_timings() {
        // A 30 % slowdown (ranges apart) and one more instruction: at 150 % for timings and 0 %
        // for counts (the CI gate's setting) the count fails and the timing passes.
        let mut new = planted("method=mt", "mrays_per_s", |f| *f = timing(10.0 / 1.3, 7.5, 7.9));
        for r in new.iter_mut().filter(|r| r.key().contains("raycast.mt")) {
            r.figures.get_mut("spirv_instructions").unwrap().median = 501.0;
            let f = r.figures.get_mut("spirv_instructions").unwrap();
            (f.min, f.max) = (501.0, 501.0);
        }
        let base = base_rows();
        let gate = |count: f64| CompareOptions {
            threshold_pct: 150.0,
            count_threshold_pct: Some(count),
            timings: TimingRule::Raw,
            ..CompareOptions::default()
        };
        let r = compare_with(side(&base, "base"), &base, side(&new, "new"), &new, &gate(0.0)).unwrap();
        assert_eq!((r.exit_code(), r.regressions), (1, 1), "{}", r.to_text());
        assert!(r.changes.iter().any(|c| c.figure == "spirv_instructions" && c.regression), "{}", r.to_text());
        assert!(r.changes.iter().all(|c| c.figure != "mrays_per_s"), "the timing is within 150 %: {}", r.to_text());
        assert!(r.to_text().contains("150 % (timings), 0 % (counts)"), "{}", r.to_text());
        // The same count change passes when the counts share the timings' 150 %.
        let r = compare_with(side(&base, "base"), &base, side(&new, "new"), &new, &gate(150.0)).unwrap();
        assert_eq!(r.exit_code(), 0, "{}", r.to_text());
    }

    #[test]
    fn overlapping_ranges_are_never_a_change() {
        let new = planted("method=mt", "mrays_per_s", |f| *f = timing(10.0 / 1.3, 7.0, 9.6));
        let r = run(&new, 10.0);
        assert_eq!(r.exit_code(), 0, "{}", r.to_text());
        assert!(r.changes.is_empty());
        assert_eq!((r.totals.within_spread, r.totals.slower), (2, 0));
        // Nor is one run without a range, however far apart.
        let new = planted("method=mt", "mrays_per_s", |f| {
            *f = Figure::timing(Summary { median: 5.0, min: 5.0, max: 5.0, runs: 1 }, "Mrays/s", Better::Higher)
        });
        let r = run(&new, 10.0);
        assert_eq!((r.exit_code(), r.totals.no_spread), (0, 1), "{}", r.to_text());
    }

    #[test]
    fn a_count_change_of_one_is_reported_with_totals() {
        let new = planted("raycast.mt", "spirv_instructions", |f| {
            f.median += 1.0;
            (f.min, f.max) = (f.median, f.median);
        });
        let r = run(&new, 10.0);
        assert_eq!(r.exit_code(), 0, "+1 of 500 is within 10 %: {}", r.to_text());
        assert_eq!(r.changes.len(), 1);
        assert_eq!(r.changes[0].verdict, Verdict::Worse);
        let total = r.counts.iter().find(|c| c.figure == "spirv_instructions").unwrap();
        assert_eq!((total.base, total.new, total.cells, total.cells_changed), (1100.0, 1101.0, 2, 1));
        assert!(r.to_text().contains("1100 -> 1101 instructions (+0.09 %), 1 of 2 cells changed"), "{}", r.to_text());
        // At a threshold below 0.2 % the same +1 fails.
        assert_eq!(run(&new, 0.1).exit_code(), 1);
    }

    #[test]
    fn a_correctness_worsening_fails_whatever_the_threshold() {
        let new = planted("method=unit", "agreement", |f| {
            f.median = 0.9998;
            f.min = 0.9998;
            f.max = 0.9998;
        });
        let r = run(&new, 1000.0);
        assert_eq!(r.exit_code(), 1, "{}", r.to_text());
        assert_eq!((r.totals.correctness_changed, r.totals.correctness_worse), (1, 1));
        assert!(r.to_text().contains("FAIL: 1 regression(s): 1 correctness figure worse ("), "{}", r.to_text());
        assert!(r.changes[0].regression);
    }

    #[test]
    fn an_improvement_is_reported_and_passes() {
        let new = planted("method=mt", "mrays_per_s", |f| *f = timing(15.0, 14.5, 15.5));
        let new = {
            let mut n = new;
            let f = n[0].figures.get_mut("scene_bytes").unwrap();
            (f.median, f.min, f.max) = (800.0, 800.0, 800.0);
            n
        };
        let r = run(&new, 10.0);
        assert_eq!(r.exit_code(), 0, "{}", r.to_text());
        let verdicts: Vec<Verdict> = r.changes.iter().map(|c| c.verdict).collect();
        assert_eq!(verdicts, [Verdict::Faster, Verdict::Better], "{}", r.to_text());
        assert_eq!(r.totals.faster_beyond_threshold, 1);
        let bench = r.speed.iter().find(|c| c.command == "bench").unwrap();
        // Geometric mean of 1.5 and 1.0.
        assert!((bench.geomean_speed - 1.5f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn cells_in_one_side_are_counted_and_a_different_command_set_warned() {
        let mut new = base_rows();
        new.retain(|r| r.command == "bench");
        new[1].cell.insert("layout".into(), "bvh4".into());
        let r = run(&new, 10.0);
        assert_eq!(r.totals.cells_compared, 1);
        assert_eq!(r.totals.only_in_base.len(), 3);
        assert_eq!(r.totals.only_in_new, ["bench layout=bvh4 method=unit scene=bunny"]);
        assert!(r.warnings.iter().any(|w| w.contains("different commands")), "{:?}", r.warnings);
        assert_eq!(r.exit_code(), 0);
    }

    #[test]
    fn a_side_with_one_cell_twice_or_no_rows_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("a/b"));
        std::fs::create_dir_all(&b).unwrap();
        rows::write(&a, None, &base_rows()[..1]).unwrap();
        rows::write(&b, None, &base_rows()[..1]).unwrap();
        let e = load(&a).unwrap_err().to_string();
        assert!(e.contains("also in") && e.contains("method=mt"), "{e}");
        let empty = dir.path().join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        rows::write(&empty, None, &[]).unwrap();
        let e = load(&empty).unwrap_err().to_string();
        assert!(e.contains("no rows") && e.contains("empty"), "{e}");
        assert!(check_threshold(-1.0).is_err() && check_threshold(f64::NAN).is_err() && check_threshold(0.0).is_ok());
    }

    /// Twelve bench cells, four methods by three ray sets (times in ms, min-max +-2 %, each cell
    /// moved by up to +-4 % by `seed`, as runs differ), and their calibration; `host` scales
    /// every time (a host that many times slower), `cal_ms` is the calibration's median.
    fn timed_side(host: f64, cal_ms: f64, machine: &str, seed: f64) -> Vec<Row> {
        let source =
            Source { host: Some(Host { cpu_model: machine.into(), cpus: 2, ..Host::default() }), ..source("aaa") };
        let ms =
            |m: f64| Figure::timing(Summary { median: m, min: m * 0.98, max: m * 1.02, runs: 5 }, "ms", Better::Lower);
        let mut rows = vec![];
        for (i, m) in ["mt", "unit", "quad-mt", "quad-unit"].iter().enumerate() {
            for (j, set) in ["primary", "diffuse", "random"].iter().enumerate() {
                let jitter = 1.0 + 0.04 * (seed + (3 * i + j) as f64).sin();
                rows.push(
                    Row::new("bench", cell([("method", *m), ("set", *set)]), &source)
                        .with("kernel_ms", ms((2.0 + i as f64 + 0.5 * j as f64) * host * jitter))
                        .with("agreement", Figure::correctness(1.0, "fraction", Better::Higher)),
                );
            }
        }
        let cal = Figure::timing(
            Summary { median: cal_ms, min: cal_ms * 0.97, max: cal_ms * 1.03, runs: 10 },
            "ms",
            Better::Lower,
        );
        rows.push(
            Row::new(calibration::COMMAND, cell([("command", "bench"), ("workload", calibration::WORKLOAD)]), &source)
                .with("cpu_ms", cal)
                .with("hits", Figure::count(1000.0, "rays"))
                .with("checksum", Figure::count(123456.0, "sum of ids")),
        );
        rows
    }

    fn gate(base: &[Row], new: &[Row], timings: TimingRule) -> Result<CompareReport> {
        let o = CompareOptions {
            threshold_pct: 25.0,
            count_threshold_pct: Some(0.0),
            command_threshold_pct: 30.0,
            timings,
        };
        compare_with(side(base, "base"), base, side(new, "new"), new, &o)
    }

    #[test]
    fn a_slower_host_passes_the_calibrated_rule_and_fails_the_raw_one() {
        // NEW's host is 2.2x slower: every kernel and the calibration alike.
        let (base, new) = (timed_side(1.0, 50.0, "fast CPU", 0.0), timed_side(2.2, 110.0, "slow CPU", 7.0));
        let r = gate(&base, &new, TimingRule::Auto).unwrap();
        assert_eq!(r.timing_rule, TimingRule::Calibrated);
        assert!(r.passed, "{}", r.to_text());
        let bench = &r.speed[0];
        assert!((bench.geomean_speed * 2.2 - 1.0).abs() < 0.03, "{bench:?}");
        assert!((bench.calibrated_speed.unwrap() - 1.0).abs() < 0.03, "{bench:?}");
        assert_eq!(r.calibrations.len(), 1);
        // Four kernels of three cells each, none apart from its command by more than the jitter.
        assert_eq!(r.kernels.len(), 4);
        assert!(r.kernels.iter().all(|k| !k.beyond_threshold && k.cells == 3), "{:?}", r.kernels);
        let text = r.to_text();
        assert!(text.contains("different hosts") && text.contains("fast CPU") && text.contains("slow CPU"), "{text}");
        assert!(text.contains("host speed NEW/BASE") && text.contains("timings calibrated"), "{text}");
        // The calibration rows themselves are never judged as timings.
        assert!(r.changes.iter().all(|c| c.command != calibration::COMMAND), "{text}");
        assert_eq!(r.totals.cells_compared, 12);
        // Raw, the same runs fail on every cell.
        let r = gate(&base, &new, TimingRule::Raw).unwrap();
        assert_eq!((r.passed, r.regressions), (false, 12), "{}", r.to_text());
    }

    #[test]
    fn the_ignore_rule_judges_no_timing_and_every_count_and_correctness_figure() {
        // NEW's host is 2.2x slower and one kernel 1.6x slower on top: neither is judged.
        let base = timed_side(1.0, 50.0, "fast CPU", 0.0);
        let mut new = timed_side(2.2, 60.0, "slow CPU", 7.0);
        for row in new.iter_mut().filter(|r| r.cell.get("method").map(String::as_str) == Some("unit")) {
            let f = row.figures.get_mut("kernel_ms").unwrap();
            (f.median, f.min, f.max) = (f.median * 1.6, f.min * 1.6, f.max * 1.6);
        }
        let r = gate(&base, &new, TimingRule::Ignore).unwrap();
        assert_eq!(r.timing_rule, TimingRule::Ignore);
        assert!(r.passed, "{}", r.to_text());
        assert_eq!(r.totals.timings_not_judged, 12, "{}", r.to_text());
        assert_eq!((r.totals.slower, r.totals.faster, r.kernels.len()), (0, 0, 0), "{}", r.to_text());
        assert!(r.changes.iter().all(|c| c.class != Class::Timing), "{}", r.to_text());
        // The calibration is shown as information: 60 ms against 50 ms, the host at 0.83.
        let host = r.speed[0].host_speed.unwrap();
        assert!((host - 50.0 / 60.0).abs() < 1e-9, "{host}");
        let text = r.to_text();
        assert!(text.contains("timings not judged: 12") && text.contains("information only"), "{text}");
        assert!(text.contains("timings are not judged (--timings ignore)"), "{text}");
        // A correctness figure worse still fails, and so does a count past its threshold.
        let mut worse = new.clone();
        worse[0].figures.get_mut("agreement").unwrap().median = 0.99;
        let r = gate(&base, &worse, TimingRule::Ignore).unwrap();
        assert_eq!((r.passed, r.totals.correctness_worse), (false, 1), "{}", r.to_text());
        let (mut base, mut more) = (base, new);
        base[0] = base[0].clone().with("scene_bytes", Figure::count(1000.0, "bytes"));
        more[0] = more[0].clone().with("scene_bytes", Figure::count(1001.0, "bytes"));
        let r = gate(&base, &more, TimingRule::Ignore).unwrap();
        assert!(!r.passed && r.changes.iter().any(|c| c.figure == "scene_bytes" && c.regression), "{}", r.to_text());
    }

    #[test]
    fn a_slower_driver_fails_command_wide_and_one_slower_kernel_fails_alone() {
        let base = timed_side(1.0, 50.0, "CPU", 0.0);
        // Every kernel 1.8x slower, the host (calibration) as fast as before: a slower driver.
        let new = timed_side(1.8, 50.0, "CPU", 3.0);
        let r = gate(&base, &new, TimingRule::Calibrated).unwrap();
        assert_eq!(r.regressions, 1, "{}", r.to_text());
        let bench = &r.speed[0];
        assert_eq!((bench.verdict, bench.regression), (Some(Verdict::Slower), true));
        assert!(r.changes.is_empty(), "no kernel slowed against the others: {}", r.to_text());
        assert!(r.to_text().contains("REGRESSION"), "{}", r.to_text());
        assert!(
            r.to_text().contains("FAIL: 1 regression(s): 1 command's timings as a whole (thresholds"),
            "{}",
            r.to_text()
        );
        // The same on a host 2x slower (calibration 2x): still 1.8x after the host is taken out.
        let r = gate(&base, &timed_side(3.6, 100.0, "CPU", 3.0), TimingRule::Calibrated).unwrap();
        assert_eq!((r.regressions, r.speed[0].regression), (1, true), "{}", r.to_text());
        // One kernel 1.6x slower in its three cells on a 2x slower host: its group alone fails.
        let mut new = timed_side(2.0, 100.0, "CPU", 5.0);
        for row in new.iter_mut().filter(|r| r.cell.get("method").map(String::as_str) == Some("unit")) {
            let f = row.figures.get_mut("kernel_ms").unwrap();
            (f.median, f.min, f.max) = (f.median * 1.6, f.min * 1.6, f.max * 1.6);
        }
        let r = gate(&base, &new, TimingRule::Calibrated).unwrap();
        assert_eq!(r.regressions, 1, "{}", r.to_text());
        let slow: Vec<&KernelChange> = r.kernels.iter().filter(|k| k.regression).collect();
        assert_eq!(slow.len(), 1, "{}", r.to_text());
        assert_eq!((slow[0].kernel.as_str(), slow[0].cells, slow[0].verdict), ("method=unit", 3, Verdict::Slower));
        // Against the command's mean, which the slow kernel moved too: 1.6^(3/4), within the jitter.
        assert!((slow[0].factor / 1.6f64.powf(0.75) - 1.0).abs() < 0.05, "{:?}", slow[0]);
        assert!(slow[0].low > 1.0 && slow[0].low < slow[0].factor && slow[0].factor < slow[0].high);
        // Its cells are printed, and none fails alone.
        assert_eq!(r.changes.len(), 3, "{}", r.to_text());
        assert!(r.changes.iter().all(|c| c.cell.contains("method=unit") && !c.regression), "{}", r.to_text());
        assert!(!r.speed[0].regression, "{}", r.to_text());
        assert!(r.to_text().contains("method=unit") && r.to_text().contains("REGRESSION"), "{}", r.to_text());
        assert!(r.to_text().contains("FAIL: 1 regression(s): 1 kernel against its command ("), "{}", r.to_text());
    }

    #[test]
    fn the_calibrated_rule_needs_a_calibration_pair_of_one_workload() {
        let base = timed_side(1.0, 50.0, "CPU", 0.0);
        let bare: Vec<Row> =
            timed_side(1.0, 50.0, "other CPU", 1.0).into_iter().filter(|r| r.command == "bench").collect();
        let e = gate(&base, &bare, TimingRule::Calibrated).unwrap_err().to_string();
        assert!(e.contains("NEW has no host calibration of `bench`"), "{e}");
        // Auto falls back to raw and says why, and that the hosts differ.
        let r = gate(&base, &bare, TimingRule::Auto).unwrap();
        assert_eq!(r.timing_rule, TimingRule::Raw);
        assert!(
            r.warnings.iter().any(|w| w.contains("different hosts") && w.contains("compared raw")),
            "{:?}",
            r.warnings
        );
        // Another workload's calibration cannot be set against this one's.
        let mut other = timed_side(1.0, 50.0, "CPU", 1.0);
        other.last_mut().unwrap().cell.insert("workload".into(), "soup-v0".into());
        let e = gate(&base, &other, TimingRule::Calibrated).unwrap_err().to_string();
        assert!(e.contains("workloads") && e.contains("soup-v0"), "{e}");
        // Nor one whose hits differ (not the same workload after all).
        let mut other = timed_side(1.0, 50.0, "CPU", 1.0);
        other.last_mut().unwrap().figures.get_mut("hits").unwrap().median = 999.0;
        let e = gate(&base, &other, TimingRule::Calibrated).unwrap_err().to_string();
        assert!(e.contains("disagree on their hits"), "{e}");
    }

    #[test]
    fn machine_code_counts_compiled_for_another_cpu_are_not_judged() {
        let row = |cpu: &str, instructions: f64| {
            let mut src = source("aaa");
            src.settings.insert(rows::JIT_CPU.into(), cpu.into());
            vec![Row::new("driver-stats", cell([("kernel", "raycast.mt.closest")]), &src)
                .with("instructions", Figure::count(instructions, "instructions"))]
        };
        let base = row("AuthenticAMD 25/17 flags:00000000", 2531.0);
        // Another CPU: 9 more instructions, not judged, said so.
        let new = row("GenuineIntel 6/85 flags:11111111", 2540.0);
        let r = compare(side(&base, "base"), &base, side(&new, "new"), &new, 0.0);
        assert!(r.passed, "{}", r.to_text());
        assert_eq!((r.totals.counts_other_cpu, r.totals.figures_compared), (1, 0));
        assert!(
            r.warnings.iter().any(|w| w.contains("GenuineIntel 6/85") && w.contains("not judged")),
            "{:?}",
            r.warnings
        );
        // The same CPU: the same 9 instructions fail at 0 %.
        let new = row("AuthenticAMD 25/17 flags:00000000", 2540.0);
        let r = compare(side(&base, "base"), &base, side(&new, "new"), &new, 0.0);
        assert_eq!((r.passed, r.totals.counts_other_cpu, r.regressions), (false, 0, 1), "{}", r.to_text());
    }

    #[test]
    fn spirv_counts_of_another_compiler_are_not_judged_and_of_the_same_one_are() {
        let row = |compiler: Option<&str>, instructions: f64| {
            let mut src = Source { device: "SPIR-V (no device)".into(), ..source("abc") };
            if let Some(c) = compiler {
                src.settings.insert(rows::SPIRV_COMPILER.into(), c.into());
            }
            vec![Row::new("spirv", cell([("kernel", "raycast.mt.closest")]), &src)
                .with("spirv_instructions", Figure::count(instructions, "instructions"))]
        };
        let debian = "shaderc 2023.2-1, glslang 12.0.0-2, SPIRV-Tools 2023.1-2 (static system libraries)";
        let base = row(Some("shaderc-sys 0.10.1 from source, SPIRV-Tools v2025.3"), 2531.0);
        let new = row(Some(debian), 2600.0);
        let r = compare(side(&base, "base"), &base, side(&new, "new"), &new, 0.0);
        assert!(r.passed, "{}", r.to_text());
        assert_eq!((r.totals.counts_other_compiler, r.totals.figures_compared), (1, 0));
        assert!(r.warnings.iter().any(|w| w.contains("v2025.3") && w.contains("2023.2-1") && w.contains("not judged")));
        // A side that names no compiler (rows from before it was recorded) is not judged either.
        let r = compare(side(&row(None, 2531.0), "base"), &row(None, 2531.0), side(&new, "new"), &new, 0.0);
        assert_eq!((r.passed, r.totals.counts_other_compiler), (true, 1), "{}", r.to_text());
        assert!(r.warnings.iter().any(|w| w.contains("BASE: not recorded")), "{:?}", r.warnings);
        // The same compiler: 69 more instructions fail at 0 %.
        let base = row(Some(debian), 2531.0);
        let r = compare(side(&base, "base"), &base, side(&new, "new"), &new, 0.0);
        assert_eq!((r.passed, r.totals.counts_other_compiler, r.regressions), (false, 0, 1), "{}", r.to_text());
    }

    #[test]
    fn one_commands_rows_from_two_sources_are_warned_and_two_commands_sources_are_not() {
        // base_rows: bench and spirv rows of one source; the SPIR-V counts of another are normal.
        let mut base = base_rows();
        for r in base.iter_mut().filter(|r| r.command == "spirv") {
            r.source.device = "SPIR-V (no device)".into();
        }
        let r = run(&base, 10.0);
        assert!(r.warnings.iter().all(|w| !w.contains("rows mix")), "{:?}", r.warnings);
        // One bench row of another commit: NEW's bench mixes two.
        let mut new = base.clone();
        new[1].source.commit = "bbb".into();
        let r = compare(side(&base, "base"), &base, side(&new, "new"), &new, 10.0);
        assert!(r.warnings.iter().any(|w| w.starts_with("NEW's bench rows mix 2")), "{:?}", r.warnings);
        assert!(!r.warnings.iter().any(|w| w.starts_with("BASE's")), "{:?}", r.warnings);
    }

    #[test]
    fn a_kernel_whose_medians_moved_but_not_its_rounds_is_not_called_slower() {
        // One kernel's medians 1.6x, but in two of its three cells some rounds as fast as the
        // base's (a burst of load, not a slower kernel): ranges overlap there.
        let base = timed_side(1.0, 50.0, "CPU", 0.0);
        let mut new = timed_side(1.0, 50.0, "CPU", 5.0);
        for (i, row) in new.iter_mut().filter(|r| r.cell.get("method").map(String::as_str) == Some("unit")).enumerate()
        {
            let f = row.figures.get_mut("kernel_ms").unwrap();
            let fastest = f.min;
            (f.median, f.max) = (f.median * 1.6, f.max * 1.6);
            f.min = if i == 0 { fastest * 1.6 } else { fastest };
        }
        let r = gate(&base, &new, TimingRule::Calibrated).unwrap();
        let unit = r.kernels.iter().find(|k| k.kernel == "method=unit").unwrap();
        assert_eq!((unit.cells_slower, unit.verdict, unit.regression), (1, Verdict::WithinSpread, false), "{unit:?}");
        assert!(unit.low > 1.0, "its interval alone would have called it slower: {unit:?}");
        assert!(r.passed, "{}", r.to_text());
    }
}
