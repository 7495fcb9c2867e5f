//! `trilab analyze`.

use std::path::PathBuf;

use clap::Args;
use trilab::conditioning::Target;
use trilab::error::Result;

use super::{scene_help, GpuArgs, JsonArg};

/// A scene's numerical conditioning and the cheapest method that meets a target
///
/// A scene's numerical conditioning (coordinate magnitude against edge length, smallest edge,
/// slivers, distance from the origin) and the cheapest method, offset scheme and placement that
/// meet an accuracy target on it.
#[derive(Args)]
pub struct AnalyzeArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    /// Target: most leaks per 10^6 rays on closed meshes (rays at shared edges and vertices
    /// included), as `trilab accuracy` measures them.
    #[arg(long, value_name = "N", default_value_t = 0.0)]
    max_leaks_per_million: f64,
    /// Target: largest 99th-percentile t error, in f32 ULPs of t.
    #[arg(long, value_name = "X", default_value_t = 4.0)]
    max_t_ulps: f64,
    /// `frontier.csv` from `trilab accuracy` on your device (default: the committed lavapipe one).
    #[arg(long, value_name = "FILE")]
    frontier: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: AnalyzeArgs) -> Result<()> {
    let target = Target { max_leaks_per_million: a.max_leaks_per_million, max_t_ulps: a.max_t_ulps };
    let report = trilab::commands::analyze::run(&a.scene, target, a.frontier.as_deref(), a.gpu.device.as_deref())?;
    report.warnings.iter().for_each(|w| super::note(w));
    a.json.print(&report);
    Ok(())
}
