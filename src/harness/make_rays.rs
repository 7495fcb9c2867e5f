//! `trilab rays`: a ray file (../shared/formats.md) for a scene: primary, diffuse or random rays.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bvh::BuildOptions;
use crate::error::Result;
use crate::harness::rayset::RaySet;
use crate::pipeline::HostScene;
use crate::rays::{self, CameraSpec};
use crate::report::Report;
use crate::scene::load_obj;

/// Which rays, and how many.
#[derive(Clone, Copy, Debug)]
pub enum RaysKind {
    /// One ray per pixel of a `width` x `height` image from `camera` (as `render` places it).
    Primary { camera: CameraSpec, width: u32, height: u32 },
    /// `per_hit` cosine-distributed bounces off the f64 reference's hits of those primary rays.
    Diffuse { camera: CameraSpec, width: u32, height: u32, per_hit: u32, seed: u64 },
    /// `count` rays from a sphere around the scene towards random points in its box.
    Random { count: usize, seed: u64 },
}

#[derive(Clone, Debug, Serialize)]
pub struct RaysReport {
    pub rays: usize,
    pub out: PathBuf,
}

impl Report for RaysReport {
    fn to_text(&self) -> String {
        format!("wrote {} rays to {}\n", self.rays, self.out.display())
    }
}

/// Makes the rays for the scene at `scene` and writes them to `out` (never over the scene or
/// an MTL it reads).
pub fn run(scene: &Path, out: &Path, kind: RaysKind) -> Result<RaysReport> {
    let mesh = load_obj(scene)?;
    crate::io::ensure_not_inputs(out, scene, &mesh.mtl_files, &[])?;
    let rays = match kind {
        RaysKind::Primary { camera, width, height } => {
            rays::primary_rays(&camera.camera(&mesh.bounds())?, width, height)
        }
        RaysKind::Diffuse { camera, width, height, per_hit, seed } => {
            let primary = rays::primary_rays(&camera.camera(&mesh.bounds())?, width, height);
            let host = HostScene::build(crate::scene::scene_name(scene), &mesh, &BuildOptions::new(4))?;
            RaySet::diffuse_from(&mesh, &host.reference(), &primary, per_hit, seed)
        }
        RaysKind::Random { count, seed } => rays::random_rays(&mesh.bounds(), count, seed),
    };
    rays::write_rays(out, &rays)?;
    Ok(RaysReport { rays: rays.len(), out: out.to_owned() })
}
