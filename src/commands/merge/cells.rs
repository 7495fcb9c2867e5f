//! The merge's tables per command, cell by cell: the headline timing (or, without one, the
//! headline count) per device, each device's worst correctness figures, and the planned cells
//! a device did not measure.

use std::path::PathBuf;

use serde::Serialize;

use super::cell_label;
use crate::rows::{self, Cell, Class, Figure, Plan, Row};

/// One cell's headline timing on every device.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedRow {
    pub command: String,
    pub cell: Cell,
    pub figure: String,
    /// One entry per device, in [`super::MergeReport::devices`]' order.
    pub per_device: Vec<Option<Figure>>,
}

/// One cell's headline count (a compiler's subgroups per SIMD, VGPRs, instructions) per device,
/// and which devices are best by the figure's own direction (more subgroups per SIMD, fewer
/// VGPRs): where the devices are two builds of one driver, which build compiled it better.
#[derive(Clone, Debug, Serialize)]
pub struct CountRow {
    pub command: String,
    pub cell: Cell,
    pub figure: String,
    /// One entry per device, in [`super::MergeReport::devices`]' order.
    pub per_device: Vec<Option<Figure>>,
    /// The devices (their labels) with the best value; empty where all that have it are equal.
    pub best: Vec<String>,
}

/// The worst value of one correctness figure over one device's rows of one command.
#[derive(Clone, Debug, Serialize)]
pub struct Worst {
    pub device: String,
    pub command: String,
    pub figure: String,
    pub value: f64,
    pub unit: String,
    /// The cell it came from.
    pub cell: String,
    pub cells: usize,
}

/// A planned cell that no runner of `device` measured.
#[derive(Clone, Debug, Serialize)]
pub struct Missing {
    pub device: String,
    pub command: String,
    pub cell: Cell,
    /// Whether one of this device's own plans has the cell (a shard that failed or was not
    /// run), rather than only another device's plan (a matrix this device did not take).
    pub planned_by_device: bool,
}

/// The headline timing of a command's rows: `render_s` (the study's, the paper's metric), else
/// `mrays_per_s` (bench's rays per second, accuracy's frontier timing), `kernel_ms`, `build_s`
/// (build-bench's build time), else the first timing figure by name.
pub fn headline<'a>(rows: impl IntoIterator<Item = &'a Row> + Clone) -> Option<String> {
    for name in ["render_s", "mrays_per_s", "kernel_ms", "build_s"] {
        if rows.clone().into_iter().any(|r| r.figures.contains_key(name)) {
            return Some(name.into());
        }
    }
    rows.into_iter()
        .flat_map(|r| r.figures.iter().filter(|(_, f)| f.class == Class::Timing).map(|(n, _)| n.clone()))
        .min()
}

/// The count a command's rows are compared by across devices, where they carry no timing:
/// `subgroups_per_simd` (a compiler's occupancy), else `vgprs`, `instructions`,
/// `spirv_instructions`.
pub fn headline_count<'a>(rows: impl IntoIterator<Item = &'a Row> + Clone) -> Option<String> {
    ["subgroups_per_simd", "vgprs", "instructions", "spirv_instructions"]
        .into_iter()
        .find(|name| rows.clone().into_iter().any(|r| r.figures.get(*name).is_some_and(|f| f.class == Class::Count)))
        .map(String::from)
}

/// A figure's value oriented so that larger is better.
fn toward_better(f: &Figure) -> f64 {
    if f.better == rows::Better::Higher {
        f.median
    } else {
        -f.median
    }
}

/// Every command's tables, commands in order of first appearance.
#[derive(Default)]
pub(super) struct Tables {
    pub speed: Vec<SpeedRow>,
    pub counts: Vec<CountRow>,
    pub correctness: Vec<Worst>,
    pub missing: Vec<Missing>,
}

impl Tables {
    /// The tables of every command of `rows` and `plans`, a column per label of `labels`.
    pub(super) fn of(labels: &[String], rows: &[(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> Tables {
        let mut commands: Vec<String> = vec![];
        for c in rows.iter().map(|(r, _)| &r.command).chain(plans.iter().map(|(p, _)| &p.command)) {
            if !commands.contains(c) {
                commands.push(c.clone());
            }
        }
        let mut t = Tables::default();
        for command in &commands {
            let c = CommandCells::of(command, rows, plans);
            let count = headline(c.mine.iter().copied()).is_none().then(|| headline_count(c.mine.iter().copied()));
            if let Some(figure) = count.flatten() {
                t.counts.extend(c.count_rows(labels, &figure));
            }
            if let Some(figure) = headline(c.mine.iter().copied()) {
                t.speed.extend(c.speed_rows(labels, &figure));
            }
            for label in labels {
                t.correctness.extend(c.worst(label));
                t.missing.extend(c.missing(label, plans));
            }
        }
        t
    }
}

/// One command's rows and cells: those of its plans in plan order, then any measured cell no
/// plan names.
struct CommandCells<'a> {
    command: &'a str,
    mine: Vec<&'a Row>,
    cells: Vec<Cell>,
    /// How many of `cells` are planned (they come first).
    planned: usize,
}

impl<'a> CommandCells<'a> {
    fn of(command: &'a str, rows: &'a [(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> CommandCells<'a> {
        let mine: Vec<&Row> = rows.iter().map(|(r, _)| r).filter(|r| r.command == command).collect();
        let mut cells: Vec<Cell> = vec![];
        for c in plans.iter().filter(|(p, _)| p.command == command).flat_map(|(p, _)| &p.cells) {
            if !cells.contains(c) {
                cells.push(c.clone());
            }
        }
        let planned = cells.len();
        for r in &mine {
            if !cells[..planned].iter().any(|c| rows::plan_matches(c, &r.cell)) && !cells.contains(&r.cell) {
                cells.push(r.cell.clone());
            }
        }
        CommandCells { command, mine, cells, planned }
    }

    /// The row of device `label` that fills `cell`. A row fills a planned cell when it agrees
    /// on every coordinate the plan names (a row may add measured ones, such as bench's `rays`);
    /// an unplanned cell only by equality.
    fn find(&self, label: &str, cell: &Cell) -> Option<&'a Row> {
        self.mine
            .iter()
            .find(|r| {
                let fills = if self.cells[..self.planned].contains(cell) {
                    rows::plan_matches(cell, &r.cell)
                } else {
                    &r.cell == cell
                };
                fills && r.source.device_label() == label
            })
            .copied()
    }

    /// `figure` of `cell` on every device.
    fn per_device(&self, labels: &[String], cell: &Cell, figure: &str) -> Vec<Option<Figure>> {
        labels.iter().map(|l| self.find(l, cell).and_then(|r| r.figures.get(figure).cloned())).collect()
    }

    /// The headline count of each cell two devices or more measured, and the best devices.
    fn count_rows(&self, labels: &[String], figure: &str) -> Vec<CountRow> {
        let mut counts = vec![];
        for cell in &self.cells {
            let per_device = self.per_device(labels, cell, figure);
            let have: Vec<(&String, &Figure)> =
                labels.iter().zip(&per_device).filter_map(|(l, f)| Some((l, f.as_ref()?))).collect();
            if have.len() < 2 {
                continue;
            }
            let top = have.iter().map(|(_, f)| toward_better(f)).fold(f64::NEG_INFINITY, f64::max);
            let best: Vec<String> = if have.iter().all(|(_, f)| toward_better(f) == top) {
                vec![]
            } else {
                have.iter().filter(|(_, f)| toward_better(f) == top).map(|(l, _)| (*l).clone()).collect()
            };
            counts.push(CountRow {
                command: self.command.to_owned(),
                cell: cell.clone(),
                figure: figure.to_owned(),
                per_device,
                best,
            });
        }
        counts
    }

    /// The headline timing of each cell some device measured.
    fn speed_rows(&self, labels: &[String], figure: &str) -> Vec<SpeedRow> {
        let mut speed = vec![];
        for cell in &self.cells {
            let per_device = self.per_device(labels, cell, figure);
            if per_device.iter().any(Option::is_some) {
                speed.push(SpeedRow {
                    command: self.command.to_owned(),
                    cell: cell.clone(),
                    figure: figure.to_owned(),
                    per_device,
                });
            }
        }
        speed
    }

    /// The worst value of each correctness figure over the rows of device `label`, by name.
    fn worst(&self, label: &str) -> Vec<Worst> {
        let dev: Vec<&Row> = self.mine.iter().copied().filter(|r| r.source.device_label() == label).collect();
        let names: Vec<&String> = {
            let mut v: Vec<&String> = dev
                .iter()
                .flat_map(|r| r.figures.iter().filter(|(_, f)| f.class == Class::Correctness).map(|(n, _)| n))
                .collect();
            v.sort();
            v.dedup();
            v
        };
        let mut out = vec![];
        for name in names {
            let with: Vec<(&Row, &Figure)> = dev.iter().filter_map(|r| Some((*r, r.figures.get(name)?))).collect();
            let worst = with
                .iter()
                .copied()
                .min_by(|a, b| toward_better(a.1).total_cmp(&toward_better(b.1)))
                .expect("at least one row has the figure");
            out.push(Worst {
                device: label.to_owned(),
                command: self.command.to_owned(),
                figure: name.clone(),
                value: worst.1.median,
                unit: worst.1.unit.clone(),
                cell: cell_label(&worst.0.cell),
                cells: with.len(),
            });
        }
        out
    }

    /// The planned cells no row of device `label` fills, and whether its own plans name each.
    fn missing(&self, label: &str, plans: &[(Plan, PathBuf)]) -> Vec<Missing> {
        let own: Vec<&Cell> = plans
            .iter()
            .filter(|(p, _)| p.command == self.command && p.source.device_label() == label)
            .flat_map(|(p, _)| &p.cells)
            .collect();
        let mut out = vec![];
        for cell in
            self.cells.iter().filter(|c| plans.iter().any(|(p, _)| p.command == self.command && p.cells.contains(c)))
        {
            if self.find(label, cell).is_none() {
                out.push(Missing {
                    device: label.to_owned(),
                    command: self.command.to_owned(),
                    cell: cell.clone(),
                    planned_by_device: own.contains(&cell),
                });
            }
        }
        out
    }
}
