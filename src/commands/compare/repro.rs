//! `compare BASE NEW --repro DIR`: the changed ray-casting cells of a comparison (at most
//! [`MOST`], correctness changes first, then the timings that moved most) each made into a
//! repro (`trilab repro`'s folder, docs/repro.md) on the device in front of it, with this build.
//!
//! A comparison's sides are result folders, not builds or drivers within reach, so the cell is
//! made once, here; the README names which side's device and driver this one is (from the rows'
//! provenance), so a driver team knows whether the folder shows BASE's behaviour or NEW's, and
//! `trilab repro --check` replays it on the other side's driver. The cell's rays are made as its
//! run made them: the run's `bench.json` (beside the rows file holding the cell) records the
//! scenes, the tree's build options and the ray sets' sizes (its `recipe`).
//!
//! ```text
//! DIR/README.md                                    every cell: the change, the side this device is
//! DIR/<scene>-<set>-<method>-<layout>[-...]/       the cell's repro
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::{CompareReport, FigureChange};
use crate::commands::bench::{BenchCell, BenchRecipe, CellTracer};
use crate::commands::repro::{self, CaptureChoice, CellRays, ReproRequest};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::rows::{self, Class, Row};
use crate::services::provenance::Provenance;

/// The most cells made into repros: a bug report holds a few.
pub const MOST: usize = 3;

/// The command whose cells are ray casts a repro can make.
const BENCH: &str = "bench";

/// One changed cell's repro, or why it was not made.
#[derive(Clone, Debug, Serialize)]
pub struct CompareRepro {
    /// `scene=bunny set=primary ...`, as the changes name it.
    pub cell: String,
    pub dir: PathBuf,
    /// The repro's one-line summary, or `not made: <why>`.
    pub made: String,
    /// Which side's device and driver this one is.
    pub this_device: String,
    /// The `bench.json` whose recipe made the rays.
    pub recipe: Option<PathBuf>,
}

/// What `compare --repro` reads from a bench run's `bench.json`.
#[derive(Deserialize)]
struct BenchJson {
    #[serde(default)]
    scenes: Vec<SceneJson>,
    recipe: Option<BenchRecipe>,
}

#[derive(Deserialize)]
struct SceneJson {
    spec: String,
}

/// The changed bench cells of trilab's kernels, each once: any correctness change first, then
/// the largest time factor either way; at most [`MOST`].
fn chosen(changes: &[FigureChange]) -> Vec<&FigureChange> {
    let mut bench: Vec<&FigureChange> = changes.iter().filter(|c| c.command == BENCH).collect();
    let moved = |c: &FigureChange| c.factor.map_or(0.0, |f| f.ln().abs());
    bench.sort_by(|x, y| {
        (y.class == Class::Correctness).cmp(&(x.class == Class::Correctness)).then(moved(y).total_cmp(&moved(x)))
    });
    let mut out: Vec<&FigureChange> = vec![];
    for c in bench {
        if out.len() < MOST && !out.iter().any(|o| o.cell == c.cell) && !c.cell.contains("peer=") {
            out.push(c);
        }
    }
    out
}

/// A side's bench rows of the `wanted` cells (as the changes name them), each with its file:
/// the side's files read once.
fn bench_rows(files: &[PathBuf], wanted: &[&str]) -> Result<BTreeMap<String, (Row, PathBuf)>> {
    let mut out = BTreeMap::new();
    for f in files {
        for r in rows::read_file(f)?.rows.into_iter().filter(|r| r.command == BENCH) {
            let key = rows::cell_key("", &r.cell).trim_start().to_owned();
            if wanted.contains(&key.as_str()) {
                out.insert(key, (r, f.clone()));
            }
        }
    }
    Ok(out)
}

/// Which side's device and driver `here` is.
fn this_device(here: &Provenance, base: Option<&Row>, new: Option<&Row>) -> String {
    let same = |r: Option<&Row>| r.is_some_and(|r| r.source.device == here.device && r.source.driver == here.driver);
    let named =
        |r: Option<&Row>| r.map_or("not recorded".to_owned(), |r| format!("{} ({})", r.source.device, r.source.driver));
    let this = format!("{} ({})", here.device, here.driver);
    match (same(base), same(new)) {
        (true, true) => format!("both sides' device and driver: {this}"),
        (true, false) => format!("BASE's device and driver, {this}; NEW ran on {}", named(new)),
        (false, true) => format!("NEW's device and driver, {this}; BASE ran on {}", named(base)),
        (false, false) => format!("neither side's: this is {this}; BASE ran on {}, NEW on {}", named(base), named(new)),
    }
}

/// `scene=bunny set=primary method=mt` as `bunny-primary-mt-...`: the values, in a fixed order.
fn folder_name(cell: &BenchCell) -> String {
    let c = cell.coordinates();
    let mut parts = vec![cell.scene.clone(), cell.set.to_string()];
    for k in ["method", "layout", "leaf", "sah_group", "traversal", "node_order", "order", "access"] {
        if let Some(v) = c.get(k) {
            parts.push(if k == "leaf" { format!("leaf{v}") } else { v.clone() });
        }
    }
    repro::folder_name(&parts.join("-"))
}

/// Makes the repros of `report`'s changed bench cells under `dir` (a new folder) on the device
/// `context` opens (only when a cell changed).
pub fn make(
    context: impl FnOnce() -> Result<Context>,
    report: &CompareReport,
    dir: &Path,
    mut progress: impl FnMut(&str),
) -> Result<Vec<CompareRepro>> {
    let chosen = chosen(&report.changes);
    if chosen.is_empty() {
        progress("--repro: no bench cell of trilab's kernels changed; no repro made");
        return Ok(vec![]);
    }
    repro::refuse_existing("--repro", dir)?;
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let ctx = &context()?;
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let here = Provenance::of(ctx);
    let mut made = vec![];
    let wanted: Vec<&str> = chosen.iter().map(|c| c.cell.as_str()).collect();
    let mut base_rows = bench_rows(&report.base.files, &wanted)?;
    let mut new_rows = bench_rows(&report.new.files, &wanted)?;
    for change in chosen {
        let base = base_rows.remove(&change.cell);
        let new = new_rows.remove(&change.cell);
        let this_device = this_device(&here, base.as_ref().map(|b| &b.0), new.as_ref().map(|n| &n.0));
        let (row, file) =
            new.or(base).ok_or_else(|| Error::Usage(format!("--repro: `{}` is in no rows file", change.cell)))?;
        progress(&format!("--repro: cell `{}`", change.cell));
        let mut r = CompareRepro {
            cell: change.cell.clone(),
            dir: dir.to_owned(),
            made: String::new(),
            this_device,
            recipe: None,
        };
        r.made = match one(ctx, &row, &file, dir, tmp.path(), &mut r) {
            Ok(summary) => summary,
            Err(e) => format!("not made: {e}"),
        };
        made.push(r);
    }
    let readme = dir.join("README.md");
    crate::io::write_atomic(&readme, readme_text(report, &made).as_bytes())?;
    Ok(made)
}

/// One cell's repro: its recipe read, its rays made, the repro made into `dir/<cell>`.
fn one(ctx: &Context, row: &Row, file: &Path, dir: &Path, tmp: &Path, r: &mut CompareRepro) -> Result<String> {
    let cell =
        BenchCell::parse(&row.cell).map_err(|e| Error::bad_input(file, None, format!("cell `{}`: {e}", r.cell)))?;
    let CellTracer::Method { method, layout, leaf, sah_group, traversal, node_order, order: _, access } = cell.tracer
    else {
        return Err(Error::Usage("a peer's cell has no kernel of ours to make a repro of".into()));
    };
    if node_order != crate::bvh::NodeOrder::default() {
        return Err(Error::Usage(format!(
            "its nodes are in the {node_order} order, and a repro uploads them as built (cells in the built order only)"
        )));
    }
    let rays =
        cell.rays.ok_or_else(|| Error::bad_input(file, None, format!("cell `{}` names no ray count", r.cell)))?;
    let json = file.with_file_name("bench.json");
    let bench: BenchJson = serde_json::from_str(&crate::io::read_text(&json)?)
        .map_err(|e| Error::bad_input(&json, None, format!("not a bench report: {e}")))?;
    let recipe = bench.recipe.ok_or_else(|| {
        Error::bad_input(
            &json,
            None,
            "records no recipe (written before bench recorded its ray sets' sizes): rerun the bench",
        )
    })?;
    r.recipe = Some(json.clone());
    let scene = bench
        .scenes
        .iter()
        .map(|s| PathBuf::from(&s.spec))
        .find(|s| crate::scene::scene_name(s) == cell.scene)
        .ok_or_else(|| Error::bad_input(&json, None, format!("names no scene `{}`", cell.scene)))?;
    let mut build = recipe.build;
    build.max_leaf_size = leaf;
    build.sah_group = sah_group.unwrap_or(1);
    let ray_file = tmp.join(format!("{}.rays", folder_name(&cell)));
    let cell_rays = CellRays {
        scene: &scene,
        set: cell.set,
        build: &build,
        sizes: &recipe.sizes,
        rays_dir: recipe.rays_dir.as_deref(),
        rays,
    };
    cell_rays.write(&r.cell, &ray_file)?;
    r.dir = dir.join(folder_name(&cell));
    let req = ReproRequest {
        scene,
        rays: ray_file,
        first: None,
        method: method.into(),
        layout,
        traversal,
        access: access.requested(),
        build,
        any_hit: false,
        capture: CaptureChoice::Auto,
        out: r.dir.clone(),
    };
    Ok(repro::make(ctx, &req, |l| eprintln!("trilab: {l}"))?.summary())
}

fn readme_text(report: &CompareReport, made: &[CompareRepro]) -> String {
    let mut s = "# Changed cells of `trilab compare`, each as a repro\n\n".to_owned();
    s += &format!("- BASE: {} ({})\n", report.base.path.display(), report.base.sources.join("; "));
    s += &format!("- NEW: {} ({})\n\n", report.new.path.display(), report.new.sources.join("; "));
    s += "Each cell was made here, with this build, on this device: its folder is `trilab repro`'s (its README \
          says how to replay it without trilab). To see it on the other side's driver: \
          `VK_DRIVER_FILES=<that ICD> trilab repro --check <folder>` (`same`, or the rays that differ).\n\n";
    for r in made {
        s += &format!("## `{}`\n\n", r.cell);
        for c in report.changes.iter().filter(|c| c.cell == r.cell && c.command == BENCH) {
            s += &format!("- {}: {} -> {} ({})\n", c.figure, super::shown(&c.base), super::shown(&c.new), c.verdict);
        }
        s += &format!("- this device: {}\n", r.this_device);
        s += &format!("- folder: `{}`\n- {}\n\n", r.dir.display(), r.made);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rows::Figure;
    use crate::services::rayset::RaySet;

    fn change(cell: &str, class: Class, factor: Option<f64>) -> FigureChange {
        let f = Figure::count(1.0, "x");
        FigureChange {
            command: BENCH.into(),
            cell: cell.into(),
            figure: "f".into(),
            class,
            unit: "x".into(),
            base: f.clone(),
            new: f,
            ratio: None,
            factor,
            relative_factor: None,
            verdict: super::super::Verdict::Slower,
            beyond_threshold: true,
            regression: true,
        }
    }

    /// Correctness first, then the factor that moved most either way; each cell once, no peer,
    /// no other command, at most three.
    #[test]
    fn the_most_changed_kernel_cells_are_chosen_once_each() {
        let mut other = change("kernel=raycast", Class::Count, Some(9.0));
        other.command = "spirv".into();
        let changes = [
            change("a", Class::Timing, Some(1.2)),
            change("b", Class::Timing, Some(0.5)),
            change("a", Class::Timing, Some(1.3)),
            change("c", Class::Correctness, None),
            change("peer=embree3 scene=bunny", Class::Timing, Some(5.0)),
            other,
            change("d", Class::Timing, Some(1.1)),
        ];
        let cells: Vec<&str> = chosen(&changes).iter().map(|c| c.cell.as_str()).collect();
        assert_eq!(cells, ["c", "b", "a"]);
    }

    #[test]
    fn folder_names_hold_the_cells_coordinates_in_order() {
        let c = crate::rows::cell([
            ("scene", "synth:soup:2000"),
            ("set", "random"),
            ("method", "quad-unit"),
            ("layout", "bvh4"),
            ("leaf", "4"),
            ("rays", "2000"),
            ("traversal", "while-while"),
        ]);
        let cell = BenchCell::parse(&c).unwrap();
        assert_eq!(cell.set, RaySet::Random);
        assert_eq!(folder_name(&cell), "synth-soup-2000-random-quad-unit-bvh4-leaf4-while-while");
    }
}
