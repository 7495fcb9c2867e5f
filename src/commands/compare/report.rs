//! The comparison's report: the changes, the totals, the tables and the text.

use serde::Serialize;

use super::judge::{FigureChange, Verdict};
use super::timing::{CommandSpeed, HostCalibration, KernelChange, KERNEL_COORDINATES};
use super::{Side, TimingRule, LIST_MAX};
use crate::report::{Report, Table};
use crate::rows::{Class, Figure};

/// A count figure summed over every matched cell of a command, and over the cells where it
/// changed (fossil-db's "totals from affected shaders").
#[derive(Clone, Debug, Serialize)]
pub struct CountTotal {
    pub command: String,
    pub figure: String,
    pub unit: String,
    /// Which way is better (more subgroups per SIMD, fewer instructions).
    pub better: crate::rows::Better,
    pub base: f64,
    pub new: f64,
    pub cells: usize,
    pub cells_changed: usize,
    /// The sums over the cells where the figure changed.
    pub base_affected: f64,
    pub new_affected: f64,
    pub cells_better: usize,
    pub cells_worse: usize,
}

/// An identity (a compiled kernel's hash) over the matched cells of a command: compared as
/// changed or unchanged, never as better or worse.
#[derive(Clone, Debug, Serialize)]
pub struct IdentityTotal {
    pub command: String,
    pub identity: String,
    pub cells: usize,
    pub cells_changed: usize,
}

/// The count totals, per command, as fossil-db reports them: each figure over every cell in both
/// sides, then over the cells where it changed, with how many got better and worse (by the
/// figure's own direction).
fn count_totals(counts: &[CountTotal]) -> String {
    let mut s = String::new();
    let mut commands: Vec<&str> = counts.iter().map(|c| c.command.as_str()).collect();
    commands.dedup();
    for command in commands {
        let of: Vec<&CountTotal> = counts.iter().filter(|c| c.command == command).collect();
        let cells = of.iter().map(|c| c.cells).max().unwrap_or(0);
        let affected = of.iter().map(|c| c.cells_changed).max().unwrap_or(0);
        s += &format!("{command} totals ({cells} cells in both; {affected} with a change in one figure at least):\n");
        for c in of.iter().filter(|c| c.cells_changed > 0) {
            let way = match c.better {
                crate::rows::Better::Lower => "lower is better",
                crate::rows::Better::Higher => "higher is better",
            };
            s += &format!(
                "  {}: {} -> {} {} ({}; {way}); {} of {} cells changed, {} better, {} worse: {} -> {} ({})\n",
                c.figure,
                value(c.base),
                value(c.new),
                c.unit,
                pct(c.base, c.new),
                c.cells_changed,
                c.cells,
                c.cells_better,
                c.cells_worse,
                value(c.base_affected),
                value(c.new_affected),
                pct(c.base_affected, c.new_affected)
            );
        }
        let unchanged: Vec<&str> = of.iter().filter(|c| c.cells_changed == 0).map(|c| c.figure.as_str()).collect();
        if !unchanged.is_empty() {
            s += &format!("  unchanged in every cell: {}\n", unchanged.join(", "));
        }
    }
    s
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
    /// Counts not judged because different driver builds compiled them ([`rows::DRIVER_BUILD`];
    /// the gate's rule: `compare` judges them and says so).
    pub counts_other_driver: usize,
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
    /// Identities (hashes) per command: in how many cells they changed.
    pub identities: Vec<IdentityTotal>,
    pub warnings: Vec<String>,
    pub regressions: usize,
    /// No regression: exit status 0.
    pub passed: bool,
    /// With `--repro`: the changed bench cells made into repros here.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub repros: Vec<super::repro::CompareRepro>,
}

/// A figure's value: whole numbers as they are, others to four significant digits.
pub(super) fn value(x: f64) -> String {
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
pub(super) fn shown(f: &Figure) -> String {
    match f.class {
        Class::Timing => format!("{} [{}..{}] {}", value(f.median), value(f.min), value(f.max), f.unit),
        _ => format!("{} {}", value(f.median), f.unit),
    }
}

/// A signed percentage of `new` over `base`.
pub(super) fn pct(base: f64, new: f64) -> String {
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
        let mut s = self.sides_text();
        s += &self.rule_text();
        s += &self.changes_text();
        s += &self.timings_text();
        s += &self.counts_and_correctness_text();
        s += &self.verdict_text();
        s
    }
}

/// [`CompareReport::to_text`]'s parts, in their order.
impl CompareReport {
    /// Each side: its path, rows, files, commands, sources and host; then the warnings.
    fn sides_text(&self) -> String {
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
        s
    }

    /// The rule the timings were judged by.
    fn rule_text(&self) -> String {
        match self.timing_rule {
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
        }
    }

    /// The changed figures, then the cells compared and those only in one side.
    fn changes_text(&self) -> String {
        let mut s = String::new();
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
        s
    }

    /// The timings' totals by the rule: not judged (each command's speed, for information),
    /// calibrated (the commands' and kernels' tables) or raw (each command's speed).
    fn timings_text(&self) -> String {
        let mut s = String::new();
        let t = &self.totals;
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
            return s;
        }
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
            s += &self.calibrated_text();
        } else {
            for c in &self.speed {
                s += &format!(
                    "speed NEW/BASE, geometric mean of {} timings of {} (> 1: NEW faster): {:.3}\n",
                    c.timings, c.command, c.geomean_speed
                );
            }
        }
        s
    }

    /// Under the calibrated rule: the commands' speed table and the kernels against their command.
    fn calibrated_text(&self) -> String {
        let mut s = format!("commands' timings as a whole (> 1: NEW faster):\n\n{}\n", self.speed_table().to_text());
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
        s
    }

    /// The counts' totals, the identities changed, the correctness totals and what was not
    /// judged.
    fn counts_and_correctness_text(&self) -> String {
        let t = &self.totals;
        let mut s = count_totals(&self.counts);
        for i in &self.identities {
            s += &format!(
                "{} {}: changed in {} of {} cells (an identity: not better or worse)\n",
                i.command, i.identity, i.cells_changed, i.cells
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
        if t.counts_other_driver > 0 {
            s += &format!("counts of different driver builds, not judged: {}\n", t.counts_other_driver);
        }
        s
    }

    /// The verdict, then each repro made.
    fn verdict_text(&self) -> String {
        let mut s = if self.passed {
            format!("verdict: pass (no regression beyond {}, no correctness worse)\n", self.thresholds())
        } else {
            format!(
                "verdict: FAIL: {} regression(s): {} (thresholds {})\n",
                self.regressions,
                self.failed(),
                self.thresholds()
            )
        };
        for r in &self.repros {
            s += &format!(
                "\nrepro of `{}`: {}\n  {}\n  this device: {}\n",
                r.cell,
                r.dir.display(),
                r.made,
                r.this_device
            );
        }
        s
    }
}
