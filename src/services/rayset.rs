//! The three ray sets every harness times: primary rays from a camera framing the scene,
//! diffuse bounces off their hits, and random rays through the scene's box. They follow the
//! distributions of the Embree peer in ../shared/peers (same camera, same offsets), so trilab's
//! numbers can be set beside the peer's; all are deterministic for a seed.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::memory::{self, Need};
use crate::named::{named_enum, Named};
use crate::rays::{self, Camera, Hit, Ray};
use crate::reference::Reference;
use crate::scene::Mesh;

named_enum! {
    /// A ray set.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum RaySet: "ray set" {
        /// One ray per pixel from a camera framing the scene.
        Primary = "primary",
        /// Cosine-distributed bounces off the primary rays' hits (the f64 reference's).
        Diffuse = "diffuse",
        /// From a sphere around the scene towards random points in its box.
        Random = "random",
    }
}

/// How large the sets are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RaySetSizes {
    /// Primary rays: a `width` x `height` image.
    pub width: u32,
    pub height: u32,
    /// Diffuse rays per primary hit.
    pub diffuse_per_hit: u32,
    pub random_rays: usize,
    pub seed: u64,
}

/// `trilab bench`'s sets: an 800 x 600 camera, 8 bounces per hit, a million random rays, seed 7.
impl Default for RaySetSizes {
    fn default() -> Self {
        use crate::defaults::{DIFFUSE_PER_HIT, HEIGHT, RANDOM_RAYS, SEED, WIDTH};
        RaySetSizes {
            width: WIDTH,
            height: HEIGHT,
            diffuse_per_hit: DIFFUSE_PER_HIT,
            random_rays: RANDOM_RAYS,
            seed: SEED,
        }
    }
}

impl RaySetSizes {
    /// Which size makes `set` empty, as the option that sets it (`--width 0`); otherwise the
    /// diffuse set is empty because no primary ray hit the scene.
    pub fn why_empty(&self, set: RaySet) -> String {
        let mut why = vec![];
        if matches!(set, RaySet::Primary | RaySet::Diffuse) {
            if self.width == 0 {
                why.push("--width 0");
            }
            if self.height == 0 {
                why.push("--height 0");
            }
        }
        if set == RaySet::Diffuse && self.diffuse_per_hit == 0 {
            why.push("--diffuse-per-hit 0");
        }
        if set == RaySet::Random && self.random_rays == 0 {
            why.push("--random-rays 0");
        }
        if why.is_empty() {
            "no primary ray hit the scene".into()
        } else {
            why.join(", ")
        }
    }

    /// What the three sets take at least: each ray and its hit record, with the diffuse set at
    /// its largest (every primary ray hits, `--diffuse-per-hit` bounces each).
    pub fn needs(&self) -> Vec<Need> {
        let pixels = u64::from(self.width) * u64::from(self.height);
        let each = memory::RAY_BYTES + memory::HIT_BYTES;
        vec![
            Need::new(format!("--width {} --height {}", self.width, self.height), "primary rays", Some(pixels), each),
            Need::new(
                format!("--width {} --height {} --diffuse-per-hit {}", self.width, self.height, self.diffuse_per_hit),
                "diffuse rays at most",
                pixels.checked_mul(u64::from(self.diffuse_per_hit)),
                each,
            ),
            Need::new(
                format!("--random-rays {}", self.random_rays),
                "random rays",
                Some(self.random_rays as u64),
                each,
            ),
        ]
    }

    /// Refuses sizes whose rays cannot fit in the memory available ([`memory::check`]), before
    /// the scene is read.
    pub fn check_memory(&self) -> Result<()> {
        memory::check(&self.needs())
    }

    /// Refuses sizes that leave any set empty, naming the option (for harnesses that need all
    /// three sets, such as the profile).
    pub fn require_all(&self) -> Result<()> {
        for set in RaySet::ALL {
            let why = self.why_empty(*set);
            if why.starts_with("--") {
                return Err(Error::Usage(format!("{why}: the {set} ray set would be empty; every set is timed here")));
            }
        }
        Ok(())
    }
}

/// The primary rays' hits, from the f64 reference, rounded to hit records.
fn reference_hits(reference: &Reference, rays: &[Ray]) -> Vec<Hit> {
    reference.trace_all(rays, false).iter().map(|h| h.to_hit()).collect()
}

impl RaySet {
    /// This set for `mesh` (diffuse bounces off the hits `reference` finds), checked as `trilab
    /// rays` checks what it writes ([`rays::check_rays`]): a set that cannot be represented in
    /// f32, or random rays on a scene whose box is one point, is refused by name before any
    /// ray is cast.
    pub fn generate(self, mesh: &Mesh, reference: &Reference, sizes: &RaySetSizes) -> Result<Vec<Ray>> {
        let primary = || rays::primary_rays(&Camera::framing(&mesh.bounds()), sizes.width, sizes.height);
        let made = match self {
            RaySet::Primary => primary(),
            RaySet::Diffuse => {
                let primary = primary();
                let hits = reference_hits(reference, &primary);
                rays::diffuse_rays(mesh, &primary, &hits, sizes.diffuse_per_hit, sizes.seed)
            }
            RaySet::Random => rays::random_rays(&mesh.bounds(), sizes.random_rays, sizes.seed),
        };
        rays::check_rays(&self.to_string(), &mesh.bounds(), made)
    }

    /// `per_hit` diffuse bounces off the hits of `primary` (any camera).
    pub fn diffuse_from(mesh: &Mesh, reference: &Reference, primary: &[Ray], per_hit: u32, seed: u64) -> Vec<Ray> {
        rays::diffuse_rays(mesh, primary, &reference_hits(reference, primary), per_hit, seed)
    }
}

/// The three sets for `mesh`, in order: generated, or read as `<scene>.<set>.rays` from
/// `rays_dir` (the peer's held-out sets, for example).
pub fn ray_sets(
    mesh: &Mesh,
    scene: &str,
    reference: &Reference,
    sizes: &RaySetSizes,
    rays_dir: Option<&Path>,
) -> Result<Vec<(RaySet, Vec<Ray>)>> {
    RaySet::ALL.iter().map(|&set| Ok((set, set.rays(mesh, scene, reference, sizes, rays_dir)?))).collect()
}

impl RaySet {
    /// This set for `mesh` as [`ray_sets`] makes it: generated, or read from `rays_dir`.
    pub fn rays(
        self,
        mesh: &Mesh,
        scene: &str,
        reference: &Reference,
        sizes: &RaySetSizes,
        rays_dir: Option<&Path>,
    ) -> Result<Vec<Ray>> {
        match rays_dir {
            Some(dir) => rays::read_rays(&dir.join(format!("{scene}.{self}.rays"))),
            None => self.generate(mesh, reference, sizes),
        }
    }
}
