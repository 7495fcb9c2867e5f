//! `trilab suite`: what a user runs once on a new device. The devices, the bench (with the peers
//! when given), the paper's study, the accuracy sweep and the profile, each scaled to fit a time
//! budget, then one `summary.md` that links the rest.
//!
//! How the parts are scaled: every part has a ladder of sizes ([`ladder`]), from a smoke size
//! (seconds on lavapipe) to the full one, each with the wall seconds it took on the reference
//! machine (lavapipe on a 2-core Xeon VM, [`REFERENCE`]). A probe (a small bench, timed on the
//! wall clock with its validation) measures how fast this device and host are against that
//! machine; a part's predicted time at a size is the reference time scaled by that factor. The
//! parts run in a fixed order (bench, study, accuracy, profile), each taking the largest size whose
//! prediction fits its share of the budget left ([`Part::weight`]); after each part the factor is
//! corrected by how far the prediction missed, so a slow host shrinks the parts that follow. A
//! part's smallest size always runs, even over budget, so the summary never lacks a section. Every
//! part validates its hits against the f64 reference before it reports, as the commands do.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use serde::Serialize;

use crate::commands::{accuracy, bench, devices, profile, study};
use crate::encoding::{Layout, Method};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::matrix::KernelAxes;
use crate::named::{named_enum, Named};
use crate::report::{Report, Table};
use crate::services::calibration;
use crate::services::provenance::Provenance;
use crate::services::rayset::RaySetSizes;
use crate::services::results::Folder;
use crate::timeline;

named_enum! {
    /// A part of the suite.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Part: "suite part" {
        /// `trilab bench`: Mrays/s per scene, ray set, method and layout (and the peers).
        Bench = "bench",
        /// `trilab study`: the paper's study and its claims.
        Study = "study",
        /// `trilab accuracy`: leaks, errors and the speed/accuracy frontier.
        Accuracy = "accuracy",
        /// `trilab profile`: timestamps, pipeline statistics, clocks, sizes, driver statistics.
        Profile = "profile",
    }
}

impl Part {
    /// Its share of the budget, relative to the others that are left.
    pub fn weight(self) -> f64 {
        match self {
            Part::Bench => 0.25,
            Part::Study => 0.45,
            Part::Accuracy => 0.18,
            Part::Profile => 0.12,
        }
    }

    /// Its section's title in the summary.
    pub fn title(self) -> &'static str {
        match self {
            Part::Bench => "Speed (bench)",
            Part::Study => "The paper's claims (study)",
            Part::Accuracy => "Speed and accuracy (accuracy)",
            Part::Profile => "Kernels (profile)",
        }
    }
}

/// One size of a part.
#[derive(Clone, Debug)]
pub struct Size {
    pub name: &'static str,
    /// Wall seconds on the reference machine ([`REFERENCE`]).
    pub reference_s: f64,
    /// Whether `reference_s` was measured (true) or extrapolated from a smaller size by its work.
    pub measured: bool,
    pub options: PartOptions,
}

/// The options of one part at one size.
#[derive(Clone, Debug)]
pub enum PartOptions {
    Bench(Box<bench::BenchOptions>),
    Study(Box<study::StudyOptions>),
    Accuracy(Box<accuracy::AccuracyOptions>),
    Profile(Box<profile::ProfileOptions>),
}

/// The machine the ladders' seconds were measured on.
pub const REFERENCE: &str = "llvmpipe (LLVM 15.0.6, 256 bits), Mesa 25.0.7, 2-core Xeon VM shared with other work";

/// The probe's wall seconds on the reference machine.
pub const PROBE_REFERENCE_S: f64 = 0.4;

/// The probe: the bunny, the paper's methods, a small camera, three timed rounds.
pub fn probe_options() -> bench::BenchOptions {
    bench::BenchOptions {
        scenes: vec![PathBuf::from("bunny")],
        axes: KernelAxes { methods: Method::paper(), ..Default::default() },
        repeat: 3,
        sizes: RaySetSizes { width: 160, height: 120, diffuse_per_hit: 1, random_rays: 20_000, ..Default::default() },
        ray_query: false,
        ray_tracing_pipeline: false,
        ..Default::default()
    }
}

fn bench_size(scenes: &[&str], w: u32, h: u32, diffuse: u32, random: usize, repeat: usize) -> bench::BenchOptions {
    bench::BenchOptions {
        scenes: scenes.iter().map(PathBuf::from).collect(),
        axes: KernelAxes { methods: Method::ALL.to_vec(), ..Default::default() },
        repeat,
        sizes: RaySetSizes { width: w, height: h, diffuse_per_hit: diffuse, random_rays: random, ..Default::default() },
        ..Default::default()
    }
}

fn study_size(scenes: &[&str], w: u32, h: u32, spp: u32, random: usize, repeat: usize) -> study::StudyOptions {
    let base = study::StudyOptions::preset(study::Preset::Lavapipe);
    study::StudyOptions {
        scenes: scenes.iter().map(PathBuf::from).collect(),
        width: w,
        height: h,
        spp,
        ray_width: w,
        ray_height: h,
        diffuse_per_hit: if w < 200 { 1 } else { base.diffuse_per_hit },
        random_rays: random,
        repeat,
        ..base
    }
}

/// The sizes of `part`, smallest first. The reference seconds of the larger sizes of the study
/// and the bench are extrapolated from the measured ones by their work (rays traced).
pub fn ladder(part: Part) -> Vec<Size> {
    let all = ["bunny", "dragon", "buddha"];
    match part {
        Part::Bench => vec![
            Size {
                name: "smoke: bunny, 160x120 camera, 20k random rays, 5 rounds",
                reference_s: 1.0,
                measured: true,
                options: PartOptions::Bench(Box::new(bench_size(&["bunny"], 160, 120, 1, 20_000, 5))),
            },
            Size {
                name: "bunny, 400x300 camera, 2 diffuse per hit, 200k random rays, 3 rounds",
                reference_s: 4.0,
                measured: true,
                options: PartOptions::Bench(Box::new(bench_size(&["bunny"], 400, 300, 2, 200_000, 3))),
            },
            Size {
                name: "bunny, dragon, buddha, 400x300 camera, 2 diffuse per hit, 200k random rays, 3 rounds",
                reference_s: 25.0,
                measured: false,
                options: PartOptions::Bench(Box::new(bench_size(&all, 400, 300, 2, 200_000, 3))),
            },
            Size {
                name: "bunny, dragon, buddha, 800x600 camera, 8 diffuse per hit, 1M random rays, 5 rounds, \
                       layouts bvh2, bvh4, bvh8, cwbvh, qbvh4",
                reference_s: 900.0,
                measured: false,
                options: PartOptions::Bench(Box::new({
                    let mut b = bench_size(&all, 800, 600, 8, 1_000_000, 5);
                    b.axes.layouts = Layout::ALL.to_vec();
                    b
                })),
            },
        ],
        Part::Study => vec![
            Size {
                name: "smoke: bunny, 48x36 at 2 spp, leaf 1-16, 3 rounds",
                reference_s: 2.0,
                measured: true,
                options: PartOptions::Study(Box::new(study::StudyOptions {
                    repeat: 3,
                    ..study::StudyOptions::preset(study::Preset::Smoke)
                })),
            },
            Size {
                name: "bunny, 100x75 at 4 spp, leaf 1-16, 3 rounds",
                reference_s: 5.0,
                measured: true,
                options: PartOptions::Study(Box::new(study_size(&["bunny"], 100, 75, 4, 20_000, 3))),
            },
            Size {
                name: "bunny, dragon, buddha, 100x75 at 4 spp, leaf 1-16, 3 rounds",
                reference_s: 40.0,
                measured: false,
                options: PartOptions::Study(Box::new(study_size(&all, 100, 75, 4, 20_000, 3))),
            },
            Size {
                name: "bunny, dragon, buddha, 200x150 at 8 spp, leaf 1-16, 3 rounds",
                reference_s: 200.0,
                measured: false,
                options: PartOptions::Study(Box::new(study_size(&all, 200, 150, 8, 100_000, 3))),
            },
            Size {
                name: "the lavapipe preset: bunny, dragon, buddha, 400x300 at 16 spp, leaf 1-16, 3 rounds",
                reference_s: 1200.0,
                measured: true,
                options: PartOptions::Study(Box::new(study::StudyOptions::preset(study::Preset::Lavapipe))),
            },
            Size {
                name: "the paper's: bunny, dragon, buddha, 800x600 at 500 spp, leaf 1-16, 5 rounds",
                reference_s: 1200.0 * 125.0 * 5.0 / 3.0,
                measured: false,
                options: PartOptions::Study(Box::new(study::StudyOptions::preset(study::Preset::Paper))),
            },
        ],
        Part::Accuracy => vec![
            Size {
                name: "smoke: the paper's methods, 2k leak rays, no fine meshes",
                reference_s: 1.0,
                measured: true,
                options: PartOptions::Accuracy(Box::new(accuracy::AccuracyOptions::preset(accuracy::Preset::Smoke))),
            },
            Size {
                name: "full: every method, 400k leak rays, fine meshes, the bunny's frontier at 800x600",
                reference_s: 240.0,
                measured: true,
                options: PartOptions::Accuracy(Box::new(accuracy::AccuracyOptions::preset(accuracy::Preset::Full))),
            },
        ],
        Part::Profile => vec![
            Size {
                name: "smoke: bunny, every method, 160x120 camera, 20k random rays, workgroup 64, 5 rounds",
                reference_s: 3.0,
                measured: true,
                options: PartOptions::Profile(Box::new(profile::ProfileOptions {
                    sizes: RaySetSizes {
                        width: 160,
                        height: 120,
                        diffuse_per_hit: 1,
                        random_rays: 20_000,
                        ..Default::default()
                    },
                    repeat: 5,
                    workgroup_sizes: vec![64],
                    command: "trilab suite (profile, smoke size)".into(),
                    ..Default::default()
                })),
            },
            Size {
                name: "full: bunny, every method, 800x600 camera, 250k random rays, workgroups 32-256, 5 rounds",
                reference_s: 60.0,
                measured: true,
                options: PartOptions::Profile(Box::new(profile::ProfileOptions {
                    command: "trilab suite (profile, full size)".into(),
                    ..Default::default()
                })),
            },
        ],
    }
}

#[derive(Clone, Debug)]
pub struct SuiteOptions {
    pub budget_minutes: f64,
    pub out: PathBuf,
    pub parts: Vec<Part>,
    /// Embree and tinybvh peer executables for the bench.
    pub embree: Option<PathBuf>,
    pub tinybvh: Option<PathBuf>,
    /// The trilab executable, for the profile's LP_NUM_THREADS section (`None`: skipped).
    pub exe: Option<PathBuf>,
    /// How the profile collects the driver's statistics (`None`: skipped).
    pub driver_stats: Option<crate::services::driver_stats::CollectOptions>,
    /// Run every part at this ladder step (0 = smoke) whatever the budget: for measuring the
    /// ladders themselves.
    pub force_size: Option<usize>,
    /// Node layouts for the bench and the study (empty: each part's own, `bvh2`): every method
    /// runs on each, and a size's predicted time grows by their number.
    pub layouts: Vec<Layout>,
}

/// `ladder` with the bench's and the study's sizes set to run on `layouts` (none: as they are),
/// their reference times scaled by how many there are.
pub fn with_layouts(mut ladder: Vec<Size>, layouts: &[Layout]) -> Vec<Size> {
    if layouts.is_empty() {
        return ladder;
    }
    for size in &mut ladder {
        let before = match &mut size.options {
            PartOptions::Bench(b) => std::mem::replace(&mut b.axes.layouts, layouts.to_vec()).len(),
            PartOptions::Study(s) => std::mem::replace(&mut s.layouts, layouts.to_vec()).len(),
            PartOptions::Accuracy(_) | PartOptions::Profile(_) => continue,
        };
        size.reference_s *= layouts.len() as f64 / before.max(1) as f64;
    }
    ladder
}

/// How one part was scaled and what it took.
#[derive(Clone, Debug, Serialize)]
pub struct PartRun {
    pub part: Part,
    /// Its step on the ladder (0 = smoke) and the ladder's length.
    pub size: usize,
    pub sizes: usize,
    pub description: String,
    /// Its share of the budget left when it started, seconds.
    pub share_s: f64,
    pub predicted_s: f64,
    /// Whether the size's reference time was measured (else extrapolated by its work).
    pub reference_measured: bool,
    pub took_s: f64,
    /// The host calibration around it (`services::calibration`): ms per pass of the fixed CPU
    /// workload, median of the passes just before and just after it.
    pub calibration_ms: f64,
    /// The files it wrote, relative to the suite's folder.
    pub files: Vec<String>,
    /// Why it stopped, where it could not run on this device (a driver without a feature it
    /// needs, a result that failed validation): the other parts still ran, and the summary says
    /// this in the part's section.
    pub failed: Option<String>,
}

/// What a suite run has written so far, kept up to date by [`run`] so that a run stopped part-way
/// (`trilab suite` on Ctrl-C or SIGTERM) can say what it leaves behind.
#[derive(Clone, Debug, Default)]
pub struct Kept {
    /// The suite's folder; empty until the run starts writing.
    pub out: PathBuf,
    /// Whether devices.txt and devices.json are written.
    pub devices: bool,
    /// The parts finished, in order, each with whether it completed (else it failed, and would
    /// have had a section saying why).
    pub done: Vec<(Part, bool)>,
    /// The part under way.
    pub running: Option<Part>,
    /// Whether summary.md and suite.json are written (the run is over).
    pub summary: bool,
}

impl Kept {
    /// One paragraph: what is in the folder, what is not, and what to run for the rest.
    pub fn describe(&self) -> String {
        if self.out.as_os_str().is_empty() {
            return "nothing was written yet".into();
        }
        let dir = self.out.display();
        if self.summary {
            return format!("every part ran; {dir}/summary.md and suite.json are written");
        }
        let mut s = format!("kept in {dir}:");
        if self.devices {
            s += " devices.txt and devices.json;";
        }
        let list = |ok: bool| -> Vec<String> {
            self.done.iter().filter(|(_, c)| *c == ok).map(|(p, _)| format!("{p} ({dir}/{p})")).collect()
        };
        let (completed, failed) = (list(true), list(false));
        s += &match completed.is_empty() {
            true => " no part completed".into(),
            false => format!(" completed parts: {}", completed.join(", ")),
        };
        if !failed.is_empty() {
            s += &format!("; parts that failed: {}", failed.join(", "));
        }
        match self.running {
            Some(p) => s += &format!("; stopped during {p}: {dir}/{p} holds only what it wrote so far"),
            None if self.done.is_empty() => {
                s += "; stopped before the first part (during the calibration or the probe)"
            }
            None => {}
        }
        s + ". summary.md and suite.json are written only when every part has run: not written. The parts' own \
             reports are in their folders; `trilab <part>` runs a missing one alone."
    }
}

/// The probe that calibrates the predictions.
#[derive(Clone, Debug, Serialize)]
pub struct Probe {
    pub seconds: f64,
    pub reference_s: f64,
    /// Seconds here per reference second, before the corrections.
    pub factor: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct SuiteReport {
    pub provenance: Provenance,
    pub budget_minutes: f64,
    pub reference: &'static str,
    pub probe: Probe,
    pub parts: Vec<PartRun>,
    /// The headline speed table, the claims, the frontier: the summary's sections in Markdown.
    pub sections: Vec<(String, String)>,
    pub seconds: f64,
    pub out: PathBuf,
}

/// `suite.json` and `summary.md`; the parts' rows are in their folders.
impl crate::services::results::Results for SuiteReport {
    const STEM: &'static str = "suite";

    fn markdown_file() -> String {
        "summary.md".into()
    }

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        summary(self)
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        None
    }
}

impl Report for SuiteReport {
    fn to_text(&self) -> String {
        let mut s = format!(
            "suite on {} ({}), budget {:.1} min, took {:.1} min\n\n{}",
            self.provenance.device,
            self.provenance.driver,
            self.budget_minutes,
            self.seconds / 60.0,
            scaling_table(self).to_text()
        );
        s += &format!("\nsummary: {}\n", self.out.join("summary.md").display());
        s
    }
}

fn scaling_table(r: &SuiteReport) -> Table {
    let mut t = Table::new(["part", "size", "what", "share s", "predicted s", "took s", "host calibration ms"]);
    for p in &r.parts {
        t.row([
            p.part.to_string(),
            format!("{} of {}", p.size + 1, p.sizes),
            p.description.clone(),
            format!("{:.0}", p.share_s),
            format!("{:.0}{}", p.predicted_s, if p.reference_measured { "" } else { " (extrapolated)" }),
            format!("{:.0}{}", p.took_s, if p.failed.is_some() { " (did not complete)" } else { "" }),
            format!("{:.1}", p.calibration_ms),
        ]);
    }
    t
}

/// Checks the options before any work.
pub fn check(o: &SuiteOptions) -> Result<()> {
    if !(o.budget_minutes.is_finite() && o.budget_minutes > 0.0) {
        return Err(Error::Usage(format!(
            "--budget-minutes {}: expected a positive number of minutes",
            o.budget_minutes
        )));
    }
    if o.parts.is_empty() {
        return Err(Error::Usage("--parts: name at least one part".into()));
    }
    for p in [&o.embree, &o.tinybvh].into_iter().flatten() {
        if !p.is_file() {
            return Err(Error::bad_input(p, None, "peer executable not found"));
        }
    }
    Ok(())
}

/// The step of `ladder` to run with `share_s` seconds at `factor` seconds per reference second:
/// the largest that fits, or the smallest.
pub fn choose(ladder: &[Size], share_s: f64, factor: f64) -> usize {
    ladder.iter().rposition(|s| s.reference_s * factor <= share_s).unwrap_or(0)
}

/// Runs the suite into `o.out`: devices, the probe, every part, then summary.md. `kept` follows
/// what is written ([`Kept`]), for whoever stops the run part-way.
pub fn run(ctx: &Context, o: &SuiteOptions, kept: &Mutex<Kept>, mut progress: impl FnMut(&str)) -> Result<SuiteReport> {
    check(o)?;
    let keep = |f: &dyn Fn(&mut Kept)| f(&mut kept.lock().unwrap_or_else(|e| e.into_inner()));
    let start = Instant::now();
    let budget_s = o.budget_minutes * 60.0;
    let mut folder = Folder::create(&o.out)?;
    keep(&|k| k.out = o.out.clone());
    write_devices(&mut folder)?;
    keep(&|k| k.devices = true);

    // The host's speed without the driver, measured before the probe and after every part: a
    // part's timings are calibrated by the points on either side of it (`trilab compare`).
    progress("calibration: a fixed CPU workload, the host's speed without the driver");
    let workload = calibration::Workload::new();
    let mut point = calibrate(&workload);
    let mut calibration_rows = vec![];

    let probe = run_probe(ctx, &mut progress)?;
    let mut factor = probe.factor;

    let mut parts = vec![];
    let mut sections = vec![];
    let todo: Vec<Part> = Part::ALL.iter().copied().filter(|p| o.parts.contains(p)).collect();
    for (i, &part) in todo.iter().enumerate() {
        let left_s = (budget_s - start.elapsed().as_secs_f64()).max(0.0);
        let weights: f64 = todo[i..].iter().map(|p| p.weight()).sum();
        let share_s = left_s * part.weight() / weights;
        let ladder = with_layouts(ladder(part), &o.layouts);
        let size = o.force_size.map(|s| s.min(ladder.len() - 1)).unwrap_or_else(|| choose(&ladder, share_s, factor));
        let predicted_s = ladder[size].reference_s * factor;
        // The part's span opens before its line is printed: a run stopped once the line is out
        // has the part in its trace.
        let span = part_span(part, &ladder[size], size, share_s, predicted_s);
        keep(&|k| k.running = Some(part));
        progress(&format!("{part}: {} (predicted {predicted_s:.0} s of a {share_s:.0} s share)", ladder[size].name));
        let t = Instant::now();
        let dir = o.out.join(part.to_string());
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        let (section, failed) = run_part_or_say_why(ctx, o, part, &ladder[size].options, &dir, t, &mut progress);
        keep(&|k| {
            k.running = None;
            k.done.push((part, failed.is_none()));
        });
        let files = part_files(&dir)?;
        let took_s = t.elapsed().as_secs_f64();
        span.arg("took_s", took_s);
        span.arg("completed", failed.is_none());
        drop(span);
        let after = calibrate(&workload);
        let calibration = calibration::row(&part.to_string(), &point, &after, &Provenance::of(ctx).source());
        let calibration_ms = calibration.figures["cpu_ms"].median;
        calibration_rows.push(calibration);
        point = after;
        // Correct the factor by how far this prediction missed (halfway, so one noisy part
        // does not swing the rest).
        if predicted_s > 0.0 {
            factor *= (took_s / predicted_s).sqrt();
        }
        parts.push(PartRun {
            part,
            size,
            sizes: ladder.len(),
            description: part_description(&ladder[size], &o.layouts),
            share_s,
            predicted_s,
            reference_measured: ladder[size].measured,
            took_s,
            calibration_ms,
            files: files.iter().map(|f| f.strip_prefix(&o.out).unwrap_or(f).display().to_string()).collect(),
            failed,
        });
        sections.push((section.0, section.1));
    }
    let writing = timeline::span("report", "summary and suite.json");
    Folder::create(&o.out.join(calibration::COMMAND))?.rows(None, &calibration_rows)?;
    let report = SuiteReport {
        provenance: Provenance::of(ctx),
        budget_minutes: o.budget_minutes,
        reference: REFERENCE,
        probe,
        parts,
        sections,
        seconds: start.elapsed().as_secs_f64(),
        out: o.out.clone(),
    };
    folder.results(&report)?;
    drop(writing);
    keep(&|k| k.summary = true);
    Ok(report)
}

/// `trilab devices` into the suite's folder, as text and JSON.
fn write_devices(folder: &mut Folder) -> Result<()> {
    let devices = devices::run()?;
    folder.put("devices.txt", devices.to_text())?;
    folder.put("devices.json", devices.to_json())?;
    Ok(())
}

/// A part's span, with the size it runs at, its share of the budget and the time predicted.
fn part_span(part: Part, step: &Size, size: usize, share_s: f64, predicted_s: f64) -> timeline::Span {
    let span = timeline::span_with("part", || format!("part {part}"));
    if span.records() {
        span.arg("size", step.name);
        span.arg("size_step", size);
        span.arg("share_s", share_s);
        span.arg("predicted_s", predicted_s);
    }
    span
}

/// One point of the host's speed without the driver, in a span of its own.
fn calibrate(workload: &calibration::Workload) -> calibration::Point {
    let calibrating = timeline::span("calibration", "calibration (fixed CPU workload)");
    let point = workload.measure();
    drop(calibrating);
    point
}

/// The probe: a small bench timed against its reference seconds, the factor that scales every
/// part to the budget.
fn run_probe(ctx: &Context, progress: &mut impl FnMut(&str)) -> Result<Probe> {
    let probing = timeline::span("part", "probe (a small bench)").with("reference_s", PROBE_REFERENCE_S);
    progress("probe: a small bench to scale the parts to the budget");
    let t = Instant::now();
    bench::run(ctx, &probe_options(), |_| {})?;
    let probe_s = t.elapsed().as_secs_f64();
    probing.arg("took_s", probe_s);
    drop(probing);
    Ok(Probe { seconds: probe_s, reference_s: PROBE_REFERENCE_S, factor: probe_s / PROBE_REFERENCE_S })
}

/// Runs one part into `dir`: its section and, where it failed, why. A part that cannot run here
/// (seen: the driver statistics on Mesa 22.3.6) is reported in its section; the rest of the
/// suite still runs and is summarised.
fn run_part_or_say_why(
    ctx: &Context,
    o: &SuiteOptions,
    part: Part,
    options: &PartOptions,
    dir: &Path,
    t: Instant,
    progress: &mut impl FnMut(&str),
) -> ((String, String), Option<String>) {
    match run_part(ctx, o, options, dir, progress) {
        Ok(section) => (section, None),
        Err(e) => {
            progress(&format!("{part} failed: {e}"));
            let why = e.to_string();
            let section = (
                format!("{} (did not complete)", part.title()),
                format!("`trilab {part}` stopped on this device after {:.0} s: {why}\n", t.elapsed().as_secs_f64()),
            );
            (section, Some(why))
        }
    }
}

/// Every file the part left in its folder (the profile's heat maps and every rows.jsonl
/// included), not only those its writer returned; sorted.
fn part_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    Ok(files)
}

/// The size a part ran at, in words: with `--layouts`, the layouts bench and study ran on.
fn part_description(step: &Size, layouts: &[Layout]) -> String {
    match (&step.options, layouts.is_empty()) {
        (PartOptions::Bench(_) | PartOptions::Study(_), false) => format!(
            "{}; on the layouts {} (--layouts)",
            step.name,
            layouts.iter().map(|l| l.to_string()).collect::<Vec<_>>().join(", ")
        ),
        _ => step.name.to_owned(),
    }
}

/// Runs one part into `dir`: its summary section (title, Markdown).
fn run_part(
    ctx: &Context,
    o: &SuiteOptions,
    options: &PartOptions,
    dir: &Path,
    progress: &mut impl FnMut(&str),
) -> Result<(String, String)> {
    let mut note = |m: &str| progress(&format!("  {m}"));
    match options {
        PartOptions::Bench(b) => {
            let mut b = (**b).clone();
            b.axes.methods = crate::conditioning::available_methods(&ctx.capabilities())
                .into_iter()
                .filter(|m| b.axes.methods.contains(m))
                .collect();
            // The driver peers as `trilab bench`'s `auto`: on wherever the device is not a CPU.
            b.ray_query = !ctx.capabilities().is_cpu();
            b.ray_tracing_pipeline = b.ray_query;
            b.embree = o.embree.clone();
            b.tinybvh = o.tinybvh.clone();
            let r = bench::run(ctx, &b, &mut note)?;
            let (json, md) = (dir.join("bench.json"), dir.join("bench.md"));
            let _span = timeline::span("report", "report writing");
            r.write(Some(&json), Some(&md))?;
            Ok((Part::Bench.title().into(), bench_section(&r, "bench/bench.md")))
        }
        PartOptions::Study(s) => {
            let r = study::run(ctx, s, &mut note)?;
            let _span = timeline::span("report", "report writing");
            study::write(&r, dir)?;
            Ok((Part::Study.title().into(), study_section(&r)))
        }
        PartOptions::Accuracy(a) => {
            let mut a = (**a).clone();
            a.methods = crate::conditioning::available_methods(&ctx.capabilities())
                .into_iter()
                .filter(|m| a.methods.contains(m))
                .collect();
            let r = accuracy::run(ctx, &a, &mut note)?;
            let _span = timeline::span("report", "report writing");
            accuracy::write(&r, dir)?;
            Ok((Part::Accuracy.title().into(), accuracy_section(&r)))
        }
        PartOptions::Profile(p) => {
            let mut p = (**p).clone();
            p.methods = crate::conditioning::available_methods(&ctx.capabilities());
            p.exe = o.exe.clone();
            p.driver_stats = o.driver_stats.clone();
            p.sizes.require_all()?;
            let r = profile::run(ctx, &p, Some(dir), &mut note)?;
            let _span = timeline::span("report", "report writing");
            profile::write(&r, dir)?;
            Ok((Part::Profile.title().into(), profile_section(&r)))
        }
    }
}

/// The profile's link, then the sections this driver could not measure and why (Debian 12's own
/// lavapipe, Mesa 22.3.6, has no driver statistics; no lavapipe has executable properties).
fn profile_section(r: &profile::ProfileReport) -> String {
    let mut out = "Timestamps, pipeline statistics, shader clocks, executable and driver statistics, subgroup and \
                   workgroup sizes per kernel: [profile/profile.md](profile/profile.md).\n"
        .to_owned();
    let missing = r.not_measured();
    if !missing.is_empty() {
        out.push_str("\nNot measured on this driver:\n\n");
        for (title, status, note) in missing {
            let word = if status == profile::Status::Unsupported { "unsupported" } else { "not applicable" };
            out.push_str(&format!("- {title} ({word}): {note}\n"));
        }
    }
    out
}

/// The headline speed table: per scene and ray set, the fastest validated method (and layout),
/// beside the paper's Möller-Trumbore on the binary tree; the peers' target when they ran.
fn bench_section(r: &bench::BenchReport, link: &str) -> String {
    use bench::Tracer;
    let mut t = Table::new(["scene", "set", "rays", "fastest", "Mrays/s (min-max)", "mt bvh2 Mrays/s", "agreement"]);
    let mut keys: Vec<(String, crate::services::rayset::RaySet)> = vec![];
    for row in &r.rows {
        if !keys.iter().any(|(s, set)| *s == row.scene && *set == row.ray_set) {
            keys.push((row.scene.clone(), row.ray_set));
        }
    }
    for (scene, set) in keys {
        let ours =
            || r.rows.iter().filter(|x| x.scene == scene && x.ray_set == set && matches!(x.method, Tracer::Method(_)));
        let Some(best) = ours().max_by(|a, b| a.mrays_per_s.total_cmp(&b.mrays_per_s)) else { continue };
        let mt = ours()
            .find(|x| x.method == Tracer::Method(Method::Mt) && x.layout.unwrap_or(Layout::DEFAULT) == Layout::DEFAULT)
            .map(|x| format!("{:.2}", x.mrays_per_s))
            .unwrap_or_else(|| "-".into());
        let layout = best.layout.map(|l| format!(" {l}")).unwrap_or_default();
        t.row([
            scene.clone(),
            set.to_string(),
            best.rays.to_string(),
            format!("{}{layout}", best.method),
            format!("{:.2} ({:.2}-{:.2})", best.mrays_per_s, best.mrays_per_s_min, best.mrays_per_s_max),
            mt,
            format!("{:.6}", best.agreement),
        ]);
    }
    let mut s = format!("{}\n\n{}", r.header(), t.to_markdown());
    if !r.peers.is_empty() {
        s += &format!(
            "\nSpeed target (trilab / peer). {}\n\n{}",
            crate::services::peer_report::target_note(),
            crate::services::peer_report::target_table(&r.peers).to_markdown()
        );
    }
    s + &format!("\nEvery row of every method and layout: [{link}]({link}).\n")
}

fn study_section(r: &study::StudyReport) -> String {
    let claims = study::claims::all(r);
    format!(
        "{}\n\n{}\nThe study's tables, plots and every cell: [study/study.md](study/study.md).\n",
        r.scaling,
        study::claims::verdicts_table(r, &claims).to_markdown()
    )
}

fn accuracy_section(r: &accuracy::AccuracyReport) -> String {
    format!(
        "The speed/accuracy frontier: each method's speed on the bunny beside its leaks and \
         errors.\n\n{}\nLeaks, false hits, errors, self-intersection and extremes: \
         [accuracy/accuracy.md](accuracy/accuracy.md).\n",
        accuracy::table::frontier_table(r).to_markdown()
    )
}

/// summary.md: the device and driver, how the parts were scaled, each part's headline, links.
pub fn summary(r: &SuiteReport) -> String {
    let p = &r.provenance;
    let mut md = format!(
        "# trilab suite: {}\n\nDevice **{}**, driver {}, commit {}, {}; host {}{}.\n\nBudget {:.1} minutes; \
         the suite took {:.1} minutes.\n\n",
        p.device,
        p.device,
        p.driver,
        p.commit,
        p.date,
        p.host.label(),
        p.settings.iter().map(|(k, v)| format!(", {k}={v}")).collect::<String>(),
        r.budget_minutes,
        r.seconds / 60.0
    );
    md += &format!(
        "## How the parts were scaled\n\nA probe (the bunny, the paper's methods, a 160x120 camera, 3 rounds, \
         validated) took {:.1} s here against {:.1} s on the reference machine ({}): {:.2} s here per reference \
         second. Each part took the largest size whose reference time times that factor fits its share of the \
         budget left (bench 25 %, study 45 %, accuracy 18 %, profile 12 %), the factor corrected after each part \
         by how far its prediction missed. The host calibration (a fixed CPU workload that does not go \
         through the driver, [calibration/rows.jsonl](calibration/rows.jsonl)) was measured before the probe and \
         after every part: it is how `trilab compare` takes the host's speed and load out of two runs' timings.\n\n{}\n",
        r.probe.seconds,
        r.probe.reference_s,
        r.reference,
        r.probe.factor,
        scaling_table(r).to_markdown()
    );
    for (title, body) in &r.sections {
        md += &format!("## {title}\n\n{body}\n");
    }
    md += "## Files\n\n- [devices.txt](devices.txt): every Vulkan device and its driver\n";
    for part in &r.parts {
        for f in &part.files {
            md += &format!("- [{f}]({f})\n");
        }
    }
    md += "\nEvery part writes `rows.jsonl` beside its files: `trilab compare BASE NEW` gates a change on them, \
           `trilab merge` joins runs of many devices.\n";
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What a stopped suite says it kept (issue 24: it said nothing).
    #[test]
    fn a_stopped_suite_names_what_it_kept() {
        assert_eq!(Kept::default().describe(), "nothing was written yet");
        let mut k = Kept { out: PathBuf::from("/r/suite"), devices: true, ..Kept::default() };
        let d = k.describe();
        assert!(
            d.contains("/r/suite") && d.contains("no part completed") && d.contains("before the first part"),
            "{d}"
        );
        k.done = vec![(Part::Bench, true), (Part::Study, false)];
        k.running = Some(Part::Accuracy);
        let d = k.describe();
        assert!(d.contains("completed parts: bench (/r/suite/bench)"), "{d}");
        assert!(d.contains("failed: study (/r/suite/study)"), "{d}");
        assert!(d.contains("stopped during accuracy: /r/suite/accuracy holds only"), "{d}");
        assert!(d.contains("summary.md") && d.contains("not written"), "{d}");
        k.summary = true;
        assert!(k.describe().starts_with("every part ran"));
    }

    #[test]
    fn ladders_grow_and_the_chosen_size_fits_its_share() {
        for &part in Part::ALL {
            let l = ladder(part);
            assert!(l.len() >= 2, "{part}");
            assert!(l.windows(2).all(|w| w[0].reference_s < w[1].reference_s), "{part}: sizes must grow");
            assert!(l[0].measured, "{part}: the smoke size's time must be measured");
            for (share, factor) in [(1.0, 1.0), (100.0, 0.5), (1e4, 2.0), (1e7, 1.0), (60.0, 0.01)] {
                let i = choose(&l, share, factor);
                if i > 0 {
                    assert!(l[i].reference_s * factor <= share, "{part}: step {i} exceeds {share} s");
                }
                if let Some(next) = l.get(i + 1) {
                    assert!(next.reference_s * factor > share, "{part}: step {} would fit {share} s", i + 1);
                }
            }
        }
        assert_eq!(choose(&ladder(Part::Study), 0.0, 1.0), 0, "nothing fits: the smoke size");
    }

    #[test]
    fn every_size_passes_its_commands_checks() {
        for &part in Part::ALL {
            for s in ladder(part) {
                if let PartOptions::Study(o) = &s.options {
                    o.check().unwrap_or_else(|e| panic!("{}: {e}", s.name));
                }
            }
        }
        let bad = SuiteOptions {
            budget_minutes: 0.0,
            out: "x".into(),
            parts: Part::ALL.to_vec(),
            embree: None,
            tinybvh: None,
            exe: None,
            driver_stats: None,
            force_size: None,
            layouts: vec![],
        };
        assert!(check(&bad).unwrap_err().to_string().contains("--budget-minutes"));
        let missing = SuiteOptions { budget_minutes: 1.0, embree: Some("/nonexistent/embree".into()), ..bad };
        assert!(check(&missing).unwrap_err().to_string().contains("/nonexistent/embree"));
    }

    /// `--layouts` sets the bench's and the study's layouts at every size and scales their
    /// reference times by how many there are; accuracy and profile are left as they are.
    #[test]
    fn layouts_scale_the_bench_and_the_study() {
        let three = [Layout::Bvh2, Layout::Bvh4, Layout::Cwbvh];
        for &part in Part::ALL {
            let plain = ladder(part);
            let wide = with_layouts(ladder(part), &three);
            assert_eq!(plain.len(), wide.len());
            for (p, w) in plain.iter().zip(&wide) {
                // The size's own layouts (none given: the binary tree alone).
                let before = match &p.options {
                    PartOptions::Bench(b) => b.axes.layouts.len().max(1) as f64,
                    PartOptions::Study(s) => s.layouts.len().max(1) as f64,
                    _ => 1.0,
                };
                let scaled = p.reference_s * 3.0 / before;
                match &w.options {
                    PartOptions::Bench(b) => assert_eq!(b.axes.layouts, three),
                    PartOptions::Study(s) => assert_eq!(s.layouts, three),
                    _ => {
                        assert_eq!(w.reference_s, p.reference_s, "{}", w.name);
                        continue;
                    }
                }
                assert!((w.reference_s - scaled).abs() < 1e-9 * scaled, "{}: {} vs {scaled}", w.name, w.reference_s);
            }
        }
        assert_eq!(with_layouts(ladder(Part::Study), &[]).len(), ladder(Part::Study).len());
    }
}
