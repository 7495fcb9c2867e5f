//! `trilab study`: the paper's Tables 1-4 on this device. The matrix scene x leaf size x method
//! is path-traced (the paper's "seconds per method") and ray-cast with the primary, diffuse and
//! random ray sets (Mrays/s), every result validated before its time counts: renders must have
//! no NaN/Inf sample and the same image mean as the scene's first render (2 %), ray casts must
//! agree with the f64 reference (see [`crate::bench::validate_hits`]).
//!
//! Timing is interleaved: each round renders and casts with every method of a leaf size in
//! turn, so a shared machine's drift spreads over all methods instead of favouring one. Round 0
//! is the warm-up; the others give median, min and max.
//!
//! Outputs ([`write`]): `study.csv`, `study.json`, `study.md` (the paper's table format, the
//! ray-set table, BVH quality, SPIR-V cost against time and the paper's claims checked) and
//! PNG plots ([`plots`]).

pub mod claims;
pub mod plots;
pub mod table;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::bench::{mrays_summary, validate_hits};
use crate::bvh::{BuildOptions, Bvh};
use crate::encoding::Method;
use crate::error::{Error, Result};
use crate::gpu::traversal_stats::{raycast_stats, TraversalSummary};
use crate::gpu::{raycast, Context, GpuScene, RaycastOptions, Summary};
use crate::named::named_enum;
use crate::rays::{self, Camera};
use crate::reference::Reference;
use crate::render::bench::{bench_settings, check_image_mean, summarise_renders, RenderMeasure};
use crate::render::{render, KernelChoice, PathtraceKernel, RenderScene};
use crate::scene::load_obj;

/// The leaf sizes of the paper's tables.
pub const PAPER_LEAF_SIZES: [u32; 6] = [1, 2, 3, 4, 8, 16];

named_enum! {
    /// Workload presets.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Preset: "study preset" {
        /// The paper's setting: 800x600, 500 spp, depth 16; ray sets from an 800x600 camera.
        Paper = "paper",
        /// Scaled so the whole study finishes in about 20 minutes on a 2-core lavapipe machine.
        Lavapipe = "lavapipe",
        /// A seconds-long run for CI: the bunny at tiny sizes, one timed round.
        Smoke = "smoke",
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct StudyOptions {
    pub preset: Preset,
    pub scenes: Vec<PathBuf>,
    pub leaf_sizes: Vec<u32>,
    pub methods: Vec<Method>,
    /// Path tracing.
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    /// Ray sets: primary rays from a `ray_width` x `ray_height` camera, `diffuse_per_hit`
    /// cosine bounces per primary hit, `random_rays` rays between random points in the bounds.
    pub ray_width: u32,
    pub ray_height: u32,
    pub diffuse_per_hit: u32,
    pub random_rays: usize,
    /// Timed rounds after one warm-up round.
    pub repeat: usize,
    /// `BuildOptions::sah_group` (1: the paper's SAH; 4: quad-aware).
    pub sah_group: u32,
    pub seed: u64,
}

impl StudyOptions {
    pub fn preset(preset: Preset) -> StudyOptions {
        let scenes = |names: &[&str]| names.iter().map(|s| PathBuf::from(format!("scenes/{s}.obj"))).collect();
        let base = StudyOptions {
            preset,
            scenes: scenes(&["bunny", "dragon", "buddha"]),
            leaf_sizes: PAPER_LEAF_SIZES.to_vec(),
            // The paper's four; `--methods` adds the others (watertight, Baldwin-Weber, f64).
            methods: Method::PAPER.to_vec(),
            width: 800,
            height: 600,
            spp: 500,
            max_depth: 16,
            ray_width: 800,
            ray_height: 600,
            diffuse_per_hit: 8,
            random_rays: 1_000_000,
            repeat: 5,
            sah_group: 1,
            seed: 7,
        };
        match preset {
            Preset::Paper => base,
            Preset::Lavapipe => StudyOptions {
                width: 400,
                height: 300,
                spp: 16,
                ray_width: 400,
                ray_height: 300,
                diffuse_per_hit: 2,
                random_rays: 200_000,
                repeat: 3,
                ..base
            },
            Preset::Smoke => StudyOptions {
                scenes: scenes(&["bunny"]),
                width: 48,
                height: 36,
                spp: 2,
                ray_width: 48,
                ray_height: 36,
                diffuse_per_hit: 1,
                random_rays: 2_000,
                repeat: 1,
                ..base
            },
        }
    }

    /// How this workload relates to the paper's, in words (stated in every output).
    pub fn scaling(&self) -> String {
        let paper = 800.0 * 600.0 * 500.0;
        let ours = self.width as f64 * self.height as f64 * self.spp as f64;
        let render = if ours == paper {
            "the paper's path-tracing workload (800x600, 500 spp".to_owned()
        } else {
            format!(
                "path tracing at {}x{}, {} spp ({:.4} of the paper's 800x600 x 500 samples",
                self.width,
                self.height,
                self.spp,
                ours / paper
            )
        };
        format!(
            "{render}, depth {}); ray sets: primary {}x{}, {} diffuse per primary hit, {} random; \
             median of {} timed rounds after 1 warm-up round, methods interleaved",
            self.max_depth, self.ray_width, self.ray_height, self.diffuse_per_hit, self.random_rays, self.repeat
        )
    }
}

/// Where and when a study ran; carried by every row.
#[derive(Clone, Debug, Serialize)]
pub struct Provenance {
    pub device: String,
    pub driver: String,
    pub mesa_version: Option<String>,
    pub commit: String,
    pub date: String,
    pub host_cpus: usize,
    pub lp_num_threads: Option<String>,
    pub timed_on_gpu: bool,
}

impl Provenance {
    pub fn of(ctx: &Context) -> Provenance {
        let info = ctx.info();
        Provenance {
            device: info.name.clone(),
            driver: info.driver_label(),
            mesa_version: info.mesa_version.clone(),
            commit: commit(),
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            host_cpus: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
            lp_num_threads: std::env::var("LP_NUM_THREADS").ok(),
            timed_on_gpu: info.timestamp_valid_bits > 0,
        }
    }
}

/// The commit the study ran from: `TRILAB_COMMIT` if set (a copy without `.git`, such as the
/// GPU machine's), else `git rev-parse` in the working directory, "-dirty" when tracked files
/// differ from it; "unknown" without either.
pub fn commit() -> String {
    if let Ok(c) = std::env::var("TRILAB_COMMIT") {
        return c;
    }
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    match git(&["rev-parse", "--short=12", "HEAD"]) {
        Some(c) => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
            if dirty {
                format!("{c}-dirty")
            } else {
                c
            }
        }
        None => "unknown".into(),
    }
}

/// One ray set's measurement in a cell.
#[derive(Clone, Debug, Serialize)]
pub struct SetResult {
    pub set: String,
    pub rays: usize,
    pub kernel_ms: Summary,
    pub mrays_per_s: Summary,
    /// Fraction of rays agreeing with the f64 reference.
    pub agreement: f64,
    /// Nodes visited and triangles tested per ray, from the kernel's statistics variant.
    pub traversal: TraversalSummary,
}

/// BVH quality of one (scene, leaf size) build.
#[derive(Clone, Debug, Serialize)]
pub struct BvhQuality {
    pub nodes: usize,
    pub leaves: usize,
    pub depth: u32,
    pub sah_cost: f64,
    /// End-point overlap (Aila, Karras & Laine 2013), see [`crate::bvh::epo`].
    pub epo: f64,
    pub quad_padding: usize,
    pub build_ms: f64,
}

/// One cell: scene x leaf size x method.
#[derive(Clone, Debug, Serialize)]
pub struct StudyRow {
    pub scene: String,
    pub triangles: usize,
    pub leaf_size: u32,
    pub method: Method,
    /// Bytes this method's encoding uploads (nodes, triangle data, slot ids).
    pub scene_bytes: usize,
    pub bvh: BvhQuality,
    /// Path tracing (render seconds = `render.ms / 1000`).
    pub render: RenderMeasure,
    pub render_kernel: &'static str,
    pub raycast_kernel: &'static str,
    pub sets: Vec<SetResult>,
    pub provenance: Provenance,
}

impl StudyRow {
    pub fn render_seconds(&self) -> Summary {
        let s = self.render.ms;
        Summary { median: s.median * 1e-3, min: s.min * 1e-3, max: s.max * 1e-3, runs: s.runs }
    }

    pub fn set(&self, name: &str) -> Option<&SetResult> {
        self.sets.iter().find(|s| s.set == name)
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct StudyReport {
    pub options: StudyOptions,
    pub scaling: String,
    pub provenance: Provenance,
    pub rows: Vec<StudyRow>,
    pub seconds: f64,
}

/// Per-method state of one (scene, leaf size) during the rounds.
struct Cell {
    method: Method,
    /// Every buffer of the encoding: the path tracer and the ray casts bind what they read.
    gpu: GpuScene,
    render_scene: RenderScene,
    render_kernel: PathtraceKernel,
    renders: Vec<crate::render::RenderResult>,
    /// Per set: kernel ms of each timed round.
    set_ms: Vec<Vec<f64>>,
    set_agreement: Vec<f64>,
    set_traversal: Vec<Option<TraversalSummary>>,
}

pub fn run(ctx: &Context, o: &StudyOptions, mut progress: impl FnMut(&str)) -> Result<StudyReport> {
    if o.leaf_sizes.is_empty() || o.methods.is_empty() || o.scenes.is_empty() {
        return Err(Error::Usage("study: need at least one scene, leaf size and method".into()));
    }
    let started = Instant::now();
    let provenance = Provenance::of(ctx);
    let raycast_kernels: Vec<_> =
        o.methods.iter().map(|&m| ctx.create_kernel(crate::kernels::raycast(m, false))).collect::<Result<_>>()?;
    let stats_kernels: Vec<_> =
        o.methods.iter().map(|&m| ctx.create_kernel(crate::kernels::raycast_stats(m))).collect::<Result<_>>()?;
    let mut rows = vec![];
    for path in &o.scenes {
        let mesh = load_obj(path)?;
        let name = crate::scene::scene_name(path);
        progress(&format!("{name}: {} triangles; ray sets and f64 reference", mesh.triangle_count()));
        // Ray sets and their reference hits, once per scene (they do not depend on the BVH).
        let reference_bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let reference = Reference::new(&mesh, &reference_bvh);
        let bounds = mesh.bounds();
        let primary = rays::primary_rays(&Camera::framing(&bounds), o.ray_width, o.ray_height);
        let diffuse = rays::diffuse_rays(&mesh, &reference, &primary, o.diffuse_per_hit, o.seed);
        let random = rays::random_rays(&bounds, o.random_rays, o.seed);
        let sets = [("primary", primary), ("diffuse", diffuse), ("random", random)];
        let ref_hits: Vec<_> = sets.iter().map(|(_, r)| reference.trace_all(r, false)).collect();

        let settings = bench_settings(&mesh, (o.width, o.height), o.spp, o.max_depth, None);
        let mut scene_mean: Option<f64> = None;

        for &leaf in &o.leaf_sizes {
            let build = BuildOptions { sah_group: o.sah_group, ..BuildOptions::new(leaf) };
            let bvh = Bvh::build(&mesh, &build);
            let st = bvh.stats_with_epo(&mesh);
            let quality = BvhQuality {
                nodes: st.nodes,
                leaves: st.leaves,
                depth: st.depth,
                sah_cost: st.sah_cost,
                epo: st.epo.unwrap_or(f64::NAN),
                quad_padding: st.quad_padding,
                build_ms: st.build_ms,
            };
            let mut cells = vec![];
            for &method in &o.methods {
                let encoded = method.encode(&mesh, &bvh);
                let render_scene = RenderScene::new(&mesh, &encoded);
                let render_kernel = PathtraceKernel::choose(method, render_scene.bsdf_mask, KernelChoice::Specialised);
                cells.push(Cell {
                    method,
                    gpu: GpuScene::upload(ctx, &encoded)?,
                    render_scene,
                    render_kernel,
                    renders: vec![],
                    set_ms: vec![vec![]; sets.len()],
                    set_agreement: vec![0.0; sets.len()],
                    set_traversal: vec![None; sets.len()],
                });
            }
            for round in 0..=o.repeat.max(1) {
                progress(&format!("{name} leaf {leaf}: round {round}/{}", o.repeat.max(1)));
                for ((cell, kernel), stats_kernel) in cells.iter_mut().zip(&raycast_kernels).zip(&stats_kernels) {
                    let what = |s: &str| format!("{name}, leaf {leaf}, {}: {s}", cell.method);
                    let r = render(ctx, &cell.gpu, &cell.render_scene, cell.render_kernel, &settings, &mut |_| true)?;
                    for (si, ((set, rays), refs)) in sets.iter().zip(&ref_hits).enumerate() {
                        let res = raycast(ctx, kernel, &cell.gpu, rays, &RaycastOptions::default())?;
                        if round == 0 {
                            // Hits are deterministic: validate once, before any time counts.
                            let a = validate_hits(&mesh, rays, &res.hits, refs)
                                .map_err(|e| Error::Usage(what(&format!("{set} rays: {e}"))))?;
                            cell.set_agreement[si] = a.fraction();
                            let (stat_hits, counts) = raycast_stats(ctx, stats_kernel, &cell.gpu, rays)?;
                            if rays::differing_hits(&stat_hits, &res.hits) > 0 {
                                return Err(Error::Usage(what(&format!(
                                    "{set} rays: the statistics variant's hits differ from the kernel's"
                                ))));
                            }
                            cell.set_traversal[si] = Some(TraversalSummary::of(&counts));
                        } else {
                            cell.set_ms[si].push(res.time_ms().median);
                        }
                    }
                    if round > 0 {
                        cell.renders.push(r);
                    }
                }
            }
            for (cell, kernel) in cells.into_iter().zip(&raycast_kernels) {
                let what = |s: &str| format!("{name}, leaf {leaf}, {}: {s}", cell.method);
                let m = summarise_renders(&cell.renders).map_err(|e| Error::Usage(what(&e.to_string())))?;
                check_image_mean(m.image_mean, &mut scene_mean).map_err(|e| Error::Usage(what(&e)))?;
                let set_results = sets
                    .iter()
                    .enumerate()
                    .map(|(si, (set, rays))| {
                        let ms = Summary::of(&cell.set_ms[si]).expect("at least one timed round");
                        SetResult {
                            set: set.to_string(),
                            rays: rays.len(),
                            kernel_ms: ms,
                            mrays_per_s: mrays_summary(rays.len(), ms),
                            agreement: cell.set_agreement[si],
                            traversal: cell.set_traversal[si].expect("measured in round 0"),
                        }
                    })
                    .collect();
                progress(&format!(
                    "{name} leaf {leaf} {}: render {:.3} s, {:.2} Msamples/s",
                    cell.method,
                    m.ms.median * 1e-3,
                    m.msamples_per_s.median
                ));
                rows.push(StudyRow {
                    scene: name.clone(),
                    triangles: mesh.triangle_count(),
                    leaf_size: leaf,
                    method: cell.method,
                    scene_bytes: cell.gpu.bytes,
                    bvh: quality.clone(),
                    render: m,
                    render_kernel: cell.render_kernel.source.name,
                    raycast_kernel: kernel.name,
                    sets: set_results,
                    provenance: provenance.clone(),
                });
            }
        }
    }
    Ok(StudyReport {
        options: o.clone(),
        scaling: o.scaling(),
        provenance,
        rows,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// Writes `study.csv`, `study.json`, `study.md` and the plots into `dir` (created if needed),
/// each atomically. Returns the paths written.
pub fn write(report: &StudyReport, dir: &Path) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut written = vec![];
    let mut put = |name: &str, bytes: &[u8]| -> Result<()> {
        let p = dir.join(name);
        crate::io::write_atomic(&p, bytes)?;
        written.push(p);
        Ok(())
    };
    put("study.csv", table::csv(report)?.as_bytes())?;
    put("study.json", (serde_json::to_string_pretty(report).expect("serialisable") + "\n").as_bytes())?;
    let plots = plots::all(report, dir)?;
    put("study.md", table::markdown(report, &plots).as_bytes())?;
    written.extend(plots.into_iter().map(|p| p.path));
    Ok(written)
}
