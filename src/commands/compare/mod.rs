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

use crate::rows::{self, Cell, Row};
use crate::services::calibration;

mod figures;
mod judge;
mod report;
pub mod repro;
mod timing;

use figures::judge_figures;

pub use judge::*;
pub use report::*;
pub use timing::*;

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
    /// Judge the counts of rows that different driver builds compiled ([`rows::DRIVER_BUILD`]):
    /// `compare` does (comparing two Mesa builds is what it is for, and it says the changes are
    /// the drivers'); the gate does not, since another build on the CI host says nothing about
    /// the code.
    pub counts_across_driver_builds: bool,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            threshold_pct: DEFAULT_THRESHOLD_PCT,
            count_threshold_pct: None,
            command_threshold_pct: DEFAULT_COMMAND_THRESHOLD_PCT,
            timings: TimingRule::Auto,
            counts_across_driver_builds: true,
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
/// the build's, named where counts are not judged for it; [`rows::DRIVER_BUILD`] is the driver's,
/// already named).
fn source_label(s: &rows::Source) -> String {
    let mut label = format!("{} ({}), commit {}", s.device, s.driver, s.commit);
    let hidden = [rows::JIT_CPU, rows::SPIRV_COMPILER, rows::DRIVER_BUILD];
    for (k, v) in s.settings.iter().filter(|(k, _)| !hidden.contains(&k.as_str())) {
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

/// Compares two sides' rows (each cell at most once per side, as [`load`] ensures) by the raw
/// rule at one threshold.
pub fn compare(base: Side, base_rows: &[Row], new: Side, new_rows: &[Row], threshold_pct: f64) -> CompareReport {
    let o = CompareOptions { threshold_pct, timings: TimingRule::Raw, ..CompareOptions::default() };
    compare_with(base, base_rows, new, new_rows, &o).expect("the raw rule needs no calibration")
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
    let mut warnings = source_warnings(&base, &base_rows, &new, &new_rows);
    totals.only_in_base = b.keys().filter(|k| !n.contains_key(*k)).map(|(c, cell)| rows::cell_key(c, cell)).collect();
    totals.only_in_new = n.keys().filter(|k| !b.contains_key(*k)).map(|(c, cell)| rows::cell_key(c, cell)).collect();

    // Pass 1: each matched cell's time factor, per command; the rule, and the calibration of
    // every timed command.
    let matched: Vec<Matched> = b.iter().filter_map(|(k, br)| n.get(k).map(|nr| (k, *br, *nr))).collect();
    let timed = time_factors(&matched);
    let log_speed: BTreeMap<String, (usize, f64)> =
        timed.iter().map(|(c, t)| (c.clone(), (t.figures, t.mean()))).collect();
    let pairs: BTreeMap<String, std::result::Result<HostCalibration, String>> =
        log_speed.keys().map(|c| (c.clone(), calibration_pair(c, &base_cal, &new_cal))).collect();
    let rule = timing_rule(o.timings, &pairs)?;
    warnings.extend(host_warning(&base, &new, rule, o.timings, log_speed.is_empty(), &pairs));

    // Pass 2: every figure.
    let figures = judge_figures(&matched, rule, o, &log_speed, &mut totals);
    warnings.extend(figures.warnings());
    if totals.cells_compared == 0 {
        warnings.push("no cell is in both sides: nothing was compared".into());
    }

    // Command-wide: the calibrated speed of each command's timings as a whole; then the kernels.
    let (speed, calibrations) = command_speeds(&log_speed, rule, &pairs, o.command_threshold_pct);
    let kernels: Vec<KernelChange> = match rule {
        TimingRule::Calibrated => timed
            .iter()
            .flat_map(|(command, t)| kernel_changes(command, t, &figures.cell_verdicts, o.threshold_pct))
            .collect(),
        _ => vec![],
    };
    let regressions = figures.regressions
        + speed.iter().filter(|c| c.regression).count()
        + kernels.iter().filter(|k| k.regression).count();
    Ok(CompareReport {
        base,
        new,
        threshold_pct: o.threshold_pct,
        count_threshold_pct: o.count_pct(),
        command_threshold_pct: o.command_threshold_pct,
        timing_rule: rule,
        calibrations,
        kernels,
        changes: figures.changes,
        totals,
        speed,
        counts: figures.counts.into_values().collect(),
        identities: figures.identities.into_values().collect(),
        warnings,
        regressions,
        passed: regressions == 0,
        repros: vec![],
    })
}

/// A cell in both sides: its key (command, cell) and its two rows.
type Matched<'a> = (&'a (String, Cell), &'a Row, &'a Row);

/// Warnings about what the sides hold: different commands, or one command's rows from several
/// devices, drivers, commits or settings (a side may hold commands of different sources, such as
/// the SPIR-V counts beside a device's run).
fn source_warnings(base: &Side, base_rows: &[&Row], new: &Side, new_rows: &[&Row]) -> Vec<String> {
    let mut warnings = vec![];
    if base.commands != new.commands {
        warnings.push(format!(
            "the sides ran different commands: BASE {}, NEW {}; only the common cells are compared",
            base.commands.join(", "),
            new.commands.join(", ")
        ));
    }
    for (side, name, rows) in [(base, "BASE", base_rows), (new, "NEW", new_rows)] {
        // Rows of GPU targets name their chip and compiler in the cell: each one's device (RADV
        // names LLVM in it) and driver are its own.
        let mut by_command: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for r in rows.iter() {
            let command = match (r.cell.get("chip"), r.cell.get("compiler")) {
                (Some(chip), Some(compiler)) => format!("{} ({chip}, {compiler})", r.command),
                (Some(chip), None) => format!("{} ({chip})", r.command),
                _ => r.command.clone(),
            };
            by_command.entry(command).or_default().insert(source_label(&r.source));
        }
        for (command, sources) in by_command.iter().filter(|(_, s)| s.len() > 1) {
            warnings.push(format!(
                "{name}'s {command} rows mix {} devices, drivers, commits or settings ({})",
                sources.len(),
                side.path.display()
            ));
        }
    }
    warnings
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Report;
    use crate::report::Summary;
    use crate::rows::{cell, Source};
    use crate::rows::{Better, Class, Figure};

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
        assert!(
            r.to_text().contains(
                "spirv_instructions: 1100 -> 1101 instructions (+0.09 %; lower is better); 1 of 2 cells changed, 0 better, \
                 1 worse: 500 -> 501 (+0.20 %)"
            ),
            "{}",
            r.to_text()
        );
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
            counts_across_driver_builds: false,
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

    /// A compiled kernel's statistics as RADV gives them, typed: VGPRs fewer-is-better,
    /// subgroups per SIMD more-is-better, the hash an identity; compiled by `driver`.
    fn compiled(vgprs: f64, subgroups: f64, hash: &str, driver: &str) -> Vec<Row> {
        let mut s = source("aaa");
        s.settings.insert(rows::DRIVER_BUILD.into(), driver.into());
        vec![Row::new("driver-stats", cell([("kernel", "raycast"), ("method", "mt"), ("chip", "navi21")]), &s)
            .with("vgprs", Figure::count(vgprs, "registers"))
            .with("subgroups_per_simd", Figure::count_toward(subgroups, "subgroups", Better::Higher))
            .with_identity("hash", hash)]
    }

    /// Issue 50: Mesa 25.0.7 gives a kernel fewer VGPRs and more subgroups per SIMD than 22.3.6;
    /// the rise in occupancy is better, not a regression, and the changed hash is an identity
    /// that changed, judged neither way.
    #[test]
    fn more_subgroups_per_simd_is_better_and_a_hash_is_only_changed() {
        let (b, n) = (compiled(48.0, 20.0, "0x1", "radv Mesa 22.3.6"), compiled(40.0, 24.0, "0x2", "radv Mesa 25.0.7"));
        let r = compare(side(&b, "base"), &b, side(&n, "new"), &n, 10.0);
        let verdict = |f: &str| r.changes.iter().find(|c| c.figure == f).map(|c| (c.verdict, c.regression));
        assert_eq!(verdict("subgroups_per_simd"), Some((Verdict::Better, false)), "{}", r.to_text());
        assert_eq!(verdict("vgprs"), Some((Verdict::Better, false)));
        assert_eq!(verdict("hash"), None, "a hash is no figure: {}", r.to_text());
        assert!(r.passed, "{}", r.to_text());
        let id = r.identities.iter().find(|i| i.identity == "hash").unwrap();
        assert_eq!((id.cells, id.cells_changed), (1, 1));
        let text = r.to_text();
        assert!(
            text.contains("driver-stats hash: changed in 1 of 1 cells (an identity: not better or worse)"),
            "{text}"
        );
        assert!(text.contains("subgroups_per_simd: 20 -> 24 subgroups (+20.00 %; higher is better)"), "{text}");
        assert!(
            r.warnings.iter().any(|w| w.contains("different driver builds") && w.contains("are the drivers'")),
            "{:?}",
            r.warnings
        );
        // The other way round, fewer subgroups per SIMD is worse, and beyond 10 % a regression.
        let r = compare(side(&n, "base"), &n, side(&b, "new"), &b, 10.0);
        let c = r.changes.iter().find(|c| c.figure == "subgroups_per_simd").unwrap();
        assert_eq!((c.verdict, c.regression), (Verdict::Worse, true), "{}", r.to_text());
        // An unchanged hash is an unchanged identity.
        let same = compiled(48.0, 20.0, "0x1", "radv Mesa 22.3.6");
        let r = compare(side(&b, "base"), &b, side(&same, "new"), &same, 10.0);
        assert_eq!(r.identities[0].cells_changed, 0);
        assert!(r.changes.is_empty() && r.passed);
    }

    /// The gate's rule: counts of another driver build are not judged, and it says so.
    #[test]
    fn the_gate_does_not_judge_counts_of_another_driver_build() {
        let (b, n) = (compiled(40.0, 24.0, "0x1", "radv Mesa 25.0.7"), compiled(48.0, 20.0, "0x2", "radv Mesa 25.1.0"));
        let o = CompareOptions {
            count_threshold_pct: Some(0.0),
            timings: TimingRule::Ignore,
            counts_across_driver_builds: false,
            ..CompareOptions::default()
        };
        let r = compare_with(side(&b, "base"), &b, side(&n, "new"), &n, &o).unwrap();
        assert!(r.passed && r.changes.is_empty(), "{}", r.to_text());
        assert_eq!(r.totals.counts_other_driver, 2);
        assert!(
            r.warnings.iter().any(|w| w.contains("differ by the driver alone, so they are not judged")),
            "{:?}",
            r.warnings
        );
        assert!(r.to_text().contains("counts of different driver builds, not judged: 2"), "{}", r.to_text());
        // The same build: judged exactly, and the worse VGPRs fail.
        let n = compiled(48.0, 20.0, "0x2", "radv Mesa 25.0.7");
        let r = compare_with(side(&b, "base"), &b, side(&n, "new"), &n, &o).unwrap();
        assert!(!r.passed, "{}", r.to_text());
    }
}
