//! `trilab steps`.

use std::path::PathBuf;

use clap::Args;
use trilab::commands::steps::{self, StepsRequest};
use trilab::error::{Error, Result};

use super::{scene_help, BuildArgs, GpuArgs, JsonArg, MethodsArg};

/// Traversal work per ray and what SIMD lock-step costs at each width
///
/// Traversal work per ray (CPU mirror of the kernels' loop): steps, triangle tests, and the
/// iterations SIMD lock-step costs at each width; `--gpu` adds the kernels' own counts.
#[derive(Args)]
pub struct StepsArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    /// Ray file to trace (32-byte rays, docs/formats.md; `trilab rays` makes one).
    #[arg(long, value_name = "FILE")]
    rays: PathBuf,
    #[command(flatten)]
    bvh: BuildArgs,
    /// SIMD widths to model (lavapipe: 8, or 4 with LP_NATIVE_VECTOR_WIDTH=128).
    #[arg(long, value_name = "N,...", value_delimiter = ',', default_values_t = [1usize, 4, 8, 32])]
    widths: Vec<usize>,
    /// Also run each method's traversal-statistics kernel (`raycast.<method>.stats`) and report
    /// its per-ray nodes visited and triangles tested (mean, max) beside the CPU mirror's.
    #[arg(long)]
    gpu: bool,
    /// Methods for `--gpu` (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu_args: GpuArgs,
}

pub fn run(a: StepsArgs) -> Result<()> {
    if !a.methods.methods.is_empty() && !a.gpu {
        return Err(Error::Usage("--methods: only with --gpu".into()));
    }
    let req = StepsRequest {
        scene: a.scene,
        rays: a.rays,
        build: a.bvh.options(),
        widths: a.widths,
        gpu_methods: a.gpu.then(|| a.methods.methods.clone()),
    };
    let ctx = if a.gpu { Some(a.gpu_args.context()?) } else { None };
    let report = steps::run(ctx.as_ref(), &req)?;
    report.warnings.iter().for_each(|w| super::note(w));
    a.json.print(&report);
    Ok(())
}
