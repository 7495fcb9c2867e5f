//! `trilab ab`: one workload under two driver environments, A and B, in one run, and what
//! changed between them with confidence (after gpu-trace-perf's A/B runs and the helped/hurt
//! reports of Mesa's shader-db).
//!
//! Each side is its own child process ([`worker`]): a driver is loaded once per process, and a
//! side is named by the ICD file the Vulkan loader is given (`VK_DRIVER_FILES`) and the
//! environment it runs in, and may run another trilab executable (two builds of the kernels).
//! In each round the parent times every cell on both sides back to back, one side running at a
//! time, which side first alternating from cell to cell and round to round, so the moment's load
//! on the host lands on both alike and each cell's ratio is paired round by round (a worker of
//! protocol 1 times whole rounds only: then rounds go A B B A and the intervals are unpaired);
//! every run of every cell is validated against the f64 reference before its time counts.
//! Rounds go on past the minimum until every judged interval ([`interval`]; each cell's, or each
//! kernel's over its cells) is narrower than the target, or the maximum rounds, or the time cap.
//! Then per cell and per kernel: the ratio B/A of kernel time with its 95 % interval and a
//! verdict, the hits of A and B compared ray by ray, and each side's agreement with the
//! reference. Cells are matched by what they are (scene, set, method, layout, traversal), so a
//! build that added or dropped a kernel is still compared on the cells both run.

pub mod compiled;
pub mod interval;
pub mod repro;
pub mod worker;

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use serde::Serialize;

use crate::encoding::Layout;
use crate::error::{Error, Result};
use crate::named::named_enum;
use crate::report::{Report, Table};
use crate::rows::{cell, Better, Class, Figure, Row, Source};
use crate::services::results::Folder;
use crate::services::worker::protocol::{ProvenanceFields, SESSION_COMMAND};
use crate::services::worker::{quote, Launch, Session};
use compiled::StatChange;
use interval::{Ratio, Verdict};
use worker::{CellInfo, CellKind, CellRound, Message, Request, Workload};

/// One side: the trilab build it runs, the driver the loader is given and the environment it
/// runs in.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Side {
    /// The trilab executable this side runs (`None`: the one running `ab`): two builds of the
    /// kernels timed side by side, as the regression gate times the baseline's build against the
    /// build under test.
    pub exe: Option<PathBuf>,
    /// The ICD JSON given to the loader as `VK_DRIVER_FILES` (`None`: the loader's own choice).
    pub icd: Option<PathBuf>,
    /// Variables set for this side only, in order.
    pub env: Vec<(String, String)>,
    /// The node layout this side runs in place of the workload's one layout (`--b-layout`).
    pub layout: Option<Layout>,
}

impl Side {
    /// `bin=... VK_DRIVER_FILES=... K=V`, or "trilab's own environment".
    pub fn describe(&self) -> String {
        let mut parts: Vec<String> = self.exe.iter().map(|p| format!("bin={}", p.display())).collect();
        parts.extend(self.icd.iter().map(|p| format!("VK_DRIVER_FILES={}", p.display())));
        parts.extend(self.env.iter().map(|(k, v)| format!("{k}={v}")));
        parts.extend(self.layout.iter().map(|l| format!("layout={l}")));
        if parts.is_empty() {
            "trilab's own environment".into()
        } else {
            parts.join(" ")
        }
    }

    /// The executable this side runs: its own, or `default` (the running trilab).
    pub fn exe<'a>(&'a self, default: &'a Path) -> &'a Path {
        self.exe.as_deref().unwrap_or(default)
    }

    /// This side's executable (its own, or `default`: the running trilab) in its driver and
    /// environment.
    pub fn launch(&self, default: &Path) -> Launch {
        let mut l = Launch::new(self.exe(default));
        if let Some(icd) = &self.icd {
            l = l.env("VK_DRIVER_FILES", icd).env("VK_ICD_FILENAMES", icd);
        }
        for (k, v) in &self.env {
            l = l.env(k, v);
        }
        l
    }
}

/// What `trilab ab` runs and when it stops.
#[derive(Clone, Debug)]
pub struct AbOptions {
    pub workload: Workload,
    pub a: Side,
    pub b: Side,
    /// The trilab executable a side runs (`__ab-worker`) unless it names its own.
    pub exe: PathBuf,
    /// Rounds per side at least (at least 2: an interval needs a spread).
    pub rounds: usize,
    /// Rounds per side at most.
    pub max_rounds: usize,
    /// Stop adding rounds once every cell's interval half-width (log scale) is below this.
    pub target: f64,
    /// Stop adding rounds past this many seconds.
    pub time_cap_s: f64,
    /// A cell (or kernel, by `judge`) whose whole interval is past 1 + threshold fails the run.
    pub threshold: f64,
    /// What the verdict judges: each cell, or each kernel over its cells.
    pub judge: Judge,
    /// Load the validation layer in the workers (any message fails the side).
    pub validation: bool,
    /// After the rounds, each side's driver statistics of the ray-casting kernels, diffed.
    pub driver_stats: bool,
    /// After the rounds, the changed ray-casting cells made into repros of both sides here
    /// ([`repro`]; a new folder).
    pub repro: Option<PathBuf>,
}

named_enum! {
    /// What `ab`'s verdict judges.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Judge: "judge" {
        /// each cell alone (a scene, ray set and kernel): one that slowed on one ray set shows
        Cells = "cells" (default),
        /// each kernel over its cells (its scenes and ray sets, pooled round by round): a narrower interval, so a smaller slowdown of a kernel is told from noise (the regression gate's)
        Kernels = "kernels",
    }
}

impl Judge {
    /// `cell` or `kernel`.
    fn unit(self) -> &'static str {
        match self {
            Judge::Cells => "cell",
            Judge::Kernels => "kernel",
        }
    }
}

/// The setting a side's rows carry (`A` or `B`): two sides' measurements of one cell on one
/// device are two cells to `merge`.
pub const SIDE_SETTING: &str = "ab_side";

/// The interval's level.
pub const LEVEL: f64 = 0.95;

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
    fn changed(&self) -> bool {
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
}

fn side_label(s: &SideReport) -> String {
    let p = ProvenanceFields::of(&s.provenance);
    format!("{} on {}", p.driver.as_deref().unwrap_or("?"), p.device.as_deref().unwrap_or("?"))
}

/// No plan: the cells are what both sides ran.
impl crate::services::results::Results for AbReport {
    const STEM: &'static str = "ab";

    /// The text report, as a code block.
    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        format!("```\n{}```\n", self.to_text())
    }

    fn rows(&self) -> Option<Vec<Row>> {
        Some(rows(self))
    }
}

impl Report for AbReport {
    fn to_text(&self) -> String {
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
        s += "\n";
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
        s += &self.kernels_text();
        s += &self.compiled_text();
        s += &self.invocations_text();
        for r in &self.repros {
            s += &format!("\nrepro of `{}`: {}\n  A: {}\n  B: {}\n", r.cell, r.dir.display(), r.sides[0], r.sides[1]);
            if let Some(d) = &r.hits {
                s += &format!("  B's hits against A's: {}\n", d.verdict());
            }
        }
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

/// The result rows of side `pick` (0: A, 1: B): its bench rows (speed per cell, agreement),
/// with that side's provenance as their source, so `compare DIR/a DIR/b` reads the two sides
/// as two runs.
pub fn side_rows(r: &AbReport, pick: usize) -> Vec<Row> {
    let source = source_of(if pick == 0 { &r.a } else { &r.b });
    r.cells
        .iter()
        .map(|c| {
            let sc = if pick == 0 { &c.a } else { &c.b };
            if c.cell.kind == CellKind::Pathtrace {
                return pathtrace_row(c, sc, &source);
            }
            // The cell as `trilab bench` names it, so `compare` matches a side with a bench run.
            let coords = c.cell.coordinates.clone();
            let row = Row::new("bench", coords, &source)
                .with(
                    "agreement",
                    Figure::correctness(sc.agree as f64 / c.cell.rays as f64, "fraction", Better::Higher),
                )
                .with("unexplained", Figure::correctness(sc.unexplained as f64, "rays", Better::Lower))
                .with("invalid", Figure::correctness(sc.invalid as f64, "rays", Better::Lower));
            match crate::report::Summary::of(&sc.ms) {
                Some(ms) => {
                    let mr = crate::services::validate::mrays_summary(c.cell.rays, ms);
                    row.with("mrays_per_s", Figure::timing(mr, "Mrays/s", Better::Higher))
                }
                None => row,
            }
        })
        .collect()
}

/// A path-trace cell's row for one side: `bench-render`'s speed and the invalid samples.
fn pathtrace_row(c: &AbCell, sc: &SideCell, source: &Source) -> Row {
    let row = Row::new("bench-render", c.cell.coordinates.clone(), source)
        .with("invalid", Figure::correctness(sc.invalid as f64, "samples", Better::Lower));
    match crate::report::Summary::of(&sc.ms) {
        // Samples per ms is thousands a second: /1e3 gives millions.
        Some(ms) => {
            let rate = |t: f64| c.cell.rays as f64 / t / 1e3;
            let f = Figure {
                median: rate(ms.median),
                min: rate(ms.max),
                max: rate(ms.min),
                runs: ms.runs,
                unit: "Msamples/s".into(),
                better: Better::Higher,
                class: Class::Timing,
            };
            row.with("msamples_per_s", f)
        }
        None => row,
    }
}

/// One `ab` row per cell: the ratio B/A with its interval, and the rays whose hits differ.
pub fn rows(r: &AbReport) -> Vec<Row> {
    let mut out = vec![];
    let source = source_of(&r.b);
    for c in &r.cells {
        let Some(ratio) = c.ratio else { continue };
        let coords = cell([
            ("scene", c.cell.scene.clone()),
            ("set", c.cell.set.clone()),
            ("method", c.cell.method.clone()),
            ("layout", c.cell.layout.clone()),
        ]);
        let f = Figure {
            median: ratio.ratio,
            min: ratio.low,
            max: ratio.high,
            runs: ratio.rounds_b,
            unit: "B/A".into(),
            better: Better::Lower,
            class: Class::Timing,
        };
        out.push(
            Row::new("ab", coords, &source)
                .with("time_ratio", f)
                .with("rays_differing", Figure::correctness(c.rays_differing as f64, "rays", Better::Lower)),
        );
    }
    out
}

fn source_of(side: &SideReport) -> Source {
    let p = ProvenanceFields::of(&side.provenance);
    let mut settings = p.settings;
    settings.insert(SIDE_SETTING.into(), side.name.into());
    Source {
        device: p.device.unwrap_or_default(),
        driver: p.driver.unwrap_or_default(),
        commit: p.commit.unwrap_or_default(),
        date: p.date.unwrap_or_default(),
        settings,
        host: p.host,
    }
}

/// Whether Mesa's on-disk shader cache held anything for this side's environment.
fn shader_cache(env: &[(String, String)]) -> String {
    let get =
        |k: &str| env.iter().rev().find(|(n, _)| n == k).map(|(_, v)| v.clone()).or_else(|| std::env::var(k).ok());
    if get("MESA_SHADER_CACHE_DISABLE").is_some_and(|v| matches!(v.trim(), "1" | "true" | "yes")) {
        return "disabled".into();
    }
    let dir = get("MESA_SHADER_CACHE_DIR").map(PathBuf::from).or_else(|| {
        get("XDG_CACHE_HOME")
            .map(|x| PathBuf::from(x).join("mesa_shader_cache"))
            .or_else(|| get("HOME").map(|h| PathBuf::from(h).join(".cache/mesa_shader_cache")))
    });
    let holds = |d: &Path| std::fs::read_dir(d).is_ok_and(|mut e| e.next().is_some());
    match dir {
        Some(d) if holds(&d) || holds(&PathBuf::from(format!("{}_db", d.display()))) => "warm".into(),
        Some(_) => "cold".into(),
        None => "unknown".into(),
    }
}

pub use crate::services::worker::{set_session_timeout as set_worker_timeout, MAX_LINE};

/// How long `ab` waits for one message of a worker by default ([`set_worker_timeout`]).
pub const DEFAULT_WORKER_TIMEOUT_S: f64 = crate::services::worker::DEFAULT_TIMEOUT_S;

/// Where a run is, for a stop handler ([`stop_requested`]): the stage, the rounds done and the
/// temporary folder the workers write their hits to.
#[derive(Default)]
struct Progress {
    stage: String,
    rounds: [usize; 2],
    least: usize,
    most: usize,
    temp: Option<PathBuf>,
}

static PROGRESS: Mutex<Option<Progress>> = Mutex::new(None);

fn progress_state() -> std::sync::MutexGuard<'static, Option<Progress>> {
    PROGRESS.lock().unwrap_or_else(|e| e.into_inner())
}

fn set_stage(stage: String) {
    if let Some(p) = progress_state().as_mut() {
        p.stage = stage;
    }
}

/// Set once a stop handler has taken over ([`stop_requested`]).
static STOPPING: AtomicBool = AtomicBool::new(false);

/// For a stop handler, before it signals the workers: marks the run as stopping (a worker that
/// the signal ends is then no failure to report: [`stopping`]) and says where the run was and
/// what it had measured. `None` when no `ab` run is under way.
pub fn stop_requested() -> Option<String> {
    STOPPING.store(true, Ordering::SeqCst);
    let state = progress_state();
    let p = state.as_ref()?;
    let [a, b] = p.rounds;
    let done = if a == b { format!("{a} rounds a side") } else { format!("{a} rounds on side A, {b} on side B") };
    Some(format!(
        "stopped during {}: {done} done (at least {} were to run, at most {}); no verdict",
        p.stage, p.least, p.most
    ))
}

/// Whether a stop handler has taken over: the caller of [`run`] leaves the exit to it.
pub fn stopping() -> bool {
    STOPPING.load(Ordering::SeqCst)
}

/// For a stop handler, once the workers have ended: removes the run's temporary folder (the
/// workers' hits), which an exit from the handler would leave behind.
pub fn remove_temp() {
    if let Some(t) = progress_state().as_mut().and_then(|p| p.temp.take()) {
        let _ = std::fs::remove_dir_all(t);
    }
}

/// A running side: its worker ([`worker`], a session of the worker service) and the folder
/// its cells' first-round hits go to.
struct Worker {
    session: Session,
    hits_dir: PathBuf,
}

impl Worker {
    fn start(o: &AbOptions, w: &Workload, name: &'static str, side: &Side, dir: &Path) -> Result<Worker> {
        let hits_dir = dir.join(name);
        std::fs::create_dir_all(&hits_dir).map_err(|e| Error::io(&hits_dir, e))?;
        let mut args: Vec<OsString> = vec![SESSION_COMMAND.into()];
        let w = Workload { runs_layout: side.layout, ..w.clone() };
        args.extend(w.args().into_iter().map(OsString::from));
        args.extend([OsString::from("--hits-dir"), hits_dir.clone().into()]);
        let launch = Launch {
            timeout: Some(crate::services::worker::session_timeout()),
            ..side.launch(&o.exe).validation(o.validation)
        };
        let session = Session::start(&launch, format!("side {name}"), &args)?.speaking("an ab message");
        Ok(Worker { session, hits_dir })
    }

    fn fail(&mut self, what: &str, when: &str) -> Error {
        self.session.fail(what, when)
    }

    fn next(&mut self, when: &str) -> Result<Message> {
        self.session.next(when)
    }

    /// Asks for one run of cell `i` (protocol 2).
    fn cell(&mut self, i: usize, when: &str) -> Result<CellRound> {
        match self.session.ask(&Request::Cell { index: i }, when)? {
            Message::Round { mut cells } if cells.len() == 1 => Ok(cells.remove(0)),
            other => Err(self.fail(&format!("expected cell {i}'s round, got {}", quote(&format!("{other:?}"))), when)),
        }
    }

    /// Asks for one round.
    fn round(&mut self, when: &str) -> Result<Vec<CellRound>> {
        match self.session.ask(&Request::Round, when)? {
            Message::Round { cells } => Ok(cells),
            other => Err(self.fail(&format!("expected a round, got {}", quote(&format!("{other:?}"))), when)),
        }
    }

    /// Asks the worker to end and waits for it (killing it past the timeout); its stderr.
    fn finish(self) -> String {
        self.session.finish()
    }
}

/// Gives each scene spec as the parent resolves it: a file by its path, so both sides read the
/// same file whatever build each runs and wherever it looks for names (a base build kept in a
/// cache has no `scenes/` beside it); the compiled-in bunny and `synth:` specs as given.
fn resolved_workload(w: &Workload) -> Result<Workload> {
    let mut w = w.clone();
    for spec in &mut w.scenes {
        let source = crate::scene::find::resolve(spec)?;
        if matches!(source.found.as_str(), "synthetic" | "built into trilab") {
            continue;
        }
        *spec = std::path::absolute(&source.path).map_err(|e| Error::io(&source.path, e))?;
    }
    Ok(w)
}

/// A started side that said it is ready.
struct Ready {
    worker: Worker,
    cells: Vec<CellInfo>,
    report: SideReport,
    invocations: Vec<Option<u64>>,
    invocations_note: Option<String>,
}

fn start_side(o: &AbOptions, w: &Workload, name: &'static str, side: &Side, dir: &Path) -> Result<Ready> {
    let cache = shader_cache(&side.env);
    let mut worker = Worker::start(o, w, name, side, dir)?;
    let when = "while it set up (before its first round)";
    let ready = worker.next(when)?;
    let Message::Ready { protocol, provenance, cells, pipeline_ms, invocations, invocations_note } = ready else {
        return Err(worker
            .fail(&format!("the worker's first message was not `ready` but {}", quote(&format!("{ready:?}"))), when));
    };
    if protocol > worker::PROTOCOL {
        return Err(worker.fail(
            &format!(
                "its trilab ({}) speaks ab protocol {protocol}, this one {} (run ab from the newer build)",
                side.exe(&o.exe).display(),
                worker::PROTOCOL
            ),
            when,
        ));
    }
    if invocations.len() != cells.len() {
        return Err(worker.fail(
            &format!("the worker's `ready` names {} cells but {} invocation counts", cells.len(), invocations.len()),
            when,
        ));
    }
    // Its requests from now on in the words of its protocol (an older build's: `cell N`).
    worker.session.speaks_protocol(protocol);
    let report = SideReport {
        name,
        given: side.clone(),
        exe: side.exe(&o.exe).to_owned(),
        protocol,
        provenance,
        shader_cache: cache,
        setup_ms: pipeline_ms,
        rounds: 0,
    };
    Ok(Ready { worker, cells, report, invocations, invocations_note })
}

/// Refuses a side's ICD file (`flag`: `--a-icd`) the loader could not use, naming the side, the
/// file and why, before any side starts: missing, a directory, empty, not JSON, naming no
/// driver library, or naming one by a path that does not exist (a bare library name is the
/// loader's to find on the library path).
fn check_icd(side: &str, flag: &str, icd: &Path) -> Result<()> {
    let refuse = |why: String| Error::Usage(format!("side {side}: {flag} {}: {why}", icd.display()));
    let meta = std::fs::metadata(icd).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => refuse("no such file (an ICD JSON naming a driver)".into()),
        _ => refuse(format!("cannot be read ({e})")),
    })?;
    if meta.is_dir() {
        return Err(refuse("a directory, not an ICD JSON file (an ICD JSON naming a driver)".into()));
    }
    let text = std::fs::read(icd).map_err(|e| refuse(format!("cannot be read ({e})")))?;
    if text.iter().all(u8::is_ascii_whitespace) {
        return Err(refuse("the file is empty, not an ICD JSON naming a driver".into()));
    }
    let json: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| refuse(format!("not JSON ({e}), so not an ICD JSON naming a driver")))?;
    let Some(library) = json.get("ICD").and_then(|d| d.get("library_path")).and_then(|l| l.as_str()) else {
        return Err(refuse("names no driver: an ICD JSON has {\"ICD\": {\"library_path\": \"...\", ...}}".into()));
    };
    if library.contains('/') {
        // A relative path is relative to the JSON file, as the loader reads it.
        let lib = icd.parent().unwrap_or(Path::new(".")).join(library);
        if !lib.is_file() {
            return Err(refuse(format!("its driver library {library} does not exist")));
        }
    }
    Ok(())
}

/// Clears the run's [`Progress`] when the run ends, however it ends.
struct ProgressGuard;

impl ProgressGuard {
    fn new(least: usize, most: usize, temp: &Path) -> ProgressGuard {
        *progress_state() =
            Some(Progress { stage: "the start".into(), rounds: [0, 0], least, most, temp: Some(temp.to_owned()) });
        ProgressGuard
    }
}

impl Drop for ProgressGuard {
    fn drop(&mut self) {
        *progress_state() = None;
    }
}

/// Runs the two sides and compares them. An error means they could not be compared (a side
/// that does not start, a missing ICD file or executable, no cell in common): exit 2.
pub fn run(o: &AbOptions, mut progress: impl FnMut(&str)) -> Result<AbReport> {
    check_options(o, &mut progress)?;
    o.workload.sizes.check_memory()?;
    let workload = resolved_workload(&o.workload)?;
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let _progress = ProgressGuard::new(o.rounds, o.max_rounds, tmp.path());
    let start = Instant::now();
    let mut ready = vec![];
    for (name, side) in [("A", &o.a), ("B", &o.b)] {
        progress(&format!("side {name}: starting ({})", side.describe()));
        set_stage(format!("side {name}'s start"));
        // A side that does not start ends the run; the side started before it is dropped,
        // which ends its worker.
        let starting = crate::trace::span_on(side_track(name), "ab", "start: worker setup");
        let r = start_side(o, &workload, name, side, tmp.path())?;
        if starting.records() {
            starting.arg("setup_ms", r.report.setup_ms);
            starting.arg("cells", r.cells.len());
            starting.arg("side", side.describe());
        }
        drop(starting);
        progress(&format!(
            "side {name}: {} ready, {} cells, setup {:.1} s (shader cache {})",
            side_label(&r.report),
            r.cells.len(),
            r.report.setup_ms / 1e3,
            r.report.shader_cache
        ));
        ready.push(r);
    }
    let Ready { worker: mut wb, cells: cells_b, report: report_b, invocations: inv_b, invocations_note: note_b } =
        ready.pop().expect("two sides");
    let Ready { worker: mut wa, cells: cells_a, report: report_a, invocations: inv_a, invocations_note: note_a } =
        ready.pop().expect("two sides");
    // The cells both sides ran, matched by what they are, not by their place in each side's list.
    let matching = match_cells(&cells_a, &cells_b);
    if matching.pairs.is_empty() {
        let labels = |c: &[CellInfo]| c.iter().map(CellInfo::label).collect::<Vec<_>>();
        return Err(Error::Usage(format!(
            "the sides have no cell in common (A: {:?}; B: {:?})",
            labels(&cells_a),
            labels(&cells_b)
        )));
    }
    let pairs = &matching.pairs;
    // Per side, per matched cell, one entry per round: the validated time, or None.
    let mut times: [Vec<Vec<Option<f64>>>; 2] = [vec![vec![]; pairs.len()], vec![vec![]; pairs.len()]];
    let mut worst: [Vec<SideCell>; 2] = std::array::from_fn(|side| {
        pairs
            .iter()
            .map(|&(ia, ib)| {
                let rays = if side == 0 { cells_a[ia].rays } else { cells_b[ib].rays };
                SideCell { ms: vec![], failed_rounds: 0, agree: rays, unexplained: 0, invalid: 0 }
            })
            .collect()
    });
    let groups = kernel_groups(pairs.iter().map(|&(_, ib)| &cells_b[ib]));
    // Both sides speak protocol 2: each cell's two sides run back to back, which side first
    // alternating, so a moment's load on the host lands on both (paired intervals). An older
    // worker times whole rounds only: rounds A B B A, unpaired intervals.
    let paired = report_a.protocol >= worker::PROTOCOL_CELL && report_b.protocol >= worker::PROTOCOL_CELL;
    let mut rounds = [0usize; 2];
    let record = |times: &mut [Vec<Vec<Option<f64>>>; 2],
                  worst: &mut [Vec<SideCell>; 2],
                  side: usize,
                  p: usize,
                  r: &CellRound| {
        let s = &mut worst[side][p];
        if r.ms.is_none() {
            s.failed_rounds += 1;
        }
        times[side][p].push(r.ms);
        s.agree = s.agree.min(r.agree);
        s.unexplained = s.unexplained.max(r.unexplained);
        s.invalid = s.invalid.max(r.invalid);
    };
    let stopped_by;
    // What a worker's failure in the rounds says after what happened: when, and what had been
    // measured (nothing is compared then).
    let in_round = |round: usize, cell: Option<&CellInfo>, done: [usize; 2]| {
        let cell = cell.map(|c| format!(", cell `{}`", c.label())).unwrap_or_default();
        let done = if done[0] == done[1] {
            format!("{} rounds a side", done[0])
        } else {
            format!("{} rounds on side A, {} on side B", done[0], done[1])
        };
        format!("in round {}{cell}, after {done}; the sides were not compared", round + 1)
    };
    'rounds: loop {
        if paired {
            let round = rounds[0];
            set_stage(format!("round {}", round + 1));
            let _round_span = crate::trace::span_with("round", || format!("round {}", round + 1));
            for k in 0..pairs.len() {
                // The cell that opens a round rotates, and which side goes first alternates
                // from cell to cell and from round to round.
                let p = (k + round) % pairs.len();
                let order = if (k + round) % 2 == 0 { [0usize, 1] } else { [1, 0] };
                for (nth, side) in order.into_iter().enumerate() {
                    let (w, i) = if side == 0 { (&mut wa, pairs[p].0) } else { (&mut wb, pairs[p].1) };
                    let span = trace_side_cell(side, &cells_b[pairs[p].1], round, nth == 0);
                    let r = w.cell(i, &in_round(round, Some(&cells_b[pairs[p].1]), rounds))?;
                    trace_answer(&span, &r);
                    record(&mut times, &mut worst, side, p, &r);
                }
            }
            rounds = [round + 1, round + 1];
        } else {
            // One balanced block: A B B A.
            for side in [0usize, 1, 1, 0] {
                set_stage(format!("round {}", rounds[side] + 1));
                let w = if side == 0 { &mut wa } else { &mut wb };
                let when = in_round(rounds[side], None, rounds);
                let span = crate::trace::span_on(side_track(["A", "B"][side]), "ab", "whole round")
                    .with("round", rounds[side] + 1)
                    .with("side", ["A", "B"][side]);
                let res = w.round(&when)?;
                drop(span);
                rounds[side] += 1;
                for (p, &(ia, ib)) in pairs.iter().enumerate() {
                    let Some(r) = res.get(if side == 0 { ia } else { ib }) else {
                        let what = format!("a round answered {} cells, fewer than it said it had", res.len());
                        return Err(w.fail(&what, &when));
                    };
                    record(&mut times, &mut worst, side, p, r);
                }
            }
        }
        if let Some(p) = progress_state().as_mut() {
            p.rounds = rounds;
        }
        let n = rounds[0].min(rounds[1]);
        if n < o.rounds {
            continue;
        }
        // The intervals the verdict is given by must be narrow enough.
        let widest = match o.judge {
            Judge::Cells => (0..pairs.len())
                .map(|p| cell_ratio(&times, p, paired).map_or(f64::INFINITY, |r| r.half_width()))
                .fold(0.0, f64::max),
            Judge::Kernels => groups
                .iter()
                .map(|g| kernel_ratio(&times, &g.members, paired).map_or(f64::INFINITY, |r| r.half_width()))
                .fold(0.0, f64::max),
        };
        progress(&format!("{n} rounds a side: widest {} interval +-{:.1} %", o.judge.unit(), widest * 100.0));
        for (why, done) in [
            ("target", widest <= o.target),
            ("max rounds", n + if paired { 1 } else { 2 } > o.max_rounds),
            ("time cap", start.elapsed().as_secs_f64() > o.time_cap_s),
        ] {
            if done {
                stopped_by = why;
                break 'rounds;
            }
        }
    }
    let (dir_a, dir_b) = (wa.hits_dir.clone(), wb.hits_dir.clone());
    let ending = crate::trace::span("ab", "the workers end");
    wa.finish();
    wb.finish();
    drop(ending);
    // Each side's matched cells: with --b-layout, B's name the kernel B ran.
    let matched =
        [0, 1].map(|s| pairs.iter().map(|&(ia, ib)| [&cells_a[ia], &cells_b[ib]][s].clone()).collect::<Vec<_>>());
    // The compilers' output, after the rounds: its compiles would time them otherwise.
    set_stage("the driver statistics, after the rounds".into());
    let stats = o.driver_stats.then(|| {
        [("A", &o.a), ("B", &o.b)].map(|(name, side)| {
            let _span = crate::trace::span_on(side_track(name), "ab", "driver statistics");
            progress(&format!("side {name}: driver statistics"));
            let protocol = if name == "A" { report_a.protocol } else { report_b.protocol };
            let cells = &matched[usize::from(name == "B")];
            compiled::collect(o, name, side, protocol, cells, &tmp.path().join(format!("driver-stats-{name}")))
        })
    });
    let judging = crate::trace::span("ab", "cells judged (hits compared ray by ray)");
    let out = judged_cells(
        o,
        pairs,
        [&cells_a, &cells_b],
        &times,
        &worst,
        paired,
        [&dir_a, &dir_b],
        stats.as_ref(),
        [&inv_a, &inv_b],
    )?;
    drop(judging);
    let kernels = groups
        .iter()
        .map(|g| {
            let ratio = kernel_ratio(&times, &g.members, paired);
            AbKernel {
                kernel: g.kernel.clone(),
                kind: g.first.kind,
                method: g.first.method.clone(),
                layout: g.first.layout.clone(),
                traversal: g.first.traversal.clone(),
                cells: g.members.len(),
                ratio,
                verdict: ratio.map(|r| r.verdict(o.threshold)),
                correctness_worse: g.members.iter().any(|&p| out[p].correctness_worse),
            }
        })
        .collect();
    let (mut a, mut b) = (report_a, report_b);
    a.rounds = rounds[0];
    b.rounds = rounds[1];
    let repros = match &o.repro {
        Some(dir) => {
            set_stage("the repros, after the rounds".into());
            repro::make(o, &workload, &out, dir, &mut progress)?
        }
        None => vec![],
    };
    Ok(AbReport {
        a,
        b,
        workload: workload.args(),
        level: LEVEL,
        threshold: o.threshold,
        target: o.target,
        judge: o.judge,
        paired,
        stopped_by: stopped_by.into(),
        seconds: start.elapsed().as_secs_f64(),
        cells: out,
        kernels,
        only_in: [
            matching.only_a.iter().map(|&i| cells_a[i].label()).collect(),
            matching.only_b.iter().map(|&i| cells_b[i].label()).collect(),
        ],
        mismatched: matching.mismatched,
        driver_stats: stats.as_ref().map(|s| s.clone().map(|x| x.note)),
        pipeline_stats: o.workload.pipeline_stats.then_some([note_a, note_b]),
        driver_stats_rows: stats.map(|s| s.map(|x| x.rows)).unwrap_or_default(),
        repros,
    })
}

/// The trace's track of side `name` ("A" or "B").
fn side_track(name: &str) -> &'static str {
    if name == "A" {
        "side A"
    } else {
        "side B"
    }
}

/// One side's run of one cell in a paired round, as a span on that side's track of the trace
/// (`side`: 0 for A): the cell, the round (from 1) and whether the side went first.
fn trace_side_cell(side: usize, cell: &CellInfo, round: usize, first: bool) -> crate::trace::Span {
    let name = ["A", "B"][side];
    if !crate::trace::on() {
        return crate::trace::span("ab", "");
    }
    let span = crate::trace::span_on(side_track(name), "ab", format!("{name}: {}", cell.label()));
    if span.records() {
        span.arg("side", name);
        span.arg("cell", cell.label());
        span.arg("round", round + 1);
        span.arg("first_in_pair", first);
    }
    span
}

/// What the side's worker answered for the cell, in its span's args.
fn trace_answer(span: &crate::trace::Span, r: &CellRound) {
    if !span.records() {
        return;
    }
    match r.ms {
        Some(ms) => span.arg("kernel_ms", ms),
        None => span.arg("validated", false),
    }
    span.arg("agree", r.agree);
}

/// The options checked before any side starts: each side's ICD file and executable, and the
/// rounds (a warning when too few to judge time).
fn check_options(o: &AbOptions, progress: &mut impl FnMut(&str)) -> Result<()> {
    if let Some(dir) = &o.repro {
        crate::commands::repro::refuse_existing("--repro", dir)?;
    }
    if let Some(l) = o.b.layout {
        if o.workload.layouts.len() != 1 {
            return Err(Error::Usage(format!(
                "--b-layout {l}: side B runs it in place of side A's one layout; give --layouts one layout"
            )));
        }
    }
    for (name, flag, side) in [("A", "--a-icd", &o.a), ("B", "--b-icd", &o.b)] {
        if let Some(icd) = &side.icd {
            check_icd(name, flag, icd)?;
        }
    }
    for (name, flag, side) in [("A", "--a-bin", &o.a), ("B", "--b-bin", &o.b)] {
        if let Some(exe) = &side.exe {
            if exe.is_dir() {
                return Err(Error::Usage(format!(
                    "side {name}: {flag} {}: a directory, not a trilab executable",
                    exe.display()
                )));
            }
            if !exe.is_file() {
                return Err(Error::Usage(format!(
                    "side {name}: {flag} {}: no such file (a trilab executable)",
                    exe.display()
                )));
            }
        }
    }
    if o.rounds < 2 || o.max_rounds < o.rounds {
        return Err(Error::Usage(format!(
            "--rounds {} --max-rounds {}: at least 2 rounds a side, and no more than the maximum",
            o.rounds, o.max_rounds
        )));
    }
    if o.max_rounds < interval::MIN_JUDGED_ROUNDS {
        progress(&format!(
            "warning: --max-rounds {}: fewer than {} rounds a side, so time is shown but not judged \
             (hits and correctness still are)",
            o.max_rounds,
            interval::MIN_JUDGED_ROUNDS
        ));
    }
    Ok(())
}

/// Each matched cell's two sides after the rounds: their validated times, worst correctness,
/// the rays (or pixels) whose answers differ, the compiled-code changes and invocations, and the
/// cell's verdict.
#[allow(clippy::too_many_arguments)]
fn judged_cells(
    o: &AbOptions,
    pairs: &[(usize, usize)],
    [cells_a, cells_b]: [&[CellInfo]; 2],
    times: &[Vec<Vec<Option<f64>>>; 2],
    worst: &[Vec<SideCell>; 2],
    paired: bool,
    [dir_a, dir_b]: [&Path; 2],
    stats: Option<&[compiled::SideStats; 2]>,
    [inv_a, inv_b]: [&[Option<u64>]; 2],
) -> Result<Vec<AbCell>> {
    let mut out = vec![];
    for (p, &(ia, ib)) in pairs.iter().enumerate() {
        let c = cells_b[ib].clone();
        let ratio = cell_ratio(times, p, paired);
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

/// How the two sides' cells pair up.
#[derive(Debug, Default, PartialEq)]
struct Matching {
    /// (index in A's cells, index in B's), in B's order.
    pairs: Vec<(usize, usize)>,
    only_a: Vec<usize>,
    only_b: Vec<usize>,
    /// Cells both name that are not the same work (other ray counts): not compared.
    mismatched: Vec<String>,
}

/// Pairs the cells of the two sides by [`CellInfo::key`]: a newer build may add cells (a new
/// method), drop some or list them in another order, and still be timed against an older one
/// on the cells both run. A cell both name but whose work differs (another ray count: the
/// builds generate other rays) is not compared, and named.
fn match_cells(a: &[CellInfo], b: &[CellInfo]) -> Matching {
    let index: std::collections::HashMap<_, usize> = a.iter().enumerate().map(|(i, c)| (c.key(), i)).collect();
    let mut m = Matching::default();
    let mut used = vec![false; a.len()];
    for (ib, c) in b.iter().enumerate() {
        match index.get(&c.key()) {
            Some(&ia) if a[ia].rays == c.rays => {
                used[ia] = true;
                m.pairs.push((ia, ib));
            }
            Some(&ia) => {
                used[ia] = true;
                m.mismatched.push(format!(
                    "{}: A traced {} rays, B {} (the builds made other rays)",
                    c.label(),
                    a[ia].rays,
                    c.rays
                ));
            }
            None => m.only_b.push(ib),
        }
    }
    m.only_a = (0..a.len()).filter(|&i| !used[i]).collect();
    m
}

/// B/A for one matched cell, from its validated rounds: paired round by round when the two
/// sides ran each round's cell back to back, else Welch's interval on the two sides' rounds.
fn cell_ratio(times: &[Vec<Vec<Option<f64>>>; 2], p: usize, paired: bool) -> Option<Ratio> {
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

/// A kernel's cells ([`CellInfo::kernel_label`]) among the matched cells.
struct KernelGroup {
    kernel: String,
    /// Its first cell (the kernel's kind, method, layout and traversal).
    first: CellInfo,
    /// Indices into the matched cells.
    members: Vec<usize>,
}

fn kernel_groups<'c>(cells: impl Iterator<Item = &'c CellInfo>) -> Vec<KernelGroup> {
    let mut groups: Vec<KernelGroup> = vec![];
    for (p, c) in cells.enumerate() {
        let k = c.kernel_label();
        match groups.iter_mut().find(|g| g.kernel == k) {
            Some(g) => g.members.push(p),
            None => groups.push(KernelGroup { kernel: k, first: c.clone(), members: vec![p] }),
        }
    }
    groups
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
fn kernel_ratio(times: &[Vec<Vec<Option<f64>>>; 2], members: &[usize], paired: bool) -> Option<Ratio> {
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

/// Writes `ab.json`, `ab.md` (the text report) and `rows.jsonl` (the `ab` rows) into `dir`,
/// and each side's bench rows into `dir/a/rows.jsonl` and `dir/b/rows.jsonl`.
pub fn write(r: &AbReport, dir: &Path) -> Result<()> {
    crate::services::results::write_folder(dir, r)?;
    for (pick, sub) in [(0, "a"), (1, "b")] {
        let mut rows = side_rows(r, pick);
        rows.extend(r.driver_stats_rows[pick].iter().cloned());
        Folder::create(&dir.join(sub))?.rows(None, &rows)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cell(method: &str, set: &str, rays: usize) -> CellInfo {
        CellInfo {
            kind: CellKind::Raycast,
            scene: "bunny".into(),
            set: set.into(),
            method: method.into(),
            layout: "bvh2".into(),
            traversal: "while-if".into(),
            rays,
            kernel: format!("raycast.{method}.closest"),
            coordinates: crate::rows::cell([("method", method), ("set", set)]),
        }
    }

    #[test]
    fn cells_pair_by_what_they_are_whatever_each_build_lists() {
        // B lists the cells in another order, adds a method and made other rays for one cell.
        let a = [cell("mt", "primary", 100), cell("mt", "random", 50), cell("unit", "primary", 100)];
        let mut renamed = cell("unit", "primary", 100);
        renamed.kernel = "raycast.unit.closest_v2".into();
        renamed.coordinates = crate::rows::cell([("method", "unit"), ("set", "primary"), ("new", "axis")]);
        let b = [renamed, cell("mt", "primary", 100), cell("quad-mt", "primary", 100), cell("mt", "random", 60)];
        let m = match_cells(&a, &b);
        assert_eq!(m.pairs, [(2, 0), (0, 1)], "{m:?}");
        assert_eq!((m.only_a.as_slice(), m.only_b.as_slice()), (&[][..], &[2usize][..]));
        assert_eq!(m.mismatched.len(), 1, "{m:?}");
        assert!(m.mismatched[0].contains("bunny random mt bvh2") && m.mismatched[0].contains("A traced 50 rays, B 60"));
        // Cells a build of protocol 1 names (no traversal field) are while-if's.
        let old: CellInfo = serde_json::from_str(
            r#"{"kind":"raycast","scene":"bunny","set":"primary","method":"mt","layout":"bvh2","rays":100,
                "kernel":"raycast.mt.closest","coordinates":{"method":"mt","set":"primary"}}"#,
        )
        .unwrap();
        assert_eq!(old.key(), cell("mt", "primary", 100).key());
    }

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

    #[test]
    fn kernels_group_cells_by_kind_method_layout_and_traversal() {
        let mut ww = cell("mt", "primary", 10);
        ww.traversal = "while-while".into();
        let cells = [cell("mt", "primary", 10), cell("mt", "random", 10), ww, cell("unit", "primary", 10)];
        let g = kernel_groups(cells.iter());
        let got: Vec<(&str, &[usize])> = g.iter().map(|g| (g.kernel.as_str(), g.members.as_slice())).collect();
        assert_eq!(
            got,
            [
                ("raycast mt bvh2", &[0usize, 1][..]),
                ("raycast mt bvh2 while-while", &[2][..]),
                ("raycast unit bvh2", &[3][..])
            ]
        );
    }
}
