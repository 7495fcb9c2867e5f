//! `trilab rays primary|diffuse|random`.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use trilab::error::Result;
use trilab::harness::make_rays::{self, RaysKind};

use super::camera::CameraArg;
use super::JsonArg;

/// Make a ray file (../shared/formats.md).
#[derive(Args)]
pub struct RaysArgs {
    #[command(subcommand)]
    kind: RaysCmd,
}

#[derive(Subcommand)]
enum RaysCmd {
    /// One ray per pixel through pixel centres, from the camera `render` uses (`--camera`).
    Primary {
        #[command(flatten)]
        common: RaysCommon,
        #[command(flatten)]
        camera: CameraArg,
        #[arg(long, default_value_t = 800)]
        width: u32,
        #[arg(long, default_value_t = 600)]
        height: u32,
    },
    /// Cosine-distributed bounces off the primary hits (hits from the f64 reference).
    Diffuse {
        #[command(flatten)]
        common: RaysCommon,
        #[command(flatten)]
        camera: CameraArg,
        #[arg(long, default_value_t = 800)]
        width: u32,
        #[arg(long, default_value_t = 600)]
        height: u32,
        /// Rays per primary hit.
        #[arg(long, default_value_t = 8)]
        per_hit: u32,
        #[arg(long, default_value_t = 7)]
        seed: u64,
    },
    /// Rays from a sphere around the scene towards random points in its box.
    Random {
        #[command(flatten)]
        common: RaysCommon,
        #[arg(long, default_value_t = 1_000_000)]
        count: usize,
        #[arg(long, default_value_t = 7)]
        seed: u64,
    },
}

#[derive(Args)]
struct RaysCommon {
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: RaysArgs) -> Result<()> {
    let (common, kind) = match a.kind {
        RaysCmd::Primary { common, camera, width, height } => {
            (common, RaysKind::Primary { camera: camera.camera, width, height })
        }
        RaysCmd::Diffuse { common, camera, width, height, per_hit, seed } => {
            (common, RaysKind::Diffuse { camera: camera.camera, width, height, per_hit, seed })
        }
        RaysCmd::Random { common, count, seed } => (common, RaysKind::Random { count, seed }),
    };
    common.json.print(&make_rays::run(&common.scene, &common.out, kind)?);
    Ok(())
}
