//! `trilab bench`.

use std::path::PathBuf;

use clap::Args;
use trilab::encoding::SceneAccess;
use trilab::error::Result;
use trilab::harness::bench::{self, BenchOptions};

use super::choice::choice;
use super::{BuildArgs, GpuArgs, MethodsArg};

/// Ray-casting benchmark: primary, diffuse and random rays, every method, validated against
/// the f64 reference, optionally beside the Embree peer.
#[derive(Args)]
pub struct BenchArgs {
    /// Scenes: OBJ paths or names of bundled scenes (bunny, dragon, buddha, cornell, bsdfs), found
    /// from any folder (see --scene-dir); default: bunny.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<PathBuf>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[command(flatten)]
    bvh: BuildArgs,
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

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum RayQueryChoice {
    Auto,
    On,
    Off,
}

pub fn run(a: BenchArgs) -> Result<()> {
    let scenes = if a.scenes.is_empty() { vec![PathBuf::from("bunny")] } else { a.scenes.clone() };
    // Names (`bunny`) resolve from any folder; the files found are the inputs to protect.
    let files = scenes.iter().map(|s| trilab::scene::resolve(s).map(|f| f.path)).collect::<Result<Vec<_>>>()?;
    for out in [&a.json_out, &a.md_out].into_iter().flatten() {
        trilab::io::ensure_not_input(out, &files.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    }
    let ctx = a.gpu.context()?;
    let o = BenchOptions {
        scenes,
        methods: a.methods.or_device(&ctx),
        leaf_size: a.bvh.leaf_size,
        leaf_policy: a.bvh.leaf_policy,
        sah_group: a.bvh.sah_group,
        repeat: a.repeat.max(1),
        width: a.width,
        height: a.height,
        diffuse_per_hit: a.diffuse_per_hit,
        random_rays: a.random_rays,
        seed: a.seed,
        rays_dir: a.rays_dir,
        embree: a.embree,
        scene_access: a.scene_access,
        ray_query: match a.ray_query {
            RayQueryChoice::On => true,
            RayQueryChoice::Off => false,
            RayQueryChoice::Auto => ctx.info().device_type != "CPU",
        },
        ..Default::default()
    };
    let report = bench::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    print!("{}", trilab::report::Report::to_text(&report));
    report.write(a.json_out.as_deref(), a.md_out.as_deref())
}
