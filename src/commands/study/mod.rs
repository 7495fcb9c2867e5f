//! `trilab study`: the paper's Tables 1-4 on this device. The matrix scene x leaf size x method
//! (x node layout, `--layouts`: issue 15's second axis, bvh2 unless asked) is path-traced (the paper's "seconds per method") and ray-cast with the primary, diffuse and
//! random ray sets (Mrays/s), every result validated before its time counts: renders must have
//! no NaN/Inf sample and the same image mean as the scene's first render (2 %), ray casts must
//! agree with the f64 reference (see [`crate::services::validate::validate_hits`]).
//!
//! Timing is interleaved: each round renders and casts with every method (on every layout) of a
//! leaf size in turn, so a shared machine's drift spreads over all methods instead of favouring one. Round 0
//! is the warm-up; the others give median, min and max.
//!
//! Outputs ([`write`]): `study.csv`, `study.json`, `study.md` (the paper's table format, the
//! ray-set table, BVH quality, SPIR-V cost against time, the paper's claims checked per layout
//! and, with more than one layout, whether the best intersector and leaf size change with it
//! ([`layouts`])), PNG plots ([`plots`]) and `rows.jsonl` ([`rows`]: one self-describing row per
//! cell and the plan of the whole matrix, what `trilab compare` and `trilab merge` read).
//!
//! Shards (`--shard I/N`, [`StudyOptions::shard`]): a shard runs every N-th (scene, leaf size)
//! group of the matrix, round-robin from group I ([`StudyOptions::split`]). A group is the unit, not a
//! single cell, so every method and layout of a leaf size is still measured side by side,
//! interleaved in one run (the comparisons claims (b) and (c) make), and each BVH is built by
//! one shard only. A shard's report judges its own cells and says it is partial; `trilab merge`
//! joins the shards.

pub mod claims;
pub mod compiled;
pub mod layouts;
pub mod plots;
pub mod table;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::bvh::BuildOptions;
use crate::encoding::{Layout, Method, Raycast};
use crate::error::{Error, Result};
use crate::gpu::{Context, RaycastOptions, TraversalSummary};
use crate::matrix::{Experiment, KernelAxes};
use crate::named::{named_enum, Named};
use crate::pipeline::HostScene;
use crate::render::{render, KernelChoice, RenderTarget};
use crate::report::Summary;
use crate::rows::{self as result_rows, Better, Figure, Plan, Row};
use crate::scene::load_obj;
use crate::services::rayset::{RaySet, RaySetSizes};
use crate::services::render_measure::{bench_settings, check_image_mean, summarise_renders, RenderMeasure};
use crate::services::shard::{Shard, Split};
use crate::services::validate::{mrays_summary, validate_hits};

pub use crate::bvh::PAPER_LEAF_SIZES;

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
    /// Set (by a stop signal) to end the run after the (scene, leaf size) group under way: the
    /// report then holds the groups finished and says it was stopped ([`StudyReport::stopped`]).
    #[serde(skip)]
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    pub preset: Preset,
    pub scenes: Vec<PathBuf>,
    pub leaf_sizes: Vec<u32>,
    pub methods: Vec<Method>,
    /// BVH node layouts: every method runs on each (default: `bvh2`, the paper's binary tree).
    pub layouts: Vec<Layout>,
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
    /// Run only this shard's (scene, leaf size) groups of the matrix ([`StudyOptions::split`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
    /// Also compile the study's kernels for AMD GPUs through RADV's null device and bound claim
    /// (c) by their occupancy ([`compiled`]); `None`: no such section.
    #[serde(skip)]
    pub compiled: Option<compiled::CompiledOptions>,
}

/// A `--scenes` entry: a scene's name (`bunny`, found from any folder by
/// [`crate::scene::resolve`]) or a path.
pub fn scene_path(s: &str) -> PathBuf {
    PathBuf::from(s)
}

impl StudyOptions {
    pub fn preset(preset: Preset) -> StudyOptions {
        let scenes = |names: &[&str]| names.iter().map(PathBuf::from).collect();
        let base = StudyOptions {
            preset,
            scenes: scenes(&["bunny", "dragon", "buddha"]),
            leaf_sizes: PAPER_LEAF_SIZES.to_vec(),
            // The paper's four; `--methods` adds the others (watertight, Baldwin-Weber, f64).
            methods: Method::paper(),
            layouts: vec![Layout::DEFAULT],
            width: 800,
            height: 600,
            spp: 500,
            max_depth: 16,
            ray_width: crate::defaults::WIDTH,
            ray_height: crate::defaults::HEIGHT,
            diffuse_per_hit: crate::defaults::DIFFUSE_PER_HIT,
            random_rays: crate::defaults::RANDOM_RAYS,
            repeat: crate::defaults::REPEAT,
            sah_group: 1,
            seed: crate::defaults::SEED,
            shard: None,
            stop: None,
            compiled: None,
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

    /// Refuses options the study cannot run, before any work: leaf sizes outside 1..=16, a SAH
    /// grouping other than 1 or 4, no layout or one named twice, scenes that do not exist.
    pub fn check(&self) -> Result<()> {
        if self.layouts.is_empty() {
            return Err(Error::Usage("--layouts: name at least one layout".into()));
        }
        for (i, l) in self.layouts.iter().enumerate() {
            if self.layouts[..i].contains(l) {
                return Err(Error::Usage(format!("--layouts: {l} is named twice")));
            }
        }
        for &l in &self.leaf_sizes {
            BuildOptions::new(l).check()?;
        }
        if ![1, 4].contains(&self.sah_group) {
            return Err(Error::Usage(format!("--sah-group {}: expected 1 or 4", self.sah_group)));
        }
        for scene in &self.scenes {
            crate::scene::resolve(scene)?;
        }
        let (scenes, leaves) = (self.scenes.len(), self.leaf_sizes.len());
        self.split().check(&format!(
            "a study shard takes whole (scene, leaf size) groups and this matrix has {} ({scenes} scene(s) x \
             {leaves} leaf size(s))",
            scenes * leaves
        ))
    }

    /// The matrix as its shards split it: a shard takes whole (scene, leaf size) groups, in the
    /// study's order (scene major).
    pub fn split(&self) -> Split {
        Split::new(self.shard, self.scenes.len(), self.leaf_sizes.len())
    }

    /// The experiment's axes: scenes, leaf sizes and the kernel axes (methods, layouts); no
    /// ray-set axis: a study cell measures every set (and the path tracer).
    pub fn experiment(&self) -> Experiment {
        Experiment {
            scenes: self.scenes.clone(),
            leaf_sizes: self.leaf_sizes.clone(),
            sets: vec![],
            kernels: KernelAxes { methods: self.methods.clone(), layouts: self.layouts.clone(), ..Default::default() },
        }
    }

    /// Every cell of the whole matrix (all shards), in the study's order: scene, leaf size,
    /// method, layout.
    pub fn plan_cells(&self) -> Vec<result_rows::Cell> {
        self.experiment().cells().iter().map(|c| StudyCell::of(c).coordinates()).collect()
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

pub use crate::services::provenance::{commit, Provenance};

/// A study cell: what the plan lists and a row measures, and what `trilab merge` reads back
/// from both to judge the claims: one (scene, leaf size, method, layout).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StudyCell {
    pub scene: String,
    pub leaf: u32,
    pub method: Method,
    pub layout: Layout,
}

impl StudyCell {
    /// A matrix cell of the study.
    pub fn of(c: &crate::matrix::Cell) -> StudyCell {
        StudyCell {
            scene: c.group.scene_name().unwrap_or_default(),
            leaf: c.group.leaf,
            method: c.kernel.method,
            layout: c.kernel.layout,
        }
    }

    /// The cell's coordinates, as `rows.jsonl` names them: `scene`, `leaf`, `method`, `layout`.
    pub fn coordinates(&self) -> result_rows::Cell {
        result_rows::cell([
            ("scene", self.scene.clone()),
            ("leaf", self.leaf.to_string()),
            ("method", self.method.to_string()),
            ("layout", self.layout.to_string()),
        ])
    }

    /// The study cell of a row's or a plan's coordinates read from `file`: an error naming the
    /// file, the cell and the coordinate it lacks or holds a value of this trilab does not know.
    pub fn parse(c: &result_rows::Cell, file: &Path) -> Result<StudyCell> {
        StudyCell::try_from(c).map_err(|why| Error::bad_input(file, None, why))
    }
}

impl TryFrom<&result_rows::Cell> for StudyCell {
    /// What is wrong, naming the cell and the coordinate.
    type Error = String;

    /// Reads [`StudyCell::coordinates`] back. Rows written before layouts were an axis have no
    /// `layout`: the binary tree.
    fn try_from(c: &result_rows::Cell) -> std::result::Result<StudyCell, String> {
        let key = result_rows::cell_key("study", c);
        let get = |k: &str| c.get(k).ok_or_else(|| format!("study cell `{key}` has no `{k}` coordinate"));
        let bad = |k: &str, e: String| format!("study cell `{key}`: {k}: {e}");
        let leaf = get("leaf")?.parse::<u32>().map_err(|e| bad("leaf", e.to_string()))?;
        let method = get("method")?.parse::<Method>().map_err(|e| bad("method", e))?;
        let layout = match c.get("layout") {
            Some(l) => l.parse::<Layout>().map_err(|e| bad("layout", e))?,
            None => Layout::DEFAULT,
        };
        Ok(StudyCell { scene: get("scene")?.clone(), leaf, method, layout })
    }
}

/// One ray set's measurement in a cell.
#[derive(Clone, Debug, Serialize)]
pub struct SetResult {
    pub set: RaySet,
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
    /// End-point overlap (Aila, Karras & Laine 2013), see [`crate::bvh::epo`]; NaN where it was
    /// not computed (past its work limit; the tables print `-`, the rows leave it out).
    pub epo: f64,
    pub quad_padding: usize,
    pub build_ms: f64,
}

/// One cell: scene x leaf size x method x layout.
#[derive(Clone, Debug, Serialize)]
pub struct StudyRow {
    pub scene: String,
    pub triangles: usize,
    pub leaf_size: u32,
    pub method: Method,
    /// The node layout the kernels traversed.
    pub layout: Layout,
    /// Bytes this method's encoding uploads (the layout's nodes, triangle data, slot ids).
    pub scene_bytes: usize,
    /// The binary tree's quality (every layout is made from it).
    pub bvh: BvhQuality,
    /// Path tracing (render seconds = `render.ms / 1000`).
    pub render: RenderMeasure,
    pub render_kernel: &'static str,
    pub raycast_kernel: &'static str,
    pub sets: Vec<SetResult>,
    pub provenance: Provenance,
}

impl StudyRow {
    /// The cell this row measured.
    pub fn cell(&self) -> StudyCell {
        StudyCell { scene: self.scene.clone(), leaf: self.leaf_size, method: self.method, layout: self.layout }
    }

    pub fn render_seconds(&self) -> Summary {
        let s = self.render.ms;
        Summary { median: s.median * 1e-3, min: s.min * 1e-3, max: s.max * 1e-3, runs: s.runs }
    }

    pub fn set(&self, set: RaySet) -> Option<&SetResult> {
        self.sets.iter().find(|s| s.set == set)
    }

    /// `mt`, or `mt bvh8` on a layout other than the binary one (progress and errors).
    pub fn label(&self) -> String {
        label(self.method, self.layout)
    }
}

/// `method`, or `method layout` on a layout other than the binary one.
pub fn label(method: Method, layout: Layout) -> String {
    if layout == Layout::DEFAULT {
        method.to_string()
    } else {
        format!("{method} {layout}")
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct StudyReport {
    pub options: StudyOptions,
    pub scaling: String,
    pub provenance: Provenance,
    pub rows: Vec<StudyRow>,
    pub seconds: f64,
    /// Why the run ended before its last group ([`StudyOptions::stop`]), with how many groups
    /// it finished; `None` for a whole run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped: Option<String>,
    /// What AMD's compiler made of the study's kernels, and the model of claim (c) from it
    /// ([`StudyOptions::compiled`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compiled: Option<compiled::CompiledSection>,
}

/// Per-method state of one (scene, leaf size) during the rounds.
struct Cell {
    /// The scene on the device for the path tracer and the ray casts alike.
    target: RenderTarget,
    renders: Vec<crate::render::RenderResult>,
    /// Per set: kernel ms of each timed round.
    set_ms: Vec<Vec<f64>>,
    set_agreement: Vec<f64>,
    set_traversal: Vec<Option<TraversalSummary>>,
}

impl StudyOptions {
    /// The ray sets' sizes.
    pub fn sizes(&self) -> RaySetSizes {
        RaySetSizes {
            width: self.ray_width,
            height: self.ray_height,
            diffuse_per_hit: self.diffuse_per_hit,
            random_rays: self.random_rays,
            seed: self.seed,
        }
    }
}

/// One (scene, leaf size) group's shared inputs: what every cell of it renders and casts.
struct Group<'a> {
    name: &'a str,
    leaf: u32,
    mesh: &'a crate::scene::Mesh,
    sets: &'a [(RaySet, Vec<crate::rays::Ray>)],
    ref_hits: &'a [Vec<crate::reference::RefHit>],
    settings: &'a crate::render::RenderSettings,
}

impl Group<'_> {
    /// An error or note about one cell, prefixed with the group and the cell.
    fn what(&self, scene: &crate::pipeline::DeviceScene, s: &str) -> String {
        format!("{}, leaf {}, {}: {s}", self.name, self.leaf, label(scene.method, scene.layout))
    }
}

pub fn run(ctx: &Context, o: &StudyOptions, mut progress: impl FnMut(&str)) -> Result<StudyReport> {
    if o.leaf_sizes.is_empty() || o.methods.is_empty() || o.scenes.is_empty() {
        return Err(Error::Usage("study: need at least one scene, leaf size and method".into()));
    }
    let started = Instant::now();
    let provenance = Provenance::of(ctx);
    let mut rows = vec![];
    let mut stopped = None;
    let mut groups_done = 0usize;
    'scenes: for (scene_index, path) in o.scenes.iter().enumerate() {
        if !o.split().runs_any(scene_index) {
            continue;
        }
        let name = crate::scene::scene_name(path);
        let _scene_span = crate::timeline::span_with("scene", || format!("scene {name}"));
        let _scene_label = crate::timeline::labels(|| vec![("scene", name.clone().into())]);
        let mesh = load_obj(path)?;
        progress(&format!("{name}: {} triangles; ray sets and f64 reference", mesh.triangle_count()));
        let (sets, ref_hits) = ray_sets(&name, &mesh, o)?;
        let settings = bench_settings(&mesh, (o.width, o.height), o.spp, o.max_depth, None);
        let mut scene_mean: Option<f64> = None;

        for (leaf_index, &leaf) in o.leaf_sizes.iter().enumerate() {
            if !o.split().runs(scene_index, leaf_index) {
                continue;
            }
            if o.stop.as_ref().is_some_and(|s| s.load(std::sync::atomic::Ordering::SeqCst)) {
                let why = format!(
                    "stopped before {name} leaf {leaf}, after {groups_done} of {} (scene, leaf size) groups",
                    o.split().owned()
                );
                progress(&why);
                stopped = Some(why);
                break 'scenes;
            }
            let _leaf_span = crate::timeline::span_with("leaf", || format!("leaf size {leaf}"));
            let host =
                HostScene::build(&name, &mesh, &BuildOptions { sah_group: o.sah_group, ..BuildOptions::new(leaf) })?;
            let group = Group { name: &name, leaf, mesh: &mesh, sets: &sets, ref_hits: &ref_hits, settings: &settings };
            let quality = bvh_quality(&group, &host, &mut progress);
            let mut cells = group_cells(ctx, o, &group, &host)?;
            for round in 0..=o.repeat.max(1) {
                run_round(ctx, &group, round, o.repeat.max(1), &mut cells, &mut progress)?;
            }
            for cell in cells {
                rows.push(study_row(&group, cell, &quality, &provenance, &mut scene_mean, &mut progress)?);
            }
            groups_done += 1;
        }
    }
    let mut report = StudyReport {
        options: o.clone(),
        scaling: o.scaling(),
        provenance,
        rows,
        seconds: 0.0,
        stopped,
        compiled: None,
    };
    if let Some(c) = &o.compiled {
        progress("compiling the study's kernels for AMD GPUs (RADV's null device)");
        report.compiled = Some(compiled::section(&report, c));
    }
    report.seconds = started.elapsed().as_secs_f64();
    Ok(report)
}

/// Ray sets and their reference hits, once per scene (they do not depend on the BVH).
#[allow(clippy::type_complexity)]
fn ray_sets(
    name: &str,
    mesh: &crate::scene::Mesh,
    o: &StudyOptions,
) -> Result<(Vec<(RaySet, Vec<crate::rays::Ray>)>, Vec<Vec<crate::reference::RefHit>>)> {
    let reference_scene = HostScene::build(name, mesh, &BuildOptions::new(crate::defaults::LEAF_SIZE))?;
    let reference = reference_scene.reference();
    let making = crate::timeline::span("rays", "ray sets");
    let sets: Vec<(RaySet, Vec<crate::rays::Ray>)> =
        RaySet::ALL.iter().map(|&s| Ok((s, s.generate(mesh, &reference, &o.sizes())?))).collect::<Result<_>>()?;
    drop(making);
    let ref_hits: Vec<_> = sets.iter().map(|(_, r)| reference.trace_all(r, false)).collect();
    Ok((sets, ref_hits))
}

/// The group's BVH statistics and EPO (a progress line when the EPO was not computed).
fn bvh_quality(group: &Group, host: &HostScene, progress: &mut dyn FnMut(&str)) -> BvhQuality {
    let quality_span = crate::timeline::span("bvh", "BVH statistics and EPO");
    let st = host.bvh.stats_with_epo(group.mesh);
    drop(quality_span);
    if st.epo.is_none() {
        progress(&format!("{} leaf {}: {}", group.name, group.leaf, crate::bvh::epo::not_computed(&host.bvh)));
    }
    BvhQuality {
        nodes: st.nodes,
        leaves: st.leaves,
        depth: st.depth,
        sah_cost: st.sah_cost,
        epo: st.epo.unwrap_or(f64::NAN),
        quad_padding: st.quad_padding,
        build_ms: st.build_ms,
    }
}

/// One cell per method and layout, each scene on the device, nothing measured yet.
fn group_cells(ctx: &Context, o: &StudyOptions, group: &Group, host: &HostScene) -> Result<Vec<Cell>> {
    let sets = group.sets.len();
    let pixels = group.settings.pixels();
    let mut cells = vec![];
    for kernel in o.experiment().kernels.kernels() {
        cells.push(Cell {
            target: RenderTarget::new(ctx, host, kernel.request(), KernelChoice::Specialised, pixels, true)?,
            renders: vec![],
            set_ms: vec![vec![]; sets],
            set_agreement: vec![0.0; sets],
            set_traversal: vec![None; sets],
        });
    }
    Ok(cells)
}

/// One round over every cell of the group: a render and a cast of every ray set each.
fn run_round(
    ctx: &Context,
    group: &Group,
    round: usize,
    rounds: usize,
    cells: &mut [Cell],
    progress: &mut dyn FnMut(&str),
) -> Result<()> {
    progress(&format!("{} leaf {}: round {round}/{rounds}", group.name, group.leaf));
    // Round 0 validates (and warms up); its times do not count.
    let _round_span = crate::timeline::span_with("round", || format!("round {round}"));
    let _round_label = crate::timeline::labels(|| vec![("round", round.into()), ("warm_up", (round == 0).into())]);
    for cell in cells.iter_mut() {
        let scene = &cell.target.device;
        let rendering =
            crate::timeline::span_with("render", || format!("path-trace render {}", label(scene.method, scene.layout)));
        let r = render(ctx, &cell.target, group.settings, &mut |_| true)?;
        drop(rendering);
        cast_sets(ctx, group, round, cell)?;
        if round > 0 {
            cell.renders.push(r);
        }
    }
    Ok(())
}

/// One cell's casts of every ray set in a round: round 0 validates them and counts their
/// traversal, the later rounds time them.
fn cast_sets(ctx: &Context, group: &Group, round: usize, cell: &mut Cell) -> Result<()> {
    let scene = &cell.target.device;
    for (si, ((set, rays), refs)) in group.sets.iter().zip(group.ref_hits).enumerate() {
        let _set_label = crate::timeline::labels(|| vec![("set", set.to_string().into())]);
        let res = scene.cast(ctx, Raycast::Closest, rays, &RaycastOptions::default())?;
        if round == 0 {
            // Hits are deterministic: validate once, before any time counts.
            let a = validate_hits(group.mesh, rays, &res.hits, refs)
                .map_err(|e| Error::Usage(group.what(scene, &format!("{set} rays: {e}"))))?;
            cell.set_agreement[si] = a.fraction();
            let once = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
            let stats = scene.cast(ctx, Raycast::Stats, rays, &once)?;
            if crate::rays::differing_hits(&stats.hits, &res.hits) > 0 {
                return Err(Error::Usage(
                    group.what(scene, &format!("{set} rays: the statistics variant's hits differ from the kernel's")),
                ));
            }
            let counts = stats.traversal.expect("a stats kernel returns its counts");
            cell.set_traversal[si] = Some(TraversalSummary::of(&counts));
        } else {
            cell.set_ms[si].push(res.time_ms()?.median);
        }
    }
    Ok(())
}

/// A measured cell as the report's row: its renders summarised and checked against the
/// scene's image mean, its ray sets' times, agreement and traversal.
fn study_row(
    group: &Group,
    cell: Cell,
    quality: &BvhQuality,
    provenance: &Provenance,
    scene_mean: &mut Option<f64>,
    progress: &mut dyn FnMut(&str),
) -> Result<StudyRow> {
    let scene = &cell.target.device;
    let m = summarise_renders(&cell.renders).map_err(|e| Error::Usage(group.what(scene, &e.to_string())))?;
    check_image_mean(m.image_mean, scene_mean).map_err(|e| Error::Usage(group.what(scene, &e)))?;
    let set_results = group
        .sets
        .iter()
        .enumerate()
        .map(|(si, (set, rays))| {
            let ms = Summary::of(&cell.set_ms[si]).expect("at least one timed round");
            SetResult {
                set: *set,
                rays: rays.len(),
                kernel_ms: ms,
                mrays_per_s: mrays_summary(rays.len(), ms),
                agreement: cell.set_agreement[si],
                traversal: cell.set_traversal[si].expect("measured in round 0"),
            }
        })
        .collect();
    progress(&format!(
        "{} leaf {} {}: render {:.3} s, {:.2} Msamples/s",
        group.name,
        group.leaf,
        label(scene.method, scene.layout),
        m.ms.median * 1e-3,
        m.msamples_per_s.median
    ));
    Ok(StudyRow {
        scene: group.name.to_string(),
        triangles: group.mesh.triangle_count(),
        leaf_size: group.leaf,
        method: scene.method,
        layout: scene.layout,
        scene_bytes: scene.bytes,
        bvh: quality.clone(),
        render: m,
        render_kernel: cell.target.kernel.source.name,
        raycast_kernel: scene.kernel_source(Raycast::Closest)?.name,
        sets: set_results,
        provenance: provenance.clone(),
    })
}

/// The report's scenes, in the order they were run.
pub fn scenes(report: &StudyReport) -> Vec<String> {
    let mut v: Vec<String> = vec![];
    for r in &report.rows {
        if !v.contains(&r.scene) {
            v.push(r.scene.clone());
        }
    }
    v
}

/// The report's layouts, in the order asked (bvh2 alone for a report without any).
pub fn layouts_of(report: &StudyReport) -> Vec<Layout> {
    if report.options.layouts.is_empty() {
        vec![Layout::DEFAULT]
    } else {
        report.options.layouts.clone()
    }
}

/// Whether the report has a layout other than the paper's binary tree: then its tables and
/// plots name the layout of every figure.
pub fn names_layouts(report: &StudyReport) -> bool {
    layouts_of(report) != [Layout::DEFAULT]
}

/// The cell (scene, leaf size, method, layout), if measured.
pub fn cell<'a>(report: &'a StudyReport, scene: &str, leaf: u32, m: Method, l: Layout) -> Option<&'a StudyRow> {
    report.rows.iter().find(|r| r.scene == scene && r.leaf_size == leaf && r.method == m && r.layout == l)
}

/// SPIR-V instruction counts of the embedded kernel variant `kernel`.
pub fn counts(kernel: &str) -> crate::spirv::InstructionCounts {
    let k = crate::kernels::KERNELS.iter().find(|k| k.name == kernel).expect("the study's kernels are embedded");
    crate::spirv::count(&k.words()).expect("embedded kernels are valid SPIR-V")
}

/// Writes `study.csv`, `study.json`, `study.md` and the plots into `dir` (created if needed),
/// each atomically. Returns the paths written.
pub fn write(report: &StudyReport, dir: &Path) -> Result<Vec<PathBuf>> {
    crate::services::results::write_folder(dir, report)
}

impl crate::services::results::Results for StudyReport {
    const STEM: &'static str = "study";

    const JSON_NEWLINE: bool = true;

    fn markdown(&self, plots: &[crate::services::plots::Plot]) -> String {
        table::markdown(self, plots)
    }

    fn rows(&self) -> Option<Vec<Row>> {
        Some(rows(self))
    }

    fn plan(&self) -> Option<Plan> {
        Some(plan(self))
    }

    fn files(&self) -> Result<Vec<(&'static str, String)>> {
        Ok(vec![("study.csv", table::csv(self)?)])
    }

    fn plots(&self, dir: &Path) -> Result<Vec<crate::services::plots::Plot>> {
        plots::all(self, dir)
    }
}

/// The plan of the whole matrix this report belongs to (every shard's cells), with its shard.
pub fn plan(report: &StudyReport) -> Plan {
    Plan {
        command: "study".into(),
        shard: report.options.shard,
        cells: report.options.plan_cells(),
        source: report.provenance.source(),
    }
}

/// One self-describing row per measured cell (cell keys `scene`, `leaf`, `method`, `layout`):
/// `render_s` and `msamples_per_s` (timings over the timed rounds), per ray set
/// `<set>_mrays_per_s` and `<set>_kernel_ms` (timings), `<set>_agreement` (correctness: the
/// fraction agreeing with the f64 reference) and `<set>_nodes_per_ray` (count: the statistics
/// kernel's mean), and the tree's `sah_cost`, `epo`, `bvh_nodes` and the encoding's
/// `scene_bytes` (counts).
pub fn rows(report: &StudyReport) -> Vec<Row> {
    let source = report.provenance.source();
    report
        .rows
        .iter()
        .map(|r| {
            let mut row = Row::new("study", r.cell().coordinates(), &source)
                .with("render_s", Figure::timing(r.render_seconds(), "s", Better::Lower))
                .with("msamples_per_s", Figure::timing(r.render.msamples_per_s, "Msamples/s", Better::Higher))
                .with("sah_cost", Figure::count(r.bvh.sah_cost, "SAH cost"))
                .with("bvh_nodes", Figure::count(r.bvh.nodes as f64, "nodes"))
                .with("scene_bytes", Figure::count(r.scene_bytes as f64, "bytes"));
            // EPO is NaN where it was not computed; a row holds only numbers.
            if r.bvh.epo.is_finite() {
                row = row.with("epo", Figure::count(r.bvh.epo, "EPO"));
            }
            for s in &r.sets {
                let set = s.set;
                row = row
                    .with(&format!("{set}_mrays_per_s"), Figure::timing(s.mrays_per_s, "Mrays/s", Better::Higher))
                    .with(&format!("{set}_kernel_ms"), Figure::timing(s.kernel_ms, "ms", Better::Lower))
                    .with(&format!("{set}_agreement"), Figure::correctness(s.agreement, "fraction", Better::Higher))
                    .with(&format!("{set}_nodes_per_ray"), Figure::count(s.traversal.nodes.mean, "nodes/ray"));
            }
            row
        })
        .collect()
}
impl crate::report::Report for StudyReport {
    /// The paper's table on this device and the paper's claims, checked.
    fn to_text(&self) -> String {
        let mut s = String::new();
        for l in layouts_of(self) {
            if names_layouts(self) {
                s += &format!("{} ({l}):\n", l.title());
            }
            s += &table::paper_table(self, l).to_text();
            s.push('\n');
        }
        s += &claims::markdown(self);
        if names_layouts(self) {
            s.push('\n');
            s += &layouts::markdown(self);
        }
        s
    }
}

/// Synthetic reports for the unit tests of the claims, tables and the layout question.
#[cfg(test)]
pub(crate) mod testing {
    use super::*;
    use crate::services::render_measure::RenderMeasure;

    fn s(median: f64, spread: f64) -> Summary {
        Summary { median, min: median - spread, max: median + spread, runs: 3 }
    }

    /// A report of three timed rounds over the smoke preset's leaf sizes and methods on `layouts`,
    /// with render times (seconds) `t(scene, leaf, method, layout)` and +-`spread`.
    pub(crate) fn synthetic(
        scenes: &[&str],
        layouts: &[Layout],
        t: impl Fn(&str, u32, Method, Layout) -> f64,
        spread: f64,
    ) -> StudyReport {
        let mut o = StudyOptions::preset(Preset::Smoke);
        o.layouts = layouts.to_vec();
        o.repeat = 3;
        let prov = Provenance {
            device: "test".into(),
            driver: "test".into(),
            mesa_version: None,
            commit: "x".into(),
            date: "d".into(),
            host: crate::host::Host { cpu_model: "test CPU".into(), cpus: 1, ..Default::default() },
            lp_num_threads: None,
            timed_on_gpu: true,
            settings: Default::default(),
            scenes: vec![],
            spirv_compiler: "test compiler",
            driver_package: None,
            compiles_for: None,
        };
        let mut rows = vec![];
        for sc in scenes {
            for &leaf in &o.leaf_sizes {
                for &m in &o.methods {
                    for &l in layouts {
                        let ms = s(t(sc, leaf, m, l) * 1e3, spread * 1e3);
                        rows.push(StudyRow {
                            scene: sc.to_string(),
                            triangles: 1,
                            leaf_size: leaf,
                            method: m,
                            layout: l,
                            scene_bytes: 1,
                            bvh: BvhQuality {
                                nodes: 1,
                                leaves: 1,
                                depth: 0,
                                sah_cost: 1.0,
                                epo: 0.0,
                                quad_padding: 0,
                                build_ms: 0.0,
                            },
                            render: RenderMeasure {
                                msamples_per_s: ms,
                                mrays_per_s: ms,
                                ms,
                                rays_per_sample: 1.0,
                                image_mean: 1.0,
                            },
                            render_kernel: "pathtrace.mt.lambert",
                            raycast_kernel: "raycast.mt.closest",
                            sets: vec![],
                            provenance: prov.clone(),
                        });
                    }
                }
            }
        }
        o.scenes = vec![];
        StudyReport {
            options: o,
            scaling: String::new(),
            provenance: prov,
            rows,
            seconds: 0.0,
            stopped: None,
            compiled: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pairs(c: &result_rows::Cell) -> Vec<(&str, &str)> {
        c.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect()
    }

    #[test]
    fn a_study_cell_reads_back_from_the_coordinates_it_writes() {
        let want = [("layout", "cwbvh"), ("leaf", "8"), ("method", "quad-unit"), ("scene", "dragon")];
        let c = StudyCell { scene: "dragon".into(), leaf: 8, method: Method::QuadUnit, layout: Layout::Cwbvh };
        assert_eq!(pairs(&c.coordinates()), want);
        let read = StudyCell::try_from(&result_rows::cell(want)).unwrap();
        assert_eq!(read, c);
        assert_eq!(pairs(&read.coordinates()), want);
        // Rows from before layouts were an axis name none: the binary tree.
        let old = result_rows::cell([("scene", "bunny"), ("leaf", "4"), ("method", "mt")]);
        let read = StudyCell::try_from(&old).unwrap();
        assert_eq!((read.layout, read.leaf, read.method), (Layout::Bvh2, 4, Method::Mt));
    }

    #[test]
    fn a_study_cell_without_a_coordinate_or_with_an_unknown_value_names_it_and_the_file() {
        let file = Path::new("runs/a/rows.jsonl");
        let no_method = result_rows::cell([("scene", "bunny"), ("leaf", "4"), ("layout", "bvh2")]);
        let e = StudyCell::parse(&no_method, file).unwrap_err().to_string();
        assert!(e.contains("runs/a/rows.jsonl") && e.contains("has no `method` coordinate"), "{e}");
        assert!(e.contains("study layout=bvh2 leaf=4 scene=bunny"), "{e}");
        let no_scene = result_rows::cell([("leaf", "4"), ("method", "mt")]);
        let e = StudyCell::parse(&no_scene, file).unwrap_err().to_string();
        assert!(e.contains("has no `scene` coordinate"), "{e}");
        let bad_leaf = result_rows::cell([("scene", "bunny"), ("leaf", "four"), ("method", "mt")]);
        let e = StudyCell::parse(&bad_leaf, file).unwrap_err().to_string();
        assert!(e.contains("leaf:") && e.contains("runs/a/rows.jsonl"), "{e}");
        let bad_layout = result_rows::cell([("scene", "bunny"), ("leaf", "4"), ("method", "mt"), ("layout", "bvh3")]);
        let e = StudyCell::parse(&bad_layout, file).unwrap_err().to_string();
        assert!(e.contains("layout:") && e.contains("bvh3"), "{e}");
    }
}
