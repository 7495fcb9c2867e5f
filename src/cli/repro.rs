//! `trilab repro`.

use std::path::PathBuf;

use clap::Args;
use trilab::commands::repro::{self, CaptureChoice, ReproRequest};
use trilab::conditioning::MethodChoice;
use trilab::encoding::{Layout, SceneAccess, Traversal};
use trilab::error::{Error, Result};

use super::choice::{choice, method_choice, method_help, traversal_choice};
use super::{note, scene_help, BuildArgs, GpuArgs, JsonArg, OutArgs};

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
    #[arg(long, value_name = "M", default_value = trilab::defaults::METHOD, value_parser = method_choice(), hide_possible_values = true,
          help = method_help("Intersection method:"))]
    method: MethodChoice,
    #[command(flatten)]
    bvh: BuildArgs,
    /// Occlusion query: any hit in [tmin, tmax] instead of the closest.
    #[arg(long)]
    any_hit: bool,
    /// How the kernel reads the scene: `texel` or `storage` (the address path's device addresses
    /// do not replay on another device); `auto` as raycast plans it, refused if it picks addresses.
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::DEFAULT)]
    scene_access: SceneAccess,
    /// BVH node layout (`trilab methods` lists them).
    #[arg(long, value_parser = choice::<Layout>(), default_value_t = Layout::DEFAULT)]
    layout: Layout,
    /// How the kernel walks the tree.
    #[arg(long, value_parser = traversal_choice(), default_value_t = Traversal::DEFAULT)]
    traversal: Traversal,
    /// `auto`: capture with GFXReconstruct where scripts/gfxreconstruct.sh (or TRILAB_GFXRECON) put
    /// it, else say why not; `required`: fail without it; `off`: no capture.
    #[arg(long, value_name = "WHEN", default_value = "auto", value_parser = ["auto", "required", "off"])]
    capture: String,
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
        method: a.method,
        layout: a.layout,
        traversal: a.traversal,
        access: a.scene_access,
        build: a.bvh.options(),
        any_hit: a.any_hit,
        capture: match a.capture.as_str() {
            "required" => CaptureChoice::Required,
            "off" => CaptureChoice::Off,
            _ => CaptureChoice::Auto,
        },
        out: a.out.dir.ok_or_else(|| missing("--out"))?,
    };
    let report = repro::make(&a.gpu.context()?, &req, note)?;
    a.json.print(&report);
    Ok(())
}
