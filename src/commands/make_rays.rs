//! `trilab rays`: a ray file (docs/formats.md) for a scene: primary, diffuse or random rays,
//! and its sidecar `<file>.json` (the scene's hash, the generator and its settings).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_json::json;

use crate::bvh::BuildOptions;
use crate::error::{Error, Result};
use crate::memory::{Need, HIT_BYTES, RAY_BYTES};
use crate::pipeline::HostScene;
use crate::rays::{self, CameraSpec, RaySidecar};
use crate::report::Report;
use crate::scene::load_obj;
use crate::services::rayset::RaySet;

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

impl RaysKind {
    /// What making the rays takes at least: each ray; a diffuse set also each primary ray and
    /// its hit, and its own rays twice (gathered per hit, then into one list) with every primary
    /// ray hitting.
    fn needs(&self) -> Vec<Need> {
        let pixels = |w: u32, h: u32| u64::from(w) * u64::from(h);
        match *self {
            RaysKind::Primary { width, height, .. } => {
                vec![Need::new(
                    format!("--width {width} --height {height}"),
                    "rays",
                    Some(pixels(width, height)),
                    RAY_BYTES,
                )]
            }
            RaysKind::Diffuse { width, height, per_hit, .. } => vec![
                Need::new(
                    format!("--width {width} --height {height}"),
                    "primary rays",
                    Some(pixels(width, height)),
                    RAY_BYTES + HIT_BYTES,
                ),
                Need::new(
                    format!("--width {width} --height {height} --diffuse-per-hit {per_hit}"),
                    "diffuse rays at most",
                    pixels(width, height).checked_mul(u64::from(per_hit)),
                    2 * RAY_BYTES,
                ),
            ],
            RaysKind::Random { count, .. } => {
                vec![Need::new(format!("--random-rays {count}"), "rays", Some(count as u64), RAY_BYTES)]
            }
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct RaysReport {
    pub rays: usize,
    pub out: PathBuf,
    /// The sidecar written beside `out`.
    pub sidecar: PathBuf,
    /// What loading the scene warned about.
    pub warnings: Vec<String>,
}

impl Report for RaysReport {
    fn to_text(&self) -> String {
        format!("wrote {} rays to {} (sidecar {})\n", self.rays, self.out.display(), self.sidecar.display())
    }
}

impl RaysKind {
    /// The generator's name, settings and seed, for the sidecar.
    fn describe(&self) -> (&'static str, BTreeMap<String, serde_json::Value>, Option<u64>) {
        let map = |kv: &[(&str, serde_json::Value)]| kv.iter().map(|(k, v)| (k.to_string(), v.clone())).collect();
        match self {
            RaysKind::Primary { camera, width, height } => (
                "primary",
                map(&[("camera", json!(camera.to_string())), ("width", json!(width)), ("height", json!(height))]),
                None,
            ),
            RaysKind::Diffuse { camera, width, height, per_hit, seed } => (
                "diffuse",
                map(&[
                    ("camera", json!(camera.to_string())),
                    ("width", json!(width)),
                    ("height", json!(height)),
                    ("per_hit", json!(per_hit)),
                ]),
                Some(*seed),
            ),
            RaysKind::Random { count, seed } => ("random", map(&[("count", json!(count))]), Some(*seed)),
        }
    }
}

/// Makes the rays for the scene at `scene` and writes them to `out` (never over the scene or
/// an MTL it reads).
pub fn run(scene: &Path, out: &Path, kind: RaysKind) -> Result<RaysReport> {
    crate::memory::check(&kind.needs())?;
    let mesh = load_obj(scene)?;
    let sidecar_path = rays::sidecar::sidecar_path(out);
    for o in [out, sidecar_path.as_path()] {
        crate::io::ensure_not_inputs(o, &mesh.source, &mesh.mtl_files, &[])?;
    }
    if let (RaysKind::Random { .. }, Some(why)) = (kind, rays::random_rays_problem(&mesh.bounds())) {
        return Err(Error::bad_input(&mesh.source, None, format!("{} triangles: {why}", mesh.triangle_count())));
    }
    let rays = match kind {
        RaysKind::Primary { camera, width, height } => {
            rays::primary_rays(&camera.camera(&mesh.bounds())?, width, height)
        }
        RaysKind::Diffuse { camera, width, height, per_hit, seed } => {
            let primary = rays::primary_rays(&camera.camera(&mesh.bounds())?, width, height);
            let host = HostScene::build(
                crate::scene::scene_name(scene),
                &mesh,
                &BuildOptions::new(crate::defaults::LEAF_SIZE),
            )?;
            RaySet::diffuse_from(&mesh, &host.reference(), &primary, per_hit, seed)
        }
        RaysKind::Random { count, seed } => rays::random_rays(&mesh.bounds(), count, seed),
    };
    let (generator, settings, seed) = kind.describe();
    if rays.is_empty() {
        // A ray file holds at least one ray (`read_rays` refuses an empty one).
        let why = match kind {
            RaysKind::Random { .. } => "--random-rays 0",
            RaysKind::Diffuse { per_hit: 0, .. } => "--diffuse-per-hit 0",
            RaysKind::Diffuse { width, height, .. } if width > 0 && height > 0 => "no primary ray hit the scene",
            _ => "--width or --height 0",
        };
        return Err(Error::Usage(format!("{}: no rays to write ({why})", out.display())));
    }
    // A set that cannot be represented is refused here, naming the scene's bounds.
    let rays = rays::check_rays(generator, &mesh.bounds(), rays)?;
    rays::write_rays(out, &rays)?;
    let name = crate::scene::scene_name(scene);
    let sidecar = RaySidecar {
        format: rays::sidecar::SIDECAR_FORMAT.into(),
        count: rays.len(),
        scene: name,
        scene_source: mesh.source.display().to_string(),
        scene_triangles: mesh.triangle_count(),
        scene_sha256: rays::sidecar::scene_hash(&mesh),
        generator: generator.into(),
        settings,
        seed,
        trilab_version: env!("CARGO_PKG_VERSION").into(),
        trilab_commit: crate::services::provenance::commit(),
    };
    rays::sidecar::write_sidecar(out, &sidecar)?;
    Ok(RaysReport { rays: rays.len(), out: out.to_owned(), sidecar: sidecar_path, warnings: mesh.warnings.clone() })
}
