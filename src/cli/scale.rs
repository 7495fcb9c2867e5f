//! `trilab scale`.

use std::path::{Path, PathBuf};

use clap::Args;
use trilab::encoding::SceneAccess;
use trilab::error::Result;
use trilab::harness::scale::{self, RayKind, ScaleOptions};

use super::choice::choice;
use super::{results_dir, GpuArgs, MethodsArg};

/// Large scenes: load and BVH-build times, each method's GPU memory plan (bytes per buffer and
/// per triangle, access path), upload and a timed, validated cast; writes scale.csv/json/md.
#[derive(Args)]
pub struct ScaleArgs {
    /// Scenes; default: ../shared/scenes/dragon_full_draco11.obj.gz if present, and a
    /// 10M-triangle synthetic scene.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<String>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    /// Rays cast per scene and method.
    #[arg(long, default_value_t = 1_000_000)]
    rays: usize,
    #[arg(long, value_parser = choice::<RayKind>(), default_value_t = RayKind::Random)]
    ray_kind: RayKind,
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

/// `trilab scale`: writes the report, then fails if any cast disagreed with the reference.
pub fn run(a: ScaleArgs) -> Result<()> {
    let scenes = if a.scenes.is_empty() { scale::default_scenes() } else { a.scenes.clone() };
    let ctx = a.gpu.context()?;
    let out = results_dir(&ctx, a.out.clone(), "scale");
    let inputs: Vec<&Path> = scenes.iter().map(Path::new).collect();
    let files = ["scale.csv", "scale.json", "scale.md"];
    trilab::io::check_output("--out", trilab::io::Output::Dir(&out, &files), &inputs)?;
    let o = ScaleOptions {
        scenes,
        methods: a.methods.or_device(&ctx),
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
    let report = scale::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    print!("{}", report.markdown());
    for p in report.write(&out)? {
        eprintln!("wrote {}", p.display());
    }
    report.verdict()
}
