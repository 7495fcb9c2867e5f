//! One side of `trilab ab`: a child process with that side's driver environment, which loads
//! the workload once (scenes, BVHs, ray sets, the f64 reference's hits, kernels; one untimed
//! warm-up of every cell) and then times one round of every cell each time the parent asks.
//! A driver is loaded once per process, so each side needs its own.
//!
//! The protocol is JSON lines: the worker prints [`Message::Ready`] (its protocol version,
//! provenance and cells), then reads one command a line on stdin and answers it with
//! [`Message::Round`]: `round` times every cell once, `cell N` (protocol 2) times cell N once;
//! `quit` ends it. Any failure is [`Message::Failed`] and the end of the process. Each cell's
//! first timed run writes its hits to `<hits_dir>/<cell index>.hits` (a path-trace cell its
//! image), so the parent can compare the sides ray by ray.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::agreement::compare_closest;
use crate::bvh::BuildOptions;
use crate::commands::bench::{path_of, BenchCell, CellTracer};
use crate::encoding::{Layout, Method, Raycast, SceneAccess, Traversal};
use crate::error::{Error, Result};
use crate::gpu::{Context, Kernel, RaycastOptions};
use crate::pipeline::{DeviceScene, HostScene, SceneRequest};
use crate::rays::{self, Ray};
use crate::reference::RefHit;
use crate::render::{render, KernelChoice, RenderResult, RenderSettings, RenderTarget};
use crate::scene::{load_obj, Mesh};
use crate::services::driver_stats::dispatch::dispatch_once;
use crate::services::provenance::Provenance;
use crate::services::rayset::{ray_sets, RaySet, RaySetSizes};
use crate::services::render_measure::{bench_settings, check_image_mean, summarise_renders};
use crate::services::validate::MIN_AGREEMENT;

/// What both sides run: bench cells (scenes x ray sets x methods x layouts). The parent gives
/// it to each worker as command-line options ([`Workload::args`]), in the bench vocabulary.
#[derive(Clone, Debug, PartialEq)]
pub struct Workload {
    pub scenes: Vec<PathBuf>,
    pub methods: Vec<Method>,
    pub layouts: Vec<Layout>,
    /// How the kernels walk the tree; a (method, layout, traversal) with no kernel is left out.
    pub traversals: Vec<Traversal>,
    pub sets: Vec<RaySet>,
    pub sizes: RaySetSizes,
    /// The BVH every cell's encoding shares (`--leaf-size`; the tree shape is the default one).
    pub build: BuildOptions,
    pub scene_access: SceneAccess,
    pub batch_rays: usize,
    /// Add a path-trace cell per scene, method and layout ([`PATHTRACE_SPP`] sample a pixel at
    /// the primary rays' size, paths of at most [`PATHTRACE_DEPTH`] bounces).
    pub pathtrace: bool,
    /// Count each ray-casting cell's compute-shader invocations once, with a pipeline-statistics
    /// query (where the device has `pipelineStatisticsQuery`).
    pub pipeline_stats: bool,
}

/// The version of the protocol below. A worker of another build answers with its own
/// ([`Message::Ready`]); the parent takes every version up to its own that shares these
/// messages, so a build can be timed against an older one (`ab --a-bin`). Version 1 (no
/// `protocol` field) had no traversal axis (its cells are all while-if) and timed whole rounds
/// only; version 2 adds `cell N`, so the parent can run the two sides' runs of one cell back to
/// back.
pub const PROTOCOL: u32 = 2;

/// The first protocol with the `cell N` command (one cell timed at a time).
pub const PROTOCOL_CELL: u32 = 2;

/// A path-trace cell's samples per pixel.
pub const PATHTRACE_SPP: u32 = 1;
/// A path-trace cell's longest path.
pub const PATHTRACE_DEPTH: u32 = 4;

/// What a cell runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CellKind {
    /// The closest-hit ray-casting kernel over a ray set.
    Raycast,
    /// The path tracer's kernel rendering the scene's image.
    Pathtrace,
}

/// One cell, as the worker names it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CellInfo {
    pub kind: CellKind,
    pub scene: String,
    /// The ray set; `pathtrace` for a path-trace cell.
    pub set: String,
    pub method: String,
    pub layout: String,
    /// The traversal (`while-if` for a path-trace cell, and from a version 1 worker).
    #[serde(default = "while_if")]
    pub traversal: String,
    /// Rays cast; a path-trace cell's samples (pixels x samples per pixel).
    pub rays: usize,
    /// The kernel that ran (`raycast.mt.closest`), for the driver statistics.
    pub kernel: String,
    /// Its cell in each side's rows, made here where the values are typed: bench's
    /// ([`BenchCell`]), or for a path-trace cell bench-render's.
    pub coordinates: crate::rows::Cell,
}

fn while_if() -> String {
    Traversal::WhileIf.to_string()
}

impl CellInfo {
    /// `bunny primary mt bvh2` (and the traversal when it is not while-if).
    pub fn label(&self) -> String {
        let mut s = format!("{} {} {} {}", self.scene, self.set, self.method, self.layout);
        if self.traversal != while_if() {
            s = format!("{s} {}", self.traversal);
        }
        s
    }

    /// What names a cell on both sides, whichever build each side runs: its kind, scene, set,
    /// method, layout and traversal (not its kernel's name, nor its rows' coordinates, which a
    /// build may spell differently).
    pub fn key(&self) -> CellKey {
        CellKey {
            kind: self.kind,
            scene: self.scene.clone(),
            set: self.set.clone(),
            method: self.method.clone(),
            layout: self.layout.clone(),
            traversal: self.traversal.clone(),
        }
    }

    /// The kernel a cell times, as `ab` groups cells: its kind, method, layout and traversal
    /// (`raycast mt bvh2`, `pathtrace mt bvh2`).
    pub fn kernel_label(&self) -> String {
        let kind = match self.kind {
            CellKind::Raycast => "raycast",
            CellKind::Pathtrace => "pathtrace",
        };
        let mut s = format!("{kind} {} {}", self.method, self.layout);
        if self.traversal != while_if() {
            s = format!("{s} {}", self.traversal);
        }
        s
    }
}

/// A cell's identity across builds ([`CellInfo::key`]).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct CellKey {
    pub kind: CellKind,
    pub scene: String,
    pub set: String,
    pub method: String,
    pub layout: String,
    pub traversal: String,
}

/// A round's result for one cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellRound {
    /// Kernel time, ms; `None` when the round did not validate (then it does not count).
    pub ms: Option<f64>,
    pub agree: usize,
    pub unexplained: usize,
    pub invalid: usize,
}

/// What a worker prints, one JSON object a line.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "message", rename_all = "kebab-case")]
pub enum Message {
    /// `provenance` is the worker's [`Provenance`], as JSON.
    Ready {
        /// [`PROTOCOL`]; absent (1) from the first version.
        #[serde(default = "first_protocol")]
        protocol: u32,
        provenance: serde_json::Value,
        cells: Vec<CellInfo>,
        pipeline_ms: f64,
        /// Per cell, its compute-shader invocations when asked for and measured.
        invocations: Vec<Option<u64>>,
        /// Why there are no invocations counts, when they were asked for and are none.
        invocations_note: Option<String>,
    },
    Round {
        cells: Vec<CellRound>,
    },
    Failed {
        error: String,
    },
}

fn first_protocol() -> u32 {
    1
}

/// A ray set, its rays and the reference's hits.
type SetRays = (RaySet, Vec<Ray>, Vec<RefHit>);

/// Runs of a cell in one round; the round's time is their median.
pub const RUNS_PER_ROUND: usize = 3;

/// A cell as the worker holds it.
struct Cell<'a> {
    info: CellInfo,
    job: Job<'a>,
}

enum Job<'a> {
    Raycast {
        scene: &'a DeviceScene,
        kernel: std::sync::Arc<Kernel>,
        mesh: &'a Mesh,
        rays: &'a [Ray],
        ref_hits: &'a [RefHit],
    },
    Pathtrace {
        target: Box<RenderTarget>,
        settings: RenderSettings,
        /// The image mean this side's first path-trace cell of the scene rendered (each
        /// method traces the same paths: bench-render's check).
        scene_mean: f64,
    },
}

impl Workload {
    /// The options that give this workload to `trilab __ab-worker` (and name it in reports).
    pub fn args(&self) -> Vec<String> {
        let join = |v: Vec<String>| v.join(",");
        let mut a = vec![
            "--scenes".into(),
            join(self.scenes.iter().map(|s| s.display().to_string()).collect()),
            "--methods".into(),
            join(self.methods.iter().map(|m| m.to_string()).collect()),
            "--layouts".into(),
            join(self.layouts.iter().map(|l| l.to_string()).collect()),
            "--sets".into(),
            join(self.sets.iter().map(|s| s.to_string()).collect()),
        ];
        // Only when asked for: a worker of protocol 1 knows no traversal axis, and runs while-if.
        if self.traversals != [Traversal::WhileIf] {
            a.push("--traversals".into());
            a.push(join(self.traversals.iter().map(|t| t.to_string()).collect()));
        }
        for (k, v) in [
            ("--width", self.sizes.width.to_string()),
            ("--height", self.sizes.height.to_string()),
            ("--diffuse-per-hit", self.sizes.diffuse_per_hit.to_string()),
            ("--random-rays", self.sizes.random_rays.to_string()),
            ("--seed", self.sizes.seed.to_string()),
            ("--leaf-size", self.build.max_leaf_size.to_string()),
            ("--scene-access", self.scene_access.to_string()),
            ("--batch-rays", self.batch_rays.to_string()),
        ] {
            a.push(k.into());
            a.push(v);
        }
        for (flag, on) in [("--pathtrace", self.pathtrace), ("--pipeline-stats", self.pipeline_stats)] {
            if on {
                a.push(flag.into());
            }
        }
        a
    }
}

/// Runs the worker: loads `w`, prints `Ready`, then serves `input`'s commands on `output`.
pub fn serve(ctx: &Context, w: &Workload, hits_dir: &Path, input: impl BufRead, mut output: impl Write) -> Result<()> {
    let say = |out: &mut dyn Write, m: &Message| -> Result<()> {
        let line = serde_json::to_string(m).expect("messages serialise");
        writeln!(out, "{line}").and_then(|_| out.flush()).map_err(|e| Error::io(Path::new("stdout"), e))
    };
    match load_and_serve(ctx, w, hits_dir, input, &mut output, &say) {
        Ok(()) => Ok(()),
        Err(e) => {
            say(&mut output, &Message::Failed { error: e.to_string() })?;
            Err(e)
        }
    }
}

type Say<'s> = dyn Fn(&mut dyn Write, &Message) -> Result<()> + 's;

fn load_and_serve(
    ctx: &Context,
    w: &Workload,
    hits_dir: &Path,
    input: impl BufRead,
    output: &mut dyn Write,
    say: &Say,
) -> Result<()> {
    let meshes: Vec<Mesh> = w.scenes.iter().map(|s| load_obj(s)).collect::<Result<_>>()?;
    let build = w.build;
    let hosts: Vec<HostScene> = meshes
        .iter()
        .zip(&w.scenes)
        .map(|(m, s)| HostScene::build(crate::scene::scene_name(s), m, &build))
        .collect::<Result<_>>()?;
    // Ray sets and the reference's hits, per scene (the same seeds on both sides: the same rays).
    let mut sets: Vec<Vec<SetRays>> = vec![];
    for (host, mesh) in hosts.iter().zip(&meshes) {
        let reference = host.reference();
        let all = ray_sets(mesh, &host.name, &reference, &w.sizes, None)?;
        sets.push(
            all.into_iter()
                .filter(|(set, rays)| w.sets.contains(set) && !rays.is_empty())
                .map(|(set, rays)| {
                    let r = reference.trace_all(&rays, false);
                    (set, rays, r)
                })
                .collect(),
        );
    }
    let t = std::time::Instant::now();
    let mut scenes: Vec<(usize, DeviceScene)> = vec![];
    for (i, host) in hosts.iter().enumerate() {
        for &m in &w.methods {
            for &l in &w.layouts {
                for &tr in &w.traversals {
                    // A traversal a layout has no kernel for is left out (bench's rule); `auto`
                    // is checked as the texel path, as bench checks it.
                    if m.traversal_kernel(Raycast::Closest, path_of(w.scene_access), l, tr).is_err() {
                        continue;
                    }
                    let request = SceneRequest::new(m).access(w.scene_access).layout(l).traversal(tr);
                    scenes.push((i, host.upload(ctx, &request)?));
                }
            }
        }
    }
    let mut cells = vec![];
    for (i, scene) in &scenes {
        let kernel = scene.kernel(ctx, Raycast::Closest)?;
        for (set, rays, ref_hits) in &sets[*i] {
            let tracer = CellTracer::Method {
                method: scene.method,
                layout: scene.layout,
                leaf: w.build.max_leaf_size,
                sah_group: None,
                traversal: scene.traversal,
                node_order: scene.node_order,
                order: crate::rays::order::RayOrder::Given,
                access: scene.access,
            };
            let bench = BenchCell { scene: hosts[*i].name.clone(), set: *set, rays: Some(rays.len()), tracer };
            let info = CellInfo {
                kind: CellKind::Raycast,
                scene: hosts[*i].name.clone(),
                set: set.to_string(),
                method: scene.method.to_string(),
                layout: scene.layout.to_string(),
                traversal: scene.traversal.to_string(),
                rays: rays.len(),
                kernel: kernel.name.to_string(),
                coordinates: bench.coordinates(),
            };
            let job = Job::Raycast { scene, kernel: kernel.clone(), mesh: &meshes[*i], rays, ref_hits };
            cells.push(Cell { info, job });
        }
    }
    if w.pathtrace {
        let size = (w.sizes.width, w.sizes.height);
        for (host, mesh) in hosts.iter().zip(&meshes) {
            let settings = bench_settings(mesh, size, PATHTRACE_SPP, PATHTRACE_DEPTH, None);
            let mut scene_mean = None;
            for &m in &w.methods {
                for &l in &w.layouts {
                    let request = SceneRequest::new(m).access(w.scene_access).layout(l);
                    let target =
                        RenderTarget::new(ctx, host, request, KernelChoice::Specialised, settings.pixels(), false)?;
                    // The warm-up render: pipelines compiled, and the scene's image mean.
                    let first = render(ctx, &target, &settings, &mut |_| true)?;
                    let mean = summarise_renders(std::slice::from_ref(&first))
                        .map_err(|e| Error::Usage(format!("{} {m} {l} path trace: {e}", host.name)))?
                        .image_mean;
                    let info = CellInfo {
                        kind: CellKind::Pathtrace,
                        scene: host.name.clone(),
                        set: "pathtrace".into(),
                        method: m.to_string(),
                        layout: l.to_string(),
                        traversal: while_if(),
                        rays: first.samples() as usize,
                        kernel: target.kernel.source.name.to_string(),
                        coordinates: crate::rows::cell([
                            ("scene", host.name.clone()),
                            ("method", m.to_string()),
                            ("layout", l.to_string()),
                            ("samples", first.samples().to_string()),
                        ]),
                    };
                    let scene_mean = *scene_mean.get_or_insert(mean);
                    let job = Job::Pathtrace { target: Box::new(target), settings: settings.clone(), scene_mean };
                    cells.push(Cell { info, job });
                }
            }
        }
    }
    if cells.is_empty() {
        return Err(Error::Usage("the workload has no cells (every ray set empty?)".into()));
    }
    // One untimed run of every ray-casting cell: pipelines compiled, caches warm.
    let warm = RaycastOptions { warmup: 0, repeat: 1, batch_rays: w.batch_rays };
    for c in &cells {
        if let Job::Raycast { scene, kernel, rays, .. } = &c.job {
            scene.cast_with(ctx, kernel, rays, &warm)?;
        }
    }
    let (invocations, invocations_note) = match (w.pipeline_stats, ctx.enabled().pipeline_statistics_query) {
        (false, _) => (vec![None; cells.len()], None),
        (true, false) => (vec![None; cells.len()], Some("the device has no pipelineStatisticsQuery".to_owned())),
        (true, true) => {
            let mut v = vec![];
            for c in &cells {
                v.push(match &c.job {
                    Job::Raycast { scene, kernel, rays, .. } => {
                        dispatch_once(ctx, kernel, scene, rays, true)?.compute_shader_invocations
                    }
                    Job::Pathtrace { .. } => None,
                });
            }
            (v, None)
        }
    };
    // A round's time for a cell is the median of [`RUNS_PER_ROUND`] runs: on a shared host the
    // driver's threads are now and then descheduled, and a single run's time is bimodal.
    let opts = RaycastOptions { warmup: 0, repeat: RUNS_PER_ROUND, batch_rays: w.batch_rays };
    let pipeline_ms = t.elapsed().as_secs_f64() * 1e3;
    let infos = cells.iter().map(|c| c.info.clone()).collect();
    let provenance = serde_json::to_value(Provenance::of(ctx)).expect("provenance serialises");
    say(
        output,
        &Message::Ready { protocol: PROTOCOL, provenance, cells: infos, pipeline_ms, invocations, invocations_note },
    )?;
    // Whether each cell has run its first timed run (which records its hits or image).
    let mut recorded = vec![false; cells.len()];
    let mut time_cell = |i: usize| -> Result<CellRound> {
        let record = |what: &str| hits_dir.join(format!("{i}.{what}"));
        let first = !std::mem::replace(&mut recorded[i], true);
        Ok(match &cells[i].job {
            Job::Raycast { scene, kernel, mesh, rays, ref_hits } => {
                let res = scene.cast_with(ctx, kernel, rays, &opts)?;
                let a = compare_closest(mesh, rays, &res.hits, ref_hits);
                if first {
                    rays::write_hits(&record("hits"), &res.hits)?;
                }
                let valid = a.passes(MIN_AGREEMENT);
                let ms = if valid { Some(res.time_ms()?.median) } else { None };
                CellRound { ms, agree: a.agree, unexplained: a.unexplained, invalid: a.invalid.len() }
            }
            Job::Pathtrace { target, settings, scene_mean } => {
                let mut runs = vec![];
                for _ in 0..RUNS_PER_ROUND {
                    runs.push(render(ctx, target, settings, &mut |_| true)?);
                }
                if first {
                    write_image(&record("image"), &runs[0])?;
                }
                let dropped = runs.iter().map(|r| r.dropped_samples).sum::<u64>() as usize;
                let checked = summarise_renders(&runs)
                    .ok()
                    .filter(|m| check_image_mean(m.image_mean, &mut Some(*scene_mean)).is_ok());
                let samples = runs[0].samples() as usize;
                match checked {
                    Some(m) => CellRound { ms: Some(m.ms.median), agree: samples, unexplained: 0, invalid: 0 },
                    None => CellRound { ms: None, agree: 0, unexplained: 0, invalid: dropped },
                }
            }
        })
    };
    let mut round = 0usize;
    for line in input.lines() {
        let line = line.map_err(|e| Error::io(Path::new("stdin"), e))?;
        let command = line.trim();
        if command == "round" {
            let mut results = vec![None; cells.len()];
            // The cell that opens a round rotates, as in every interleaved harness.
            for k in 0..cells.len() {
                let i = (k + round) % cells.len();
                results[i] = Some(time_cell(i)?);
            }
            round += 1;
            let cells = results.into_iter().map(|r| r.expect("every cell ran")).collect();
            say(output, &Message::Round { cells })?;
        } else if let Some(i) = command.strip_prefix("cell ") {
            // One cell (protocol 2): the parent times the two sides' runs of a cell back to
            // back, so the moment's load on the host is the same for both.
            let i: usize =
                i.trim().parse().ok().filter(|&i| i < cells.len()).ok_or_else(|| {
                    Error::Usage(format!("ab worker: `{command}`: not one of the {} cells", cells.len()))
                })?;
            let r = time_cell(i)?;
            say(output, &Message::Round { cells: vec![r] })?;
        } else if matches!(command, "quit" | "") {
            return Ok(());
        } else {
            return Err(Error::Usage(format!("ab worker: unknown command `{command}`")));
        }
    }
    Ok(())
}

/// A path-trace cell's image, its pixels' RGBA as little-endian f32, for the parent to compare
/// bit for bit.
fn write_image(path: &Path, r: &RenderResult) -> Result<()> {
    let bytes: Vec<u8> = r.image().iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    crate::io::write_atomic(path, &bytes)
}

/// Pixels whose RGBA differs bit for bit between two images [`write_image`] wrote.
pub fn differing_pixels(a: &Path, b: &Path) -> Result<usize> {
    let read = |p: &Path| std::fs::read(p).map_err(|e| Error::io(p, e));
    let (a, b) = (read(a)?, read(b)?);
    if a.len() != b.len() {
        return Err(Error::Usage(format!("the sides rendered images of {} and {} bytes", a.len(), b.len())));
    }
    Ok(a.chunks(16).zip(b.chunks(16)).filter(|(x, y)| x != y).count())
}
