//! `trilab rays primary|diffuse|random`.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use trilab::commands::make_rays::{self, RaysKind};
use trilab::error::Result;

use super::camera::CameraArg;
use super::JsonArg;

/// Make a ray file (primary, diffuse or random rays) and its JSON sidecar
///
/// Make a ray file and its sidecar `<out>.json` (scene hash, generator, settings; docs/formats.md).
#[derive(Args)]
pub struct RaysArgs {
    #[command(subcommand)]
    kind: RaysCmd,
}

#[derive(Subcommand)]
enum RaysCmd {
    /// One ray per pixel through pixel centres, from `render`'s camera
    ///
    /// One ray per pixel through pixel centres, from the camera `render` uses (`--camera`).
    Primary {
        #[command(flatten)]
        common: RaysCommon,
        #[command(flatten)]
        camera: CameraArg,
        /// Image width in pixels.
        #[arg(long, value_name = "W", default_value_t = trilab::defaults::WIDTH)]
        width: u32,
        /// Image height in pixels.
        #[arg(long, value_name = "H", default_value_t = trilab::defaults::HEIGHT)]
        height: u32,
    },
    /// Cosine-distributed bounces off the primary hits (hits from the f64 reference).
    Diffuse {
        #[command(flatten)]
        common: RaysCommon,
        #[command(flatten)]
        camera: CameraArg,
        /// Width in pixels of the primary image whose hits bounce.
        #[arg(long, value_name = "W", default_value_t = trilab::defaults::WIDTH)]
        width: u32,
        /// Height in pixels of the primary image whose hits bounce.
        #[arg(long, value_name = "H", default_value_t = trilab::defaults::HEIGHT)]
        height: u32,
        /// Rays per primary hit (was `--per-hit`).
        #[arg(long, value_name = "N", default_value_t = trilab::defaults::DIFFUSE_PER_HIT, alias = "per-hit")]
        diffuse_per_hit: u32,
        /// Random seed.
        #[arg(long, value_name = "N", default_value_t = trilab::defaults::SEED)]
        seed: u64,
    },
    /// Rays from a sphere around the scene towards random points in its box.
    Random {
        #[command(flatten)]
        common: RaysCommon,
        /// How many rays (was `--count`).
        #[arg(long, value_name = "N", default_value_t = trilab::defaults::RANDOM_RAYS, alias = "count")]
        random_rays: usize,
        /// Random seed.
        #[arg(long, value_name = "N", default_value_t = trilab::defaults::SEED)]
        seed: u64,
    },
}

#[derive(Args)]
struct RaysCommon {
    #[arg(long, value_name = "S", help = super::scene_help!())]
    scene: PathBuf,
    /// Ray file to write (32-byte rays: origin, tmin, direction, tmax; docs/formats.md).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: RaysArgs) -> Result<()> {
    let (common, kind) = match a.kind {
        RaysCmd::Primary { common, camera, width, height } => {
            (common, RaysKind::Primary { camera: camera.camera, width, height })
        }
        RaysCmd::Diffuse { common, camera, width, height, diffuse_per_hit, seed } => {
            (common, RaysKind::Diffuse { camera: camera.camera, width, height, per_hit: diffuse_per_hit, seed })
        }
        RaysCmd::Random { common, random_rays, seed } => (common, RaysKind::Random { count: random_rays, seed }),
    };
    let report = make_rays::run(&common.scene, &common.out, kind)?;
    report.warnings.iter().for_each(|w| super::note(w));
    common.json.print(&report);
    Ok(())
}
