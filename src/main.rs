//! `trilab`: the command-line tool. Each subcommand is a thin layer over the library.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

mod cli;
use cli::choice::choice;
use serde_json::json;

use trilab::analyze::MethodChoice;
use trilab::bench::{self, BenchOptions};
use trilab::bvh::{BuildOptions, Builder, Bvh, LeafPolicy, MAX_LEAF_SIZE};
use trilab::compare::{compare_any, compare_closest};
use trilab::encoding::Method;
use trilab::error::{Error, Result};
use trilab::gpu::{
    raycast, raycast_rq, raycast_stats, rayquery, AccelStructure, Context, ContextOptions, GpuScene, Peer,
    RaycastOptions, SceneAccess, TraversalCounts, TraversalSummary, Validation,
};
use trilab::rays::{self, Camera};
use trilab::reference::Reference;
use trilab::render::{self as pt, KernelChoice, PathtraceKernel, RenderScene, RenderSettings};
use trilab::report::Table;
use trilab::scene::load_obj;
use trilab::study::{Preset, StudyOptions};

#[derive(Parser)]
#[command(
    name = "trilab",
    version,
    about = "GPU ray-triangle intersection laboratory (Vulkan compute, BVH, four intersection methods)"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Args, Clone)]
struct GpuArgs {
    /// Vulkan device: index or part of its name/driver (see `trilab devices`). Default: a
    /// discrete GPU if present, else the best other device.
    #[arg(long, global = true)]
    device: Option<String>,
    /// Load the Khronos validation layer, synchronization validation included, and fail on
    /// any message (default: on in debug builds only; also TRILAB_VALIDATION=1).
    #[arg(long, global = true)]
    validation: bool,
}

/// The validation log of the context a command made, checked before exit.
static VALIDATION_LOG: std::sync::OnceLock<std::sync::Arc<trilab::gpu::ValidationLog>> = std::sync::OnceLock::new();

impl GpuArgs {
    fn context(&self) -> Result<Context> {
        let mut o = ContextOptions { device: self.device.clone(), ..Default::default() };
        let env = std::env::var("TRILAB_VALIDATION").unwrap_or_default();
        if self.validation || !matches!(env.trim(), "" | "0" | "off" | "false") {
            o.validation = Validation::Required;
        }
        let ctx = Context::new(&o)?;
        let _ = VALIDATION_LOG.set(ctx.validation_log());
        Ok(ctx)
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// List Vulkan devices, their drivers and the features trilab uses.
    Devices {
        #[arg(long)]
        json: bool,
    },
    /// Make a ray file (../shared/formats.md).
    Rays {
        #[command(subcommand)]
        kind: RaysCmd,
    },
    /// Cast rays from a ray file; write hits and report kernel time.
    Raycast(RaycastArgs),
    /// Build the BVH and report its statistics (nodes, depth, leaf sizes, SAH cost, end-point
    /// overlap, time).
    Bvh {
        #[arg(long)]
        scene: PathBuf,
        /// Max triangles per leaf; repeat or omit for 1, 2, 3, 4, 8, 16.
        #[arg(long = "leaf-size")]
        leaf_sizes: Vec<u32>,
        #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
        leaf_policy: LeafPolicy,
        /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
        /// Quad kernels test them.
        #[arg(long, default_value_t = 1)]
        sah_group: u32,
        /// Build threads (default: one per logical CPU). The tree does not depend on it.
        #[arg(long)]
        threads: Option<usize>,
        #[arg(long)]
        json: bool,
    },
    /// BVH build benchmark: seconds, Mtris/s, SAH cost, nodes and depth per scene and thread
    /// count for the parallel and serial binned SAH and the full sweep, optionally beside
    /// Embree 3's builder on the same triangles; build.csv/json/md.
    BuildBench(BuildBenchArgs),
    /// Traversal work per ray (CPU mirror of the kernels' loop): steps, triangle tests, and the
    /// iterations SIMD lock-step costs at each width; `--gpu` adds the kernels' own counts.
    Steps(StepsArgs),
    /// SPIR-V instruction counts of every kernel variant; `--write DIR` refreshes spirv/.
    Spirv {
        #[arg(long)]
        write: Option<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Ray-casting benchmark: primary, diffuse and random rays, every method, validated against
    /// the f64 reference, optionally beside the Embree peer.
    Bench(BenchArgs),
    /// Large scenes: load and BVH-build times, each method's GPU memory plan (bytes per buffer and
    /// per triangle, access path), upload and a timed, validated cast; writes
    /// scale.csv/json/md.
    Scale(ScaleArgs),
    /// Path-trace a scene: linear RGBA EXR, a tone-mapped sRGB PNG and a JSON sidecar.
    Render(RenderArgs),
    /// Path-tracing benchmark: samples/s and rays/s per scene, method and kernel choice.
    BenchRender(BenchRenderArgs),
    /// The paper's study on this device: scene x leaf size {1,2,3,4,8,16} x method, path-trace
    /// seconds and Mrays/s per ray set, validated; writes study.csv/json/md and plots.
    Study(StudyArgs),
    /// Driver-level profile of the ray-casting kernels: timestamps, pipeline statistics,
    /// shader-clock heat maps, executable statistics, subgroup/workgroup-size sweeps,
    /// LP_NUM_THREADS scaling; profile.md, profile.json and PNGs.
    Profile(ProfileArgs),
    /// Intersection accuracy per method x leaf size: leaks on closed meshes, false hits,
    /// t/barycentric error, self-intersection per offset scheme, extremes, and the speed frontier;
    /// accuracy.csv/json/md and plots.
    Accuracy(AccuracyArgs),
    /// A scene's numerical conditioning (coordinate magnitude against edge length, smallest
    /// edge, slivers, distance from the origin) and the cheapest method, offset scheme and
    /// placement that meet an accuracy target on it.
    Analyze(AnalyzeArgs),
}

#[derive(Args)]
struct AccuracyArgs {
    /// full: the whole sweep (about 20 minutes on 2-core lavapipe); smoke: seconds, for CI.
    #[arg(long, value_parser = choice::<trilab::accuracy::Preset>(), default_value_t = trilab::accuracy::Preset::Full)]
    preset: trilab::accuracy::Preset,
    /// Default: every method (the smoke preset: the paper's four).
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    /// Leaf sizes of the leak, false-hit and error tables (default: 1,2,3,4,8,16).
    #[arg(long, value_delimiter = ',')]
    leaf_sizes: Vec<u32>,
    /// Leak rays per closed mesh and kind (default: the preset's).
    #[arg(long)]
    rays: Option<usize>,
    /// Output directory. Default: results/<device>/accuracy/.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Args)]
struct AnalyzeArgs {
    #[arg(long)]
    scene: PathBuf,
    /// Target: most leaks per 10^6 rays on closed meshes (rays at shared edges and vertices
    /// included), as `trilab accuracy` measures them.
    #[arg(long, default_value_t = 0.0)]
    max_leaks_per_million: f64,
    /// Target: largest 99th-percentile t error, in f32 ULPs of t.
    #[arg(long, default_value_t = 4.0)]
    max_t_ulps: f64,
    /// `frontier.csv` from `trilab accuracy` on your device (default: the committed lavapipe one).
    #[arg(long)]
    frontier: Option<PathBuf>,
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum RayQueryChoice {
    Auto,
    On,
    Off,
}

#[derive(Args)]
struct StudyArgs {
    /// Scenes: names of bundled scenes (bunny, dragon, buddha) or OBJ paths. Default: the
    /// preset's (bunny, dragon, buddha; the smoke preset only the bunny).
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// paper: 800x600, 500 spp, depth 16; lavapipe: scaled to about 20 minutes on 2 CPU cores;
    /// smoke: seconds, for CI.
    #[arg(long, value_parser = choice::<Preset>(), default_value_t = Preset::Lavapipe)]
    preset: Preset,
    /// Output directory. Default: results/<device>/study/ (lavapipe, or the device name).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Leaf sizes (default: 1,2,3,4,8,16).
    #[arg(long, value_delimiter = ',')]
    leaf_sizes: Vec<u32>,
    /// Methods (default: the paper's four, mt,unit,quad-mt,quad-unit).
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    /// Timed rounds after the warm-up round (default: the preset's).
    #[arg(long)]
    repeat: Option<usize>,
    /// Triangles the SAH prices as one test: 1 (the paper's SAH) or 4 (quad-aware).
    #[arg(long, default_value_t = 1)]
    sah_group: u32,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Args)]
struct StepsArgs {
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    rays: PathBuf,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    leaf_policy: LeafPolicy,
    /// SIMD widths to model (lavapipe: 8, or 4 with LP_NATIVE_VECTOR_WIDTH=128).
    #[arg(long, value_delimiter = ',', default_values_t = [1usize, 4, 8, 32])]
    widths: Vec<usize>,
    /// Also run each method's traversal-statistics kernel (`raycast.<method>.stats`) and report
    /// its per-ray nodes visited and triangles tested (mean, max) beside the CPU mirror's.
    #[arg(long)]
    gpu: bool,
    /// Methods for `--gpu` (comma-separated; default all).
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    gpu_args: GpuArgs,
}

#[derive(Subcommand)]
enum RaysCmd {
    /// One ray per pixel from a camera framing the scene.
    Primary {
        #[command(flatten)]
        common: RaysCommon,
        #[arg(long, default_value_t = 800)]
        width: u32,
        #[arg(long, default_value_t = 600)]
        height: u32,
    },
    /// Cosine-distributed bounces off the primary hits (hits from the f64 reference).
    Diffuse {
        #[command(flatten)]
        common: RaysCommon,
        #[arg(long, default_value_t = 800)]
        width: u32,
        #[arg(long, default_value_t = 600)]
        height: u32,
        /// Rays per primary hit.
        #[arg(long, default_value_t = 8)]
        per_hit: u32,
        #[arg(long, default_value_t = 7)]
        seed: u64,
    },
    /// Rays from a sphere around the scene towards random points in its box.
    Random {
        #[command(flatten)]
        common: RaysCommon,
        #[arg(long, default_value_t = 1_000_000)]
        count: usize,
        #[arg(long, default_value_t = 7)]
        seed: u64,
    },
}

#[derive(Args)]
struct RaysCommon {
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    out: PathBuf,
}

#[derive(Args)]
struct RaycastArgs {
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    rays: PathBuf,
    /// Hit file to write (../shared/formats.md).
    #[arg(long)]
    out: PathBuf,
    /// Intersection method, or `auto`: the cheapest that meets the default accuracy target on
    /// this scene (see `trilab analyze`); what it picked and why goes to stderr and the JSON.
    #[arg(long, default_value = "mt")]
    method: MethodChoice,
    /// Translate the scene to its bounding-box centre, and the ray origins with it, in f64
    /// before rounding to f32 and uploading (t, ids and barycentrics are unchanged in exact
    /// arithmetic; `trilab analyze` says when this helps).
    #[arg(long)]
    recentre: bool,
    /// Trace with a peer instead of our kernels: `ray-query` is the driver's own ray tracing
    /// (VK_KHR_ray_query through its acceleration structure, built from the same triangles).
    /// Not a method: it uses none of our BVH, so the BVH options only shape the f64 reference.
    #[arg(long, value_parser = choice::<Peer>(), conflicts_with = "method")]
    peer: Option<Peer>,
    /// Max triangles per BVH leaf (1..=16; the paper studies 1, 2, 3, 4, 8, 16).
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    /// `fill`: nodes with <= leaf-size triangles become leaves (the paper's); `sah`: the SAH
    /// decides and leaf-size is only a cap.
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    leaf_policy: LeafPolicy,
    /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
    /// Quad kernels test them.
    #[arg(long, default_value_t = 1)]
    sah_group: u32,
    /// Occlusion query: any hit in [tmin, tmax] instead of the closest.
    #[arg(long)]
    any_hit: bool,
    /// How the kernels read the scene: `auto` plans its GPU memory and uses texel buffers when
    /// every buffer fits one binding, else buffer device addresses (the JSON says which).
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::Auto)]
    scene_access: SceneAccess,
    /// Timed runs after one warm-up; the median is reported.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Most rays per dispatch (each dispatch is its own submit).
    #[arg(long, default_value_t = 1 << 20)]
    batch_rays: usize,
    /// Also check every hit against the f64 reference and report agreement.
    #[arg(long)]
    validate: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Args)]
struct ScaleArgs {
    /// Scenes; default: ../shared/scenes/dragon_full_draco11.obj.gz if present, and a
    /// 10M-triangle synthetic scene.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Methods; default: every method this device runs.
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    /// Rays cast per scene and method.
    #[arg(long, default_value_t = 1_000_000)]
    rays: usize,
    #[arg(long, value_parser = choice::<trilab::scale::RayKind>(), default_value_t = trilab::scale::RayKind::Random)]
    ray_kind: trilab::scale::RayKind,
    /// Timed runs after one warm-up (median, min, max reported).
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Hits checked against the f64 reference (evenly spaced over the ray set).
    #[arg(long, default_value_t = 20_000)]
    validate: usize,
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::Auto)]
    scene_access: SceneAccess,
    #[arg(long, default_value_t = 1 << 20)]
    batch_rays: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Only the memory plan (bytes per triangle, access path): no upload, no cast.
    #[arg(long)]
    plan_only: bool,
    /// Output directory; default results/<device>/scale/.
    #[arg(long)]
    out: Option<PathBuf>,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Args)]
struct BenchArgs {
    /// Scenes (OBJ files); default: the bundled bunny.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<PathBuf>,
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    leaf_policy: LeafPolicy,
    /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
    /// Quad kernels test them.
    #[arg(long, default_value_t = 1)]
    sah_group: u32,
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    #[arg(long, default_value_t = 8)]
    diffuse_per_hit: u32,
    #[arg(long, default_value_t = 1_000_000)]
    random_rays: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Read <scene>.{primary,diffuse,random}.rays from this directory instead of generating.
    #[arg(long)]
    rays_dir: Option<PathBuf>,
    /// The Embree peer (`embree_rays` from scripts/embree-peer.sh), run on the same rays.
    #[arg(long)]
    embree: Option<PathBuf>,
    /// The driver's ray-query peer row: `auto` runs it wherever the device has ray query except
    /// on CPU devices (on lavapipe it traces 12-1,266x slower than our kernels, hours at the
    /// default sizes); `on` runs it there too; `off` leaves it out.
    #[arg(long, value_enum, default_value_t = RayQueryChoice::Auto)]
    ray_query: RayQueryChoice,
    /// How the kernels read the scenes: `auto` uses texel buffers when every buffer fits one
    /// binding, else buffer device addresses (`trilab scale` reports which).
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::Auto)]
    scene_access: SceneAccess,
    /// Write the report as JSON here.
    #[arg(long)]
    json_out: Option<PathBuf>,
    /// Write the tables as Markdown here.
    #[arg(long)]
    md_out: Option<PathBuf>,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Args)]
struct BenchRenderArgs {
    /// Scenes (OBJ files); default: the bundled bunny, dragon and buddha.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<PathBuf>,
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    /// Kernel choices to time (specialised, general).
    #[arg(long, value_parser = choice::<KernelChoice>(), value_delimiter = ',', default_value = "specialised")]
    kernels: Vec<KernelChoice>,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    #[arg(long, default_value_t = 200)]
    width: u32,
    #[arg(long, default_value_t = 150)]
    height: u32,
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[arg(long, default_value_t = 16)]
    max_depth: u32,
    /// Timed renders per configuration (after one warm-up).
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    #[arg(long)]
    json_out: Option<PathBuf>,
    #[arg(long)]
    md_out: Option<PathBuf>,
    #[command(flatten)]
    gpu: GpuArgs,
}

#[derive(Args)]
struct RenderArgs {
    #[arg(long)]
    scene: PathBuf,
    /// Intersection method, or `auto`: the cheapest that meets the default accuracy target on
    /// this scene (see `trilab analyze`); what it picked and why goes to stderr and the JSON.
    #[arg(long, default_value = "mt")]
    method: MethodChoice,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    leaf_policy: LeafPolicy,
    /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
    /// Quad kernels test them.
    #[arg(long, default_value_t = 1)]
    sah_group: u32,
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 500)]
    spp: u32,
    /// Most scattering events per path.
    #[arg(long, default_value_t = 16)]
    max_depth: u32,
    /// Russian roulette from this many scattering events on.
    #[arg(long, default_value_t = 3)]
    rr_depth: u32,
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,fov_y_degrees`; default: frames
    /// the scene as the ray generators do.
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<String>,
    /// Constant environment radiance `r,g,b` (or one value).
    #[arg(long, default_value = "1")]
    env: String,
    /// PNG exposure in stops (the EXR is not scaled).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// `specialised`: only the BSDFs the scene uses; `general`: the all-BSDF kernel.
    #[arg(long, value_parser = choice::<KernelChoice>(), default_value_t = KernelChoice::Specialised)]
    kernel: KernelChoice,
    /// Wall-clock target per GPU submit, milliseconds (keeps each submit far from a watchdog).
    #[arg(long, default_value_t = 250.0)]
    submit_ms: f64,
    /// Output OpenEXR file; the PNG and JSON are written beside it (same stem).
    #[arg(long)]
    out: PathBuf,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Write the image so far (EXR, PNG, JSON with `"checkpoint": true`) every this many
    /// seconds, so a killed process still leaves one; 0 turns checkpoints off.
    #[arg(long, default_value_t = 300.0)]
    checkpoint_secs: f64,
    #[command(flatten)]
    gpu: GpuArgs,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = run(cli);
    // Contexts are gone by now, so teardown messages are in the log too.
    let messages = VALIDATION_LOG.get().map(|l| l.messages()).unwrap_or_default();
    for m in &messages {
        eprintln!("trilab: validation: {m}");
    }
    match result {
        Err(e) => {
            eprintln!("trilab: error: {e}");
            ExitCode::FAILURE
        }
        Ok(()) if !messages.is_empty() => {
            eprintln!("trilab: error: {} validation message(s)", messages.len());
            ExitCode::FAILURE
        }
        Ok(()) => ExitCode::SUCCESS,
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Cmd::Devices { json } => devices(json),
        Cmd::Rays { kind } => make_rays(kind),
        Cmd::Raycast(a) => raycast_cmd(a),
        Cmd::Bvh { scene, leaf_sizes, leaf_policy, sah_group, threads, json } => match threads {
            Some(t) => {
                trilab::build_bench::pool(t)?.install(|| bvh_cmd(&scene, leaf_sizes, leaf_policy, sah_group, json))
            }
            None => bvh_cmd(&scene, leaf_sizes, leaf_policy, sah_group, json),
        },
        Cmd::BuildBench(a) => build_bench_cmd(a),
        Cmd::Spirv { write, json } => spirv_cmd(write, json),
        Cmd::Steps(a) => steps_cmd(a),
        Cmd::Bench(a) => bench_cmd(a),
        Cmd::Scale(a) => scale_cmd(a),
        Cmd::Render(a) => render_cmd(a),
        Cmd::BenchRender(a) => bench_render_cmd(a),
        Cmd::Study(a) => study_cmd(a),
        Cmd::Profile(a) => profile_cmd(a),
        Cmd::Accuracy(a) => accuracy_cmd(a),
        Cmd::Analyze(a) => analyze_cmd(a),
    }
}

fn check_sah_group(g: u32) -> Result<()> {
    if (1..=MAX_LEAF_SIZE).contains(&g) {
        Ok(())
    } else {
        Err(Error::Usage(format!("--sah-group {g}: must be 1..={MAX_LEAF_SIZE} (4 prices leaves in quads)")))
    }
}

fn check_leaf_size(n: u32) -> Result<()> {
    if (1..=MAX_LEAF_SIZE).contains(&n) {
        Ok(())
    } else {
        Err(Error::Usage(format!("--leaf-size {n}: must be 1..={MAX_LEAF_SIZE}")))
    }
}

fn devices(json: bool) -> Result<()> {
    let list = Context::list_devices()?;
    if json {
        println!("{}", serde_json::to_string_pretty(&list).unwrap());
        return Ok(());
    }
    if list.is_empty() {
        println!("no Vulkan devices");
    }
    let chosen = trilab::gpu::context::choose_device(&list, None).ok();
    for d in &list {
        print!("{}", d.report());
        if Some(d.index) == chosen {
            println!("    (default choice)");
        }
    }
    Ok(())
}

fn make_rays(kind: RaysCmd) -> Result<()> {
    let common = match &kind {
        RaysCmd::Primary { common, .. } | RaysCmd::Diffuse { common, .. } | RaysCmd::Random { common, .. } => common,
    };
    let mesh = load_obj(&common.scene)?;
    refuse_over_scene(&common.out, &common.scene, &mesh, &[])?;
    let rays = match kind {
        RaysCmd::Primary { width, height, .. } => rays::primary_rays(&Camera::framing(&mesh.bounds()), width, height),
        RaysCmd::Diffuse { width, height, per_hit, seed, .. } => {
            let primary = rays::primary_rays(&Camera::framing(&mesh.bounds()), width, height);
            let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
            rays::diffuse_rays(&mesh, &Reference::new(&mesh, &bvh), &primary, per_hit, seed)
        }
        RaysCmd::Random { count, seed, .. } => rays::random_rays(&mesh.bounds(), count, seed),
    };
    rays::write_rays(&common.out, &rays)?;
    println!("wrote {} rays to {}", rays.len(), common.out.display());
    Ok(())
}

fn raycast_cmd(a: RaycastArgs) -> Result<()> {
    check_leaf_size(a.leaf_size)?;
    let mut mesh = load_obj(&a.scene)?;
    refuse_over_scene(&a.out, &a.scene, &mesh, &[&a.rays])?;
    let mut rays = rays::read_rays(&a.rays)?;
    if a.recentre {
        let (m, shift) = trilab::analyze::recentre(&mesh);
        trilab::analyze::recentre_rays(&mut rays, shift);
        eprintln!("trilab: recentred: scene and ray origins translated by -({}, {}, {})", shift.x, shift.y, shift.z);
        mesh = m;
    }
    check_sah_group(a.sah_group)?;
    let bvh = Bvh::build(
        &mesh,
        &BuildOptions { leaf_policy: a.leaf_policy, sah_group: a.sah_group, ..BuildOptions::new(a.leaf_size) },
    );
    let opts = RaycastOptions { warmup: 1, repeat: a.repeat.max(1), batch_rays: a.batch_rays };
    let ctx;
    // The method that traced them (None for a peer) and, for `--method auto`, why.
    let (mut method, mut auto) = (None, None);
    // How our kernels read the scene (None for a peer).
    let mut scene_access = None;
    // What traced the rays: (label, bytes on the GPU, the driver's structure stats for a peer).
    let (res, tracer, scene_bytes, accel) = match a.peer {
        Some(Peer::RayQuery) => {
            ctx = a.gpu.context()?;
            let accel = AccelStructure::build(&ctx, &mesh)?;
            let kernel = rayquery::kernel(&ctx, a.any_hit)?;
            // Submits of about a second, whatever the driver's speed (--batch-rays caps them).
            let batch = rayquery::batch_for(&ctx, &kernel, &accel, &rays, 1000.0, a.batch_rays)?;
            let res = raycast_rq(&ctx, &kernel, &accel, &rays, &RaycastOptions { batch_rays: batch, ..opts })?;
            let s = accel.stats;
            (res, Peer::RayQuery.to_string(), (s.blas_bytes + s.tlas_bytes) as usize, Some(s))
        }
        None => {
            ctx = a.gpu.context()?;
            let (m, rec) = resolve_method(a.method, &mesh, &ctx)?;
            (method, auto) = (Some(m), rec);
            // Plan before encoding: a scene that cannot fit fails here, naming the buffer.
            let limits = trilab::gpu::DeviceLimits::of(&ctx);
            let access = trilab::gpu::MemoryPlan::for_bvh(m, &mesh, &bvh).choose(
                &a.scene.display().to_string(),
                a.scene_access,
                &limits,
            )?;
            scene_access = Some(access);
            let encoded = m.encode(&mesh, &bvh);
            if !encoded.unrepresentable.is_empty() {
                eprintln!(
                    "trilab: warning: {} triangles cannot be represented by {m} (their map overflows f32) and are never hit, e.g. id {}",
                    encoded.unrepresentable.len(),
                    encoded.unrepresentable[0]
                );
            }
            let kernel = ctx.create_kernel(trilab::kernels::raycast_via(m, a.any_hit, access))?;
            let scene = GpuScene::upload_with(&ctx, &encoded, access)?;
            drop(encoded);
            let res = raycast(&ctx, &kernel, &scene, &rays, &opts)?;
            (res, format!("{m} leaf size {} ({})", a.leaf_size, a.leaf_policy), scene.bytes, None)
        }
    };
    rays::write_hits(&a.out, &res.hits)?;

    let t = res.time_ms();
    let mrays = |ms: f64| rays.len() as f64 / (ms * 1e-3) / 1e6;
    let hits = res.hits.iter().filter(|h| h.is_hit()).count();
    let validation = if a.validate {
        let reference = Reference::new(&mesh, &bvh);
        if a.any_hit {
            let closest = reference.trace_all(&rays, false).iter().map(|h| h.to_hit()).collect::<Vec<_>>();
            let c = compare_any(&mesh, &rays, &closest, &res.hits);
            Some(
                json!({"any_hit_status_mismatches": c.status_mismatch.len(), "bogus": c.bogus.len(), "passes": c.passes()}),
            )
        } else {
            let agreement = compare_closest(&mesh, &rays, &res.hits, &reference.trace_all(&rays, false));
            Some(json!({
                "agreement": agreement.fraction(),
                "disagreements": agreement.disagreements.len(),
                "unexplained": agreement.unexplained,
                "max_ambiguity_ulps": agreement.max_ambiguity_ulps,
                "invalid": agreement.invalid.len(),
                "passes": agreement.all_explained(),
                "summary": agreement.summary(),
            }))
        }
    } else {
        None
    };
    let info = ctx.info();
    if a.json {
        let out = json!({
            "method": method,
            "method_choice": a.peer.is_none().then(|| a.method.to_string()),
            "auto": auto,
            "peer": a.peer,
            "accel": accel,
            "leaf_size": a.leaf_size,
            "leaf_policy": a.leaf_policy.to_string(),
            "sah_group": a.sah_group,
            "any_hit": a.any_hit,
            "recentred": a.recentre,
            "rays": rays.len(),
            "hits": hits,
            "kernel_ms": t.median,
            "kernel_ms_min": t.min,
            "kernel_ms_max": t.max,
            "runs": t.runs,
            "timed_with": if res.timed_on_gpu() { "gpu timestamps" } else { "host wall clock" },
            "mrays_per_s": mrays(t.median),
            "batches": res.batches,
            "scene_bytes": scene_bytes,
            "scene_access": scene_access,
            "triangles": mesh.triangle_count(),
            "degenerate_triangles": bvh.degenerate_excluded,
            "device": info.name,
            "driver": info.driver_label(),
            "mesa_version": info.mesa_version,
            "validation": validation,
        });
        println!("{}", serde_json::to_string_pretty(&out).unwrap());
    } else {
        println!("device:    {} ({})", info.name, info.driver_label());
        println!(
            "scene:     {} ({} triangles, {} degenerate never hit), {tracer}, {:.2} MB on the GPU",
            a.scene.display(),
            mesh.triangle_count(),
            bvh.degenerate_excluded,
            scene_bytes as f64 / 1e6
        );
        if let Some(s) = accel {
            let ms = |m: Option<f64>| m.map(|m| format!("{m:.2} ms")).unwrap_or_else(|| "no timestamps".into());
            println!(
                "driver AS: BLAS {} B, TLAS {} B; build {} + {} (GPU), {:.1} ms wall",
                s.blas_bytes,
                s.tlas_bytes,
                ms(s.blas_build_ms),
                ms(s.tlas_build_ms),
                s.wall_ms
            );
        }
        println!("rays:      {} ({} hit) -> {}", rays.len(), hits, a.out.display());
        println!(
            "kernel:    {:.3} ms median of {} (min {:.3}, max {:.3}; {}), {:.2} Mrays/s",
            t.median,
            t.runs,
            t.min,
            t.max,
            if res.timed_on_gpu() { "GPU timestamps" } else { "host wall clock" },
            mrays(t.median)
        );
        if let Some(v) = &validation {
            println!("reference: {v}");
        }
    }
    if let Some(v) = validation {
        if v["passes"] == json!(false) {
            return Err(Error::Usage("hits disagree with the f64 reference (see above)".into()));
        }
    }
    Ok(())
}

fn bvh_cmd(scene: &Path, leaf_sizes: Vec<u32>, leaf_policy: LeafPolicy, sah_group: u32, json: bool) -> Result<()> {
    check_sah_group(sah_group)?;
    let mesh = load_obj(scene)?;
    let leaf_sizes = if leaf_sizes.is_empty() { vec![1, 2, 3, 4, 8, 16] } else { leaf_sizes };
    let mut stats = vec![];
    for &leaf in &leaf_sizes {
        check_leaf_size(leaf)?;
        for builder in [Builder::default(), Builder::Sweep] {
            let bvh = Bvh::build(&mesh, &BuildOptions { builder, leaf_policy, sah_group, ..BuildOptions::new(leaf) });
            let mut sizes = serde_json::Map::new();
            for m in Method::ALL {
                sizes.insert(m.name().into(), json!(m.encode(&mesh, &bvh).gpu_bytes()));
            }
            stats.push((bvh.stats_with_epo(&mesh), sizes));
        }
    }
    if json {
        let v: Vec<_> = stats.iter().map(|(s, sizes)| json!({"stats": s, "gpu_scene_bytes": sizes})).collect();
        println!("{}", serde_json::to_string_pretty(&v).unwrap());
        return Ok(());
    }
    println!(
        "{}: {} triangles, {} vertices; SAH with {} triangle(s) per test, leaf policy {leaf_policy}",
        scene.display(),
        mesh.triangle_count(),
        mesh.positions.len(),
        sah_group
    );
    let mut t = Table::new([
        "leaf",
        "builder",
        "nodes",
        "depth",
        "SAH cost",
        "EPO",
        "EPO ms",
        "quad padding",
        "build ms",
        "threads",
        "Mtris/s",
        "leaf sizes (count:leaves)",
        "MB mt",
        "MB unit",
        "MB quad-mt",
        "MB quad-unit",
    ]);
    for (s, sizes) in &stats {
        let hist: Vec<String> =
            s.leaf_histogram.iter().enumerate().filter(|(_, &n)| n > 0).map(|(k, n)| format!("{k}:{n}")).collect();
        let mb = |m: &str| format!("{:.2}", sizes[m].as_u64().unwrap() as f64 / 1e6);
        t.row([
            s.max_leaf_size.to_string(),
            s.builder.clone(),
            s.nodes.to_string(),
            s.depth.to_string(),
            format!("{:.2}", s.sah_cost),
            s.epo.map_or("-".into(), |e| format!("{e:.3}")),
            s.epo_ms.map_or("-".into(), |t| format!("{t:.0}")),
            s.quad_padding.to_string(),
            format!("{:.1}", s.build_ms),
            s.build_threads.to_string(),
            format!("{:.2}", s.mtris_per_s),
            hist.join(" "),
            mb("mt"),
            mb("unit"),
            mb("quad-mt"),
            mb("quad-unit"),
        ]);
    }
    print!("{}", t.to_text());
    Ok(())
}

#[derive(Args)]
struct BuildBenchArgs {
    /// Scenes, comma-separated: OBJ files (.obj, .obj.gz) or synth:<kind>:<N>.
    #[arg(long, value_delimiter = ',', required = true)]
    scenes: Vec<PathBuf>,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    leaf_policy: LeafPolicy,
    /// Triangles the SAH prices as one test (1: classic; Embree's SAH block size).
    #[arg(long, default_value_t = 1)]
    sah_group: u32,
    /// Thread counts, comma-separated (default: one per logical CPU).
    #[arg(long, value_delimiter = ',')]
    threads: Vec<usize>,
    /// Timed runs after one warm-up.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Leave out the single-threaded reference loop.
    #[arg(long)]
    no_serial: bool,
    /// Full-sweep SAH reference only on scenes of at most this many triangles.
    #[arg(long, default_value_t = 300_000)]
    sweep_max: usize,
    /// The Embree build peer (`embree_build` from scripts/embree-peer.sh).
    #[arg(long)]
    embree: Option<PathBuf>,
    /// Directory for build.csv, build.json and build.md (e.g. results/<host>/build).
    #[arg(long)]
    out: Option<PathBuf>,
}

fn build_bench_cmd(a: BuildBenchArgs) -> Result<()> {
    use trilab::build_bench::{self, BuildBenchOptions};
    let d = BuildBenchOptions::default();
    let o = BuildBenchOptions {
        scenes: a.scenes,
        leaf_size: a.leaf_size,
        leaf_policy: a.leaf_policy,
        sah_group: a.sah_group,
        threads: if a.threads.is_empty() { d.threads } else { a.threads },
        repeat: a.repeat,
        serial: !a.no_serial,
        sweep_max_triangles: a.sweep_max,
        embree: a.embree,
    };
    if let Some(out) = &a.out {
        for name in ["build.csv", "build.json", "build.md"] {
            let inputs: Vec<&Path> = o.scenes.iter().map(PathBuf::as_path).collect();
            trilab::io::ensure_not_input(&out.join(name), &inputs)?;
        }
    }
    let report = build_bench::run(&o, |m| eprintln!("{m}"))?;
    print!("{}", report.table().to_text());
    if let Some(out) = &a.out {
        report.write(out)?;
        eprintln!("wrote {}/build.{{csv,json,md}}", out.display());
    }
    Ok(())
}

fn steps_cmd(a: StepsArgs) -> Result<()> {
    check_leaf_size(a.leaf_size)?;
    if a.widths.contains(&0) {
        return Err(Error::Usage("--widths: a SIMD width must be at least 1".into()));
    }
    if !a.methods.is_empty() && !a.gpu {
        return Err(Error::Usage("--methods: only with --gpu".into()));
    }
    let (leaf, leaf_policy) = (a.leaf_size, a.leaf_policy);
    let mesh = load_obj(&a.scene)?;
    let rays = rays::read_rays(&a.rays)?;
    let bvh = Bvh::build(&mesh, &BuildOptions { leaf_policy, ..BuildOptions::new(leaf) });
    let stats: Vec<_> = a.widths.iter().map(|&w| trilab::traversal::step_stats(&mesh, &bvh, &rays, w)).collect();
    let gpu = if a.gpu { Some(gpu_steps(&a, &mesh, &bvh, &rays)?) } else { None };
    if a.json {
        let v = match &gpu {
            None => json!(stats),
            Some((cpu, rows)) => json!({
                "cpu": stats,
                "cpu_summary": cpu,
                "gpu": rows.iter().map(|(m, s, d)| json!({"method": m, "summary": s, "rays_differing_from_cpu": d}))
                    .collect::<Vec<_>>(),
            }),
        };
        println!("{}", serde_json::to_string_pretty(&v).unwrap());
        return Ok(());
    }
    let s0 = &stats[0];
    println!(
        "{} rays, leaf size {leaf} ({leaf_policy}); per ray alone: {:.2} iterations ({:.2} inner, {:.2} leaf), {:.2} triangle tests",
        s0.rays, s0.iterations, s0.inner, s0.leaves, s0.triangles
    );
    let mut t = Table::new([
        "SIMD width",
        "iterations/ray",
        "x alone",
        "inner code/ray",
        "leaf code/ray",
        "triangle slots/ray",
    ]);
    for s in &stats {
        t.row([
            s.width.to_string(),
            format!("{:.2}", s.simd_iterations),
            format!("{:.2}", s.lockstep_overhead()),
            format!("{:.2}", s.simd_inner),
            format!("{:.2}", s.simd_leaf),
            format!("{:.2}", s.simd_triangles),
        ]);
    }
    print!("{}", t.to_text());
    if let Some((cpu, rows)) = &gpu {
        println!("\nper ray, GPU stats kernels beside the CPU mirror (nodes = inner + leaf iterations; slots include quad padding):");
        let mut t = Table::new([
            "source",
            "nodes mean",
            "nodes max",
            "inner mean",
            "leaf mean",
            "triangles mean",
            "triangles max",
            "slots mean",
            "slots max",
            "rays differing",
        ]);
        let row = |name: String, s: &TraversalSummary, slots: bool, differing: String| {
            [
                name,
                format!("{:.2}", s.nodes.mean),
                s.nodes.max.to_string(),
                format!("{:.2}", s.inner.mean),
                format!("{:.2}", s.leaves.mean),
                format!("{:.2}", s.triangles.mean),
                s.triangles.max.to_string(),
                if slots { format!("{:.2}", s.slots.mean) } else { "-".into() },
                if slots { s.slots.max.to_string() } else { "-".into() },
                differing,
            ]
        };
        t.row(row("CPU mirror".into(), cpu, false, "-".into()));
        for (m, s, d) in rows {
            t.row(row(format!("GPU {m}"), s, true, d.to_string()));
        }
        print!("{}", t.to_text());
    }
    Ok(())
}

/// Per-method summaries of the GPU traversal counters, each with the number of rays whose
/// counts differ from the CPU mirror's, and the mirror's own summary.
type GpuSteps = (TraversalSummary, Vec<(Method, TraversalSummary, usize)>);

fn gpu_steps(a: &StepsArgs, mesh: &trilab::scene::Mesh, bvh: &Bvh, rays: &[rays::Ray]) -> Result<GpuSteps> {
    let mirror = |conservative| -> Vec<TraversalCounts> {
        trilab::traversal::ray_steps_with(mesh, bvh, rays, conservative)
            .iter()
            .map(|s| TraversalCounts { inner: s.inner, leaves: s.leaves, triangles: s.triangles, slots: 0 })
            .collect()
    };
    let (cpu, cpu_conservative) = (mirror(false), mirror(true));
    let ctx = a.gpu_args.context()?;
    let methods = if a.methods.is_empty() { device_methods(&ctx) } else { a.methods.clone() };
    let mut rows = vec![];
    for m in methods {
        let kernel = ctx.create_kernel(trilab::kernels::raycast_stats(m))?;
        let scene = GpuScene::upload(&ctx, &m.encode(mesh, bvh))?;
        let (_, counts) = raycast_stats(&ctx, &kernel, &scene, rays)?;
        let differing = counts
            .iter()
            .zip(if m.conservative_traversal() { &cpu_conservative } else { &cpu })
            .filter(|(g, c)| (g.inner, g.leaves, g.triangles) != (c.inner, c.leaves, c.triangles))
            .count();
        rows.push((m, TraversalSummary::of(&counts), differing));
    }
    Ok((TraversalSummary::of(&cpu), rows))
}

fn spirv_cmd(write: Option<PathBuf>, json: bool) -> Result<()> {
    if let Some(dir) = write {
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        let files = trilab::spirv::review_files();
        let keep: Vec<&String> = files.iter().map(|(n, _)| n).collect();
        // Remove stale files of variants that no longer exist.
        for e in std::fs::read_dir(&dir).map_err(|e| Error::io(&dir, e))?.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if (name.ends_with(".spvasm") || name == "instruction_counts.csv") && !keep.contains(&&name) {
                std::fs::remove_file(e.path()).map_err(|err| Error::io(&e.path(), err))?;
            }
        }
        for (name, text) in &files {
            trilab::io::write_atomic(&dir.join(name), text.as_bytes())?;
        }
        println!("wrote {} files to {}", files.len(), dir.display());
        return Ok(());
    }
    let counts = trilab::spirv::all_counts();
    if json {
        let v: Vec<_> = counts.iter().map(|(k, c)| json!({"variant": k.name, "counts": c})).collect();
        println!("{}", serde_json::to_string_pretty(&v).unwrap());
        return Ok(());
    }
    let mut t = Table::new([
        "variant",
        "module",
        "functions",
        "arithmetic",
        "memory",
        "control flow",
        "conversion",
        "image",
        "composite",
        "other",
    ]);
    for (k, c) in counts {
        t.row([
            k.name.to_string(),
            c.module.to_string(),
            c.functions.to_string(),
            c.arithmetic.to_string(),
            c.memory.to_string(),
            c.control_flow.to_string(),
            c.conversion.to_string(),
            c.image.to_string(),
            c.composite.to_string(),
            c.other.to_string(),
        ]);
    }
    print!("{}", t.to_text());
    Ok(())
}

fn bench_cmd(a: BenchArgs) -> Result<()> {
    check_leaf_size(a.leaf_size)?;
    let scenes = if a.scenes.is_empty() { vec![PathBuf::from("scenes/bunny.obj")] } else { a.scenes.clone() };
    let methods = if a.methods.is_empty() { Method::ALL.to_vec() } else { a.methods.clone() };
    for out in [&a.json_out, &a.md_out].into_iter().flatten() {
        let inputs: Vec<&Path> = scenes.iter().map(PathBuf::as_path).collect();
        trilab::io::ensure_not_input(out, &inputs)?;
    }
    let mut o = BenchOptions {
        scenes,
        methods,
        leaf_size: a.leaf_size,
        leaf_policy: a.leaf_policy,
        sah_group: a.sah_group,
        repeat: a.repeat.max(1),
        width: a.width,
        height: a.height,
        diffuse_per_hit: a.diffuse_per_hit,
        random_rays: a.random_rays,
        seed: a.seed,
        rays_dir: a.rays_dir.clone(),
        embree: a.embree.clone(),
        scene_access: a.scene_access,
        ..Default::default()
    };
    let ctx = a.gpu.context()?;
    if a.methods.is_empty() {
        o.methods = device_methods(&ctx);
    }
    o.ray_query = match a.ray_query {
        RayQueryChoice::On => true,
        RayQueryChoice::Off => false,
        RayQueryChoice::Auto => ctx.info().device_type != "CPU",
    };
    let report = bench::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    let lp = report.lp_num_threads.as_deref().map(|n| format!(", LP_NUM_THREADS={n}")).unwrap_or_default();
    let header = format!(
        "device: {} ({}); host CPUs: {}{lp}; leaf size {}; median of {} runs after 1 warm-up (GPU timestamps)",
        report.device, report.driver, report.host_cpus, o.leaf_size, o.repeat
    );
    println!("{header}\n");
    print!("{}", report.table().to_text());
    if !report.embree.is_empty() {
        println!();
        print!("{}", report.embree_table().to_text());
    }
    if !report.accel.is_empty() {
        println!("\nthe driver's acceleration structures (ray-query rows):\n");
        print!("{}", report.accel_table().to_text());
    }
    if let Some(note) = &report.ray_query_note {
        println!("\n{note}");
    }
    if let Some(p) = &a.json_out {
        trilab::io::write_atomic(p, serde_json::to_string_pretty(&report).unwrap().as_bytes())?;
    }
    if let Some(p) = &a.md_out {
        let mut md = format!("{header}\n\n{}", report.table().to_markdown());
        if !report.embree.is_empty() {
            md += &format!("\n{}", report.embree_table().to_markdown());
        }
        if !report.accel.is_empty() {
            md += &format!("\n{}", report.accel_table().to_markdown());
        }
        if let Some(note) = &report.ray_query_note {
            md += &format!("\n{note}\n");
        }
        trilab::io::write_atomic(p, md.as_bytes())?;
    }
    Ok(())
}

fn parse_floats(what: &str, s: &str, n: &[usize]) -> Result<Vec<f32>> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| Error::Usage(format!("--{what} `{s}`: {e}")))?;
    if !n.contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
        return Err(Error::Usage(format!("--{what} `{s}`: expected {n:?} finite comma-separated numbers")));
    }
    Ok(v)
}

fn render_cmd(a: RenderArgs) -> Result<()> {
    check_leaf_size(a.leaf_size)?;
    if a.out.extension().and_then(|e| e.to_str()) != Some("exr") {
        return Err(Error::Usage(format!("--out {}: the output must be an .exr file", a.out.display())));
    }
    let (png_path, json_path) = pt::output::sidecar_paths(&a.out);
    let mesh = load_obj(&a.scene)?;
    for out in [&a.out, &png_path, &json_path] {
        refuse_over_scene(out, &a.scene, &mesh, &[])?;
    }
    for w in &mesh.warnings {
        eprintln!("trilab: warning: {w}");
    }
    let mut settings = RenderSettings::paper(&mesh);
    settings.width = a.width;
    settings.height = a.height;
    settings.spp = a.spp;
    settings.max_depth = a.max_depth;
    settings.rr_depth = a.rr_depth;
    settings.seed = a.seed;
    settings.submit_ms = a.submit_ms;
    let env = parse_floats("env", &a.env, &[1, 3])?;
    settings.env = if env.len() == 1 { [env[0]; 3] } else { [env[0], env[1], env[2]] };
    if let Some(c) = &a.camera {
        let v = parse_floats("camera", c, &[10])?;
        let eye = glam::Vec3::new(v[0], v[1], v[2]);
        let target = glam::Vec3::new(v[3], v[4], v[5]);
        let up = glam::Vec3::new(v[6], v[7], v[8]);
        settings.camera = Camera::look(eye, target - eye, up, v[9].to_radians());
    }

    let t_build = std::time::Instant::now();
    check_sah_group(a.sah_group)?;
    let bvh = Bvh::build(
        &mesh,
        &BuildOptions { leaf_policy: a.leaf_policy, sah_group: a.sah_group, ..BuildOptions::new(a.leaf_size) },
    );
    let build_ms = t_build.elapsed().as_secs_f64() * 1e3;
    let ctx = a.gpu.context()?;
    let (method, auto) = resolve_method(a.method, &mesh, &ctx)?;
    // Plan the path tracer's buffers before encoding anything: a scene that cannot fit is an
    // error naming the buffer and the limit, not a driver failure half-way through the upload.
    let pixels = u64::from(settings.width) * u64::from(settings.height);
    let limits = trilab::gpu::DeviceLimits::of(&ctx);
    trilab::gpu::plan::check_render(&mesh.source.display().to_string(), &mesh, &bvh, method, pixels, &limits)?;
    let t_encode = std::time::Instant::now();
    let encoded = method.encode(&mesh, &bvh);
    let scene = RenderScene::new(&mesh, &encoded);
    let build_ms = build_ms + t_encode.elapsed().as_secs_f64() * 1e3;
    let kernel = PathtraceKernel::choose(method, scene.bsdf_mask, a.kernel);
    let gpu = GpuScene::upload_for(&ctx, &encoded, kernel.source)?;

    let interrupted = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    {
        let flag = interrupted.clone();
        // Ctrl-C: finish the pass in flight, then write what has accumulated.
        if let Err(e) = ctrlc::set_handler(move || flag.store(true, std::sync::atomic::Ordering::SeqCst)) {
            eprintln!("trilab: warning: cannot catch Ctrl-C ({e}); interrupting will not save the partial image");
        }
    }
    let bar = if a.quiet { indicatif::ProgressBar::hidden() } else { indicatif::ProgressBar::new(settings.spp as u64) };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} spp  {msg}  ETA {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    if !(a.checkpoint_secs >= 0.0 && a.checkpoint_secs.is_finite()) {
        return Err(Error::Usage(format!("--checkpoint-secs {}: must be a finite number >= 0", a.checkpoint_secs)));
    }
    let info = ctx.info();
    // What every write of the outputs shares: the request and the scene.
    let base = json!({
        "scene": a.scene.display().to_string(),
        "scene_sha256": pt::output::scene_hash(&mesh),
        "triangles": mesh.triangle_count(),
        "method": method.name(),
        "method_choice": a.method.to_string(),
        "auto": auto,
        "leaf_size": a.leaf_size,
        "leaf_policy": a.leaf_policy,
        "sah_group": a.sah_group,
        "kernel": kernel.source.name,
        "kernel_choice": a.kernel,
        "bsdfs_in_kernel": kernel.bsdfs(),
        "bsdfs_in_scene": trilab::scene::BsdfKind::in_mask(scene.bsdf_mask).map(|k| k.name()).collect::<Vec<_>>(),
        "settings": settings,
        "camera": {
            "eye": settings.camera.eye.to_array(),
            "forward": settings.camera.forward.to_array(),
            "up": settings.camera.up.to_array(),
            "fov_y_degrees": settings.camera.fov_y.to_degrees(),
        },
        "emissive_triangles": scene.light_count,
        "gpu_scene_bytes": gpu.bytes + scene.gpu_bytes(),
        "device": info.name,
        "driver": info.driver_label(),
        "build_ms": build_ms,
        "warnings": mesh.warnings,
    });
    // EXR, PNG and JSON of `spp` samples per pixel accumulated in `accum`, each atomically.
    let write_outputs = |accum: &[[f32; 4]], spp: u32, extra: serde_json::Value| -> Result<()> {
        let inv = 1.0 / spp.max(1) as f32;
        let image: Vec<[f32; 4]> = accum.iter().map(|p| p.map(|c| c * inv)).collect();
        let exr = pt::output::encode_exr(settings.width, settings.height, &image)?;
        let png = pt::output::encode_png(settings.width, settings.height, &image, a.exposure)?;
        let mut report = base.clone();
        report["spp_done"] = json!(spp);
        for (k, v) in extra.as_object().into_iter().flatten() {
            report[k] = v.clone();
        }
        trilab::io::write_atomic(&a.out, &exr)?;
        trilab::io::write_atomic(&png_path, &png)?;
        trilab::io::write_atomic(&json_path, serde_json::to_string_pretty(&report).unwrap().as_bytes())
    };

    let pixels = settings.pixels() as f64;
    let mut last_checkpoint = std::time::Instant::now();
    let rendered = pt::render(&ctx, &gpu, &scene, kernel, &settings, &mut |p| {
        bar.set_position(p.spp_done as u64);
        bar.set_message(format!("{:.3} Msamples/s", p.spp_done as f64 * pixels / p.seconds * 1e-6));
        if a.checkpoint_secs > 0.0 && last_checkpoint.elapsed().as_secs_f64() >= a.checkpoint_secs {
            last_checkpoint = std::time::Instant::now();
            let extra = json!({"checkpoint": true, "interrupted": false, "failed": null, "seconds": p.seconds});
            if let Err(e) = write_outputs(p.accum, p.spp_done, extra) {
                bar.println(format!("trilab: warning: checkpoint not written: {e}"));
            }
        }
        !interrupted.load(std::sync::atomic::Ordering::SeqCst)
    });
    bar.finish_and_clear();
    let result = match rendered {
        Ok(r) => r,
        // A lost device (say) part-way: write the last whole pass, then report the error.
        Err(pt::RenderFailure::Partial(pt::PartialRender { result, source })) => {
            let extra = json!({
                "checkpoint": false,
                "interrupted": false,
                "failed": source.to_string(),
                "submits": result.submits,
                "wall_ms": result.wall_ms,
            });
            write_outputs(&result.accum, result.spp, extra)?;
            eprintln!("trilab: wrote the {} spp completed before the failure to {}", result.spp, a.out.display());
            return Err(source);
        }
        Err(pt::RenderFailure::Error(e)) => return Err(e),
    };
    let extra = json!({
        "checkpoint": false,
        "kernel": result.kernel,
        "spp_done": result.spp,
        "interrupted": result.interrupted,
        "failed": null,
        "gpu_ms": result.gpu_ms,
        "wall_ms": result.wall_ms,
        "submits": result.submits,
        "samples": result.samples(),
        "samples_per_second": result.samples_per_second(),
        "closest_rays": result.closest_rays,
        "shadow_rays": result.shadow_rays,
        "mrays_per_second": result.mrays_per_second(),
        "ray_definition": "every BVH traversal counts: camera and bounce rays (closest hit) and next-event occlusion rays (any hit); rates use GPU timestamp time when available, else wall time",
        "dropped_samples_nan_or_inf": result.dropped_samples,
    });
    write_outputs(&result.accum, result.spp, extra)?;
    if result.dropped_samples > 0 {
        eprintln!(
            "trilab: warning: {} samples had NaN or infinite radiance and were left out of the image",
            result.dropped_samples
        );
    }
    println!(
        "{}: {}x{}, {} spp{} with {} ({}), {:.1} s: {:.3} Msamples/s, {:.2} Mrays/s{}",
        a.out.display(),
        result.width,
        result.height,
        result.spp,
        if result.interrupted { format!(" of {} (interrupted)", settings.spp) } else { String::new() },
        result.kernel,
        kernel.bsdfs().join("+"),
        result.seconds(),
        result.samples_per_second() * 1e-6,
        result.mrays_per_second(),
        if result.gpu_ms.is_some() { " (GPU time)" } else { " (wall time)" },
    );
    Ok(())
}

fn bench_render_cmd(a: BenchRenderArgs) -> Result<()> {
    check_leaf_size(a.leaf_size)?;
    let scenes = if a.scenes.is_empty() {
        ["bunny", "dragon", "buddha"].iter().map(|s| PathBuf::from(format!("scenes/{s}.obj"))).collect()
    } else {
        a.scenes
    };
    for out in [&a.json_out, &a.md_out].into_iter().flatten() {
        trilab::io::ensure_not_input(out, &scenes.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    }
    let ctx = a.gpu.context()?;
    let opts = pt::bench::RenderBenchOptions {
        scenes,
        methods: if a.methods.is_empty() { device_methods(&ctx) } else { a.methods },
        kernels: a.kernels,
        leaf_size: a.leaf_size,
        width: a.width,
        height: a.height,
        spp: a.spp,
        max_depth: a.max_depth,
        env: None,
        repeat: a.repeat,
    };
    let report = pt::bench::run(&ctx, &opts, |m| eprintln!("  {m}"))?;
    let head = format!(
        "device: {} ({})\n{}x{}, {} spp, max depth {}, leaf size {}, median (min-max) of {} renders after a warm-up, {} time\n",
        report.device,
        report.driver,
        report.width,
        report.height,
        report.spp,
        report.max_depth,
        report.leaf_size,
        a.repeat.max(1),
        if report.timed_on_gpu { "GPU timestamp" } else { "wall" }
    );
    let table = report.table();
    println!("{head}\n{}", table.to_text());
    if let Some(p) = &a.md_out {
        trilab::io::write_atomic(p, format!("{head}\n{}", table.to_markdown()).as_bytes())?;
    }
    if let Some(p) = &a.json_out {
        trilab::io::write_atomic(p, serde_json::to_string_pretty(&report).unwrap().as_bytes())?;
    }
    Ok(())
}

fn study_cmd(a: StudyArgs) -> Result<()> {
    let mut o = StudyOptions::preset(a.preset);
    if !a.scenes.is_empty() {
        o.scenes = a
            .scenes
            .iter()
            .map(|s| {
                let p = PathBuf::from(s);
                if p.extension().is_none() && p.components().count() == 1 {
                    PathBuf::from(format!("scenes/{s}.obj"))
                } else {
                    p
                }
            })
            .collect();
    }
    if !a.leaf_sizes.is_empty() {
        o.leaf_sizes = a.leaf_sizes.clone();
    }
    for &l in &o.leaf_sizes {
        check_leaf_size(l)?;
    }
    if !a.methods.is_empty() {
        o.methods = a.methods.clone();
    }
    if let Some(r) = a.repeat {
        o.repeat = r.max(1);
    }
    if ![1, 4].contains(&a.sah_group) {
        return Err(Error::Usage(format!("--sah-group {}: expected 1 or 4", a.sah_group)));
    }
    o.sah_group = a.sah_group;
    for scene in &o.scenes {
        if !scene.is_file() {
            return Err(Error::Usage(format!("study: scene {} does not exist", scene.display())));
        }
    }
    let ctx = a.gpu.context()?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("results").join(ctx.info().results_dir()).join("study"));
    let inputs: Vec<&Path> = o.scenes.iter().map(PathBuf::as_path).collect();
    for f in ["study.csv", "study.json", "study.md"] {
        trilab::io::ensure_not_input(&out.join(f), &inputs)?;
    }
    eprintln!("study: {}", o.scaling());
    let report = trilab::study::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    print!("{}", trilab::study::table::paper_table(&report).to_text());
    println!();
    print!("{}", trilab::study::claims::markdown(&report));
    let written = trilab::study::write(&report, &out)?;
    eprintln!("study took {:.0} s; wrote:", report.seconds);
    for w in written {
        eprintln!("  {}", w.display());
    }
    Ok(())
}

fn accuracy_cmd(a: AccuracyArgs) -> Result<()> {
    let mut o = trilab::accuracy::AccuracyOptions::preset(a.preset);
    if !a.methods.is_empty() {
        o.methods = a.methods.clone();
    }
    if !a.leaf_sizes.is_empty() {
        o.leaf_sizes = a.leaf_sizes.clone();
    }
    for &l in &o.leaf_sizes {
        check_leaf_size(l)?;
    }
    if let Some(n) = a.rays {
        o.leak_rays = n;
    }
    let ctx = a.gpu.context()?;
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("results").join(ctx.info().results_dir()).join("accuracy"));
    let t = std::time::Instant::now();
    let report = trilab::accuracy::run(&ctx, &o, |m| eprintln!("  [{:5.0} s] {m}", t.elapsed().as_secs_f64()))?;
    print!("{}", trilab::accuracy::table::frontier_table(&report).to_text());
    for w in trilab::accuracy::write(&report, &out)? {
        eprintln!("  wrote {}", w.display());
    }
    Ok(())
}

#[derive(Args)]
struct ProfileArgs {
    #[arg(long)]
    scene: PathBuf,
    #[arg(long, value_enum, value_delimiter = ',')]
    methods: Vec<Method>,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    /// Output directory; default results/<device>/profile (lavapipe for Mesa's llvmpipe).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Primary rays: a width x height camera image (also the heat maps' size).
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    #[arg(long, default_value_t = 2)]
    diffuse_per_hit: u32,
    #[arg(long, default_value_t = 250_000)]
    random_rays: usize,
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Timed runs after one warm-up; median, min and max are reported.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// The ray set the subgroup- and workgroup-size sweeps time: primary, diffuse or random.
    #[arg(long, default_value = "random")]
    sweep_set: String,
    #[arg(long, value_delimiter = ',', default_values_t = [32u32, 64, 128, 256])]
    workgroup_sizes: Vec<u32>,
    /// LP_NUM_THREADS values to run (lavapipe only); default 1..=host cores.
    #[arg(long, value_delimiter = ',')]
    threads: Vec<usize>,
    /// Leave out the LP_NUM_THREADS section.
    #[arg(long)]
    no_threads: bool,
    #[command(flatten)]
    gpu: GpuArgs,
}

fn profile_cmd(a: ProfileArgs) -> Result<()> {
    use trilab::profile::{self, ProfileOptions};
    check_leaf_size(a.leaf_size)?;
    let exe = if a.no_threads {
        None
    } else {
        Some(std::env::current_exe().map_err(|e| Error::io(Path::new("the trilab executable"), e))?)
    };
    let ctx = a.gpu.context()?;
    let o = ProfileOptions {
        scene: a.scene.clone(),
        methods: if a.methods.is_empty() { device_methods(&ctx) } else { a.methods.clone() },
        leaf_size: a.leaf_size,
        width: a.width,
        height: a.height,
        diffuse_per_hit: a.diffuse_per_hit,
        random_rays: a.random_rays,
        seed: a.seed,
        repeat: a.repeat.max(1),
        sweep_set: a.sweep_set.clone(),
        workgroup_sizes: a.workgroup_sizes.clone(),
        thread_counts: a.threads.clone(),
        exe,
        ..Default::default()
    };
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("results").join(ctx.info().results_dir()).join("profile"));
    for f in ["profile.json", "profile.md"] {
        trilab::io::ensure_not_input(&out.join(f), &[&a.scene])?;
    }
    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    let report = profile::run(&ctx, &o, Some(&out), |m| eprintln!("  {m}"))?;
    let command: Vec<String> = std::env::args().skip(1).collect();
    let md = profile::markdown::render(&report, &format!("trilab {}", command.join(" ")));
    trilab::io::write_atomic(&out.join("profile.json"), serde_json::to_string_pretty(&report).unwrap().as_bytes())?;
    trilab::io::write_atomic(&out.join("profile.md"), md.as_bytes())?;
    print!("{md}");
    println!("\nwrote {}", out.display());
    Ok(())
}

fn analyze_cmd(a: AnalyzeArgs) -> Result<()> {
    use trilab::analyze::{self, Conditioning, Frontier, Target};
    for (name, v) in [("--max-leaks-per-million", a.max_leaks_per_million), ("--max-t-ulps", a.max_t_ulps)] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(Error::Usage(format!("{name} {v}: must be a finite number >= 0")));
        }
    }
    let mesh = load_obj(&a.scene)?;
    let frontier = match &a.frontier {
        Some(p) => Frontier::read(p)?,
        None => Frontier::builtin(),
    };
    // The device only decides whether f64 is available; no device is needed to analyze.
    let (available, device_note) = match Context::list_devices()
        .ok()
        .and_then(|l| trilab::gpu::context::choose_device(&l, a.gpu.device.as_deref()).ok().map(|i| l[i].clone()))
    {
        Some(info) => {
            let f = trilab::gpu::EnabledFeatures::for_device(&info);
            (analyze::available_methods(&f), format!("methods this device ({}) can run", info.name))
        }
        None => (Method::ALL.to_vec(), "no Vulkan device found: every method assumed available".to_owned()),
    };
    let target = Target { max_leaks_per_million: a.max_leaks_per_million, max_t_ulps: a.max_t_ulps };
    let cond = Conditioning::of(&mesh);
    let rec = analyze::recommend(&cond, &target, &frontier, &available, analyze::OFFSET_SCHEME);
    if a.json {
        let out = json!({
            "scene": a.scene.display().to_string(),
            "conditioning": cond,
            "target": target,
            "frontier": frontier,
            "available_methods": available,
            "recommendation": rec,
        });
        println!("{}", serde_json::to_string_pretty(&out).unwrap());
        return Ok(());
    }
    println!("scene {} ({} triangles, {} degenerate)", a.scene.display(), cond.triangles, cond.degenerate);
    let b = |v: [f64; 3]| format!("({:.6e}, {:.6e}, {:.6e})", v[0], v[1], v[2]);
    println!("  bounds                 {} .. {}", b(cond.bounds_min), b(cond.bounds_max));
    println!("  extent (largest side)  {:.6e}", cond.extent);
    println!(
        "  centre from origin     {:.6e} ({:.2}x the extent)",
        cond.centre_distance,
        cond.centre_distance / cond.extent.max(f64::MIN_POSITIVE)
    );
    println!("  max |coordinate|       {:.6e}  (f32 ULP there: {:.3e})", cond.max_abs_coord, cond.position_ulp);
    println!("  edges min/median/max   {:.3e} / {:.3e} / {:.3e}", cond.edge_min, cond.edge_median, cond.edge_max);
    println!("  magnitude / min edge   {:.3e}", cond.magnitude_over_edge);
    println!(
        "  f32 bits across the smallest edge: {:.1} as placed, {:.1} recentred",
        cond.edge_bits, cond.edge_bits_recentred
    );
    println!(
        "  sliver ratio (longest edge / shortest altitude) median {:.3}, p99 {:.3}, max {:.3e}",
        cond.sliver_median, cond.sliver_p99, cond.sliver_max
    );
    println!(
        "target: <= {} leaks per 10^6 rays, p99 t error <= {} ULPs; {device_note}: {}",
        target.max_leaks_per_million,
        target.max_t_ulps,
        available.iter().map(|m| m.name()).collect::<Vec<_>>().join(", ")
    );
    println!(
        "recommendation: --method {}, offset scheme {}, {}{}",
        rec.method,
        rec.offset_scheme,
        if rec.recentre { "recentre the scene in f64 before upload" } else { "no recentring needed" },
        if rec.meets_target { "" } else { " (the target is NOT met)" }
    );
    for r in &rec.reasons {
        println!("  {r}");
    }
    Ok(())
}

/// Resolves `--method` (a method or `auto`) for `mesh` on `ctx`, saying on stderr what `auto`
/// picked and why.
fn resolve_method(
    choice: MethodChoice,
    mesh: &trilab::scene::Mesh,
    ctx: &Context,
) -> Result<(Method, Option<trilab::analyze::Recommendation>)> {
    let (m, rec) = trilab::analyze::resolve(choice, mesh, ctx.enabled(), None)?;
    if let Some(r) = &rec {
        eprintln!("trilab: --method auto picked {m}:");
        for line in &r.reasons {
            eprintln!("trilab:   {line}");
        }
    }
    Ok((m, rec))
}

/// `trilab scale`: writes the report, then fails if any cast disagreed with the reference.
fn scale_cmd(a: ScaleArgs) -> Result<()> {
    check_leaf_size(a.leaf_size)?;
    let scenes = if a.scenes.is_empty() {
        let dragon = Path::new("../shared/scenes/dragon_full_draco11.obj.gz");
        let mut v = vec![];
        if dragon.exists() {
            v.push(dragon.display().to_string());
        }
        v.push("synth:terrain:10M".to_owned());
        v
    } else {
        a.scenes.clone()
    };
    let ctx = a.gpu.context()?;
    let methods = if a.methods.is_empty() { device_methods(&ctx) } else { a.methods.clone() };
    let out = a.out.clone().unwrap_or_else(|| PathBuf::from("results").join(ctx.info().results_dir()).join("scale"));
    let o = trilab::scale::ScaleOptions {
        scenes,
        methods,
        leaf_size: a.leaf_size,
        rays: a.rays,
        ray_kind: a.ray_kind,
        warmup: 1,
        repeat: a.repeat.max(1),
        validate: a.validate,
        scene_access: a.scene_access,
        batch_rays: a.batch_rays,
        seed: a.seed,
        plan_only: a.plan_only,
    };
    let report = trilab::scale::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    print!("{}", report.markdown());
    for p in report.write(&out)? {
        eprintln!("wrote {}", p.display());
    }
    if !report.passes() {
        return Err(Error::Usage("scale: some casts disagree with the f64 reference (see scale.md)".into()));
    }
    Ok(())
}

/// Every method this device can run: the default of `bench`, `bench-render`, `profile` and
/// `steps --gpu` (f64 needs shaderFloat64; elsewhere it is left out rather than failing).
fn device_methods(ctx: &Context) -> Vec<Method> {
    trilab::analyze::available_methods(ctx.enabled())
}

/// Refuses an output over the scene, any MTL it read, or one of `other` inputs (every command
/// writes through `io::write_atomic`; this keeps it off the inputs).
fn refuse_over_scene(out: &Path, scene: &Path, mesh: &trilab::scene::Mesh, other: &[&Path]) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![scene];
    inputs.extend(mesh.mtl_files.iter().map(PathBuf::as_path));
    inputs.extend_from_slice(other);
    trilab::io::ensure_not_input(out, &inputs)
}
