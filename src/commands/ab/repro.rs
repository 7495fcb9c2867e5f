//! `ab --repro DIR`: each changed ray-casting cell as a repro of both sides in one step
//! (`trilab repro`'s folder, made by each side's own worker, so with its build and in its driver
//! environment), and what differs between the two sides' hits, for a driver team.
//!
//! ```text
//! DIR/<scene>-<set>-<method>-<layout>[-<traversal>]/README.md   the cell, the two sides, the verdict
//! DIR/<cell>/a/ , DIR/<cell>/b/                                 each side's repro (docs/repro.md)
//! ```

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::worker::{CellKind, Workload};
use super::{AbCell, AbOptions, Side};
use crate::commands::repro::{folder_name, CellRays, Differences, Query};
use crate::error::{Error, Result};
use crate::rays;
use crate::scene::scene_name;
use crate::services::worker::protocol::ReproSpec;
use crate::services::worker::{self, Message, Request};

/// The most cells made into repros (the most changed first): a bug report holds a few.
pub const MOST: usize = 3;

/// One changed cell's pair of repros.
#[derive(Clone, Debug, Serialize)]
pub struct AbRepro {
    pub cell: String,
    pub dir: PathBuf,
    /// Each side's outcome: the repro's summary, or why it could not be made.
    pub sides: [String; 2],
    /// Side B's expected hits against side A's, ray by ray (when both were made).
    pub hits: Option<Differences>,
}

/// The changed ray-casting cells, most changed first (rays whose hits differ, then how far the
/// time ratio moved), at most [`MOST`].
fn chosen(cells: &[AbCell]) -> Vec<&AbCell> {
    let mut changed: Vec<&AbCell> = cells.iter().filter(|c| c.cell.kind == CellKind::Raycast && c.changed()).collect();
    let moved = |c: &AbCell| c.ratio.map_or(0.0, |r| r.ratio.ln().abs());
    changed.sort_by(|x, y| y.rays_differing.cmp(&x.rays_differing).then(moved(y).total_cmp(&moved(x))));
    changed.truncate(MOST);
    changed
}

/// Makes the repros of `cells`' changed cells under `dir`: the cell's rays generated here as
/// both sides generated them, then each side's worker makes its repro of them.
pub fn make(
    o: &AbOptions,
    workload: &Workload,
    cells: &[AbCell],
    dir: &Path,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<AbRepro>> {
    let chosen = chosen(cells);
    if chosen.is_empty() {
        progress("--repro: no ray-casting cell changed; no repro made");
        return Ok(vec![]);
    }
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut made = vec![];
    for c in chosen {
        let info = &c.cell;
        let label = info.label();
        let cell_dir = dir.join(folder_name(&label));
        std::fs::create_dir(&cell_dir).map_err(|e| Error::io(&cell_dir, e))?;
        let scene = workload
            .scenes
            .iter()
            .find(|s| scene_name(s) == info.scene)
            .ok_or_else(|| Error::Usage(format!("--repro: cell `{label}`: its scene is not in the workload")))?;
        let ray_file = tmp.path().join(format!("{}.rays", folder_name(&label)));
        let cell_rays = CellRays {
            scene,
            set: info.set.parse().map_err(Error::Usage)?,
            build: &workload.build,
            sizes: &workload.sizes,
            rays_dir: None,
            rays: info.rays,
        };
        cell_rays.write(&label, &ray_file)?;
        let spec = |out: PathBuf| -> Result<ReproSpec> {
            Ok(ReproSpec {
                scene: scene.clone(),
                rays: ray_file.clone(),
                method: info.method.parse().map_err(Error::Usage)?,
                layout: info.layout.parse().map_err(Error::Usage)?,
                traversal: info.traversal.parse().map_err(Error::Usage)?,
                access: workload.scene_access,
                build: workload.build,
                out,
            })
        };
        let mut sides: [String; 2] = Default::default();
        for (i, (name, side)) in [("A", &o.a), ("B", &o.b)].into_iter().enumerate() {
            progress(&format!("--repro: cell `{label}`, side {name}"));
            let out = cell_dir.join(name.to_lowercase());
            sides[i] = match side_repro(o, side, name, spec(out)?) {
                Ok(summary) => summary,
                Err(e) => format!("not made: {e}"),
            };
        }
        let expected = |s: &str| rays::read_hits(&cell_dir.join(s).join("expected.hits")).ok();
        let hits = match (expected("a"), expected("b")) {
            (Some(a), Some(b)) if a.len() == b.len() => Some(Differences::of(Query::Closest, &a, &b)),
            _ => None,
        };
        let r = AbRepro { cell: label, dir: cell_dir.clone(), sides, hits };
        let readme = cell_dir.join("README.md");
        std::fs::write(&readme, readme_text(o, c, &r)).map_err(|e| Error::io(&readme, e))?;
        made.push(r);
    }
    Ok(made)
}

/// One side's repro, made by that side's worker (its build, its driver environment).
fn side_repro(o: &AbOptions, side: &Side, name: &str, spec: ReproSpec) -> Result<String> {
    let launch = side.launch(&o.exe).validation(o.validation);
    let answer = worker::call(&launch, format!("side {name}'s repro"), &Request::MakeRepro(spec))?;
    match answer.message {
        Message::ReproMade { summary } => Ok(summary),
        Message::Failed { error } => Err(Error::Usage(error)),
        m => Err(worker::unexpected(&format!("side {name}'s repro"), "repro-made", &m)),
    }
}

fn readme_text(o: &AbOptions, c: &AbCell, r: &AbRepro) -> String {
    let mut s = format!("# `{}`: side A against side B\n\n", r.cell);
    s += &format!("- A: {} — {}\n- B: {} — {}\n\n", o.a.describe(), r.sides[0], o.b.describe(), r.sides[1]);
    if let Some(ratio) = c.ratio {
        s += &format!(
            "`trilab ab` measured B/A = {:.3} (95 % interval {:.3}..{:.3}) over the rounds{}.\n\n",
            ratio.ratio,
            ratio.low,
            ratio.high,
            c.verdict.map(|v| format!(", verdict {v}")).unwrap_or_default()
        );
    }
    s += &format!("Rays whose hit records differ between A's and B's first rounds in `ab`: {}.\n", c.rays_differing);
    match &r.hits {
        Some(d) => s += &format!("The two repros' expected hits (B against A): {}\n\n", d.to_text()),
        None => s += "The two repros' hits could not be compared (a side has none).\n\n",
    }
    s += "Each folder is a repro (its README says how to replay it). To see one side's dispatch on the \
          other side's driver: `VK_DRIVER_FILES=<B's ICD> trilab repro --check a` (`same`, or the rays that \
          differ from A's hits).\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn folder_names_keep_letters_digits_and_dashes() {
        assert_eq!(folder_name("bunny primary mt bvh2"), "bunny-primary-mt-bvh2");
        assert_eq!(folder_name("a/b c"), "a-b-c");
    }
}
