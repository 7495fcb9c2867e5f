//! What an `ab` run writes: one `ab` row per matched cell (B/A with its interval, the rays that
//! differ), each side's bench rows with that side's provenance, and the results folder.

use std::path::Path;

use super::report::{AbCell, AbReport, SideCell, SideReport};
use super::worker::CellKind;
use crate::error::Result;
use crate::report::Report;
use crate::rows::{cell, Better, Class, Figure, Row, Source};
use crate::services::results::Folder;
use crate::services::worker::protocol::ProvenanceFields;

/// The setting a side's rows carry (`A` or `B`): two sides' measurements of one cell on one
/// device are two cells to `merge`.
pub const SIDE_SETTING: &str = "ab_side";

/// No plan: the cells are what both sides ran.
impl crate::services::results::Results for AbReport {
    const STEM: &'static str = "ab";

    /// The text report, as a code block.
    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        format!("```\n{}```\n", self.to_text())
    }

    fn rows(&self) -> Option<Vec<Row>> {
        Some(rows(self))
    }
}

/// The result rows of side `pick` (0: A, 1: B): its bench rows (speed per cell, agreement),
/// with that side's provenance as their source, so `compare DIR/a DIR/b` reads the two sides
/// as two runs.
pub fn side_rows(r: &AbReport, pick: usize) -> Vec<Row> {
    let source = source_of(if pick == 0 { &r.a } else { &r.b });
    r.cells
        .iter()
        .map(|c| {
            let sc = if pick == 0 { &c.a } else { &c.b };
            if c.cell.kind == CellKind::Pathtrace {
                return pathtrace_row(c, sc, &source);
            }
            // The cell as `trilab bench` names it, so `compare` matches a side with a bench run.
            let coords = c.cell.coordinates.clone();
            let row = Row::new("bench", coords, &source)
                .with(
                    "agreement",
                    Figure::correctness(sc.agree as f64 / c.cell.rays as f64, "fraction", Better::Higher),
                )
                .with("unexplained", Figure::correctness(sc.unexplained as f64, "rays", Better::Lower))
                .with("invalid", Figure::correctness(sc.invalid as f64, "rays", Better::Lower));
            match crate::report::Summary::of(&sc.ms) {
                Some(ms) => {
                    let mr = crate::services::validate::mrays_summary(c.cell.rays, ms);
                    row.with("mrays_per_s", Figure::timing(mr, "Mrays/s", Better::Higher))
                }
                None => row,
            }
        })
        .collect()
}

/// A path-trace cell's row for one side: `bench-render`'s speed and the invalid samples.
fn pathtrace_row(c: &AbCell, sc: &SideCell, source: &Source) -> Row {
    let row = Row::new("bench-render", c.cell.coordinates.clone(), source)
        .with("invalid", Figure::correctness(sc.invalid as f64, "samples", Better::Lower));
    match crate::report::Summary::of(&sc.ms) {
        // Samples per ms is thousands a second: /1e3 gives millions.
        Some(ms) => {
            let rate = |t: f64| c.cell.rays as f64 / t / 1e3;
            let f = Figure {
                median: rate(ms.median),
                min: rate(ms.max),
                max: rate(ms.min),
                runs: ms.runs,
                unit: "Msamples/s".into(),
                better: Better::Higher,
                class: Class::Timing,
            };
            row.with("msamples_per_s", f)
        }
        None => row,
    }
}

/// One `ab` row per cell: the ratio B/A with its interval, and the rays whose hits differ.
pub fn rows(r: &AbReport) -> Vec<Row> {
    let mut out = vec![];
    let source = source_of(&r.b);
    for c in &r.cells {
        let Some(ratio) = c.ratio else { continue };
        let coords = cell([
            ("scene", c.cell.scene.clone()),
            ("set", c.cell.set.clone()),
            ("method", c.cell.method.clone()),
            ("layout", c.cell.layout.clone()),
        ]);
        let f = Figure {
            median: ratio.ratio,
            min: ratio.low,
            max: ratio.high,
            runs: ratio.rounds_b,
            unit: "B/A".into(),
            better: Better::Lower,
            class: Class::Timing,
        };
        out.push(
            Row::new("ab", coords, &source)
                .with("time_ratio", f)
                .with("rays_differing", Figure::correctness(c.rays_differing as f64, "rays", Better::Lower)),
        );
    }
    out
}

fn source_of(side: &SideReport) -> Source {
    let p = ProvenanceFields::of(&side.provenance);
    let mut settings = p.settings;
    settings.insert(SIDE_SETTING.into(), side.name.into());
    Source {
        device: p.device.unwrap_or_default(),
        driver: p.driver.unwrap_or_default(),
        commit: p.commit.unwrap_or_default(),
        date: p.date.unwrap_or_default(),
        settings,
        host: p.host,
    }
}

/// Writes `ab.json`, `ab.md` (the text report) and `rows.jsonl` (the `ab` rows) into `dir`,
/// and each side's bench rows into `dir/a/rows.jsonl` and `dir/b/rows.jsonl`.
pub fn write(r: &AbReport, dir: &Path) -> Result<()> {
    crate::services::results::write_folder(dir, r)?;
    for (pick, sub) in [(0, "a"), (1, "b")] {
        let mut rows = side_rows(r, pick);
        rows.extend(r.driver_stats_rows[pick].iter().cloned());
        Folder::create(&dir.join(sub))?.rows(None, &rows)?;
    }
    Ok(())
}
