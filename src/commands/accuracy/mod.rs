//! `trilab accuracy`: how exact each intersector is, on the same rays for every method and
//! leaf size, judged by proofs (closed meshes) and by the f64 [`crate::reference`].
//!
//! - **Leaks** ([`closed`], [`probes`]): rays from origins proven inside closed meshes (winding
//!   number in f64 on the rounded f32 mesh), towards random directions, vertices and points on
//!   shared edges. Every one must hit; a miss is a leak. Reported per 10^6 rays.
//! - **False hits**: rays aimed just outside silhouette edges (offset d x edge length across the
//!   line of sight, d from 1e-1 to 1e-7, in f64) that the f64 reference says miss; a GPU hit is a
//!   false hit.
//! - **Errors** ([`metrics`]): where GPU and reference hit the same triangle, |t - t_ref| in f32
//!   ULPs of t_ref and the barycentric error (median, p99, max).
//! - **Self-intersection** ([`offset`]): secondary rays from hit points reconstructed from the
//!   barycentrics, offset by each scheme, at scales 10^-8 .. 10^8; self-hits and near hits.
//! - **Extremes** (leaf size 4 only: the intersector, not the tree, decides them): the scene
//!   scaled by 10^k and translated by 10^k, grazing rays, slivers, tiny and huge triangles,
//!   zero-area and repeated-vertex triangles.
//! - **Frontier**: Mrays/s (bunny diffuse rays, leaf 4, validated, [`crate::commands::bench::measure_rays`])
//!   against leak rate and t error per method.
//!
//! - **Layouts** (`--layouts`, default `bvh2`): leaks, false hits and errors are measured with
//!   every layout's kernels (the same rays, the same leaves; only the node layout and its
//!   traversal differ), the claim to hold being that a watertight test stays leak-free on every
//!   layout (the box test must not cull what the triangle test would hit). The extremes, the
//!   self-intersection study and the frontier stay on `bvh2`.
//!
//! Every output carries the device's float controls and the run's provenance. A method whose
//! kernel the device cannot create (`Error::Unsupported`, e.g. f64 without shaderFloat64) is
//! listed as unsupported and skipped.

pub mod closed;
pub mod metrics;

pub mod plots;
pub mod probes;
pub mod rng;
pub mod table;

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec3, Vec3};
use serde::Serialize;

use self::closed::{prove_closed, ClosedMesh, Placement};
use self::metrics::{per_million, Tally, TallyBuilder};
use self::probes::{LeakKind, Rng};
use crate::bvh::{BuildOptions, Bvh};
use crate::encoding::{AccessPath, Layout, Method, Raycast};
use crate::error::{Error, Result};
use crate::gpu::{Context, DeviceInfo, RaycastOptions};
use crate::matrix::{Experiment, KernelAxes};
use crate::named::named_enum;
use crate::pipeline::{HostScene, SceneRequest};
use crate::rays::offset::{Offset, SurfacePoint};
use crate::rays::{Camera, Hit, Ray};
use crate::reference::{RefHit, Reference};
use crate::report::Summary;
use crate::scene::Mesh;
use crate::services::provenance::Provenance;
use crate::services::rayset::RaySet;
use crate::services::shard::{self, Shard, Split};
use crate::services::validate::measure_rays;
use crate::shared::MISS_ID;

named_enum! {
    /// Workload presets.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Preset: "accuracy preset" {
        /// The whole sweep: about 4 minutes on a 2-core lavapipe machine with the eight methods.
        Full = "full",
        /// Seconds, for CI.
        Smoke = "smoke",
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct AccuracyOptions {
    pub preset: Preset,
    pub methods: Vec<Method>,
    pub leaf_sizes: Vec<u32>,
    /// Node layouts the leaks, false hits and errors are measured on (each method on each).
    pub layouts: Vec<Layout>,
    /// Leak rays per (closed mesh, kind); 0 skips leaks, false hits and errors.
    pub leak_rays: usize,
    /// Proven-inside origins per closed mesh (rays share them).
    pub origins: usize,
    /// Finer closed meshes (tens of thousands of triangles) instead of coarse ones.
    pub fine_meshes: bool,
    /// Silhouette rays tried per (mesh, d).
    pub silhouette_rays: usize,
    /// Secondary rays per (scale, method, scheme); 0 skips the self-intersection study.
    pub self_rays: usize,
    pub schemes: Vec<Offset>,
    /// Scales 10^k of the self-intersection study.
    pub self_scales: Vec<i32>,
    /// Rays per extreme case; 0 skips the extremes.
    pub extreme_rays: usize,
    /// Frontier speed: diffuse rays from a `bench_width` x `bench_height` camera on the bunny,
    /// one per primary hit; 0 skips the frontier.
    pub bench_width: u32,
    pub bench_height: u32,
    pub repeat: usize,
    /// Bundled scenes whose closedness is checked (and, if proven closed, used for leaks).
    pub real_scenes: Vec<PathBuf>,
    /// The user's own meshes (`--scene`): each must be proven closed (else the run is refused
    /// before any work), then its leaks are measured beside the generated meshes'.
    pub scenes: Vec<PathBuf>,
    pub seed: u64,
    /// Run only this shard's (leaf size, layout) groups of the leak, false-hit and error sweeps
    /// ([`AccuracyOptions::split`]); the extremes, self-intersection and frontier run in
    /// the one shard that owns the frontier's group ([`AccuracyOptions::runs_fixed_parts`]).
    pub shard: Option<Shard>,
}

/// Offsets d (relative to the edge length) of the false-hit rays.
pub const FALSE_HIT_OFFSETS: [i32; 7] = [-1, -2, -3, -4, -5, -6, -7];
/// Leaf size of the extremes, the self-intersection study and the frontier.
pub const FIXED_LEAF: u32 = 4;

impl AccuracyOptions {
    pub fn preset(preset: Preset) -> AccuracyOptions {
        let full = AccuracyOptions {
            preset,
            methods: Method::ALL.to_vec(),
            leaf_sizes: crate::bvh::PAPER_LEAF_SIZES.to_vec(),
            layouts: vec![Layout::DEFAULT],
            leak_rays: 400_000,
            origins: 64,
            fine_meshes: true,
            silhouette_rays: 50_000,
            self_rays: 100_000,
            schemes: Offset::ALL.to_vec(),
            self_scales: (-8..=8).collect(),
            extreme_rays: 100_000,
            bench_width: crate::defaults::WIDTH,
            bench_height: crate::defaults::HEIGHT,
            repeat: 3,
            real_scenes: vec![PathBuf::from("bunny")],
            scenes: vec![],
            seed: crate::defaults::SEED,
            shard: None,
        };
        match preset {
            Preset::Full => full,
            Preset::Smoke => AccuracyOptions {
                methods: Method::paper(),
                leak_rays: 2_000,
                origins: 16,
                fine_meshes: false,
                silhouette_rays: 500,
                self_rays: 2_000,
                self_scales: vec![-8, -4, 0, 4, 8],
                extreme_rays: 500,
                bench_width: 40,
                bench_height: 30,
                repeat: 1,
                real_scenes: vec![],
                ..full
            },
        }
    }
}

impl AccuracyOptions {
    /// The leak sweep's matrix for `methods`: no scene (the closed meshes are the part's own),
    /// each leaf size, each method on each layout (`bvh2` where none is named).
    pub fn leak_experiment(&self, methods: &[Method]) -> Experiment {
        Experiment {
            leaf_sizes: self.leaf_sizes.clone(),
            kernels: KernelAxes { methods: methods.to_vec(), layouts: self.layouts.clone(), ..Default::default() },
            ..Default::default()
        }
    }

    /// The layout of the frontier (and its leaf size [`FIXED_LEAF`]): `bvh2` when measured.
    pub fn frontier_layout(&self) -> Layout {
        if self.layouts.contains(&Layout::DEFAULT) || self.layouts.is_empty() {
            Layout::DEFAULT
        } else {
            self.layouts[0]
        }
    }

    /// The leak, false-hit and error sweeps as their shards split them: a shard takes whole
    /// (leaf size, layout) groups, leaf size major.
    pub fn split(&self) -> Split {
        Split::new(self.shard, self.leaf_sizes.len(), self.layouts.len())
    }

    /// Refuses more shards than (leaf size, layout) groups, naming `--shard`, before any work.
    pub fn check_shard(&self) -> Result<()> {
        let (leaves, layouts) = (self.leaf_sizes.len(), self.layouts.len());
        self.split().check(&format!(
            "an accuracy shard takes whole (leaf size, layout) groups of the leak sweep and this run has {} \
             ({leaves} leaf size(s) x {layouts} layout(s))",
            leaves * layouts
        ))
    }

    /// Whether this run takes the extremes, self-intersection and frontier: the shard owning
    /// the frontier's group (leaf [`FIXED_LEAF`] on [`Self::frontier_layout`], whose leak and
    /// error rows the frontier reads; the first leaf size when [`FIXED_LEAF`] is not swept).
    /// Their rays come from the one random stream after the leak rays, which every shard draws
    /// whole, so they are the unsharded run's rays.
    pub fn runs_fixed_parts(&self) -> bool {
        let leaf = self.leaf_sizes.iter().position(|&l| l == FIXED_LEAF).unwrap_or(0);
        let layout = self.layouts.iter().position(|&l| l == self.frontier_layout()).unwrap_or(0);
        self.split().runs(leaf, layout)
    }
}

/// Every cell of the whole accuracy matrix (all shards), with [`rows`]'s coordinates for the
/// `methods` the device runs, except the frontier's `rays` (its diffuse ray count depends on the
/// bunny's primary hits: measured, not planned).
pub fn plan_cells(o: &AccuracyOptions, methods: &[Method]) -> Vec<crate::rows::Cell> {
    let mut methods = methods.to_vec();
    methods.sort_by_key(|m| m.to_string());
    let leaks = o.leak_experiment(&methods).cells();
    let mut cells = vec![];
    for m in &methods {
        if o.leak_rays > 0 && !o.leaf_sizes.is_empty() {
            for c in leaks.iter().filter(|c| c.kernel.method == *m) {
                let (leaf, layout) = (c.group.leaf, c.kernel.layout);
                cells.push(AccuracyCell::Leaks { method: *m, leaf, layout, rays: o.leak_rays });
            }
        }
        if o.extreme_rays > 0 {
            for kind in EXTREME_KINDS {
                cells.push(AccuracyCell::Extremes { method: *m, kind: kind.to_string(), rays: o.extreme_rays });
            }
        }
        if o.self_rays > 0 && !o.self_scales.is_empty() {
            for scheme in &o.schemes {
                cells.push(AccuracyCell::SelfIntersection { method: *m, scheme: *scheme, rays: o.self_rays });
            }
        }
        if o.bench_width > 0 && o.bench_height > 0 {
            cells.push(AccuracyCell::Frontier { method: *m, layout: o.frontier_layout(), rays: None });
        }
    }
    cells.iter().map(AccuracyCell::coordinates).collect()
}

/// An accuracy cell: what the plan lists and a row measures, one per part of the study.
#[derive(Clone, Debug, PartialEq)]
pub enum AccuracyCell {
    /// Leaks and false hits through the closed meshes (`rays`: `--leak-rays`).
    Leaks { method: Method, leaf: u32, layout: Layout, rays: usize },
    /// One kind of extreme geometry (`EXTREME_KINDS`).
    Extremes { method: Method, kind: String, rays: usize },
    /// One self-intersection offset scheme.
    SelfIntersection { method: Method, scheme: Offset, rays: usize },
    /// The speed/accuracy frontier's timing (`rays`: known once measured; the plan has none).
    Frontier { method: Method, layout: Layout, rays: Option<usize> },
}

impl AccuracyCell {
    /// The cell's coordinates, as `rows.jsonl` names them.
    pub fn coordinates(&self) -> crate::rows::Cell {
        use crate::rows::cell;
        match self {
            AccuracyCell::Leaks { method, leaf, layout, rays } => cell([
                ("part", "leaks".to_owned()),
                ("method", method.to_string()),
                ("leaf", leaf.to_string()),
                ("layout", layout.to_string()),
                ("leak_rays", rays.to_string()),
            ]),
            AccuracyCell::Extremes { method, kind, rays } => cell([
                ("part", "extremes".to_owned()),
                ("method", method.to_string()),
                ("kind", kind.clone()),
                ("rays", rays.to_string()),
            ]),
            AccuracyCell::SelfIntersection { method, scheme, rays } => cell([
                ("part", "self-intersection".to_owned()),
                ("method", method.to_string()),
                ("scheme", scheme.name().to_owned()),
                ("rays", rays.to_string()),
            ]),
            AccuracyCell::Frontier { method, layout, rays } => {
                let mut c = cell([
                    ("part", "frontier".to_owned()),
                    ("method", method.to_string()),
                    ("layout", layout.to_string()),
                ]);
                if let Some(r) = rays {
                    c.insert("rays".into(), r.to_string());
                }
                c
            }
        }
    }
}

/// The extreme kinds, in the order [`extremes`] measures them.
pub const EXTREME_KINDS: [&str; 6] = ["scale", "translate", "grazing", "sliver", "size", "degenerate"];

/// A closed mesh of the leak study.
#[derive(Clone, Debug, Serialize)]
pub struct MeshInfo {
    pub name: String,
    pub triangles: usize,
    /// `Ok` or why the closedness proof failed.
    pub closed: std::result::Result<(), String>,
    pub origins: usize,
    pub rejected_origins: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct LeakRow {
    pub method: Method,
    pub leaf_size: u32,
    pub layout: Layout,
    pub mesh: String,
    pub kind: LeakKind,
    pub tally: Tally,
}

#[derive(Clone, Debug, Serialize)]
pub struct FalseHitRow {
    pub method: Method,
    pub leaf_size: u32,
    pub layout: Layout,
    pub mesh: String,
    /// log10 of the offset relative to the edge length.
    pub d_exp: i32,
    /// Rays tried; `tally.rays` are those the reference says miss.
    pub candidates: usize,
    pub tally: Tally,
}

/// t and barycentric errors over all leak rays of a (method, leaf size, layout).
#[derive(Clone, Debug, Serialize)]
pub struct ErrorRow {
    pub method: Method,
    pub leaf_size: u32,
    pub layout: Layout,
    pub tally: Tally,
}

#[derive(Clone, Debug, Serialize)]
pub struct SelfHitRow {
    pub method: Method,
    pub leaf_size: u32,
    pub scale_exp: i32,
    pub scheme: Offset,
    pub rays: usize,
    /// Secondary rays that hit the triangle they left.
    pub self_hits: usize,
    /// Secondary rays that hit any triangle at t < 1e-4 of the scene's extent.
    pub near_hits: usize,
    /// Secondary rays spawned on the inside of the closed mesh (their primary came from a
    /// proven-inside origin) that hit nothing: the offset pushed the origin out through the
    /// surface (or a leak). Of `inside_rays`.
    pub escaped: usize,
    pub inside_rays: usize,
    pub nan: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct ExtremeRow {
    pub kind: String,
    pub param: String,
    pub method: Method,
    pub leaf_size: u32,
    pub triangles: usize,
    /// The scene's largest |coordinate| over its largest side (`analyze::Conditioning`): how
    /// far from the origin it sits in units of its own size (about 0.5 when centred).
    pub magnitude_over_extent: f64,
    /// Triangles the encoding could not represent (replaced by never-hit padding).
    pub unrepresentable: usize,
    /// Whether every ray is proven to hit (closed mesh, inside origin).
    pub must_hit: bool,
    pub tally: Tally,
}

#[derive(Clone, Debug, Serialize)]
pub struct FrontierRow {
    pub method: Method,
    /// The layout it was timed on (and whose leaks it shows): bvh2 when measured, else the first.
    pub layout: Layout,
    /// How the kernel read the scene.
    pub scene_access: AccessPath,
    pub mrays_per_s: Option<Summary>,
    /// Why there is no speed (validation failed), if there is none.
    pub note: Option<String>,
    pub leaks_per_million: f64,
    pub false_hits_per_million: f64,
    pub t_ulps_median: f64,
    pub t_ulps_p99: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct AccuracyReport {
    pub provenance: Provenance,
    pub device: DeviceInfo,
    pub options: AccuracyOptions,
    pub meshes: Vec<MeshInfo>,
    /// Real scenes checked for closedness: (name, triangles, proof result).
    pub real_scenes: Vec<(String, usize, std::result::Result<(), String>)>,
    pub unsupported: Vec<(Method, String)>,
    pub leaks: Vec<LeakRow>,
    pub false_hits: Vec<FalseHitRow>,
    pub errors: Vec<ErrorRow>,
    pub self_hits: Vec<SelfHitRow>,
    pub extremes: Vec<ExtremeRow>,
    pub frontier: Vec<FrontierRow>,
    pub frontier_rays: usize,
    pub seconds: f64,
    /// Every cell of the whole matrix (all shards; [`plan_cells`]), written as the rows' plan.
    #[serde(skip)]
    pub plan: Vec<crate::rows::Cell>,
}

/// A method whose kernel exists on this device.
struct RunnableMethod {
    method: Method,
}

/// Methods the device cannot run, with the reason.
type Unsupported = Vec<(Method, String)>;

/// The error tally of every leak ray of one (method, leaf size, layout), for the error rows
/// (8 bytes per ray: keeping the rays and hits themselves ran a four-layout sweep out of 24 GiB).
struct ErrorSample {
    method: Method,
    leaf: u32,
    layout: Layout,
    tally: TallyBuilder,
}

/// Kernels for `methods`; `Error::Unsupported` ones are returned separately, not as errors.
fn tracers(ctx: &Context, methods: &[Method]) -> Result<(Vec<RunnableMethod>, Unsupported)> {
    let mut ok = Vec::new();
    let mut unsupported = Vec::new();
    for &method in methods {
        // Creating the kernel (kept by the context for the casts) finds what the device lacks.
        match ctx.kernel(method.raycast_kernel(Raycast::Closest, AccessPath::Texel)) {
            Ok(_) => ok.push(RunnableMethod { method }),
            Err(Error::Unsupported(why)) => unsupported.push((method, why)),
            Err(e) => return Err(e),
        }
    }
    Ok((ok, unsupported))
}

/// Closest hits of `rays` with `t`'s method over `host`'s nodes in `layout`; also the number
/// of triangles the encoding could not represent.
fn cast(
    ctx: &Context,
    t: &RunnableMethod,
    host: &HostScene,
    layout: Layout,
    rays: &[Ray],
) -> Result<(Vec<Hit>, usize)> {
    let scene = host.upload(ctx, &SceneRequest::new(t.method).layout(layout))?;
    let res =
        scene.cast(ctx, Raycast::Closest, rays, &RaycastOptions { warmup: 0, repeat: 1, ..Default::default() })?;
    Ok((res.hits, scene.unrepresentable.len()))
}

/// `mesh`'s BVH at `leaf` (checked by [`run`]), shared by every method.
fn build(mesh: &Mesh, leaf: u32) -> HostScene<'_> {
    HostScene::with_bvh("accuracy", mesh, Bvh::build(mesh, &BuildOptions::new(leaf)))
}

/// A closed mesh ready for leak rays: placed, proven closed, with proven-inside origins.
struct LeakScene {
    name: String,
    mesh: Mesh,
    origins: Vec<Vec3>,
    info: MeshInfo,
}

fn leak_scene(cm: &ClosedMesh, place: Placement, origins: usize, rng: &mut Rng) -> LeakScene {
    let mesh = cm.to_mesh(place);
    let closed = prove_closed(&mesh.triangles);
    let (o, rejected) =
        if closed.is_ok() { probes::inside_origins(cm, &mesh, place, origins, rng) } else { (vec![], 0) };
    LeakScene {
        name: cm.name.clone(),
        info: MeshInfo {
            name: cm.name.clone(),
            triangles: mesh.triangle_count(),
            closed,
            origins: o.len(),
            rejected_origins: rejected,
        },
        mesh,
        origins: o,
    }
}

/// The user's meshes (`--scene`), loaded and proven closed: a mesh that is not closed is
/// refused with the proof's reason, before any ray is cast.
fn load_user_scenes(paths: &[PathBuf]) -> Result<Vec<(String, Mesh)>> {
    paths
        .iter()
        .map(|path| {
            let mesh = crate::scene::load_obj(path)?;
            if let Err(why) = prove_closed(&mesh.triangles) {
                return Err(Error::Usage(format!(
                    "accuracy --scene {}: not proven closed ({why}); leaks can only be measured on a closed mesh",
                    path.display()
                )));
            }
            Ok((crate::scene::scene_name(path), mesh))
        })
        .collect()
}

/// A real scene: checked for closedness; if closed, origins are drawn from its bounds and kept
/// where the winding number proves them inside.
fn real_leak_scene(path: &Path, origins: usize, rng: &mut Rng) -> Result<(LeakScene, bool)> {
    let mesh = crate::scene::load_obj(path)?;
    Ok(leak_scene_of(crate::scene::scene_name(path), mesh, origins, rng))
}

/// [`real_leak_scene`] for a loaded mesh.
fn leak_scene_of(name: String, mesh: Mesh, origins: usize, rng: &mut Rng) -> (LeakScene, bool) {
    let closed = prove_closed(&mesh.triangles);
    let mut o = Vec::new();
    let mut rejected = 0;
    if closed.is_ok() {
        let b = mesh.bounds();
        let (lo, hi) = (b.min.as_dvec3(), b.max.as_dvec3());
        for _ in 0..origins * 8 {
            if o.len() == origins {
                break;
            }
            let p = (lo + (hi - lo) * DVec3::new(rng.unit(), rng.unit(), rng.unit())).as_vec3();
            if closed::proven_inside(&mesh, p.as_dvec3()) {
                o.push(p);
            } else {
                rejected += 1;
            }
        }
    }
    let ok = closed.is_ok() && !o.is_empty();
    let info = MeshInfo {
        name: name.clone(),
        triangles: mesh.triangle_count(),
        closed,
        origins: o.len(),
        rejected_origins: rejected,
    };
    (LeakScene { name, mesh, origins: o, info }, ok)
}

/// Runs the study. `progress` gets one line per step.
pub fn run(ctx: &Context, o: &AccuracyOptions, mut progress: impl FnMut(&str)) -> Result<AccuracyReport> {
    let start = Instant::now();
    if o.methods.is_empty() {
        return Err(Error::Usage("accuracy: no methods".into()));
    }
    if o.layouts.is_empty() {
        return Err(Error::Usage("accuracy --layouts: name at least one layout".into()));
    }
    for (i, l) in o.layouts.iter().enumerate() {
        if o.layouts[..i].contains(l) {
            return Err(Error::Usage(format!("accuracy --layouts: {l} is named twice")));
        }
    }
    for &l in &o.leaf_sizes {
        if !(1..=crate::bvh::MAX_LEAF_SIZE).contains(&l) {
            return Err(Error::Usage(format!("accuracy: leaf size {l} is not 1..={}", crate::bvh::MAX_LEAF_SIZE)));
        }
    }
    // The user's meshes are refused now, not after the generated meshes' rays.
    let user_scenes = load_user_scenes(&o.scenes)?;
    // Bundled scenes are found (or refused) now, and so named in the provenance.
    for path in &o.real_scenes {
        crate::scene::resolve(path)?;
    }
    if o.bench_width > 0 && o.bench_height > 0 {
        crate::scene::resolve(Path::new("bunny"))?;
    }
    o.check_shard()?;
    let (tracers, unsupported) = tracers(ctx, &o.methods)?;
    for (m, why) in &unsupported {
        progress(&format!("{m}: unsupported on this device ({why}); skipped"));
    }
    let mut report = AccuracyReport {
        provenance: Provenance::of(ctx),
        device: ctx.info().clone(),
        options: o.clone(),
        meshes: vec![],
        real_scenes: vec![],
        unsupported,
        leaks: vec![],
        false_hits: vec![],
        errors: vec![],
        self_hits: vec![],
        extremes: vec![],
        frontier: vec![],
        frontier_rays: 0,
        seconds: 0.0,
        plan: plan_cells(o, &tracers.iter().map(|t| t.method).collect::<Vec<_>>()),
    };
    let mut rng = Rng::new(o.seed);
    if o.leak_rays > 0 {
        let _span = crate::timeline::span("section", "leaks and false hits on closed meshes");
        leaks_and_false_hits(ctx, o, user_scenes, &tracers, &mut report, &mut rng, &mut progress)?;
    }
    let fixed = o.runs_fixed_parts();
    if o.self_rays > 0 && fixed {
        for &k in &o.self_scales {
            let _span = crate::timeline::span_with("section", || format!("self-intersection at scale 1e{k}"));
            let rows = self_intersection(ctx, &tracers, k, o.self_rays, &o.schemes, &mut rng)?;
            for m in tracers.iter().map(|t| t.method) {
                let line: Vec<String> = rows
                    .iter()
                    .filter(|r| r.method == m)
                    .map(|r| format!("{} {}", r.scheme.name(), r.self_hits))
                    .collect();
                progress(&format!("self-hits at scale 1e{k} {m}: {}", line.join(", ")));
            }
            report.self_hits.extend(rows);
        }
    }
    if o.extreme_rays > 0 && fixed {
        let _span = crate::timeline::span("section", "extremes");
        extremes(ctx, o, &tracers, &mut report, &mut rng, &mut progress)?;
    }
    if o.bench_width > 0 && o.bench_height > 0 && fixed {
        let _span = crate::timeline::span("section", "speed/accuracy frontier");
        frontier(ctx, o, &tracers, &mut report, &mut progress)?;
    }
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// Leaks, false hits and errors per method x leaf size on the closed meshes.
fn leaks_and_false_hits(
    ctx: &Context,
    o: &AccuracyOptions,
    user_scenes: Vec<(String, Mesh)>,
    tracers: &[RunnableMethod],
    report: &mut AccuracyReport,
    rng: &mut Rng,
    progress: &mut impl FnMut(&str),
) -> Result<()> {
    let scenes = leak_scenes(o, user_scenes, report, rng, progress)?;
    let cells = o.leak_experiment(&tracers.iter().map(|t| t.method).collect::<Vec<_>>()).cells();
    // Per leaf size and method: (all leak rays' GPU hits, reference hits) for the error rows.
    let mut errors: Vec<ErrorSample> = Vec::new();
    for scene in &scenes {
        report.meshes.push(scene.info.clone());
        if let Err(e) = &scene.info.closed {
            return Err(Error::Usage(format!("generated mesh {} is not closed: {e}", scene.name)));
        }
        let mesh = &scene.mesh;
        let host4 = build(mesh, FIXED_LEAF);
        let reference = host4.reference();
        let probe = probe_rays(o, scene, &reference, rng);
        let (rays, leak_count) = (&probe.rays, probe.leak_count);
        let t0 = Instant::now();
        let ref_hits = reference.trace_all(rays, false);
        progress(&format!(
            "{}: {} triangles, {} origins, {} leak + {} false-hit rays; reference in {:.1} s",
            scene.name,
            mesh.triangle_count(),
            scene.origins.len(),
            leak_count,
            rays.len() - leak_count,
            t0.elapsed().as_secs_f64()
        ));
        let split = o.split();
        for same in cells.chunk_by(|a, b| a.group == b.group) {
            let (li, leaf) = (same[0].group.leaf_index, same[0].group.leaf);
            if !split.runs_any(li) {
                continue; // another shard's leaf size
            }
            let host = build(mesh, leaf);
            let layout_index = |l| o.layouts.iter().position(|&x| x == l).unwrap_or(0);
            for c in same.iter().filter(|c| split.runs(li, layout_index(c.kernel.layout))) {
                let Some(t) = tracers.iter().find(|t| t.method == c.kernel.method) else { continue };
                let layout = c.kernel.layout;
                let (hits, _) = cast(ctx, t, &host, layout, rays)?;
                let leaks = tally_parts(report, scene, &probe, (t.method, leaf, layout), &hits, &ref_hits);
                let pos = match errors.iter().position(|e| e.method == t.method && e.leaf == leaf && e.layout == layout)
                {
                    Some(p) => p,
                    None => {
                        errors.push(ErrorSample { method: t.method, leaf, layout, tally: TallyBuilder::default() });
                        errors.len() - 1
                    }
                };
                errors[pos].tally.add(&rays[..leak_count], &hits[..leak_count], &ref_hits[..leak_count], true, &[]);
                let on = if layout == Layout::DEFAULT { String::new() } else { format!(" on {layout}") };
                progress(&format!("{} leaf {leaf} {}{on}: {leaks} leaks in {leak_count} rays", scene.name, t.method));
            }
        }
    }
    for e in errors {
        report.errors.push(ErrorRow { method: e.method, leaf_size: e.leaf, layout: e.layout, tally: e.tally.finish() });
    }
    Ok(())
}

/// The closed meshes leak rays start inside: the standard ones, the real scenes proven closed
/// (every real scene is listed in the report, closed or not) and the user's `--scene`s.
fn leak_scenes(
    o: &AccuracyOptions,
    user_scenes: Vec<(String, Mesh)>,
    report: &mut AccuracyReport,
    rng: &mut Rng,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<LeakScene>> {
    let mut scenes: Vec<LeakScene> = closed::standard_meshes(o.fine_meshes)
        .iter()
        .map(|cm| leak_scene(cm, Placement::IDENTITY, o.origins, rng))
        .collect();
    for path in &o.real_scenes {
        // Bundled names resolve from any folder; one found nowhere is an error, not a skip.
        let (scene, usable) = real_leak_scene(path, o.origins, rng)?;
        report.real_scenes.push((scene.name.clone(), scene.info.triangles, scene.info.closed.clone()));
        match &scene.info.closed {
            Ok(()) => progress(&format!("{}: proven closed; used for leaks", scene.name)),
            Err(e) => progress(&format!("{}: not closed ({e}); not used for leaks", scene.name)),
        }
        if usable {
            scenes.push(scene);
        }
    }
    for (name, mesh) in user_scenes {
        // Proven closed by `load_user_scenes`; origins still have to be found inside it.
        let (scene, usable) = leak_scene_of(name, mesh, o.origins, rng);
        if !usable {
            return Err(Error::Usage(format!(
                "accuracy --scene {}: closed, but none of {} random points in its bounds is proven inside it \
                 (a very thin mesh?); no leak rays can start inside it",
                scene.name,
                o.origins * 8
            )));
        }
        progress(&format!("{}: proven closed; {} inside origins; used for leaks", scene.name, scene.origins.len()));
        report.real_scenes.push((scene.name.clone(), scene.info.triangles, scene.info.closed.clone()));
        scenes.push(scene);
    }
    Ok(scenes)
}

/// One closed mesh's probe rays in one list: leak rays of each kind, then the false-hit rays
/// the reference misses.
struct ProbeRays {
    rays: Vec<Ray>,
    /// Each part of `rays`: (label, start, len).
    parts: Vec<(String, usize, usize)>,
    /// The leak rays, the first parts.
    leak_count: usize,
    /// Per false-hit offset: the silhouette rays made before the reference's misses were kept.
    candidates: Vec<usize>,
}

fn probe_rays(o: &AccuracyOptions, scene: &LeakScene, reference: &Reference, rng: &mut Rng) -> ProbeRays {
    let mesh = &scene.mesh;
    let mut rays = Vec::new();
    let mut parts: Vec<(String, usize, usize)> = Vec::new(); // (label, start, len)
    for kind in LeakKind::ALL {
        let r = probes::leak_rays(mesh, &scene.origins, kind, o.leak_rays, rng);
        parts.push((kind.name().into(), rays.len(), r.len()));
        rays.extend(r);
    }
    let leak_count = rays.len();
    let b = mesh.bounds();
    let centre = ((b.min + b.max) * 0.5).as_dvec3();
    let eye = centre + DVec3::new(2.5, 1.5, 3.5) * (b.max - b.min).max_element() as f64;
    let mut candidates = Vec::new();
    for &d in &FALSE_HIT_OFFSETS {
        let r = probes::silhouette_rays(mesh, eye, 10f64.powi(d), o.silhouette_rays, rng);
        let hits = reference.trace_all(&r, false);
        let kept: Vec<Ray> = r.iter().zip(&hits).filter(|(_, h)| !h.is_hit()).map(|(r, _)| *r).collect();
        candidates.push(r.len());
        parts.push((format!("d{d}"), rays.len(), kept.len()));
        rays.extend(kept);
    }
    ProbeRays { rays, parts, leak_count, candidates }
}

/// One cell's (method, leaf size, layout) leak and false-hit rows, part by part, into the
/// report; returns the leaks counted.
fn tally_parts(
    report: &mut AccuracyReport,
    scene: &LeakScene,
    probe: &ProbeRays,
    (method, leaf, layout): (Method, u32, Layout),
    hits: &[Hit],
    ref_hits: &[RefHit],
) -> usize {
    let mut leaks = 0;
    for (pi, (label, s, n)) in probe.parts.iter().enumerate() {
        let (r, h, rh) = (&probe.rays[*s..s + n], &hits[*s..s + n], &ref_hits[*s..s + n]);
        if pi < LeakKind::ALL.len() {
            let tally = Tally::of(r, h, rh, true, &[]);
            leaks += tally.leaks;
            let kind = LeakKind::ALL[pi];
            report.leaks.push(LeakRow { method, leaf_size: leaf, layout, mesh: scene.name.clone(), kind, tally });
        } else {
            let d_exp: i32 = label[1..].parse().expect("labels are d<exp>");
            report.false_hits.push(FalseHitRow {
                method,
                leaf_size: leaf,
                layout,
                mesh: scene.name.clone(),
                d_exp,
                candidates: probe.candidates[pi - LeakKind::ALL.len()],
                tally: Tally::of(r, h, rh, false, &[]),
            });
        }
    }
    leaks
}

/// Cosine-weighted direction about the unit normal `n` (f64, rounded once).
fn cosine_direction(n: Vec3, rng: &mut Rng) -> Vec3 {
    let n = n.as_dvec3();
    let (t, b) = n.any_orthonormal_pair();
    let r1 = rng.unit();
    let phi = std::f64::consts::TAU * rng.unit();
    let d = t * (r1.sqrt() * phi.cos()) + b * (r1.sqrt() * phi.sin()) + n * (1.0 - r1).max(0.0).sqrt();
    d.as_vec3()
}

/// The self-intersection study at scale 10^k on a closed icosphere: primary rays from inside
/// (hitting the inner surface) and from outside; for each method and scheme, `n` secondary rays.
fn self_intersection(
    ctx: &Context,
    tracers: &[RunnableMethod],
    k: i32,
    n: usize,
    schemes: &[Offset],
    rng: &mut Rng,
) -> Result<Vec<SelfHitRow>> {
    let scale = 10f64.powi(k);
    let cm = closed::icosphere(3);
    let place = Placement { scale, translate: DVec3::ZERO };
    let mesh = cm.to_mesh(place);
    let (origins, _) = probes::inside_origins(&cm, &mesh, place, 16, rng);
    let extra = n / 50 + 16;
    let mut primary = probes::leak_rays(&mesh, &origins, LeakKind::Random, (n + extra) / 2, rng);
    let inside = primary.len();
    for _ in 0..(n + extra) - primary.len() {
        let from = rng.direction() * 3.0;
        let to = rng.in_ball() * cm.inner_radius;
        primary.push(probes::ray64(place.apply(from), (to - from) * scale));
    }
    let host = build(&mesh, FIXED_LEAF);
    let near = 1e-4 * 2.0 * scale;
    let mut rows = Vec::new();
    for t in tracers {
        let (hits, _) = cast(ctx, t, &host, Layout::DEFAULT, &primary)?;
        let mut points = Vec::with_capacity(n);
        for (i, (r, h)) in primary.iter().zip(&hits).enumerate() {
            if points.len() == n {
                break;
            }
            if h.id == MISS_ID || !(h.u.is_finite() && h.v.is_finite()) {
                continue;
            }
            let vertices = mesh.vertices(h.id as usize);
            let g = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]).normalize();
            // The side the incoming ray came from.
            let nrm = if g.dot(Vec3::from_array(r.dir)) > 0.0 { -g } else { g };
            let sp = SurfacePoint { vertices, u: h.u, v: h.v, n: nrm };
            points.push((h.id, i < inside, sp, cosine_direction(nrm, rng)));
        }
        for &scheme in schemes {
            let rays: Vec<Ray> = points
                .iter()
                .map(|(_, _, sp, d)| Ray {
                    origin: scheme.apply(sp).to_array(),
                    tmin: 0.0,
                    dir: d.to_array(),
                    tmax: f32::INFINITY,
                })
                .collect();
            let (sec, _) = cast(ctx, t, &host, Layout::DEFAULT, &rays)?;
            let mut row = SelfHitRow {
                method: t.method,
                leaf_size: FIXED_LEAF,
                scale_exp: k,
                scheme,
                rays: rays.len(),
                self_hits: 0,
                near_hits: 0,
                escaped: 0,
                inside_rays: points.iter().filter(|p| p.1).count(),
                nan: 0,
            };
            for ((id, from_inside, _, _), h) in points.iter().zip(&sec) {
                if h.id == MISS_ID {
                    row.escaped += *from_inside as usize;
                    continue;
                }
                row.self_hits += (h.id == *id) as usize;
                row.near_hits += ((h.t as f64) < near) as usize;
                row.nan += !(h.t.is_finite() && h.u.is_finite() && h.v.is_finite()) as usize;
            }
            rows.push(row);
        }
    }
    Ok(rows)
}

/// One extreme case: every method at leaf 4 on the same rays.
#[allow(clippy::too_many_arguments)]
fn extreme_case(
    ctx: &Context,
    tracers: &[RunnableMethod],
    report: &mut AccuracyReport,
    kind: &str,
    param: String,
    mesh: &Mesh,
    rays: &[Ray],
    must_hit: bool,
    degenerate: &[u32],
) -> Result<()> {
    let host = build(mesh, FIXED_LEAF);
    let ref_hits = host.reference().trace_all(rays, false);
    let cond = crate::conditioning::Conditioning::of(mesh);
    for t in tracers {
        let (hits, unrepresentable) = cast(ctx, t, &host, Layout::DEFAULT, rays)?;
        report.extremes.push(ExtremeRow {
            kind: kind.into(),
            param: param.clone(),
            method: t.method,
            leaf_size: FIXED_LEAF,
            triangles: mesh.triangle_count(),
            magnitude_over_extent: cond.max_abs_coord / cond.extent.max(f64::MIN_POSITIVE),
            unrepresentable,
            must_hit,
            tally: Tally::of(rays, &hits, &ref_hits, must_hit, degenerate),
        });
    }
    Ok(())
}

fn extremes(
    ctx: &Context,
    o: &AccuracyOptions,
    tracers: &[RunnableMethod],
    report: &mut AccuracyReport,
    rng: &mut Rng,
    progress: &mut impl FnMut(&str),
) -> Result<()> {
    let n = o.extreme_rays;
    let cm = closed::icosphere(3);
    let per_kind = n.div_ceil(3);
    let closed_case = |report: &mut AccuracyReport, kind: &str, param: String, place: Placement, rng: &mut Rng| {
        let s = leak_scene(&cm, place, o.origins, rng);
        let rays: Vec<Ray> =
            LeakKind::ALL.iter().flat_map(|&k| probes::leak_rays(&s.mesh, &s.origins, k, per_kind, rng)).collect();
        extreme_case(ctx, tracers, report, kind, param, &s.mesh, &rays, true, &[])
    };
    for k in -8..=8 {
        closed_case(
            report,
            "scale",
            format!("1e{k}"),
            Placement { scale: 10f64.powi(k), translate: DVec3::ZERO },
            rng,
        )?;
    }
    progress("extremes: scale 1e-8..1e8 done");
    for k in 0..=7 {
        let place = Placement { scale: 1.0, translate: DVec3::new(1.0, 0.7, 0.3) * 10f64.powi(k) };
        closed_case(report, "translate", format!("1e{k}"), place, rng)?;
    }
    progress("extremes: translation 1e0..1e7 done");
    let rot = rng.rotation();
    let plane = probes::grid(16, rot, 1.0);
    for k in 1..=7 {
        let rays = probes::grazing_rays(rot, 1.0, 10f64.powi(-k), n, rng);
        extreme_case(ctx, tracers, report, "grazing", format!("1e-{k} rad"), &plane, &rays, false, &[])?;
    }
    progress("extremes: grazing rays done");
    for k in 0..=6 {
        let h = 10f64.powi(-k);
        let count = 64;
        let strip = probes::sliver_strip(count, h, rot);
        let rays = probes::plane_rays(rot, 1.0, h * count as f64, n, rng);
        extreme_case(ctx, tracers, report, "sliver", format!("aspect 1e{k}"), &strip, &rays, false, &[])?;
    }
    progress("extremes: slivers done");
    for k in [-30, -20, -10, 10, 20, 30] {
        let s = 10f64.powi(k);
        let g = probes::grid(4, rot, s);
        let rays = probes::grazing_rays(rot, s, 0.5, n, rng);
        extreme_case(ctx, tracers, report, "size", format!("1e{k}"), &g, &rays, false, &[])?;
    }
    progress("extremes: tiny and huge triangles done");
    let (mesh, degenerate, rays) = probes::degenerate_scene(n, rng);
    extreme_case(
        ctx,
        tracers,
        report,
        "degenerate",
        format!("{} zero-area", degenerate.len()),
        &mesh,
        &rays,
        false,
        &degenerate,
    )?;
    progress("extremes: degenerate triangles done");
    Ok(())
}

/// Speed against accuracy per method: bunny diffuse rays at leaf 4, validated.
fn frontier(
    ctx: &Context,
    o: &AccuracyOptions,
    tracers: &[RunnableMethod],
    report: &mut AccuracyReport,
    progress: &mut impl FnMut(&str),
) -> Result<()> {
    let mesh = crate::scene::load_obj(Path::new("bunny"))?;
    let host = HostScene::build("bunny", &mesh, &BuildOptions::new(FIXED_LEAF))?;
    let reference = host.reference();
    let primary = crate::rays::primary_rays(&Camera::framing(&mesh.bounds()), o.bench_width, o.bench_height);
    let rays = RaySet::diffuse_from(&mesh, &reference, &primary, 1, o.seed);
    let ref_hits = reference.trace_all(&rays, false);
    report.frontier_rays = rays.len();
    let layout = if o.layouts.contains(&Layout::DEFAULT) { Layout::DEFAULT } else { o.layouts[0] };
    for t in tracers {
        let scene = host.upload(ctx, &SceneRequest::new(t.method).layout(layout))?;
        let opts = RaycastOptions { warmup: 1, repeat: o.repeat.max(1), ..Default::default() };
        let (speed, note) = match measure_rays(ctx, &scene, &mesh, &rays, &ref_hits, &opts) {
            Ok(m) => (Some(m.mrays_per_s), None),
            Err(e) => (None, Some(e.to_string())),
        };
        let at_leaf = |leaf_rows: &mut dyn Iterator<Item = &Tally>| {
            let (mut n, mut bad) = (0, 0);
            for t in leaf_rows {
                n += t.rays;
                bad += t.leaks + t.false_hits;
            }
            per_million(bad, n)
        };
        let leaks = at_leaf(
            &mut report
                .leaks
                .iter()
                .filter(|r| r.method == t.method && r.leaf_size == FIXED_LEAF && r.layout == layout)
                .map(|r| &r.tally),
        );
        let false_hits = at_leaf(
            &mut report
                .false_hits
                .iter()
                .filter(|r| r.method == t.method && r.leaf_size == FIXED_LEAF && r.layout == layout)
                .map(|r| &r.tally),
        );
        let err =
            report.errors.iter().find(|r| r.method == t.method && r.leaf_size == FIXED_LEAF && r.layout == layout);
        let row = FrontierRow {
            method: t.method,
            layout,
            scene_access: scene.access,
            mrays_per_s: speed,
            note,
            leaks_per_million: leaks,
            false_hits_per_million: false_hits,
            t_ulps_median: err.map_or(f64::NAN, |e| e.tally.t_ulps.median),
            t_ulps_p99: err.map_or(f64::NAN, |e| e.tally.t_ulps.p99),
        };
        progress(&format!(
            "frontier {}: {} Mrays/s, {:.1} leaks per 1e6, t error median {:.2} ULP",
            t.method,
            row.mrays_per_s.map_or_else(|| "-".into(), |s| format!("{:.2}", s.median)),
            row.leaks_per_million,
            row.t_ulps_median
        ));
        report.frontier.push(row);
    }
    Ok(())
}

/// The plan of the whole matrix this report belongs to (every shard's cells), with its shard.
pub fn plan(report: &AccuracyReport) -> crate::rows::Plan {
    crate::rows::Plan {
        command: "accuracy".into(),
        shard: report.options.shard,
        cells: report.plan.clone(),
        source: report.provenance.source(),
    }
}

/// `partial: shard I/N, X of Y cells ...` for a sharded run, `None` for a whole one.
pub fn partial(report: &AccuracyReport) -> Option<String> {
    let fixed = if report.options.runs_fixed_parts() {
        "with the extremes, self-intersection and frontier"
    } else {
        "without the extremes, self-intersection and frontier (another shard's)"
    };
    let whole = format!("whole leaf size and layout groups, {fixed}");
    shard::partial(report.options.shard, &report.plan, &rows(report), &whole)
}

/// Writes accuracy.csv, accuracy.json, accuracy.md and the plots into `dir`; returns the paths.
pub fn write(report: &AccuracyReport, dir: &Path) -> Result<Vec<PathBuf>> {
    crate::services::results::write_folder(dir, report)
}

impl crate::services::results::Results for AccuracyReport {
    const STEM: &'static str = "accuracy";

    fn markdown(&self, plots: &[crate::services::plots::Plot]) -> String {
        table::markdown(self, plots)
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        Some(rows(self))
    }

    fn plan(&self) -> Option<crate::rows::Plan> {
        Some(plan(self))
    }

    fn files(&self) -> Result<Vec<(&'static str, String)>> {
        // frontier.csv is what `trilab analyze --frontier` reads.
        Ok(vec![
            ("accuracy.csv", table::csv(self)?),
            ("frontier.csv", table::frontier_csv(self)?),
            ("translation.csv", table::translation_csv(self)?),
        ])
    }

    fn plots(&self, dir: &Path) -> Result<Vec<crate::services::plots::Plot>> {
        plots::all(self, dir)
    }
}

/// The report as result rows (`rows.jsonl`, what `trilab compare` reads), cell key `part`:
/// - `leaks` per method, leaf size and layout (`leak_rays` per mesh and kind in the cell):
///   `leaks`, `false_hits`, `nan_hits` and `different_triangle` summed over the meshes, kinds and
///   offsets, and the t and barycentric error quantiles of the error rows (all correctness,
///   lower is better);
/// - `extremes` per method and extreme kind (summed over its parameters): `leaks`,
///   `false_hits`, `nan_hits`, `degenerate_hits`;
/// - `self-intersection` per method and offset scheme (summed over the scales): `self_hits`,
///   `escaped`, `nan_hits`;
/// - `frontier` per method and layout: `mrays_per_s` (timing, min-max over the rounds) where it
///   was timed.
pub fn rows(report: &AccuracyReport) -> Vec<crate::rows::Row> {
    use crate::rows::{Better, Figure, Row};
    let source = report.provenance.source();
    let bad = |n: usize, unit: &str| Figure::correctness(n as f64, unit, Better::Lower);
    let mut out = vec![];
    let mut methods: Vec<(Method, u32, Layout)> =
        report.leaks.iter().map(|r| (r.method, r.leaf_size, r.layout)).collect();
    methods.dedup();
    methods.sort_by_key(|&(m, l, y)| (m.to_string(), l, y.to_string()));
    methods.dedup();
    for (method, leaf, layout) in methods {
        let mine = |m: Method, l: u32, y: Layout| m == method && l == leaf && y == layout;
        let (mut leaks, mut false_hits, mut nan, mut different) = (0, 0, 0, 0);
        let tallies = report
            .leaks
            .iter()
            .filter(|r| mine(r.method, r.leaf_size, r.layout))
            .map(|r| &r.tally)
            .chain(report.false_hits.iter().filter(|r| mine(r.method, r.leaf_size, r.layout)).map(|r| &r.tally));
        for t in tallies {
            leaks += t.leaks;
            false_hits += t.false_hits;
            nan += t.nan;
            different += t.different_triangle;
        }
        let c = AccuracyCell::Leaks { method, leaf, layout, rays: report.options.leak_rays }.coordinates();
        let mut row = Row::new("accuracy", c, &source)
            .with("leaks", bad(leaks, "rays"))
            .with("false_hits", bad(false_hits, "rays"))
            .with("nan_hits", bad(nan, "rays"))
            .with("different_triangle", bad(different, "rays"));
        if let Some(e) = report.errors.iter().find(|r| mine(r.method, r.leaf_size, r.layout)) {
            let q = |x: f64, unit: &str| Figure::correctness(x, unit, Better::Lower);
            row = row
                .with("t_ulps_median", q(e.tally.t_ulps.median, "ulp"))
                .with("t_ulps_p99", q(e.tally.t_ulps.p99, "ulp"))
                .with("t_ulps_max", q(e.tally.t_ulps.max, "ulp"))
                .with("bary_error_p99", q(e.tally.bary.p99, "barycentric"))
                .with("bary_error_max", q(e.tally.bary.max, "barycentric"));
        }
        out.push(row);
    }
    let mut extremes: Vec<(Method, &str)> = report.extremes.iter().map(|r| (r.method, r.kind.as_str())).collect();
    extremes.sort_by_key(|&(m, k)| (m.to_string(), k));
    extremes.dedup();
    for (method, kind) in extremes {
        let (mut leaks, mut false_hits, mut nan, mut degenerate) = (0, 0, 0, 0);
        for r in report.extremes.iter().filter(|r| r.method == method && r.kind == kind) {
            leaks += r.tally.leaks;
            false_hits += r.tally.false_hits;
            nan += r.tally.nan;
            degenerate += r.tally.degenerate_hits;
        }
        let c =
            AccuracyCell::Extremes { method, kind: kind.to_owned(), rays: report.options.extreme_rays }.coordinates();
        out.push(
            Row::new("accuracy", c, &source)
                .with("leaks", bad(leaks, "rays"))
                .with("false_hits", bad(false_hits, "rays"))
                .with("nan_hits", bad(nan, "rays"))
                .with("degenerate_hits", bad(degenerate, "rays")),
        );
    }
    let mut schemes: Vec<(Method, Offset)> = report.self_hits.iter().map(|r| (r.method, r.scheme)).collect();
    schemes.sort_by_key(|&(m, o)| (m.to_string(), o.name()));
    schemes.dedup();
    for (method, scheme) in schemes {
        let (mut self_hits, mut escaped, mut nan) = (0, 0, 0);
        for r in report.self_hits.iter().filter(|r| r.method == method && r.scheme == scheme) {
            self_hits += r.self_hits;
            escaped += r.escaped;
            nan += r.nan;
        }
        let c = AccuracyCell::SelfIntersection { method, scheme, rays: report.options.self_rays }.coordinates();
        out.push(
            Row::new("accuracy", c, &source)
                .with("self_hits", bad(self_hits, "rays"))
                .with("escaped", bad(escaped, "rays"))
                .with("nan_hits", bad(nan, "rays")),
        );
    }
    for f in &report.frontier {
        if let Some(speed) = f.mrays_per_s {
            let c = AccuracyCell::Frontier { method: f.method, layout: f.layout, rays: Some(report.frontier_rays) }
                .coordinates();
            out.push(
                Row::new("accuracy", c, &source).with("mrays_per_s", Figure::timing(speed, "Mrays/s", Better::Higher)),
            );
        }
    }
    // A non-finite figure has no JSON number; such a figure is left out, not written as null.
    for r in &mut out {
        r.figures.retain(|_, f| f.median.is_finite() && f.min.is_finite() && f.max.is_finite());
    }
    out
}
impl crate::report::Report for AccuracyReport {
    /// The speed/accuracy frontier.
    fn to_text(&self) -> String {
        let partial = partial(self).map(|n| format!("{n}\n\n")).unwrap_or_default();
        format!("{partial}{}", table::frontier_table(self).to_text())
    }
}
