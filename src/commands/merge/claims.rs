//! The paper's claims per device: each device's study rows as a [`claims::Grid`] of render
//! times, judged by the same code as `trilab study`'s report.

use std::path::PathBuf;

use serde::Serialize;

use super::push;
use crate::commands::study::claims::{self, Claim, Grid, GridCell};
use crate::commands::study::StudyCell;
use crate::error::Result;
use crate::report::Summary;
use crate::rows::{Cell, Plan, Row};

/// The paper's claims judged on one device's study rows.
#[derive(Clone, Debug, Serialize)]
pub struct DeviceClaims {
    pub device: String,
    /// Study cells measured and planned for this device.
    pub measured: usize,
    pub planned: usize,
    /// Timed rounds behind the render times (the fewest of any cell).
    pub repeat: usize,
    pub claims: Vec<Claim>,
}

/// The render-time grid of one device's study rows (None without any): the axes in the order of
/// its plans' cells (the study's order), then of its rows; the fewest timed rounds of any cell.
pub fn grid(label: &str, rows: &[(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> Result<Option<Grid>> {
    let mine: Vec<(&Row, &PathBuf)> = rows
        .iter()
        .filter(|(r, _)| r.command == "study" && r.source.device_label() == label && r.figures.contains_key("render_s"))
        .map(|(r, f)| (r, f))
        .collect();
    if mine.is_empty() {
        return Ok(None);
    }
    let mut g = Grid { repeat: usize::MAX, ..Grid::default() };
    let planned = plans
        .iter()
        .filter(|(p, _)| p.command == "study" && p.source.device_label() == label)
        .flat_map(|(p, f)| p.cells.iter().map(move |c| (c, f)));
    for (c, f) in planned.chain(mine.iter().map(|(r, f)| (&r.cell, *f))) {
        let c = StudyCell::parse(c, f)?;
        push(&mut g.scenes, c.scene);
        push(&mut g.leaf_sizes, c.leaf);
        push(&mut g.methods, c.method);
        push(&mut g.layouts, c.layout);
    }
    for (r, f) in mine {
        let t = &r.figures["render_s"];
        g.repeat = g.repeat.min(t.runs);
        g.times.push(GridCell {
            cell: StudyCell::parse(&r.cell, f)?,
            seconds: Summary { median: t.median, min: t.min, max: t.max, runs: t.runs },
        });
    }
    Ok(Some(g))
}

/// The claims judged on the study rows of `label` (None without any).
pub(super) fn device_claims(
    label: &str,
    rows: &[(Row, PathBuf)],
    plans: &[(Plan, PathBuf)],
) -> Result<Option<DeviceClaims>> {
    let Some(g) = grid(label, rows, plans)? else { return Ok(None) };
    let mut planned: Vec<&Cell> = plans
        .iter()
        .filter(|(p, _)| p.command == "study" && p.source.device_label() == label)
        .flat_map(|(p, _)| &p.cells)
        .collect();
    planned.sort();
    planned.dedup();
    Ok(Some(DeviceClaims {
        device: label.to_owned(),
        measured: g.times.len(),
        planned: planned.len(),
        repeat: g.repeat,
        claims: claims::all_in(&g),
    }))
}
