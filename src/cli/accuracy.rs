//! `trilab accuracy`.

use super::OutArgs;
use super::ShardArg;
use std::path::PathBuf;

use clap::Args;
use trilab::commands::accuracy::{self, AccuracyOptions, Preset};
use trilab::encoding::Layout;
use trilab::error::Result;

use super::choice::choice;
use super::{results_dir, scene_help, GpuArgs, JsonArg, MethodsArg};

/// Intersection accuracy per method and leaf size: leaks, false hits, errors
///
/// Intersection accuracy per method x leaf size: leaks on closed meshes, false hits,
/// t/barycentric error, self-intersection per offset scheme, extremes, and the speed frontier;
/// accuracy.csv/json/md and plots.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Output directory for accuracy.csv/json/md and plots. Default: results/<device>/accuracy/")))]
#[command(mut_arg("shard", |a| a.help("Run only shard I of N: every N-th (leaf size, layout) group of the leak, false-hit and error sweeps, round-robin (leaf size major); the extremes, self-intersection and frontier run in the shard owning the frontier's group (leaf 4 on bvh2). rows.jsonl names the shard and plans the whole matrix; `trilab merge` joins the shards' folders")))]
pub struct AccuracyArgs {
    /// full: the whole sweep (about 4 minutes on 2-core lavapipe); smoke: seconds, for CI.
    #[arg(long, value_parser = choice::<Preset>(), default_value_t = Preset::Full)]
    preset: Preset,
    /// Methods (default: every method; the smoke preset: the paper's four).
    #[command(flatten)]
    methods: MethodsArg,
    /// Leaf sizes of the leak, false-hit and error tables (default: 1,2,3,4,8,16).
    #[arg(long, value_name = "N,...", value_delimiter = ',')]
    leaf_sizes: Vec<u32>,
    /// BVH node layouts the leaks, false hits and errors are measured on, comma-separated
    /// (`bvh2`, `bvh4`, `bvh8`, ...; each method on each; default: bvh2); accuracy.md then
    /// says whether watertight stays leak-free on every one.
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    /// Leak rays per closed mesh and kind (default: the preset's; was `--rays`).
    #[arg(long, value_name = "N", alias = "rays")]
    leak_rays: Option<usize>,
    #[arg(long, value_name = "S", help = concat!(scene_help!(), ". Also measure leaks on this mesh \
        (repeatable); it must be proven closed (every edge shared by exactly two consistently wound \
        triangles), else the run is refused at once with the reason"))]
    scene: Vec<PathBuf>,
    #[command(flatten)]
    shard: ShardArg,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: AccuracyArgs) -> Result<()> {
    let mut o = AccuracyOptions::preset(a.preset);
    if !a.methods.methods.is_empty() {
        o.methods = a.methods.methods.clone();
    }
    if !a.leaf_sizes.is_empty() {
        o.leaf_sizes = a.leaf_sizes.clone();
    }
    if !a.layouts.is_empty() {
        o.layouts = a.layouts.clone();
    }
    if let Some(n) = a.leak_rays {
        if n == 0 {
            return Err(trilab::error::Error::Usage("--leak-rays 0: the leak probes need at least one ray".into()));
        }
        o.leak_rays = n;
        // Each probe ray and its hit record, held for a mesh and kind at a time.
        let each = trilab::memory::RAY_BYTES + trilab::memory::HIT_BYTES;
        trilab::memory::check(&[trilab::memory::Need::new(format!("--leak-rays {n}"), "rays", Some(n as u64), each)])?;
    }
    // `accuracy::run` loads and proves them closed before any ray is cast (once, not here too).
    o.scenes = a.scene.clone();
    o.shard = a.shard.shard;
    o.check_shard()?;
    let ctx = a.gpu.context()?;
    let out = results_dir(&ctx, a.out.dir.clone(), "accuracy");
    let files = ["accuracy.csv", "frontier.csv", "translation.csv", "accuracy.json", "accuracy.md", trilab::rows::FILE];
    OutArgs::check(&out, &files, &[])?;
    let t = std::time::Instant::now();
    let report = accuracy::run(&ctx, &o, |m| eprintln!("  [{:5.0} s] {m}", t.elapsed().as_secs_f64()))?;
    a.json.print(&report);
    for w in accuracy::write(&report, &out)? {
        eprintln!("  wrote {}", w.display());
    }
    Ok(())
}
