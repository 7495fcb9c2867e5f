//! The report of an `ab` run: each side as it ran, each matched cell's and each kernel's
//! comparison with its verdict, the totals and the exit code, and the text printed.

use std::path::PathBuf;

use serde::Serialize;

use super::compiled::{self, StatChange};
use super::interval::{Ratio, Verdict};
use super::options::{Judge, Side};
use super::repro;
use super::worker::{self, CellInfo, CellKind};
use crate::report::{Report, Table};
use crate::rows::Row;
use crate::services::worker::protocol::ProvenanceFields;

/// One side as it ran.
#[derive(Clone, Debug, Serialize)]
pub struct SideReport {
    pub name: &'static str,
    pub given: Side,
    /// The executable it ran.
    pub exe: PathBuf,
    /// The ab protocol its worker spoke ([`worker::PROTOCOL`]).
    pub protocol: u32,
    /// The worker's provenance: device, driver and version, Mesa version, host, settings.
    pub provenance: serde_json::Value,
    /// Mesa's on-disk shader cache before the side started: `warm` (it held files), `cold`,
    /// or `disabled` (`MESA_SHADER_CACHE_DISABLE`).
    pub shader_cache: String,
    /// Loading, uploading, compiling and one untimed run of every cell, ms.
    pub setup_ms: f64,
    pub rounds: usize,
}

/// One side's figures for a cell.
#[derive(Clone, Debug, Serialize)]
pub struct SideCell {
    /// Validated rounds' kernel times, ms.
    pub ms: Vec<f64>,
    /// Rounds that did not validate (their time is left out).
    pub failed_rounds: usize,
    /// Worst over the rounds: fewest rays agreeing, most unexplained, most invalid.
    pub agree: usize,
    pub unexplained: usize,
    pub invalid: usize,
}

/// One kernel's comparison over its cells ([`Judge::Kernels`]).
#[derive(Clone, Debug, Serialize)]
pub struct AbKernel {
    /// `raycast mt bvh2` ([`CellInfo::kernel_label`]).
    pub kernel: String,
    pub kind: CellKind,
    pub method: String,
    pub layout: String,
    pub traversal: String,
    pub cells: usize,
    /// B/A over its cells, round by round; `None` with fewer than two rounds a side in which
    /// all its cells validated.
    pub ratio: Option<Ratio>,
    pub verdict: Option<Verdict>,
    /// One of its cells' correctness is worse on B.
    pub correctness_worse: bool,
}

/// One cell's comparison.
#[derive(Clone, Debug, Serialize)]
pub struct AbCell {
    pub cell: CellInfo,
    pub a: SideCell,
    pub b: SideCell,
    /// B/A kernel time; `None` when a side has fewer than two validated rounds.
    pub ratio: Option<Ratio>,
    pub verdict: Option<Verdict>,
    /// Rays whose hit records differ bit for bit between A's and B's first round.
    pub rays_differing: usize,
    /// B's agreement, unexplained or invalid count worse than A's.
    pub correctness_worse: bool,
    /// With `--driver-stats`: the kernel's driver statistics that differ (empty: none); `None`
    /// when a side has none for it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compiled: Option<Vec<StatChange>>,
    /// With `--pipeline-stats`: compute-shader invocations of one dispatch, A and B.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub invocations: Option<[Option<u64>; 2]>,
}

impl AbCell {
    pub(super) fn changed(&self) -> bool {
        self.verdict.is_some_and(Verdict::moved)
            || self.rays_differing > 0
            || self.correctness_worse
            || self.invocations_differ()
    }

    fn invocations_differ(&self) -> bool {
        self.invocations.is_some_and(|[a, b]| a.is_some() && b.is_some() && a != b)
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct AbReport {
    pub a: SideReport,
    pub b: SideReport,
    pub workload: Vec<String>,
    pub level: f64,
    pub threshold: f64,
    pub target: f64,
    /// What the verdict judged.
    pub judge: Judge,
    /// Whether each round timed every cell's two sides back to back (paired intervals), or
    /// whole rounds apart (a worker of protocol 1: unpaired).
    pub paired: bool,
    /// Why the rounds stopped: `target`, `max rounds` or `time cap`.
    pub stopped_by: String,
    pub seconds: f64,
    /// The cells both sides ran.
    pub cells: Vec<AbCell>,
    /// The kernels over those cells.
    pub kernels: Vec<AbKernel>,
    /// Cells only side A ran, and only side B (two builds: a kernel added or dropped).
    pub only_in: [Vec<String>; 2],
    /// Cells both sides name whose work differs (not compared), each with why.
    pub mismatched: Vec<String>,
    /// With `--driver-stats`: how each side's statistics were obtained, or why it has none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub driver_stats: Option<[String; 2]>,
    /// With `--pipeline-stats`: why a side counted no invocations, if it did not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pipeline_stats: Option<[Option<String>; 2]>,
    /// Each side's driver-stats rows (written to `a/` and `b/` beside the bench rows).
    #[serde(skip)]
    pub driver_stats_rows: [Vec<Row>; 2],
    /// With `--repro`: the changed cells made into repros of both sides.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub repros: Vec<repro::AbRepro>,
}

impl AbReport {
    /// 1 when a cell (or a kernel, by [`Judge`]) is hurt beyond the threshold with its whole
    /// interval, has no interval, or any correctness figure got worse; else 0.
    pub fn exit_code(&self) -> u8 {
        let judged = match self.judge {
            Judge::Cells => {
                self.cells.iter().any(|c| c.verdict == Some(Verdict::HurtBeyondThreshold) || c.ratio.is_none())
            }
            Judge::Kernels => {
                self.kernels.iter().any(|k| k.verdict == Some(Verdict::HurtBeyondThreshold) || k.ratio.is_none())
            }
        };
        u8::from(judged || self.cells.iter().any(|c| c.correctness_worse))
    }

    /// The kernels hurt beyond the threshold with their whole interval.
    pub fn kernels_hurt(&self) -> Vec<&AbKernel> {
        self.kernels.iter().filter(|k| k.verdict == Some(Verdict::HurtBeyondThreshold)).collect()
    }

    /// Cells helped, hurt (either kind), no change, and without an interval or with too few
    /// rounds to judge.
    pub fn totals(&self) -> (usize, usize, usize, usize) {
        let count = |f: &dyn Fn(Option<Verdict>) -> bool| self.cells.iter().filter(|c| f(c.verdict)).count();
        (
            count(&|v| v == Some(Verdict::Helped)),
            count(&|v| matches!(v, Some(Verdict::Hurt | Verdict::HurtBeyondThreshold))),
            count(&|v| v == Some(Verdict::Same)),
            count(&|v| v.is_none_or(|v| v == Verdict::TooFewRounds)),
        )
    }

    /// The geometric mean of the cells' ratios B/A.
    pub fn geomean(&self) -> Option<f64> {
        let r: Vec<f64> = self.cells.iter().filter_map(|c| c.ratio.map(|r| r.ratio.ln())).collect();
        (!r.is_empty()).then(|| (r.iter().sum::<f64>() / r.len() as f64).exp())
    }
}

impl AbReport {
    /// Kernels over their cells: those that changed, then the count; every kernel when they are
    /// what the verdict judges.
    fn kernels_text(&self) -> String {
        let changed: Vec<&AbKernel> = self.kernels.iter().filter(|k| k.verdict.is_none_or(Verdict::moved)).collect();
        let mut s = format!(
            "\nkernels (each over its cells, round by round{}): {} compared, {} changed\n",
            if self.judge == Judge::Kernels { "; what the verdict judges" } else { "" },
            self.kernels.len(),
            changed.len()
        );
        if !changed.is_empty() {
            let mut t = Table::new(["kernel", "cells", "B/A", "interval", "verdict"]);
            for k in changed {
                let (ratio, interval) = match k.ratio {
                    Some(r) => (format!("{:.3}", r.ratio), format!("[{:.3}, {:.3}]", r.low, r.high)),
                    None => ("-".into(), "-".into()),
                };
                t.row([
                    k.kernel.clone(),
                    k.cells.to_string(),
                    ratio,
                    interval,
                    k.verdict.map(|v| v.to_string()).unwrap_or_else(|| "no interval (rounds did not validate)".into()),
                ]);
            }
            s += &format!("\n{}", t.to_text());
        }
        s
    }

    /// Kernels whose driver statistics changed (each once, however many cells ran it), then
    /// totals per figure: kernels helped and hurt, by each figure's direction (fewer
    /// instructions, more subgroups per SIMD).
    fn compiled_text(&self) -> String {
        let Some(notes) = &self.driver_stats else { return String::new() };
        let mut s = String::from("\ncompiled code (driver statistics; kernels that changed):\n");
        for (name, note) in ["A", "B"].iter().zip(notes) {
            if self.driver_stats_rows[usize::from(*name == "B")].is_empty() {
                s += &format!("  side {name} has none: {note}\n");
            }
        }
        let mut seen = std::collections::BTreeMap::new();
        for c in &self.cells {
            if let Some(changes) = &c.compiled {
                seen.entry(c.cell.kernel.clone()).or_insert(changes);
            }
        }
        let changed: Vec<_> = seen.iter().filter(|(_, ch)| !ch.is_empty()).collect();
        for (kernel, changes) in &changed {
            s += &format!("  {kernel}: {}\n", compiled::describe(changes));
        }
        let mut per_figure: std::collections::BTreeMap<&str, (usize, usize)> = Default::default();
        for ch in changed.iter().flat_map(|(_, ch)| ch.iter()) {
            let e = per_figure.entry(&ch.figure).or_default();
            if ch.helped() {
                e.0 += 1;
            } else if ch.hurt() {
                e.1 += 1;
            }
        }
        s += &format!("  {} kernels compared, {} changed", seen.len(), changed.len());
        for (figure, (helped, hurt)) in per_figure {
            s += &format!("; {figure}: {helped} helped, {hurt} hurt");
        }
        s + "\n"
    }

    /// Cells whose compute-shader invocations differ, and why a side counted none.
    fn invocations_text(&self) -> String {
        let Some(notes) = &self.pipeline_stats else { return String::new() };
        let mut s = String::from("\npipeline statistics (compute-shader invocations of one dispatch):\n");
        for (name, note) in ["A", "B"].iter().zip(notes) {
            if let Some(n) = note {
                s += &format!("  side {name} has none: {n}\n");
            }
        }
        let differ: Vec<&AbCell> = self.cells.iter().filter(|c| c.invocations_differ()).collect();
        for c in &differ {
            if let Some([Some(a), Some(b)]) = c.invocations {
                s += &format!("  {}: {a} -> {b}\n", c.cell.label());
            }
        }
        let counted = self.cells.iter().filter(|c| c.invocations.is_some_and(|[a, b]| a.is_some() && b.is_some()));
        s + &format!("  {} cells counted on both sides, {} differ\n", counted.count(), differ.len())
    }

    /// Each side as it ran, how the rounds went, and the cells not compared.
    fn header_text(&self) -> String {
        let mut s = String::new();
        for side in [&self.a, &self.b] {
            s += &format!(
                "{}: {} ({}; shader cache {}, setup {:.1} s, {} rounds{})\n",
                side.name,
                side_label(side),
                side.given.describe(),
                side.shader_cache,
                side.setup_ms / 1e3,
                side.rounds,
                if side.protocol < worker::PROTOCOL {
                    format!("; an older build: ab protocol {}", side.protocol)
                } else {
                    String::new()
                }
            );
        }
        s += &format!(
            "{} cells, {}, stopped by {} after {:.0} s; B/A kernel time, {:.0} % interval ({})\n",
            self.cells.len(),
            if self.paired {
                "each cell's sides back to back in every round, which first alternating"
            } else {
                "rounds interleaved A B B A (a side's worker times whole rounds only)"
            },
            self.stopped_by,
            self.seconds,
            self.level * 100.0,
            if self.paired { "Student's t on each round's log ratio" } else { "Welch's t on log times" }
        );
        for (name, list) in ["A", "B"].iter().zip(&self.only_in) {
            if !list.is_empty() {
                s += &format!("only side {name} ran {} cell(s), not compared: {}\n", list.len(), list.join(", "));
            }
        }
        for m in &self.mismatched {
            s += &format!("not compared: {m}\n");
        }
        s
    }

    /// The cells that changed, as a table, or that none did.
    fn cells_text(&self) -> String {
        let mut s = String::new();
        let changed: Vec<&AbCell> = self.cells.iter().filter(|c| c.changed()).collect();
        if changed.is_empty() {
            s += "no cell changed\n";
        } else {
            let mut t = Table::new([
                "cell",
                "A ms",
                "B ms",
                "B/A",
                "interval",
                "verdict",
                "rays differing",
                "agree A/B",
                "unexplained A/B",
            ]);
            for c in changed {
                let median =
                    |x: &[f64]| crate::report::Summary::of(x).map(|m| format!("{:.3}", m.median)).unwrap_or("-".into());
                let (ratio, interval) = match c.ratio {
                    Some(r) => (format!("{:.3}", r.ratio), format!("[{:.3}, {:.3}]", r.low, r.high)),
                    None => ("-".into(), "-".into()),
                };
                t.rows.push(vec![
                    c.cell.label(),
                    median(&c.a.ms),
                    median(&c.b.ms),
                    ratio,
                    interval,
                    c.verdict.map(|v| v.to_string()).unwrap_or_else(|| "no interval (rounds did not validate)".into()),
                    c.rays_differing.to_string(),
                    format!("{}/{}", c.a.agree, c.b.agree),
                    format!("{}/{}", c.a.unexplained, c.b.unexplained),
                ]);
            }
            s += &t.to_text();
        }
        s
    }

    /// The repros made (`--repro`): each one's folder, its two sides, and B's hits against A's.
    fn repros_text(&self) -> String {
        let mut s = String::new();
        for r in &self.repros {
            s += &format!("\nrepro of `{}`: {}\n  A: {}\n  B: {}\n", r.cell, r.dir.display(), r.sides[0], r.sides[1]);
            if let Some(d) = &r.hits {
                s += &format!("  B's hits against A's: {}\n", d.verdict());
            }
        }
        s
    }

    /// Cells helped, hurt and unchanged, their geometric mean B/A, and the verdict.
    fn totals_text(&self) -> String {
        let mut s = String::new();
        let (helped, hurt, same, none) = self.totals();
        s += &format!(
            "\ntotals: {helped} helped, {hurt} hurt, {same} no change{}; geometric mean B/A {}\n",
            if none > 0 { format!(", {none} without an interval") } else { String::new() },
            self.geomean().map(|g| format!("{g:.3}")).unwrap_or("-".into())
        );
        let worse = self.cells.iter().filter(|c| c.correctness_worse).count();
        s += &format!(
            "verdict: {} (threshold {} %: fails on a {} hurt with its whole interval past it, or any correctness worse: {worse} cell(s))\n",
            if self.exit_code() == 0 { "pass" } else { "FAIL" },
            self.threshold * 100.0,
            self.judge.unit()
        );
        s
    }
}

/// `driver on device`, from a side's provenance.
pub(super) fn side_label(s: &SideReport) -> String {
    let p = ProvenanceFields::of(&s.provenance);
    format!("{} on {}", p.driver.as_deref().unwrap_or("?"), p.device.as_deref().unwrap_or("?"))
}

impl Report for AbReport {
    fn to_text(&self) -> String {
        let mut s = self.header_text();
        s += "\n";
        s += &self.cells_text();
        s += &self.kernels_text();
        s += &self.compiled_text();
        s += &self.invocations_text();
        s += &self.repros_text();
        s + &self.totals_text()
    }
}
