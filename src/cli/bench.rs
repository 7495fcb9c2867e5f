//! `trilab bench`.

use std::path::PathBuf;

use clap::Args;
use trilab::encoding::{Layout, SceneAccess};
use trilab::error::{Error, Result};
use trilab::harness::bench::{self, BenchOptions};
use trilab::harness::peers::TinybvhLayout;

use super::choice::choice;
use super::{repeat, scenes_help, BuildArgs, GpuArgs, JsonArg, MethodsArg};

/// Ray-casting benchmark: primary, diffuse and random rays, every method, validated against
/// the f64 reference, optionally beside the Embree and tinybvh peers.
#[derive(Args)]
pub struct BenchArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', help = concat!(scenes_help!(), "; default: bunny"))]
    scenes: Vec<PathBuf>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[command(flatten)]
    bvh: BuildArgs,
    /// Timed runs per ray set and method after one warm-up (at least 1; median, min, max).
    #[arg(long, value_name = "N", default_value_t = 5, value_parser = repeat)]
    repeat: usize,
    /// Primary rays: the camera image's width in pixels.
    #[arg(long, value_name = "W", default_value_t = 800)]
    width: u32,
    /// Primary rays: the camera image's height in pixels.
    #[arg(long, value_name = "H", default_value_t = 600)]
    height: u32,
    /// Diffuse rays: cosine-distributed bounces per primary hit.
    #[arg(long, value_name = "N", default_value_t = 8, alias = "per-hit")]
    diffuse_per_hit: u32,
    /// Random rays: how many, from a sphere around the scene into its box.
    #[arg(long, value_name = "N", default_value_t = 1_000_000, alias = "count")]
    random_rays: usize,
    /// Seed of the diffuse and random ray sets.
    #[arg(long, value_name = "N", default_value_t = 7)]
    seed: u64,
    /// Read <scene>.{primary,diffuse,random}.rays from this directory instead of generating.
    #[arg(long, value_name = "DIR")]
    rays_dir: Option<PathBuf>,
    /// The Embree peer (`embree_rays` from scripts/embree-peer.sh), run on the same rays; its
    /// hits are checked against the f64 reference before its speed counts.
    #[arg(long, value_name = "FILE")]
    embree: Option<PathBuf>,
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
    /// binding, else buffer device addresses (`trilab scale` reports which).
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::Auto)]
    scene_access: SceneAccess,
    /// BVH node layouts, comma-separated (`bvh2`, `bvh4`, `bvh8`, ...): every method is timed on
    /// each, side by side in one run (default: bvh2).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    /// Run only shard I of N: every N-th scene, round-robin from scene I (a scene is the unit, so
    /// its methods, layouts and peers stay interleaved in one run). rows.jsonl names the shard
    /// and plans the whole matrix; `trilab merge` joins the shards' folders.
    #[arg(long, value_name = "I/N")]
    shard: Option<trilab::rows::Shard>,
    /// Directory to write bench.json (the report) and bench.md (the tables) into.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Old spelling: write the report as JSON to this file (use --out DIR).
    #[arg(long, value_name = "FILE", hide = true)]
    json_out: Option<PathBuf>,
    /// Old spelling: write the tables as Markdown to this file (use --out DIR).
    #[arg(long, value_name = "FILE", hide = true)]
    md_out: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
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
            PeerChoice::Auto => ctx.info().device_type != "CPU",
        }
    }
}

/// `--out DIR` as the two report files (`<stem>.json`, `<stem>.md`), or the old
/// `--json-out`/`--md-out` files, each checked before any work: writable, and not one of the
/// `scenes` (names are resolved to the files they find).
pub fn output_files(
    out: &Option<PathBuf>,
    json_out: &Option<PathBuf>,
    md_out: &Option<PathBuf>,
    stem: &str,
    scenes: &[PathBuf],
) -> Result<(Option<PathBuf>, Option<PathBuf>)> {
    let (json, md) = match out {
        Some(dir) => {
            if dir.is_file() {
                return Err(Error::Usage(format!("--out {}: is a file; --out names a directory", dir.display())));
            }
            let json = json_out.clone().unwrap_or_else(|| dir.join(format!("{stem}.json")));
            let md = md_out.clone().unwrap_or_else(|| dir.join(format!("{stem}.md")));
            (Some(json), Some(md))
        }
        None => (json_out.clone(), md_out.clone()),
    };
    let files = scenes.iter().map(|s| trilab::scene::resolve(s).map(|f| f.path)).collect::<Result<Vec<_>>>()?;
    let inputs: Vec<&std::path::Path> = files.iter().map(PathBuf::as_path).collect();
    for (option, file) in [("--json-out", &json), ("--md-out", &md)] {
        if let Some(file) = file {
            let option = if out.is_some() { "--out" } else { option };
            trilab::io::check_output(option, trilab::io::Output::File(file), &inputs)?;
        }
    }
    Ok((json, md))
}

pub fn run(a: BenchArgs) -> Result<()> {
    let scenes = if a.scenes.is_empty() { vec![PathBuf::from("bunny")] } else { a.scenes.clone() };
    let (json_out, md_out) = output_files(&a.out, &a.json_out, &a.md_out, "bench", &scenes)?;
    BenchOptions { scenes: scenes.clone(), shard: a.shard, ..Default::default() }.check_shard()?;
    let ctx = a.gpu.context()?;
    let o = BenchOptions {
        scenes,
        methods: a.methods.or_device(&ctx),
        leaf_size: a.bvh.leaf_size,
        leaf_policy: a.bvh.shape.leaf_policy,
        sah_group: a.bvh.shape.sah_group,
        repeat: a.repeat,
        width: a.width,
        height: a.height,
        diffuse_per_hit: a.diffuse_per_hit,
        random_rays: a.random_rays,
        seed: a.seed,
        rays_dir: a.rays_dir,
        embree: a.embree,
        tinybvh: a.tinybvh,
        tinybvh_layouts: a.tinybvh_layouts,
        scene_access: a.scene_access,
        layouts: if a.layouts.is_empty() { vec![Layout::Bvh2] } else { a.layouts },
        ray_query: a.ray_query.runs(&ctx),
        ray_tracing_pipeline: a.ray_tracing_pipeline.runs(&ctx),
        shard: a.shard,
        ..Default::default()
    };
    if let Some(shard) = o.shard {
        let owned = o.split().owned();
        eprintln!("bench: shard {shard}: {owned} of {} scene(s)", o.scenes.len());
    }
    let report = bench::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    a.json.print(&report);
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    report.write(json_out.as_deref(), md_out.as_deref())
}
