//! `trilab bench`.

use std::path::PathBuf;

use clap::Args;
use trilab::bvh::NodeOrder;
use trilab::commands::bench::{self, BenchOptions, BenchReport};
use trilab::encoding::{Layout, SceneAccess, Traversal};
use trilab::error::Result;
use trilab::matrix::KernelAxes;
use trilab::rays::order::RayOrder;
use trilab::services::peers::{EmbreeApi, TinybvhLayout};
use trilab::services::results::Results;

use super::choice::choice;
use super::ShardArg;
use super::{repeat, scenes_help, BuildArgs, GpuArgs, JsonArg, MethodsArg, RaySetArgs, ReportOutArgs, TimelineArg};

/// Ray-casting benchmark: every method on three ray sets, validated, beside peers
///
/// Ray-casting benchmark: primary, diffuse and random rays, every method, validated against
/// the f64 reference, optionally beside the Embree and tinybvh peers.
#[derive(Args)]
#[command(mut_arg("shard", |a| a.help("Run only shard I of N: every N-th scene, round-robin from scene I (a scene is the unit, so its methods, layouts and peers stay interleaved in one run). rows.jsonl names the shard and plans the whole matrix; `trilab merge` joins the shards' folders")))]
#[command(mut_arg("out", |a| a.help("Folder for bench.json (the report), bench.md (its tables), rows.jsonl and plots, made when missing")))]
pub struct BenchArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', help = concat!(scenes_help!(), "; default: bunny"))]
    scenes: Vec<PathBuf>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[command(flatten)]
    bvh: BuildArgs,
    /// Timed runs per ray set and method after one warm-up (at least 1; median, min, max).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::REPEAT, value_parser = repeat)]
    repeat: usize,
    #[command(flatten)]
    rays: RaySetArgs,
    /// Read <scene>.{primary,diffuse,random}.rays from this directory instead of generating.
    #[arg(long, value_name = "DIR")]
    rays_dir: Option<PathBuf>,
    /// The Embree peer (`embree_rays` from scripts/embree-peer.sh), run on the same rays with
    /// each of --embree-apis; its hits are checked against the f64 reference before its speed
    /// counts.
    #[arg(long, value_name = "FILE")]
    embree: Option<PathBuf>,
    /// Embree's calls, comma-separated, each run as its own peer, named `embree3` (ray1),
    /// `embree3 packet8`, `embree3 packet16` (default: ray1,packet8). A packet width the library
    /// does not run natively is an error before any work.
    #[arg(long, value_name = "A,...", value_parser = choice::<EmbreeApi>(), value_delimiter = ',', requires = "embree")]
    embree_apis: Vec<EmbreeApi>,
    /// The tinybvh peer (`tinybvh_rays` from scripts/tinybvh-peer.sh), run on the same rays in
    /// each of --tinybvh-layouts; its hits are checked against the f64 reference before its speed
    /// counts. An ocl-* layout without OpenCL is skipped with a note.
    #[arg(long, value_name = "FILE")]
    tinybvh: Option<PathBuf>,
    /// tinybvh's layouts, comma-separated (default: cpu-bvh8,ocl-bvh2,ocl-cwbvh: its fastest CPU
    /// traversal and both OpenCL kernels).
    #[arg(long, value_name = "L,...", value_parser = choice::<TinybvhLayout>(), value_delimiter = ',', requires = "tinybvh")]
    tinybvh_layouts: Vec<TinybvhLayout>,
    /// The driver's ray-query peer row: `auto` runs it wherever the device has ray query except
    /// on CPU devices (on lavapipe it traces 12-1,266x slower than our kernels, hours at the
    /// default sizes); `on` runs it there too; `off` leaves it out.
    #[arg(long, value_enum, default_value_t = PeerChoice::Auto)]
    ray_query: PeerChoice,
    /// The driver's ray-tracing-pipeline peer row (ray generation, closest-hit and miss stages
    /// through the same acceleration structure; NVIDIA's H100 and H200 have it but no ray
    /// query): `auto` runs it wherever the device has it except on CPU devices; `on` runs it
    /// there too; `off` leaves it out.
    #[arg(long, value_enum, default_value_t = PeerChoice::Auto)]
    ray_tracing_pipeline: PeerChoice,
    /// How the kernels read the scenes: `auto` uses texel buffers when every buffer fits one
    /// binding, else buffer device addresses (`trilab scale` reports which); several,
    /// comma-separated (`texel,address`), are timed side by side.
    #[arg(long, value_name = "A,...", value_parser = choice::<SceneAccess>(), value_delimiter = ',', default_values_t = [SceneAccess::DEFAULT])]
    scene_access: Vec<SceneAccess>,
    /// BVH node layouts, comma-separated (`bvh2`, `bvh4`, `bvh8`, ...): every method is timed on
    /// each, side by side in one run (default: bvh2).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    /// Traversals, comma-separated (`while-if`, `while-while`, `coop`, `persistent`, `packet`, `hybrid`): every
    /// method and layout is timed with each that has a kernel for it, side by side in one run; a
    /// traversal x layout without one is left out with a note (default: while-if).
    #[arg(long, value_name = "T,...", value_parser = choice::<Traversal>(), value_delimiter = ',')]
    traversals: Vec<Traversal>,
    /// Orders to dispatch each ray set in, comma-separated (`given`, `octant-origin`, `tiles`), timed
    /// side by side: a reordering's host time (sorting the rays, putting the hits back) counts in
    /// its kernel time and is shown as `reorder ms` (default: given).
    #[arg(long, value_name = "O,...", value_parser = choice::<RayOrder>(), value_delimiter = ',')]
    orders: Vec<RayOrder>,
    /// Orders of each layout's nodes in memory, comma-separated (`built`, `depth-first`,
    /// `breadth-first`, `treelets`): every method, layout and traversal is timed on the nodes in
    /// each, side by side in one run; the tree, its leaves and the rays' walks are the same
    /// (default: built, the layout's own order).
    #[arg(long, value_name = "O,...", value_parser = choice::<NodeOrder>(), value_delimiter = ',')]
    node_orders: Vec<NodeOrder>,
    #[command(flatten)]
    shard: ShardArg,
    /// Also measure the traversal roofline (`trilab roofline`: node steps/s of a dependent
    /// 32-byte-node walk) at each scene's working set (its encoded bytes: nodes, primitives,
    /// slot ids) on the access path its kernels read, and add per kernel its share of it:
    /// (nodes visited + triangles tested per ray, from the kernel's stats variant on the same
    /// rays) x Mrays/s / the roofline's Msteps/s. A node of any layout and a triangle each count
    /// as one fetch.
    #[arg(long)]
    roofline: bool,
    #[command(flatten)]
    out: ReportOutArgs,
    #[command(flatten)]
    trace: TimelineArg,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

/// `--node-orders` as given, each order once, where it was first named (`bench` and `bvh`): a
/// repeated order would run the same cells again under the same name, however long the list;
/// a note names the orders given more than once.
pub fn distinct_node_orders(given: Vec<NodeOrder>) -> Vec<NodeOrder> {
    let mut once: Vec<NodeOrder> = vec![];
    let mut repeated: Vec<String> = vec![];
    for o in given {
        if !once.contains(&o) {
            once.push(o);
        } else if !repeated.contains(&o.to_string()) {
            repeated.push(o.to_string());
        }
    }
    if !repeated.is_empty() {
        super::note(&format!("--node-orders: {} given more than once; each order runs once", repeated.join(", ")));
    }
    once
}

/// Whether a driver peer row runs (`--ray-query`, `--ray-tracing-pipeline`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum PeerChoice {
    /// The peer except on CPU devices.
    Auto,
    /// The peer wherever the device has it.
    On,
    /// No peer row.
    Off,
}

impl PeerChoice {
    /// Whether the row runs on `ctx`'s device (`auto`: unless it is a CPU device, where the
    /// driver's ray tracing is far too slow for the default sizes).
    fn runs(self, ctx: &trilab::gpu::Context) -> bool {
        match self {
            PeerChoice::On => true,
            PeerChoice::Off => false,
            PeerChoice::Auto => !ctx.capabilities().is_cpu(),
        }
    }
}

pub fn run(a: BenchArgs) -> Result<()> {
    let scenes = if a.scenes.is_empty() { vec![PathBuf::from("bunny")] } else { a.scenes.clone() };
    let (json_out, md_out) = a.out.files(<BenchReport as Results>::STEM, &scenes)?;
    BenchOptions { scenes: scenes.clone(), shard: a.shard.shard, ..Default::default() }.check_shard()?;
    // The trace is neither an input (a scene, a peer program) nor one of the report's files.
    let scene_files = scenes.iter().map(|s| trilab::scene::resolve(s).map(|f| f.path)).collect::<Result<Vec<_>>>()?;
    let mut inputs: Vec<&std::path::Path> = scene_files.iter().map(PathBuf::as_path).collect();
    inputs.extend(a.embree.as_deref().into_iter().chain(a.tinybvh.as_deref()));
    let mut outputs: Vec<PathBuf> = json_out.iter().chain(&md_out).cloned().collect();
    outputs.extend(a.out.out.dir.iter().map(|d| d.join(trilab::rows::FILE)));
    a.trace.check(&inputs, &outputs)?;
    let trace = a.trace.clone();
    let run = trace.start("bench");
    let result = measure(a, (json_out, md_out));
    let written = trace.finish(run, &result);
    result?;
    written
}

/// The bench itself, and its report written (`--timeline`'s run span covers it all).
fn measure(a: BenchArgs, files: (Option<PathBuf>, Option<PathBuf>)) -> Result<()> {
    let (json_out, md_out) = files;
    let scenes = if a.scenes.is_empty() { vec![PathBuf::from("bunny")] } else { a.scenes.clone() };
    let ctx = {
        let _span = trilab::timeline::span("device", "device context");
        a.gpu.context()?
    };
    TimelineArg::device(&ctx);
    let o = BenchOptions {
        scenes,
        axes: KernelAxes {
            methods: a.methods.or_device(&ctx),
            layouts: a.layouts,
            traversals: a.traversals,
            access: a.scene_access,
            node_orders: distinct_node_orders(a.node_orders),
            orders: a.orders,
        },
        build: a.bvh.options(),
        repeat: a.repeat,
        sizes: a.rays.sizes(),
        rays_dir: a.rays_dir,
        embree: a.embree,
        embree_apis: a.embree_apis,
        tinybvh: a.tinybvh,
        tinybvh_layouts: a.tinybvh_layouts,
        ray_query: a.ray_query.runs(&ctx),
        ray_tracing_pipeline: a.ray_tracing_pipeline.runs(&ctx),
        shard: a.shard.shard,
        roofline: a
            .roofline
            .then(|| trilab::services::roofline::RooflineOptions { rounds: a.repeat, ..Default::default() }),
        ..Default::default()
    };
    if let Some(shard) = o.shard {
        let owned = o.split().owned();
        eprintln!("bench: shard {shard}: {owned} of {} scene(s)", o.scenes.len());
    }
    let report = bench::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    let _span = trilab::timeline::span("report", "report writing");
    a.json.print(&report);
    a.out.create_dir()?;
    report.write(json_out.as_deref(), md_out.as_deref())
}
