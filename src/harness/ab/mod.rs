//! `trilab ab`: one workload under two driver environments, A and B, in one run, and what
//! changed between them with confidence (after gpu-trace-perf's A/B runs and the helped/hurt
//! reports of Mesa's shader-db).
//!
//! Each side is its own child process ([`worker`]): a driver is loaded once per process, and a
//! side is named by the ICD file the Vulkan loader is given (`VK_DRIVER_FILES`) and the
//! environment it runs in. The parent asks the sides for rounds in a balanced order (A B B A,
//! repeated), so a slow drift of the host lands on both alike, one side running at a time;
//! every round of every cell is validated against the f64 reference before its time counts.
//! Rounds go on past the minimum until every cell's interval ([`interval`]) is narrower than
//! the target, or the maximum rounds, or the time cap. Then per cell: the ratio B/A of kernel
//! time with its 95 % interval and a verdict, the hits of A and B compared ray by ray, and each
//! side's agreement with the reference.

pub mod compiled;
pub mod interval;
pub mod worker;

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::Instant;

use serde::Serialize;

use crate::error::{Error, Result};
use crate::harness::results::Folder;
use crate::report::{Report, Table};
use crate::rows::{cell, Better, Class, Figure, Row, Source};
use compiled::StatChange;
use interval::{Ratio, Verdict};
use worker::{CellInfo, CellKind, CellRound, Message, Workload};

/// One side: the driver the loader is given and the environment it runs in.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Side {
    /// The ICD JSON given to the loader as `VK_DRIVER_FILES` (`None`: the loader's own choice).
    pub icd: Option<PathBuf>,
    /// Variables set for this side only, in order.
    pub env: Vec<(String, String)>,
}

impl Side {
    /// `VK_DRIVER_FILES=... K=V`, or "trilab's own environment".
    pub fn describe(&self) -> String {
        let mut parts: Vec<String> = self.icd.iter().map(|p| format!("VK_DRIVER_FILES={}", p.display())).collect();
        parts.extend(self.env.iter().map(|(k, v)| format!("{k}={v}")));
        if parts.is_empty() {
            "trilab's own environment".into()
        } else {
            parts.join(" ")
        }
    }

    /// Gives `cmd` this side's driver and environment.
    pub fn apply(&self, cmd: &mut Command) {
        if let Some(icd) = &self.icd {
            cmd.env("VK_DRIVER_FILES", icd).env("VK_ICD_FILENAMES", icd);
        }
        for (k, v) in &self.env {
            cmd.env(k, v);
        }
    }
}

/// What `trilab ab` runs and when it stops.
#[derive(Clone, Debug)]
pub struct AbOptions {
    pub workload: Workload,
    pub a: Side,
    pub b: Side,
    /// The trilab executable the workers run (`__ab-worker`).
    pub exe: PathBuf,
    /// Rounds per side at least (at least 2: an interval needs a spread).
    pub rounds: usize,
    /// Rounds per side at most.
    pub max_rounds: usize,
    /// Stop adding rounds once every cell's interval half-width (log scale) is below this.
    pub target: f64,
    /// Stop adding rounds past this many seconds.
    pub time_cap_s: f64,
    /// A cell whose whole interval is past 1 + threshold fails the run.
    pub threshold: f64,
    /// Load the validation layer in the workers (any message fails the side).
    pub validation: bool,
    /// After the rounds, each side's driver statistics of the ray-casting kernels, diffed.
    pub driver_stats: bool,
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
        self.verdict.is_some_and(|v| v != Verdict::Same)
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
    /// Why the rounds stopped: `target`, `max rounds` or `time cap`.
    pub stopped_by: String,
    pub seconds: f64,
    pub cells: Vec<AbCell>,
    /// With `--driver-stats`: how each side's statistics were obtained, or why it has none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub driver_stats: Option<[String; 2]>,
    /// With `--pipeline-stats`: why a side counted no invocations, if it did not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pipeline_stats: Option<[Option<String>; 2]>,
    /// Each side's driver-stats rows (written to `a/` and `b/` beside the bench rows).
    #[serde(skip)]
    pub driver_stats_rows: [Vec<Row>; 2],
}

impl AbReport {
    /// 1 when a cell is hurt beyond the threshold with its whole interval, or any correctness
    /// figure got worse; else 0.
    pub fn exit_code(&self) -> u8 {
        let failed = self
            .cells
            .iter()
            .any(|c| c.verdict == Some(Verdict::HurtBeyondThreshold) || c.correctness_worse || c.ratio.is_none());
        u8::from(failed)
    }

    /// Cells helped, hurt (either kind), no change, and without an interval.
    pub fn totals(&self) -> (usize, usize, usize, usize) {
        let count = |f: &dyn Fn(Option<Verdict>) -> bool| self.cells.iter().filter(|c| f(c.verdict)).count();
        (
            count(&|v| v == Some(Verdict::Helped)),
            count(&|v| matches!(v, Some(Verdict::Hurt | Verdict::HurtBeyondThreshold))),
            count(&|v| v == Some(Verdict::Same)),
            count(&|v| v.is_none()),
        )
    }

    /// The geometric mean of the cells' ratios B/A.
    pub fn geomean(&self) -> Option<f64> {
        let r: Vec<f64> = self.cells.iter().filter_map(|c| c.ratio.map(|r| r.ratio.ln())).collect();
        (!r.is_empty()).then(|| (r.iter().sum::<f64>() / r.len() as f64).exp())
    }
}

impl AbReport {
    /// Kernels whose driver statistics changed (each once, however many cells ran it), then
    /// totals per figure: kernels helped (fewer) and hurt (more).
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
            if ch.b < ch.a {
                e.0 += 1;
            } else if ch.b > ch.a {
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
    let p = &s.provenance;
    let field = |k: &str| p.get(k).and_then(|v| v.as_str()).unwrap_or("?").to_owned();
    format!("{} on {}", field("driver"), field("device"))
}

/// No plan: the cells are what both sides ran.
impl crate::harness::results::Results for AbReport {
    const STEM: &'static str = "ab";

    /// The text report, as a code block.
    fn markdown(&self, _: &[crate::harness::plots::Plot]) -> String {
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
                "{}: {} ({}; shader cache {}, setup {:.1} s, {} rounds)\n",
                side.name,
                side_label(side),
                side.given.describe(),
                side.shader_cache,
                side.setup_ms / 1e3,
                side.rounds
            );
        }
        s += &format!(
            "{} cells, rounds interleaved A B B A, stopped by {} after {:.0} s; B/A kernel time, {:.0} % interval (Welch's t on log times)\n\n",
            self.cells.len(),
            self.stopped_by,
            self.seconds,
            self.level * 100.0
        );
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
        s += &self.compiled_text();
        s += &self.invocations_text();
        let (helped, hurt, same, none) = self.totals();
        s += &format!(
            "\ntotals: {helped} helped, {hurt} hurt, {same} no change{}; geometric mean B/A {}\n",
            if none > 0 { format!(", {none} without an interval") } else { String::new() },
            self.geomean().map(|g| format!("{g:.3}")).unwrap_or("-".into())
        );
        let worse = self.cells.iter().filter(|c| c.correctness_worse).count();
        s += &format!(
            "verdict: {} (threshold {:.0} %: fails on a cell hurt with its whole interval past it, or any correctness worse: {worse} cell(s))\n",
            if self.exit_code() == 0 { "pass" } else { "FAIL" },
            self.threshold * 100.0
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
                    let mr = crate::harness::validate::mrays_summary(c.cell.rays, ms);
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
    let p = &side.provenance;
    let s = |k: &str| p.get(k).and_then(|v| v.as_str()).unwrap_or_default().to_owned();
    let mut settings: std::collections::BTreeMap<String, String> =
        p.get("settings").and_then(|v| serde_json::from_value(v.clone()).ok()).unwrap_or_default();
    settings.insert(SIDE_SETTING.into(), side.name.into());
    Source {
        device: s("device"),
        driver: s("driver"),
        commit: s("commit"),
        date: s("date"),
        settings,
        host: p.get("host").and_then(|v| serde_json::from_value(v.clone()).ok()),
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

/// A running side.
struct Worker {
    name: &'static str,
    child: Child,
    stdin: ChildStdin,
    lines: std::io::Lines<BufReader<std::process::ChildStdout>>,
    stderr: std::thread::JoinHandle<String>,
    hits_dir: PathBuf,
}

impl Worker {
    fn start(o: &AbOptions, name: &'static str, side: &Side, dir: &Path) -> Result<Worker> {
        let hits_dir = dir.join(name);
        std::fs::create_dir_all(&hits_dir).map_err(|e| Error::io(&hits_dir, e))?;
        let mut cmd = Command::new(&o.exe);
        cmd.arg("__ab-worker").args(o.workload.args()).arg("--hits-dir").arg(&hits_dir);
        if o.validation {
            cmd.arg("--validation");
        }
        side.apply(&mut cmd);
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| Error::io(&o.exe, e))?;
        let stdin = child.stdin.take().expect("piped");
        let lines = BufReader::new(child.stdout.take().expect("piped")).lines();
        let mut err = child.stderr.take().expect("piped");
        let stderr = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut err, &mut s);
            s
        });
        Ok(Worker { name, child, stdin, lines, stderr, hits_dir })
    }

    /// The worker's next message; its failure (or its end) as an error naming the side.
    fn next(&mut self) -> Result<Message> {
        let fail = |w: &mut Worker, what: String| -> Error {
            let _ = w.child.kill();
            let _ = w.child.wait();
            Error::Usage(format!("side {}: {what}", w.name))
        };
        match self.lines.next() {
            Some(Ok(line)) => match serde_json::from_str::<Message>(&line) {
                Ok(Message::Failed { error }) => Err(fail(self, error)),
                Ok(m) => Ok(m),
                Err(e) => Err(fail(self, format!("unreadable worker line ({e}): {line}"))),
            },
            _ => {
                let _ = self.child.wait();
                Err(Error::Usage(format!("side {}: the worker ended", self.name)))
            }
        }
    }

    fn send(&mut self, command: &str) -> Result<()> {
        writeln!(self.stdin, "{command}")
            .and_then(|_| self.stdin.flush())
            .map_err(|e| Error::Usage(format!("side {}: the worker stopped reading ({e})", self.name)))
    }

    /// Asks for one round.
    fn round(&mut self) -> Result<Vec<CellRound>> {
        self.send("round")?;
        match self.next()? {
            Message::Round { cells } => Ok(cells),
            other => Err(Error::Usage(format!("side {}: expected a round, got {other:?}", self.name))),
        }
    }

    fn finish(mut self) -> String {
        let _ = self.send("quit");
        let _ = self.child.wait();
        self.stderr.join().unwrap_or_default()
    }
}

/// Runs the two sides and compares them. An error means they could not be compared (a side
/// that does not start, a missing ICD file, different cells): exit 2.
pub fn run(o: &AbOptions, mut progress: impl FnMut(&str)) -> Result<AbReport> {
    for (name, side) in [("--a-icd", &o.a), ("--b-icd", &o.b)] {
        if let Some(icd) = &side.icd {
            if !icd.is_file() {
                return Err(Error::Usage(format!(
                    "{name} {}: no such file (an ICD JSON naming a driver)",
                    icd.display()
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
    o.workload.sizes.check_memory()?;
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let start = Instant::now();
    let mut sides = vec![];
    let mut reports = vec![];
    let mut counted = vec![];
    for (name, side) in [("A", &o.a), ("B", &o.b)] {
        let cache = shader_cache(&side.env);
        progress(&format!("side {name}: starting ({}; shader cache {cache})", side.describe()));
        let mut w = Worker::start(o, name, side, tmp.path())?;
        let ready = match w.next() {
            Ok(m) => m,
            Err(e) => {
                let err = w.finish();
                return Err(Error::Usage(format!("{e}{}", tail(&err))));
            }
        };
        let Message::Ready { provenance, cells, pipeline_ms, invocations, invocations_note } = ready else {
            return Err(Error::Usage(format!("side {name}: the worker did not say it was ready")));
        };
        let report =
            SideReport { name, given: side.clone(), provenance, shader_cache: cache, setup_ms: pipeline_ms, rounds: 0 };
        progress(&format!(
            "side {name}: {} ready, {} cells, setup {:.1} s",
            side_label(&report),
            cells.len(),
            pipeline_ms / 1e3
        ));
        sides.push((w, cells));
        reports.push(report);
        counted.push((invocations, invocations_note));
    }
    let (mut wb, cells_b) = sides.pop().expect("two sides");
    let (mut wa, cells) = sides.pop().expect("two sides");
    if cells != cells_b {
        let (a, b) = (
            cells.iter().map(CellInfo::label).collect::<Vec<_>>(),
            cells_b.iter().map(CellInfo::label).collect::<Vec<_>>(),
        );
        wa.finish();
        wb.finish();
        return Err(Error::Usage(format!("the sides do not run the same cells (A: {a:?}; B: {b:?})")));
    }
    let mut times: [Vec<Vec<f64>>; 2] = [vec![vec![]; cells.len()], vec![vec![]; cells.len()]];
    let mut worst: [Vec<SideCell>; 2] = std::array::from_fn(|_| {
        cells
            .iter()
            .map(|c| SideCell { ms: vec![], failed_rounds: 0, agree: c.rays, unexplained: 0, invalid: 0 })
            .collect()
    });
    let mut rounds = [0usize; 2];
    let stopped_by;
    'rounds: loop {
        // One balanced block: A B B A.
        for side in [0usize, 1, 1, 0] {
            let w = if side == 0 { &mut wa } else { &mut wb };
            let res = w.round()?;
            rounds[side] += 1;
            for (i, r) in res.iter().enumerate() {
                let s = &mut worst[side][i];
                match r.ms {
                    Some(ms) => times[side][i].push(ms),
                    None => s.failed_rounds += 1,
                }
                s.agree = s.agree.min(r.agree);
                s.unexplained = s.unexplained.max(r.unexplained);
                s.invalid = s.invalid.max(r.invalid);
            }
        }
        let n = rounds[0].min(rounds[1]);
        if n < o.rounds {
            continue;
        }
        let widest = (0..cells.len())
            .map(|i| Ratio::welch(&times[0][i], &times[1][i], LEVEL).map_or(f64::INFINITY, |r| r.half_width()))
            .fold(0.0, f64::max);
        progress(&format!("{n} rounds a side: widest interval +-{:.1} %", widest * 100.0));
        for (why, done) in [
            ("target", widest <= o.target),
            ("max rounds", n + 2 > o.max_rounds),
            ("time cap", start.elapsed().as_secs_f64() > o.time_cap_s),
        ] {
            if done {
                stopped_by = why;
                break 'rounds;
            }
        }
    }
    let (dir_a, dir_b) = (wa.hits_dir.clone(), wb.hits_dir.clone());
    wa.finish();
    wb.finish();
    // The compilers' output, after the rounds: its compiles would time them otherwise.
    let stats = o.driver_stats.then(|| {
        [("A", &o.a), ("B", &o.b)].map(|(name, side)| {
            progress(&format!("side {name}: driver statistics"));
            compiled::collect(o, name, side, &cells, &tmp.path().join(format!("driver-stats-{name}")))
        })
    });
    let mut out = vec![];
    for (i, c) in cells.into_iter().enumerate() {
        let [ta, tb] = [&times[0][i], &times[1][i]];
        let ratio = Ratio::welch(ta, tb, LEVEL);
        let mut a = worst[0][i].clone();
        let mut b = worst[1][i].clone();
        a.ms = ta.clone();
        b.ms = tb.clone();
        let rays_differing = match c.kind {
            CellKind::Raycast => {
                let read = |d: &Path| crate::rays::read_hits(&d.join(format!("{i}.hits")));
                crate::rays::differing_hits(&read(&dir_a)?, &read(&dir_b)?)
            }
            CellKind::Pathtrace => {
                let image = |d: &Path| d.join(format!("{i}.image"));
                worker::differing_pixels(&image(&dir_a), &image(&dir_b))?
            }
        };
        let compiled = stats.as_ref().and_then(|[sa, sb]| compiled::diff(sa, sb, &c));
        let invocations = o.workload.pipeline_stats.then(|| [counted[0].0[i], counted[1].0[i]]);
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
    reports[0].rounds = rounds[0];
    reports[1].rounds = rounds[1];
    let b = reports.pop().expect("two");
    let a = reports.pop().expect("two");
    Ok(AbReport {
        a,
        b,
        workload: o.workload.args(),
        level: LEVEL,
        threshold: o.threshold,
        target: o.target,
        stopped_by: stopped_by.into(),
        seconds: start.elapsed().as_secs_f64(),
        cells: out,
        driver_stats: stats.as_ref().map(|s| s.clone().map(|x| x.note)),
        pipeline_stats: o.workload.pipeline_stats.then(|| [counted[0].1.clone(), counted[1].1.clone()]),
        driver_stats_rows: stats.map(|s| s.map(|x| x.rows)).unwrap_or_default(),
    })
}

/// The last lines of a worker's stderr, for an error message.
fn tail(stderr: &str) -> String {
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    if lines.is_empty() {
        String::new()
    } else {
        format!("\n{}", lines[lines.len().saturating_sub(8)..].join("\n"))
    }
}

/// Writes `ab.json`, `ab.md` (the text report) and `rows.jsonl` (the `ab` rows) into `dir`,
/// and each side's bench rows into `dir/a/rows.jsonl` and `dir/b/rows.jsonl`.
pub fn write(r: &AbReport, dir: &Path) -> Result<()> {
    crate::harness::results::write_folder(dir, r)?;
    for (pick, sub) in [(0, "a"), (1, "b")] {
        let mut rows = side_rows(r, pick);
        rows.extend(r.driver_stats_rows[pick].iter().cloned());
        Folder::create(&dir.join(sub))?.rows(None, &rows)?;
    }
    Ok(())
}
