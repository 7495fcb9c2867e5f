//! A measured cell's rays made again, for its repro (`ab --repro`, `compare --repro`): the scene
//! loaded and its tree built as the run built them, the set generated (or read from the run's
//! `--rays-dir`) as the run made it, and refused when it does not hold the cell's count of rays.

use std::path::Path;

use crate::bvh::BuildOptions;
use crate::error::{Error, Result};
use crate::pipeline::HostScene;
use crate::rays;
use crate::scene::{load_obj, scene_name};
use crate::services::rayset::{RaySet, RaySetSizes};

/// How a run made a cell's rays.
#[derive(Clone, Copy, Debug)]
pub struct CellRays<'a> {
    pub scene: &'a Path,
    pub set: RaySet,
    pub build: &'a BuildOptions,
    pub sizes: &'a RaySetSizes,
    pub rays_dir: Option<&'a Path>,
    /// Rays in the cell as measured.
    pub rays: usize,
}

impl CellRays<'_> {
    /// Writes the cell's rays to `out`; `label` names the cell in an error.
    pub fn write(&self, label: &str, out: &Path) -> Result<()> {
        let mesh = load_obj(self.scene)?;
        let name = scene_name(self.scene);
        let host = HostScene::build(&name, &mesh, self.build)?;
        let made = self.set.rays(&mesh, &name, &host.reference(), self.sizes, self.rays_dir)?;
        if made.len() != self.rays {
            return Err(Error::Usage(format!(
                "cell `{label}`: {} rays made here, {} in the cell (its run made another set)",
                made.len(),
                self.rays
            )));
        }
        rays::write_rays(out, &made)
    }
}
