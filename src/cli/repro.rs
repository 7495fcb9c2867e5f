//! `trilab repro`.

use std::path::PathBuf;

use clap::Args;
use trilab::commands::repro::{self, CaptureChoice, ReproRequest};
use trilab::error::{Error, Result};

use super::choice::choice;
use super::raycast::KernelArgs;
use super::{note, scene_help, GpuArgs, JsonArg, OutArgs};

/// One cell for a driver team: capture, SPIR-V, buffers, rays, hits; or check one
///
/// A folder holding a GFXReconstruct capture of the cell's dispatch alone (the device made with
/// only what the kernel needs, so it replays on any device that can run it), the SPIR-V and its
/// disassembly, the scene's buffers, the rays, the expected hits (checked against the f64
/// reference) and a README; or, with `--check DIR`, such a folder's dispatch replayed on this
/// device and its hits compared with the expected ones ray by ray.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("New folder for the repro (refused when it exists: nothing is overwritten)").required_unless_present("check")))]
pub struct ReproArgs {
    /// Replay the repro in this folder on this device (`--device`, `VK_DRIVER_FILES`) and compare
    /// its hits with the expected ones ray by ray: `same`, or how many rays differ and how (exit 1).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["scene", "rays", "out"])]
    check: Option<PathBuf>,
    /// With `--check`: also replay the folder's capture with GFXReconstruct's `gfxrecon-replay` on
    /// the same device (from scripts/gfxreconstruct.sh, or TRILAB_GFXRECON), which must end cleanly.
    #[arg(long, requires = "check")]
    gfxrecon: bool,
    #[arg(long, value_name = "S", required_unless_present = "check", help = scene_help!())]
    scene: Option<PathBuf>,
    /// Ray file to cast (32-byte rays, docs/formats.md; `trilab rays` makes one).
    #[arg(long, value_name = "FILE", required_unless_present = "check")]
    rays: Option<PathBuf>,
    /// Only the first N rays of the file (a repro small enough to attach to a bug report).
    #[arg(long, value_name = "N")]
    first: Option<usize>,
    /// The kernel and tree, as `raycast` takes them; the access path must be `texel` or
    /// `storage` (the address path's device addresses do not replay on another device), or
    /// `auto` where it picks one of them.
    #[command(flatten)]
    kernel: KernelArgs,
    /// Capture the dispatch with GFXReconstruct:
    #[arg(long, value_parser = choice::<CaptureChoice>(), default_value_t = CaptureChoice::DEFAULT)]
    capture: CaptureChoice,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: ReproArgs) -> Result<()> {
    if let Some(dir) = &a.check {
        let r = repro::Repro::read(dir)?;
        let ctx = repro::replay::context(r.kernel, a.gpu.device.clone(), a.gpu.validation_choice())?;
        GpuArgs::watch(&ctx);
        let report = repro::check(&ctx, &r, a.gfxrecon)?;
        a.json.print(&report);
        return report.verdict();
    }
    let missing = |what: &str| Error::Usage(format!("{what} is required (or --check DIR)"));
    let req = ReproRequest {
        scene: a.scene.ok_or_else(|| missing("--scene"))?,
        rays: a.rays.ok_or_else(|| missing("--rays"))?,
        first: a.first,
        method: a.kernel.method,
        layout: a.kernel.layout,
        traversal: a.kernel.traversal,
        access: a.kernel.scene_access,
        build: a.kernel.bvh.options(),
        any_hit: a.kernel.any_hit,
        capture: a.capture,
        out: a.out.dir.ok_or_else(|| missing("--out"))?,
    };
    let report = repro::make(&a.gpu.context()?, &req, note)?;
    a.json.print(&report);
    Ok(())
}
