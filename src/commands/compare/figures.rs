//! Pass 2 of a comparison: every figure of every matched cell judged by its class (a count
//! exactly, correctness by direction, a timing against its command's mean change under the
//! calibrated rule), with the totals, the count sums and what was not judged and why.

use std::collections::{BTreeMap, BTreeSet};

use super::judge::{judge, scaled, time_factor, FigureChange, Verdict};
use super::report::{CountTotal, IdentityTotal, Totals};
use super::{CompareOptions, Matched, TimingRule};
use crate::rows::{self, Cell, Class, Figure, Row};

/// What judging every figure of the matched cells gave.
#[derive(Default)]
pub(super) struct Judged {
    pub(super) changes: Vec<FigureChange>,
    pub(super) counts: BTreeMap<(String, String), CountTotal>,
    pub(super) regressions: usize,
    /// Figures that changed class, unit or direction: not compared.
    pub(super) mismatched: Vec<String>,
    /// (command, BASE's JIT CPU, NEW's) of counts not judged.
    pub(super) other_cpus: BTreeSet<(String, String, String)>,
    /// (command, BASE's GLSL compiler, NEW's) of counts not judged.
    pub(super) other_compilers: BTreeSet<(String, String, String)>,
    /// (command, BASE's driver build, NEW's) of counts compiled by different driver builds:
    /// judged (`compare`: the changes are the drivers') or not (the gate).
    pub(super) other_drivers: BTreeSet<(String, String, String)>,
    pub(super) judged_across_drivers: bool,
    /// Identities (hashes) per command and name: in how many cells, changed in how many.
    pub(super) identities: BTreeMap<(String, String), IdentityTotal>,
    /// Each timed cell's one verdict under the calibrated rule (for the kernels' groups).
    pub(super) cell_verdicts: BTreeMap<(String, Cell), Verdict>,
}

impl Judged {
    /// What was not judged, and why.
    pub(super) fn warnings(&self) -> Vec<String> {
        let mut warnings = vec![];
        if !self.mismatched.is_empty() {
            warnings.push(format!(
                "{} figure(s) changed class, unit or direction and were not compared, e.g. {}",
                self.mismatched.len(),
                self.mismatched[0]
            ));
        }
        let name = |c: &String| if c.is_empty() { "not recorded".to_owned() } else { c.clone() };
        for (command, b_cpu, n_cpu) in &self.other_cpus {
            warnings.push(format!(
                "{command}: the driver compiled BASE's kernels for another CPU than NEW's ({} {} / {}): their machine \
                 code differs by the CPU alone, so its counts are not judged",
                rows::JIT_CPU,
                name(b_cpu),
                name(n_cpu)
            ));
        }
        for (command, b, n) in &self.other_drivers {
            warnings.push(if self.judged_across_drivers {
                format!(
                    "{command}: BASE's kernels and NEW's were compiled by different driver builds (BASE: {}; NEW: {}): \
                     the count changes below are the drivers' (and the code's, if it changed too)",
                    name(b),
                    name(n)
                )
            } else {
                format!(
                    "{command}: BASE's kernels and NEW's were compiled by different driver builds (BASE: {}; NEW: {}): \
                     their counts differ by the driver alone, so they are not judged",
                    name(b),
                    name(n)
                )
            });
        }
        for (command, b, n) in &self.other_compilers {
            warnings.push(format!(
                "{command}: BASE's SPIR-V and NEW's come from different GLSL compilers (BASE: {}; NEW: {}): their \
                 counts differ by the compiler alone, so they are not judged",
                name(b),
                name(n)
            ));
        }
        warnings
    }
}

/// Pass 2: every figure of every matched cell judged by its class, counted into `totals`.
pub(super) fn judge_figures(
    matched: &[Matched],
    rule: TimingRule,
    o: &CompareOptions,
    log_speed: &BTreeMap<String, (usize, f64)>,
    totals: &mut Totals,
) -> Judged {
    // A command's speed NEW/BASE: the geometric mean over its cells.
    let geomean = |c: &str| log_speed.get(c).map(|(_, mean_log_factor)| (-mean_log_factor).exp());
    let mut j = Judged { judged_across_drivers: o.counts_across_driver_builds, ..Judged::default() };
    for &(k, br, nr) in matched {
        totals.cells_compared += 1;
        j.count_identities(k, br, nr);
        let names: BTreeSet<&String> = br.figures.keys().chain(nr.figures.keys()).collect();
        for name in names {
            let (Some(bf), Some(nf)) = (br.figures.get(name), nr.figures.get(name)) else {
                totals.figures_only_in_one_side += 1;
                continue;
            };
            if !j.comparable(k, name, (br, bf), (nr, nf), rule, o, totals) {
                continue;
            }
            totals.figures_compared += 1;
            // Under the calibrated rule a timing is judged against its command's mean change.
            let command_speed = geomean(&k.0).filter(|_| rule == TimingRule::Calibrated && bf.class == Class::Timing);
            j.judge_figure(k, name, bf, nf, command_speed, o, totals);
        }
    }
    j
}

impl Judged {
    /// Counts the identities (hashes) both rows of a cell have, and whether each changed.
    fn count_identities(&mut self, k: &(String, Cell), br: &Row, nr: &Row) {
        for (name, bv) in &br.identities {
            let Some(nv) = nr.identities.get(name) else { continue };
            let t = self.identities.entry((k.0.clone(), name.clone())).or_insert_with(|| IdentityTotal {
                command: k.0.clone(),
                identity: name.clone(),
                cells: 0,
                cells_changed: 0,
            });
            t.cells += 1;
            t.cells_changed += (bv != nv) as usize;
        }
    }

    /// Whether figure `name` of one cell is judged at all: not when it changed class, unit or
    /// direction, is a timing the rule ignores, or is a count of another CPU, GLSL compiler or
    /// (unless the options judge across them) driver build; each counted where it belongs.
    #[allow(clippy::too_many_arguments)]
    fn comparable(
        &mut self,
        k: &(String, Cell),
        name: &str,
        (br, bf): (&Row, &Figure),
        (nr, nf): (&Row, &Figure),
        rule: TimingRule,
        o: &CompareOptions,
        totals: &mut Totals,
    ) -> bool {
        if bf.class != nf.class || bf.unit != nf.unit || bf.better != nf.better {
            self.mismatched.push(format!("{} {name}", br.key()));
            return false;
        }
        if rule == TimingRule::Ignore && bf.class == Class::Timing {
            totals.timings_not_judged += 1;
            return false;
        }
        // A count is the same code's only where both rows name the same CPU the driver's JIT
        // compiled for and the same GLSL compiler (rows whose counts depend on neither, such
        // as bench's bytes and SAH cost, name neither: equal).
        let setting = |r: &Row, key: &str| r.source.settings.get(key).cloned().unwrap_or_default();
        if bf.class == Class::Count && setting(br, rows::JIT_CPU) != setting(nr, rows::JIT_CPU) {
            totals.counts_other_cpu += 1;
            self.other_cpus.insert((k.0.clone(), setting(br, rows::JIT_CPU), setting(nr, rows::JIT_CPU)));
            return false;
        }
        if bf.class == Class::Count && setting(br, rows::SPIRV_COMPILER) != setting(nr, rows::SPIRV_COMPILER) {
            totals.counts_other_compiler += 1;
            self.other_compilers.insert((
                k.0.clone(),
                setting(br, rows::SPIRV_COMPILER),
                setting(nr, rows::SPIRV_COMPILER),
            ));
            return false;
        }
        let (b_driver, n_driver) = (setting(br, rows::DRIVER_BUILD), setting(nr, rows::DRIVER_BUILD));
        if bf.class == Class::Count && b_driver != n_driver {
            self.other_drivers.insert((k.0.clone(), b_driver, n_driver));
            if !o.counts_across_driver_builds {
                totals.counts_other_driver += 1;
                return false;
            }
        }
        true
    }

    /// Judges one comparable figure of cell `k` (a timing under the calibrated rule against its
    /// command's speed), counts it and keeps the change where it is printed.
    #[allow(clippy::too_many_arguments)]
    fn judge_figure(
        &mut self,
        k: &(String, Cell),
        name: &str,
        bf: &Figure,
        nf: &Figure,
        command_speed: Option<f64>,
        o: &CompareOptions,
        totals: &mut Totals,
    ) {
        let t = if bf.class == Class::Count { o.count_pct() } else { o.threshold_pct };
        let judged = command_speed.map(|s| scaled(nf, 1.0 / s));
        let (verdict, relative, beyond, regression) = judge(bf, judged.as_ref().unwrap_or(nf), t);
        // Under the calibrated rule one timing alone is printed, not failed: on a busy host one
        // sub-millisecond cell moves by itself far more than a kernel's slowdown (the kernels'
        // groups below judge that, over all their cells).
        let regression = regression && judged.is_none();
        if judged.is_some() && bf.runs >= 2 && nf.runs >= 2 {
            // A cell is slower (faster) when every timing of it is; one that disagrees with
            // itself is within spread.
            let e = self.cell_verdicts.entry((k.0.clone(), k.1.clone())).or_insert(verdict);
            if *e != verdict {
                *e = Verdict::WithinSpread;
            }
        }
        let factor = time_factor(bf, nf);
        tally(totals, bf.class, verdict, beyond);
        if bf.class == Class::Count {
            self.add_count(k, name, bf, nf, verdict);
        }
        self.regressions += regression as usize;
        let change = FigureChange {
            command: k.0.clone(),
            cell: rows::cell_key("", &k.1).trim_start().to_owned(),
            figure: name.to_owned(),
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
            self.changes.push(change);
        }
    }

    /// Adds a count judged `verdict` to its command's sums.
    fn add_count(&mut self, k: &(String, Cell), name: &str, bf: &Figure, nf: &Figure, verdict: Verdict) {
        let t = self.counts.entry((k.0.clone(), name.to_owned())).or_insert_with(|| CountTotal {
            command: k.0.clone(),
            figure: name.to_owned(),
            unit: bf.unit.clone(),
            better: bf.better,
            base: 0.0,
            new: 0.0,
            cells: 0,
            cells_changed: 0,
            base_affected: 0.0,
            new_affected: 0.0,
            cells_better: 0,
            cells_worse: 0,
        });
        t.base += bf.median;
        t.new += nf.median;
        t.cells += 1;
        if verdict != Verdict::Unchanged {
            t.cells_changed += 1;
            t.base_affected += bf.median;
            t.new_affected += nf.median;
            t.cells_better += (verdict == Verdict::Better) as usize;
            t.cells_worse += (verdict == Verdict::Worse) as usize;
        }
    }
}

/// Counts one verdict of a figure of `class` into `totals`.
fn tally(totals: &mut Totals, class: Class, verdict: Verdict, beyond: bool) {
    match verdict {
        Verdict::Faster => totals.faster += 1,
        Verdict::Slower => totals.slower += 1,
        Verdict::WithinSpread => totals.within_spread += 1,
        Verdict::NoSpread => totals.no_spread += 1,
        Verdict::Better | Verdict::Worse if class == Class::Count => totals.counts_changed += 1,
        Verdict::Better | Verdict::Worse => totals.correctness_changed += 1,
        Verdict::Unchanged => {}
    }
    if class == Class::Correctness && verdict == Verdict::Worse {
        totals.correctness_worse += 1;
    }
    if class == Class::Timing && beyond {
        if verdict == Verdict::Faster {
            totals.faster_beyond_threshold += 1;
        } else {
            totals.slower_beyond_threshold += 1;
        }
    }
}
