//! One side of `trilab ab`: a child process with that side's driver environment, which loads
//! the workload once (scenes, BVHs, ray sets, the f64 reference's hits, kernels; one untimed
//! warm-up of every cell) and then times one round of every cell each time the parent asks.
//! A driver is loaded once per process, so each side needs its own.
//!
//! The protocol is the worker service's ([`crate::services::worker::protocol`], JSON lines): the
//! worker prints [`Message::Ready`] (its protocol version, provenance and cells), then reads one
//! [`Request`] a line on stdin and answers it with [`Message::Round`]: `round` times every cell
//! once, `cell` (protocol 2) times one cell once; `quit` ends it (the words of protocols 1 and 2
//! are read too). Any failure is [`Message::Failed`] and the end of the process. Each cell's
//! first timed run writes its hits to `<hits_dir>/<cell index>.hits` (a path-trace cell its
//! image), so the parent can compare the sides ray by ray.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use crate::agreement::compare_closest;
use crate::bvh::BuildOptions;
use crate::commands::bench::{BenchCell, CellTracer};
use crate::encoding::{Layout, Method, Raycast, SceneAccess, Traversal};
use crate::error::{Error, Result};
use crate::gpu::{Context, Kernel, RaycastOptions};
use crate::matrix::{KernelAxes, KernelCell};
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
pub use crate::services::worker::protocol::{
    while_if, CellInfo, CellKey, CellKind, CellRound, Message, Request, PROTOCOL, PROTOCOL_CELL,
};

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
    /// The layout this side runs in every cell in place of the cell's (`ab --b-layout`: two
    /// kernels of one build side by side); its cells keep the workload's layout as their name,
    /// so they pair with the other side's, and name the kernel they ran.
    pub runs_layout: Option<Layout>,
}

/// A path-trace cell's samples per pixel.
pub const PATHTRACE_SPP: u32 = 1;
/// A path-trace cell's longest path.
pub const PATHTRACE_DEPTH: u32 = 4;

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
    /// The options that give this workload to `trilab __ab-worker` (every build's worker reads
    /// them; they also name it in reports).
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
        if let Some(l) = self.runs_layout {
            a.push("--runs-layout".into());
            a.push(l.to_string());
        }
        a
    }
}

/// Runs the worker: loads `w`, prints `Ready`, then serves `input`'s commands on `output`.
pub fn serve(ctx: &Context, w: &Workload, hits_dir: &Path, input: impl BufRead, mut output: impl Write) -> Result<()> {
    let say = |out: &mut dyn Write, m: &Message| crate::services::worker::say(out, m);
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
    let hosts: Vec<HostScene> = meshes
        .iter()
        .zip(&w.scenes)
        .map(|(m, s)| HostScene::build(crate::scene::scene_name(s), m, &w.build))
        .collect::<Result<_>>()?;
    let sets = scene_sets(w, &hosts, &meshes)?;
    let t = std::time::Instant::now();
    let scenes = upload_scenes(ctx, w, &hosts)?;
    let mut cells = raycast_cells(ctx, w, &hosts, &meshes, &scenes, &sets)?;
    if w.pathtrace {
        cells.extend(pathtrace_cells(ctx, w, &hosts, &meshes)?);
    }
    if cells.is_empty() {
        return Err(Error::Usage("the workload has no cells (every ray set empty?)".into()));
    }
    warm_up(ctx, w, &cells)?;
    let (invocations, invocations_note) = invocations(ctx, w, &cells)?;
    let pipeline_ms = t.elapsed().as_secs_f64() * 1e3;
    let infos = cells.iter().map(|c| c.info.clone()).collect();
    let provenance = serde_json::to_value(Provenance::of(ctx)).expect("provenance serialises");
    say(
        output,
        &Message::Ready { protocol: PROTOCOL, provenance, cells: infos, pipeline_ms, invocations, invocations_note },
    )?;
    serve_requests(ctx, w, hits_dir, &cells, input, output, say)
}

/// Per scene, its ray sets the workload asks for (non-empty) with the reference's hits: the same
/// seeds on both sides, so the same rays.
fn scene_sets(w: &Workload, hosts: &[HostScene], meshes: &[Mesh]) -> Result<Vec<Vec<SetRays>>> {
    let mut sets = vec![];
    for (host, mesh) in hosts.iter().zip(meshes) {
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
    Ok(sets)
}

/// Each scene's kernel cells uploaded (the matrix's cells of the workload's axes), with the
/// layout its cells are named by: the workload's, where `runs_layout` runs another.
fn upload_scenes(ctx: &Context, w: &Workload, hosts: &[HostScene]) -> Result<Vec<(usize, (Layout, DeviceScene))>> {
    let axes = KernelAxes {
        methods: w.methods.clone(),
        layouts: w.layouts.clone(),
        traversals: w.traversals.clone(),
        access: vec![w.scene_access],
        ..Default::default()
    };
    let mut scenes = vec![];
    for (i, host) in hosts.iter().enumerate() {
        for cell in axes.kernels() {
            // The layout the side runs in the cells named by the workload's (`runs_layout`:
            // `--b-layout`) needs its kernel too.
            let run = KernelCell { layout: w.runs_layout.unwrap_or(cell.layout), ..cell };
            if run.exists() {
                scenes.push((i, (cell.layout, host.upload(ctx, &run.request())?)));
            }
        }
    }
    Ok(scenes)
}

/// A ray-casting cell per uploaded scene and ray set, named as bench names it.
fn raycast_cells<'a>(
    ctx: &Context,
    w: &Workload,
    hosts: &[HostScene],
    meshes: &'a [Mesh],
    scenes: &'a [(usize, (Layout, DeviceScene))],
    sets: &'a [Vec<SetRays>],
) -> Result<Vec<Cell<'a>>> {
    let mut cells = vec![];
    for (i, (named, scene)) in scenes {
        let kernel = scene.kernel(ctx, Raycast::Closest)?;
        for (set, rays, ref_hits) in &sets[*i] {
            let tracer = CellTracer::Method {
                method: scene.method,
                layout: *named,
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
                layout: named.to_string(),
                traversal: scene.traversal.to_string(),
                rays: rays.len(),
                kernel: kernel.name.to_string(),
                coordinates: bench.coordinates(),
            };
            let job = Job::Raycast { scene, kernel: kernel.clone(), mesh: &meshes[*i], rays, ref_hits };
            cells.push(Cell { info, job });
        }
    }
    Ok(cells)
}

/// A path-trace cell per scene, method and layout, each rendered once (pipelines compiled, the
/// scene's image mean taken from its first).
fn pathtrace_cells<'a>(ctx: &Context, w: &Workload, hosts: &[HostScene], meshes: &[Mesh]) -> Result<Vec<Cell<'a>>> {
    let size = (w.sizes.width, w.sizes.height);
    let mut cells = vec![];
    for (host, mesh) in hosts.iter().zip(meshes) {
        let settings = bench_settings(mesh, size, PATHTRACE_SPP, PATHTRACE_DEPTH, None);
        let mut scene_mean = None;
        for &m in &w.methods {
            for &l in &w.layouts {
                let request = SceneRequest::new(m).access(w.scene_access).layout(w.runs_layout.unwrap_or(l));
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
    Ok(cells)
}

/// One untimed run of every ray-casting cell: pipelines compiled, caches warm.
fn warm_up(ctx: &Context, w: &Workload, cells: &[Cell]) -> Result<()> {
    let warm = RaycastOptions { warmup: 0, repeat: 1, batch_rays: w.batch_rays };
    for c in cells {
        if let Job::Raycast { scene, kernel, rays, .. } = &c.job {
            scene.cast_with(ctx, kernel, rays, &warm)?;
        }
    }
    Ok(())
}

/// Each ray-casting cell's compute-shader invocations, counted once where asked for and the
/// device has the query; else `None`s, with why when it was asked for.
fn invocations(ctx: &Context, w: &Workload, cells: &[Cell]) -> Result<(Vec<Option<u64>>, Option<String>)> {
    match (w.pipeline_stats, ctx.enabled().pipeline_statistics_query) {
        (false, _) => Ok((vec![None; cells.len()], None)),
        (true, false) => Ok((vec![None; cells.len()], Some("the device has no pipelineStatisticsQuery".to_owned()))),
        (true, true) => {
            let mut v = vec![];
            for c in cells {
                v.push(match &c.job {
                    Job::Raycast { scene, kernel, rays, .. } => {
                        dispatch_once(ctx, kernel, scene, rays, true)?.compute_shader_invocations
                    }
                    Job::Pathtrace { .. } => None,
                });
            }
            Ok((v, None))
        }
    }
}

/// Answers the parent's requests until it says quit: a round of every cell, or one cell.
fn serve_requests(
    ctx: &Context,
    w: &Workload,
    hits_dir: &Path,
    cells: &[Cell],
    input: impl BufRead,
    output: &mut dyn Write,
    say: &Say,
) -> Result<()> {
    // A round's time for a cell is the median of [`RUNS_PER_ROUND`] runs: on a shared host the
    // driver's threads are now and then descheduled, and a single run's time is bimodal.
    let opts = RaycastOptions { warmup: 0, repeat: RUNS_PER_ROUND, batch_rays: w.batch_rays };
    // Whether each cell has run its first timed run (which records its hits or image).
    let mut recorded = vec![false; cells.len()];
    let mut time = |i: usize| -> Result<CellRound> {
        let first = !std::mem::replace(&mut recorded[i], true);
        time_cell(ctx, &cells[i], &opts, first.then(|| hits_dir.join(i.to_string())).as_deref())
    };
    let mut round = 0usize;
    for line in input.lines() {
        let line = line.map_err(|e| Error::io(Path::new("stdin"), e))?;
        match Request::parse(&line).map_err(|e| Error::Usage(format!("ab worker: {e}")))? {
            Request::Round => {
                let mut results = vec![None; cells.len()];
                // The cell that opens a round rotates, as in every interleaved harness.
                for k in 0..cells.len() {
                    let i = (k + round) % cells.len();
                    results[i] = Some(time(i)?);
                }
                round += 1;
                let cells = results.into_iter().map(|r| r.expect("every cell ran")).collect();
                say(output, &Message::Round { cells })?;
            }
            Request::Cell { index: i } => {
                // One cell (protocol 2): the parent times the two sides' runs of a cell back to
                // back, so the moment's load on the host is the same for both.
                if i >= cells.len() {
                    return Err(Error::Usage(format!("ab worker: cell {i}: not one of the {} cells", cells.len())));
                }
                let r = time(i)?;
                say(output, &Message::Round { cells: vec![r] })?;
            }
            Request::Quit => return Ok(()),
            other => {
                return Err(Error::Usage(format!("ab worker: an ab side answers round, cell and quit, not {other:?}")))
            }
        }
    }
    Ok(())
}

/// One timed run of a cell (its median over [`RUNS_PER_ROUND`]); `record`: where its first run
/// writes its hits (`<record>.hits`) or image (`<record>.image`).
fn time_cell(ctx: &Context, cell: &Cell, opts: &RaycastOptions, record: Option<&Path>) -> Result<CellRound> {
    let file = |what: &str| record.map(|r| r.with_extension(what));
    Ok(match &cell.job {
        Job::Raycast { scene, kernel, mesh, rays, ref_hits } => {
            let res = scene.cast_with(ctx, kernel, rays, opts)?;
            let a = compare_closest(mesh, rays, &res.hits, ref_hits);
            if let Some(path) = file("hits") {
                rays::write_hits(&path, &res.hits)?;
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
            if let Some(path) = file("image") {
                write_image(&path, &runs[0])?;
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
