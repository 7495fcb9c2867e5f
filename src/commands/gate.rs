//! The regression gate (`trilab gate`, the last step of CI through `scripts/ci-gate.sh`): what a
//! change did to the kernels, judged only on evidence about the code.
//!
//! - **Counts and correctness** against the committed baseline (`results/lavapipe/baseline/`):
//!   SPIR-V instructions, scene bytes, SAH cost, EPO, lavapipe's machine code where the
//!   baseline's host compiled for the same CPU (exact: `--count-threshold 0`), and agreement
//!   with the f64 reference, leaks and NaN hits (any worsening fails). These are what they are
//!   on any host, so a run can be judged against a committed one: [`compare`] with its timings
//!   left unjudged ([`TimingRule::Ignore`]).
//! - **Timings** only against timings measured in the same run, on the same host, interleaved:
//!   an A/B ([`ab`]) of the build the baseline was measured at (side A, built from the
//!   baseline's commit) against the build under test (side B), each kernel judged over its
//!   cells ([`Judge::Kernels`]). A slower driver or a slower, busier host slows both sides alike
//!   and passes; a kernel that B alone made slower, with its whole 95 % interval past the
//!   threshold, fails. A timing from another run, let alone another host, is no evidence about
//!   the code (issue 36: a calibration by a scalar CPU workload did not carry lavapipe's SIMD
//!   kernels from one CPU model to another), so where there is no base build (a shallow clone,
//!   the baseline's commit missing) the gate says so and judges counts and correctness alone.
//!
//! A kernel's timing failure must repeat: the gate times the kernels that failed once more,
//! A against B again, and fails only those hurt beyond the threshold both times (a burst of
//! load on a 2-core host can move one round of one side; it does not move two runs of the same
//! kernel alike). Counts and correctness are exact and are never measured twice.

use std::path::PathBuf;

use serde::Serialize;

use crate::commands::ab::worker::{CellKind, Workload};
use crate::commands::ab::{self, AbKernel, AbOptions, AbReport, Judge};
use crate::commands::compare::{self, CompareOptions, CompareReport, TimingRule};
use crate::encoding::{Layout, Method, Traversal};
use crate::error::{Error, Result};
use crate::named::Named;
use crate::report::Report;
use crate::services::rayset::RaySet;

/// The build the baseline was measured at, or why there is none.
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BaseBuild {
    /// Its executable and the commit it was built from.
    Built { exe: PathBuf, commit: String },
    /// No base build, and why (a shallow clone, the commit missing, a baseline measured on a
    /// tree with uncommitted changes).
    Missing { why: String },
}

/// What `trilab gate` is asked.
#[derive(Clone, Debug)]
pub struct GateOptions {
    /// The committed baseline: a result folder of `trilab suite` and `trilab spirv`.
    pub baseline: PathBuf,
    /// The same measured on the build under test.
    pub new: PathBuf,
    pub base: BaseBuild,
    /// The A/B of the timings: its workload, rounds, threshold and sides' environments; the
    /// gate sets side A's executable and the judge.
    pub ab: AbOptions,
    /// Time the kernels that failed once more and fail only on those that fail again.
    pub repeat_failures: bool,
}

/// A kernel fails when the build under test is slower than the base build by more than this,
/// with its whole 95 % interval past it, twice. Measured (`results/lavapipe/gate-sensitivity/`,
/// 2-core AMD EPYC, the default workload): no unplanted kernel crossed 5 % in 536 kernel-runs of
/// one A/B each (idle, beside a busy loop, on one CPU, with a slower driver on both sides), and at
/// 5 % one A/B caught 5 of 8 planted kernels slowed about 1.09x and 8 of 8 slowed about 1.15x on
/// an idle host (at 10 %: 0 of 8 and 6 of 8).
pub const DEFAULT_THRESHOLD_PCT: f64 = 5.0;

/// The gate's workload unless told: every intersector on every node layout, while-if, on the
/// bunny's three ray sets at ab's sizes (160x120 primary rays, 2 diffuse rays a hit, 20,000
/// random rays), so every ray-casting kernel the study times is timed.
pub fn default_workload(sizes: crate::services::rayset::RaySetSizes, build: crate::bvh::BuildOptions) -> Workload {
    Workload {
        scenes: vec![PathBuf::from("bunny")],
        methods: Method::ALL.to_vec(),
        layouts: Layout::ALL.to_vec(),
        traversals: vec![Traversal::DEFAULT],
        sets: RaySet::ALL.to_vec(),
        sizes,
        build,
        scene_access: crate::encoding::SceneAccess::DEFAULT,
        batch_rays: crate::defaults::BATCH_RAYS,
        pathtrace: false,
        pipeline_stats: false,
        runs_layout: None,
    }
}

/// How the timings were judged.
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "kebab-case", tag = "judged")]
pub enum Timings {
    /// Not judged, and why (no base build).
    NotJudged { why: String },
    /// The A/B of the base build against this one; with the repeat of the kernels it found
    /// hurt, when there were any.
    Judged {
        base_commit: String,
        ab: Box<AbReport>,
        repeat: Option<Box<AbReport>>,
        /// The kernels that fail: hurt beyond the threshold in the A/B and (with the repeat)
        /// again in the repeat.
        failed: Vec<String>,
        /// Hurt in the first A/B but not in the repeat: the host, not the code.
        did_not_repeat: Vec<String>,
        /// The workload's layouts the base build has no kernel of (added since): not timed,
        /// their counts are new cells of the comparison.
        layouts_not_timed: Vec<String>,
    },
}

#[derive(Clone, Debug, Serialize)]
pub struct GateReport {
    /// Counts and correctness against the committed baseline.
    pub counts: CompareReport,
    pub timings: Timings,
    /// Every reason the gate fails; empty: it passes.
    pub failures: Vec<String>,
}

impl GateReport {
    pub fn passed(&self) -> bool {
        self.failures.is_empty()
    }

    /// 0 pass, 1 fail.
    pub fn exit_code(&self) -> u8 {
        u8::from(!self.passed())
    }
}

/// The workload that times only `kernels` again: their methods, layouts and traversals (a
/// cross product, so perhaps a few more), their scenes and ray sets as before.
fn workload_of(w: &Workload, kernels: &[&AbKernel]) -> Workload {
    let mut w = w.clone();
    let pick = |name: &str| kernels.iter().any(|k| k.method == name);
    w.methods.retain(|m| pick(m.name()));
    w.layouts.retain(|l| kernels.iter().any(|k| k.layout == l.name()));
    w.traversals.retain(|t| kernels.iter().any(|k| k.traversal == t.name()));
    w.pathtrace = w.pathtrace && kernels.iter().any(|k| k.kind == CellKind::Pathtrace);
    if w.traversals.is_empty() {
        w.traversals = vec![Traversal::DEFAULT];
    }
    w
}

/// The layouts the baseline's build has kernels of: those of the registry's kernels its `spirv`
/// rows name (empty where it has no SPIR-V rows).
fn base_layouts(rows: &[crate::rows::Row]) -> Vec<Layout> {
    let names: std::collections::BTreeSet<&str> =
        rows.iter().filter(|r| r.command == "spirv").filter_map(|r| r.cell.get("kernel")).map(String::as_str).collect();
    let has = |l: Layout| crate::kernels::KERNELS.iter().any(|k| k.layout == l.name() && names.contains(k.name));
    Layout::ALL.iter().copied().filter(|&l| has(l)).collect()
}

/// Runs the gate: counts and correctness against the baseline, then the timings' A/B.
pub fn run(o: &GateOptions, mut progress: impl FnMut(&str)) -> Result<GateReport> {
    // Counts exactly, and only against rows of the same driver build: the baseline's RADV rows
    // (Mesa 25.0.7) say nothing about the code where CI has another Mesa, and the gate says so.
    let compare_options = CompareOptions {
        count_threshold_pct: Some(0.0),
        timings: TimingRule::Ignore,
        counts_across_driver_builds: false,
        ..CompareOptions::default()
    };
    progress("counts and correctness against the baseline");
    let counts = compare::run(&o.baseline, &o.new, &compare_options)?;
    let mut failures = vec![];
    if !counts.passed {
        failures.push(format!("counts and correctness against the baseline: {}", counts.failed()));
    }
    let timings = match &o.base {
        BaseBuild::Missing { why } => Timings::NotJudged { why: why.clone() },
        BaseBuild::Built { exe, commit } => {
            if !exe.is_file() {
                return Err(Error::Usage(format!("--base-bin {}: no such file (the base build)", exe.display())));
            }
            let mut a = o.ab.a.clone();
            a.exe = Some(exe.clone());
            // The base build names its own commit in its provenance, not the checkout's.
            a.env.insert(0, ("TRILAB_COMMIT".to_owned(), commit.clone()));
            // A layout added since the base build is not timed: that build cannot run it (its
            // counts are new cells of the comparison above).
            let mut workload = o.ab.workload.clone();
            let known = base_layouts(&crate::rows::read(&o.baseline)?.rows);
            let mut layouts_not_timed = vec![];
            if !known.is_empty() {
                let (kept, new): (Vec<Layout>, Vec<Layout>) = workload.layouts.iter().partition(|l| known.contains(l));
                layouts_not_timed = new.iter().map(Layout::to_string).collect();
                if !new.is_empty() {
                    progress(&format!(
                        "timings: {} not timed: the base build ({commit}) has no kernel of it",
                        layouts_not_timed.join(", ")
                    ));
                }
                workload.layouts = kept;
            }
            let options = AbOptions { a, judge: Judge::Kernels, workload, ..o.ab.clone() };
            progress(&format!("timings: the base build ({commit}) against this one, interleaved"));
            let first = ab::run(&options, &mut progress)?;
            let hurt: Vec<&AbKernel> = first.kernels_hurt();
            let (repeat, failed, did_not_repeat) = if hurt.is_empty() || !o.repeat_failures {
                (None, hurt.iter().map(|k| k.kernel.clone()).collect(), vec![])
            } else {
                progress(&format!("timings: {} kernel(s) hurt beyond the threshold; timing them again", hurt.len()));
                let again = AbOptions { workload: workload_of(&options.workload, &hurt), ..options.clone() };
                let second = ab::run(&again, &mut progress)?;
                let still: Vec<String> = second.kernels_hurt().iter().map(|k| k.kernel.clone()).collect();
                let (failed, gone): (Vec<String>, Vec<String>) =
                    hurt.iter().map(|k| k.kernel.clone()).partition(|k| still.contains(k));
                (Some(Box::new(second)), failed, gone)
            };
            let correctness: Vec<String> = std::iter::once(&first)
                .chain(repeat.as_deref())
                .flat_map(|r| r.cells.iter().filter(|c| c.correctness_worse).map(|c| c.cell.label()))
                .collect();
            let no_interval: Vec<String> =
                first.kernels.iter().filter(|k| k.ratio.is_none()).map(|k| k.kernel.clone()).collect();
            if !failed.is_empty() {
                failures.push(format!(
                    "timings: {} kernel(s) slower in this build beyond {} % with the whole 95 % interval past it{}: {}",
                    failed.len(),
                    options.threshold * 100.0,
                    if o.repeat_failures { ", twice" } else { "" },
                    failed.join(", ")
                ));
            }
            if !correctness.is_empty() {
                failures.push(format!(
                    "A/B: this build agrees with the f64 reference on fewer rays than the base build in {}",
                    correctness.join(", ")
                ));
            }
            if !no_interval.is_empty() {
                failures.push(format!(
                    "timings: no interval (rounds that did not validate) for {}",
                    no_interval.join(", ")
                ));
            }
            Timings::Judged {
                base_commit: commit.clone(),
                ab: Box::new(first),
                repeat,
                failed,
                did_not_repeat,
                layouts_not_timed,
            }
        }
    };
    Ok(GateReport { counts, timings, failures })
}

impl Report for GateReport {
    fn to_text(&self) -> String {
        let mut s = String::from(
            "== counts and correctness against the committed baseline (exact; timings of another run are not judged) ==\n\n",
        );
        s += &self.counts.to_text();
        s += "\n== timings: the baseline's build against this build, in this run, interleaved ==\n\n";
        match &self.timings {
            Timings::NotJudged { why } => {
                s += &format!("not judged: {why}. The gate judged counts and correctness alone.\n");
            }
            Timings::Judged { ab, repeat, failed, did_not_repeat, layouts_not_timed, base_commit } => {
                if !layouts_not_timed.is_empty() {
                    s += &format!(
                        "not timed: {} (the base build, {base_commit}, has no kernel of it: its baseline's SPIR-V rows name none; its counts are new cells above)\n\n",
                        layouts_not_timed.join(", ")
                    );
                }
                s += &ab.to_text();
                if let Some(r) = repeat {
                    s += "\n-- the kernels hurt beyond the threshold, timed again --\n\n";
                    s += &r.to_text();
                }
                if !did_not_repeat.is_empty() {
                    s += &format!(
                        "\nhurt once, not again (the host, not the code; not failed): {}\n",
                        did_not_repeat.join(", ")
                    );
                }
                if !failed.is_empty() {
                    s += &format!("\nslower in this build, twice: {}\n", failed.join(", "));
                }
            }
        }
        s += "\n";
        if self.failures.is_empty() {
            s += &format!(
                "gate: pass ({})\n",
                match &self.timings {
                    Timings::NotJudged { .. } => "counts and correctness; timings not judged".to_owned(),
                    Timings::Judged { layouts_not_timed, .. } if layouts_not_timed.is_empty() =>
                        "counts, correctness, and every kernel's timing against the base build".to_owned(),
                    Timings::Judged { layouts_not_timed, .. } => format!(
                        "counts, correctness, and the timing against the base build of every kernel but {}'s",
                        layouts_not_timed.join(", ")
                    ),
                }
            );
        } else {
            s += &format!("gate: FAIL: {}\n", self.failures.join("; "));
        }
        s
    }
}

impl crate::services::results::Results for GateReport {
    const STEM: &'static str = "gate";

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        format!("```\n{}```\n", self.to_text())
    }

    /// The A/B's rows (its ratios), so `merge` can keep a gate's timings.
    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        match &self.timings {
            Timings::Judged { ab, .. } => Some(ab::rows(ab)),
            Timings::NotJudged { .. } => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rows::{cell, Figure, Row, Source};

    fn spirv_row(kernel: &str) -> Row {
        Row::new("spirv", cell([("kernel", kernel)]), &Source::default())
            .with("spirv_instructions", Figure::count(1.0, "instructions"))
    }

    /// A baseline whose build had kernels of bvh2 and cwbvh only: those are its layouts, in the
    /// registry's order; rows of other commands and unknown kernels name none.
    #[test]
    fn the_base_builds_layouts_are_those_its_spirv_rows_name() {
        let rows = vec![
            spirv_row("raycast.mt.closest"),
            spirv_row("raycast.mt.closest_cwbvh"),
            spirv_row("raycast.nope.closest_bvh8"),
            Row::new("bench", cell([("layout", "bvh4")]), &Source::default()),
        ];
        assert_eq!(base_layouts(&rows), [Layout::Bvh2, Layout::Cwbvh]);
        assert!(base_layouts(&[]).is_empty());
        // Every kernel of the registry named: every layout.
        let all: Vec<Row> = crate::kernels::KERNELS.iter().map(|k| spirv_row(k.name)).collect();
        assert_eq!(base_layouts(&all), Layout::ALL);
    }
}
