//! `trilab scale`.

use super::OutArgs;
use std::path::Path;

use clap::Args;
use trilab::commands::scale::{self, ScaleOptions};
use trilab::encoding::SceneAccess;
use trilab::error::Result;
use trilab::services::rayset::RaySet;

use super::choice::choice;
use super::{repeat, results_dir, GpuArgs, JsonArg, LeafSizeArg, MethodsArg};

/// Large scenes: memory placement, load, build and upload times, a validated cast
///
/// Large scenes: load and BVH-build times, each method's GPU memory placement (bytes per buffer and
/// per triangle, access path), upload and a timed, validated cast; writes scale.csv/json/md.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Output directory for scale.csv/json/md; default results/<device>/scale/")))]
pub struct ScaleArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', help = concat!(super::scenes_help!(),
          "; default: ../shared/scenes/dragon_full_draco11.obj.gz if present, and a 10M-triangle synthetic scene"))]
    scenes: Vec<String>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[command(flatten)]
    leaf: LeafSizeArg,
    /// Rays cast per scene and method (was `--rays`).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::RANDOM_RAYS, alias = "rays")]
    ray_count: usize,
    /// The ray set cast (was `--ray-kind`).
    #[arg(long, value_parser = choice::<RaySet>(), default_value_t = RaySet::Random, alias = "ray-kind")]
    ray_set: RaySet,
    /// Timed runs after one warm-up (at least 1; median, min, max reported).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::REPEAT, value_parser = repeat)]
    repeat: usize,
    /// Hits checked against the f64 reference, evenly spaced over the ray set (was `--validate`).
    #[arg(long, value_name = "N", default_value_t = 20_000, alias = "validate")]
    reference_rays: usize,
    /// How the kernels read the scenes: `auto` uses texel buffers when every buffer fits one
    /// binding, else buffer device addresses.
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::DEFAULT)]
    scene_access: SceneAccess,
    /// Most rays per dispatch (each dispatch is its own submit).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::BATCH_RAYS)]
    batch_rays: usize,
    /// Seed of the ray set.
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::SEED)]
    seed: u64,
    /// Only the memory placement (bytes per triangle, access path): no upload, no cast (was
    /// `--plan-only`).
    #[arg(long, alias = "plan-only")]
    placement_only: bool,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

/// `trilab scale`: writes the report, then fails if any cast disagreed with the reference.
pub fn run(a: ScaleArgs) -> Result<()> {
    let scenes = if a.scenes.is_empty() { scale::default_scenes() } else { a.scenes.clone() };
    let ctx = a.gpu.context()?;
    let out = results_dir(&ctx, a.out.dir.clone(), "scale");
    let inputs: Vec<&Path> = scenes.iter().map(Path::new).collect();
    let files = ["scale.csv", "scale.json", "scale.md"];
    OutArgs::check(&out, &files, &inputs)?;
    let o = ScaleOptions {
        scenes,
        methods: a.methods.or_device(&ctx),
        build: a.leaf.options(),
        rays: a.ray_count,
        ray_kind: a.ray_set,
        warmup: 1,
        repeat: a.repeat,
        validate: a.reference_rays,
        scene_access: a.scene_access,
        batch_rays: a.batch_rays,
        seed: a.seed,
        placement_only: a.placement_only,
    };
    let report = scale::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    if a.json.json {
        a.json.print(&report);
    } else {
        print!("{}", report.markdown());
    }
    for p in report.write(&out)? {
        eprintln!("wrote {}", p.display());
    }
    report.verdict()
}
