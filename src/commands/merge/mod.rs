//! `trilab merge DIR...`: joins the self-describing rows (`rows.jsonl`, [`crate::rows`]) of many
//! runners, shards and devices into one report, the way deqp-runner merges the result lists of
//! its shards.
//!
//! - **Columns are devices.** Rows are grouped by [`Source::device_label`]: the device's name and
//!   the driver settings that change what is measured (`LP_NATIVE_VECTOR_WIDTH`, the subgroup
//!   size, ...), so two runs of one device at different settings are two columns, and the shards
//!   of one device's matrix fill one column.
//! - **A cell measured twice for one device is refused**, naming the cell and both files: a
//!   shard run twice, overlapping splits or two commits' results in one folder would otherwise
//!   be silently averaged or one of them dropped. Merge the runs you mean, or give them
//!   different settings. (The same file reached twice, through a folder and its sub-folder, is
//!   read once.)
//! - **The paper's claims per device**: each device's study rows become a
//!   [`claims::Grid`] of render times, judged by the same code as `trilab study`'s report.
//! - **Speed per cell**: each command's headline timing ([`headline`]) per cell, one column per
//!   device; the worst correctness figures per device.
//! - **Missing cells**: for each device, the cells of its command's plans (every plan of every
//!   runner names the whole matrix) that no row of that device measured, and the shards of its
//!   plans that never reported.
//!
//! Outputs ([`write`]): `merge.md`, `merge.json` and the plots ([`plots`]), each atomically.

pub mod plots;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::commands::study::claims::{self, Claim, Grid, GridCell};
use crate::commands::study::StudyCell;
use crate::encoding::Layout;
use crate::error::{Error, Result};
use crate::report::{Summary, Table};
use crate::rows::{self, Cell, Class, Figure, Plan, Row, Shard, Source};

/// One column of the merge: every row of one device at one set of settings.
#[derive(Clone, Debug, Serialize)]
pub struct Device {
    /// [`Source::device_label`]: the column's name.
    pub label: String,
    pub device: String,
    /// The settings in its label (those of its first row).
    pub settings: BTreeMap<String, String>,
    /// The drivers, commits and dates its rows name (several when runners differ).
    pub drivers: Vec<String>,
    pub commits: Vec<String>,
    pub dates: Vec<String>,
    pub rows: usize,
    /// The rows files it came from.
    pub files: Vec<PathBuf>,
    /// Per command, the shards its plans name (`1/2`, `2/2`; empty for an unsharded run) and
    /// those of the same count that no file of this device holds.
    pub shards: Vec<Shards>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Shards {
    pub command: String,
    pub seen: Vec<Shard>,
    pub missing: Vec<Shard>,
}

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

/// One cell's headline timing on every device.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedRow {
    pub command: String,
    pub cell: Cell,
    pub figure: String,
    /// One entry per device, in [`MergeReport::devices`]' order.
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
    /// One entry per device, in [`MergeReport::devices`]' order.
    pub per_device: Vec<Option<Figure>>,
    /// The devices (their labels) with the best value; empty where all that have it are equal.
    pub best: Vec<String>,
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

#[derive(Clone, Debug, Serialize)]
pub struct MergeReport {
    /// The folders (or files) given.
    pub inputs: Vec<PathBuf>,
    /// The rows files read, each once.
    pub files: Vec<PathBuf>,
    pub devices: Vec<Device>,
    pub claims: Vec<DeviceClaims>,
    pub speed: Vec<SpeedRow>,
    /// Commands without a timing: their headline count per cell measured by two devices or more.
    pub counts: Vec<CountRow>,
    pub correctness: Vec<Worst>,
    pub missing: Vec<Missing>,
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

/// A row and the file it was read from.
struct Read {
    row: Row,
    file: PathBuf,
}

/// Reads every rows file under `inputs` (each file once) and merges them.
pub fn run(inputs: &[PathBuf]) -> Result<MergeReport> {
    if inputs.is_empty() {
        return Err(Error::Usage("merge: name at least one folder of results".into()));
    }
    let mut files: Vec<PathBuf> = vec![];
    let mut seen: Vec<PathBuf> = vec![];
    for input in inputs {
        for f in rows::read(input)?.files {
            let canon = f.canonicalize().map_err(|e| Error::io(&f, e))?;
            if !seen.contains(&canon) {
                seen.push(canon);
                files.push(f);
            }
        }
    }
    let mut read = vec![];
    let mut plans = vec![];
    for f in &files {
        let set = rows::read_file(f)?;
        read.extend(set.rows.into_iter().map(|row| Read { row, file: f.clone() }));
        plans.extend(set.plans.into_iter().map(|p| (p, f.clone())));
    }
    if read.is_empty() {
        // Nothing was measured: a report of only missing cells (or none) would read as a merge.
        let why = "holds no measured row (it is empty or holds only plans): nothing to merge";
        return Err(match &files[..] {
            [one] => Error::bad_input(one, None, why),
            _ => Error::Usage(format!(
                "none of {} holds a measured row (each is empty or holds only plans): nothing to merge",
                files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", ")
            )),
        });
    }
    merge(inputs.to_vec(), files, read.into_iter().map(|r| (r.row, r.file)).collect(), plans)
}

/// Merges rows and plans already read (each with the file it came from).
pub fn merge(
    inputs: Vec<PathBuf>,
    files: Vec<PathBuf>,
    mut rows: Vec<(Row, PathBuf)>,
    mut plans: Vec<(Plan, PathBuf)>,
) -> Result<MergeReport> {
    // Two drivers of one device are two columns: lavapipe 22.3.6 and 25.0.7 both name their
    // device "llvmpipe (LLVM 15.0.6, 256 bits)". Where one label covers more than one driver,
    // the driver joins the label's settings.
    let mut drivers: BTreeMap<String, std::collections::BTreeSet<String>> = BTreeMap::new();
    for s in rows.iter().map(|(r, _)| &r.source).chain(plans.iter().map(|(p, _)| &p.source)) {
        drivers.entry(s.device_label()).or_default().insert(s.driver.clone());
    }
    let by_driver = |s: &mut rows::Source| {
        if drivers.get(&s.device_label()).is_some_and(|d| d.len() > 1) {
            s.settings.insert("driver".into(), s.driver.clone());
        }
    };
    rows.iter_mut().for_each(|(r, _)| by_driver(&mut r.source));
    plans.iter_mut().for_each(|(p, _)| by_driver(&mut p.source));
    // Devices in order of first appearance.
    let mut labels: Vec<String> = vec![];
    for s in rows.iter().map(|(r, _)| &r.source).chain(plans.iter().map(|(p, _)| &p.source)) {
        let l = s.device_label();
        if !labels.contains(&l) {
            labels.push(l);
        }
    }
    // A cell measured twice for one device is refused.
    let mut by_cell: BTreeMap<(String, String), &PathBuf> = BTreeMap::new();
    for (r, f) in &rows {
        let label = r.source.device_label();
        if let Some(first) = by_cell.insert((label.clone(), r.key()), f) {
            return Err(Error::bad_input(
                f,
                None,
                format!(
                    "`{} {}` was measured twice for device `{label}` (also in {}): merge refuses to choose \
                     between two measurements of one cell; merge one of the runs, or run them with different settings",
                    r.command,
                    cell_label(&r.cell),
                    first.display()
                ),
            ));
        }
    }
    let devices: Vec<Device> = labels.iter().map(|l| device(l, &rows, &plans)).collect();
    let claims = labels.iter().filter_map(|l| device_claims(l, &rows, &plans).transpose()).collect::<Result<_>>()?;

    // Commands in order of first appearance; per command, the cells in plan order, then any
    // measured cell no plan names.
    let mut commands: Vec<String> = vec![];
    for c in rows.iter().map(|(r, _)| &r.command).chain(plans.iter().map(|(p, _)| &p.command)) {
        if !commands.contains(c) {
            commands.push(c.clone());
        }
    }
    let mut speed = vec![];
    let mut counts = vec![];
    let mut correctness = vec![];
    let mut missing = vec![];
    for command in &commands {
        let mine: Vec<&Row> = rows.iter().map(|(r, _)| r).filter(|r| &r.command == command).collect();
        let mut cells: Vec<Cell> = vec![];
        for c in plans.iter().filter(|(p, _)| &p.command == command).flat_map(|(p, _)| &p.cells) {
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
        // A row fills a planned cell when it agrees on every coordinate the plan names (a row
        // may add measured ones, such as bench's `rays`); an unplanned cell only by equality.
        let find = |label: &str, cell: &Cell| {
            mine.iter()
                .find(|r| {
                    let fills = if cells[..planned].contains(cell) {
                        rows::plan_matches(cell, &r.cell)
                    } else {
                        &r.cell == cell
                    };
                    fills && r.source.device_label() == label
                })
                .copied()
        };
        let count = headline(mine.iter().copied()).is_none().then(|| headline_count(mine.iter().copied())).flatten();
        if let Some(figure) = count {
            for cell in &cells {
                let per_device: Vec<Option<Figure>> =
                    labels.iter().map(|l| find(l, cell).and_then(|r| r.figures.get(&figure).cloned())).collect();
                let have: Vec<(&String, &Figure)> =
                    labels.iter().zip(&per_device).filter_map(|(l, f)| Some((l, f.as_ref()?))).collect();
                if have.len() < 2 {
                    continue;
                }
                let key = |f: &Figure| if f.better == rows::Better::Higher { f.median } else { -f.median };
                let top = have.iter().map(|(_, f)| key(f)).fold(f64::NEG_INFINITY, f64::max);
                let best: Vec<String> = if have.iter().all(|(_, f)| key(f) == top) {
                    vec![]
                } else {
                    have.iter().filter(|(_, f)| key(f) == top).map(|(l, _)| (*l).clone()).collect()
                };
                counts.push(CountRow {
                    command: command.clone(),
                    cell: cell.clone(),
                    figure: figure.clone(),
                    per_device,
                    best,
                });
            }
        }
        if let Some(figure) = headline(mine.iter().copied()) {
            for cell in &cells {
                let per_device: Vec<Option<Figure>> =
                    labels.iter().map(|l| find(l, cell).and_then(|r| r.figures.get(&figure).cloned())).collect();
                if per_device.iter().any(Option::is_some) {
                    speed.push(SpeedRow {
                        command: command.clone(),
                        cell: cell.clone(),
                        figure: figure.clone(),
                        per_device,
                    });
                }
            }
        }
        for label in &labels {
            let dev: Vec<&Row> = mine.iter().copied().filter(|r| &r.source.device_label() == label).collect();
            let names: Vec<&String> = {
                let mut v: Vec<&String> = dev
                    .iter()
                    .flat_map(|r| r.figures.iter().filter(|(_, f)| f.class == Class::Correctness).map(|(n, _)| n))
                    .collect();
                v.sort();
                v.dedup();
                v
            };
            for name in names {
                let with: Vec<(&Row, &Figure)> = dev.iter().filter_map(|r| Some((*r, r.figures.get(name)?))).collect();
                let worst = with
                    .iter()
                    .copied()
                    .min_by(|a, b| {
                        let key = |f: &Figure| if f.better == rows::Better::Higher { f.median } else { -f.median };
                        key(a.1).total_cmp(&key(b.1))
                    })
                    .expect("at least one row has the figure");
                correctness.push(Worst {
                    device: label.clone(),
                    command: command.clone(),
                    figure: name.clone(),
                    value: worst.1.median,
                    unit: worst.1.unit.clone(),
                    cell: cell_label(&worst.0.cell),
                    cells: with.len(),
                });
            }
            let own: Vec<&Cell> = plans
                .iter()
                .filter(|(p, _)| &p.command == command && &p.source.device_label() == label)
                .flat_map(|(p, _)| &p.cells)
                .collect();
            for cell in cells.iter().filter(|c| plans.iter().any(|(p, _)| &p.command == command && p.cells.contains(c)))
            {
                if find(label, cell).is_none() {
                    missing.push(Missing {
                        device: label.clone(),
                        command: command.clone(),
                        cell: cell.clone(),
                        planned_by_device: own.contains(&cell),
                    });
                }
            }
        }
    }
    Ok(MergeReport { inputs, files, devices, claims, speed, counts, correctness, missing })
}

fn device(label: &str, rows: &[(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> Device {
    let sources: Vec<&Source> = rows
        .iter()
        .map(|(r, _)| &r.source)
        .chain(plans.iter().map(|(p, _)| &p.source))
        .filter(|s| s.device_label() == label)
        .collect();
    let distinct = |f: fn(&Source) -> &String| {
        let mut v: Vec<String> = sources.iter().map(|s| f(s).clone()).collect();
        v.sort();
        v.dedup();
        v
    };
    let mut files: Vec<PathBuf> = rows
        .iter()
        .filter(|(r, _)| r.source.device_label() == label)
        .map(|(_, f)| f.clone())
        .chain(plans.iter().filter(|(p, _)| p.source.device_label() == label).map(|(_, f)| f.clone()))
        .collect();
    files.sort();
    files.dedup();
    let mut shards: Vec<Shards> = vec![];
    for (p, _) in plans.iter().filter(|(p, _)| p.source.device_label() == label) {
        let Some(s) = p.shard else { continue };
        match shards.iter_mut().find(|x| x.command == p.command) {
            Some(x) => {
                if !x.seen.contains(&s) {
                    x.seen.push(s)
                }
            }
            None => shards.push(Shards { command: p.command.clone(), seen: vec![s], missing: vec![] }),
        }
    }
    for x in &mut shards {
        x.seen.sort_by_key(|s| (s.count, s.index));
        let mut counts: Vec<u32> = x.seen.iter().map(|s| s.count).collect();
        counts.dedup();
        for count in counts {
            for index in 1..=count {
                let s = Shard { index, count };
                if !x.seen.contains(&s) {
                    x.missing.push(s);
                }
            }
        }
    }
    Device {
        label: label.to_owned(),
        device: sources.first().map(|s| s.device.clone()).unwrap_or_default(),
        settings: sources.first().map(|s| s.settings.clone()).unwrap_or_default(),
        drivers: distinct(|s| &s.driver),
        commits: distinct(|s| &s.commit),
        dates: distinct(|s| &s.date),
        rows: rows.iter().filter(|(r, _)| r.source.device_label() == label).count(),
        files,
        shards,
    }
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

fn push<T: PartialEq>(v: &mut Vec<T>, x: T) {
    if !v.contains(&x) {
        v.push(x);
    }
}

fn device_claims(label: &str, rows: &[(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> Result<Option<DeviceClaims>> {
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

impl MergeReport {
    fn device_headers(&self, first: &str) -> Vec<String> {
        std::iter::once(first.to_owned()).chain(self.devices.iter().map(|d| d.label.clone())).collect()
    }

    /// One row per (claim, layout), one verdict column per device.
    pub fn claims_table(&self) -> Table {
        let mut t = Table::new(self.device_headers("claim"));
        let mut keys: Vec<(char, Layout)> = vec![];
        for c in self.claims.iter().flat_map(|d| &d.claims) {
            push(&mut keys, (c.id, c.layout));
        }
        let layouts = keys.iter().any(|k| k.1 != Layout::DEFAULT);
        for (id, layout) in keys {
            let mut row = vec![if layouts { format!("({id}) on {layout}") } else { format!("({id})") }];
            for d in &self.devices {
                let c = self
                    .claims
                    .iter()
                    .find(|x| x.device == d.label)
                    .and_then(|x| x.claims.iter().find(|c| c.id == id && c.layout == layout));
                row.push(c.map_or_else(|| "-".into(), |c| c.verdict.label().to_owned()));
            }
            t.row(row);
        }
        t
    }

    /// One speed table per command: the headline figure per cell, a column per device.
    pub fn speed_tables(&self) -> Vec<(String, String, Table)> {
        let mut out: Vec<(String, String, Table)> = vec![];
        for r in &self.speed {
            if !out.iter().any(|(c, _, _)| c == &r.command) {
                out.push((r.command.clone(), r.figure.clone(), Table::new(self.device_headers("cell"))));
            }
            let t = &mut out.iter_mut().find(|(c, _, _)| c == &r.command).expect("just pushed").2;
            let mut row = vec![cell_label(&r.cell)];
            row.extend(r.per_device.iter().map(|f| {
                f.as_ref().map_or_else(
                    || "missing".to_owned(),
                    |f| {
                        if f.min == f.max {
                            format!("{} {}", sig(f.median), f.unit)
                        } else {
                            format!("{} ({}-{}) {}", sig(f.median), sig(f.min), sig(f.max), f.unit)
                        }
                    },
                )
            }));
            t.row(row);
        }
        out
    }

    pub fn markdown(&self, plots: &[crate::services::plots::Plot]) -> String {
        let mut s = String::from("# trilab merge\n\n");
        let _ = writeln!(
            s,
            "{} rows file(s) from {}; one column per device and driver setting (its name and the settings that \
             change a measurement); a cell measured twice for one device is refused.\n",
            self.files.len(),
            self.inputs.iter().map(|p| format!("`{}`", p.display())).collect::<Vec<_>>().join(", ")
        );
        s += "## Devices\n\n";
        let mut t = Table::new(["column", "plot series", "device", "driver", "commit", "date", "rows", "shards"]);
        let series = series_names(&self.devices);
        for (d, series) in self.devices.iter().zip(series) {
            let shards = d
                .shards
                .iter()
                .map(|x| {
                    let seen = x.seen.iter().map(Shard::to_string).collect::<Vec<_>>().join(", ");
                    let missing = x.missing.iter().map(Shard::to_string).collect::<Vec<_>>().join(", ");
                    if missing.is_empty() {
                        format!("{}: {seen}", x.command)
                    } else {
                        format!("{}: {seen} (missing {missing})", x.command)
                    }
                })
                .collect::<Vec<_>>()
                .join("; ");
            t.row([
                d.label.clone(),
                series,
                d.device.clone(),
                d.drivers.join(", "),
                d.commits.join(", "),
                d.dates.join(", "),
                d.rows.to_string(),
                if shards.is_empty() { "-".into() } else { shards },
            ]);
        }
        s += &t.to_markdown();
        s.push('\n');

        if !self.claims.is_empty() {
            s += "## The paper's claims per device\n\n";
            s += "Judged from each device's study render times by the rule of `trilab study`: a difference is real only \
                  when the min-max ranges over the timed rounds do not overlap.\n\n";
            s += &self.claims_table().to_markdown();
            s.push('\n');
            for d in &self.claims {
                let _ = writeln!(s, "### {}\n", d.device);
                let partial = if d.measured < d.planned {
                    format!(", **partial: {} of {} planned cells measured**", d.measured, d.planned)
                } else {
                    String::new()
                };
                let _ = writeln!(s, "{} study cells, {} timed round(s){partial}.\n", d.measured, d.repeat);
                for c in &d.claims {
                    let on = if c.layout == Layout::DEFAULT { String::new() } else { format!(" on {}", c.layout) };
                    let _ = writeln!(s, "- **({}){on} {}: {}.** {}.", c.id, c.statement, c.verdict.label(), c.summary);
                }
                s.push('\n');
            }
        }

        for (command, figure, t) in self.speed_tables() {
            let _ = writeln!(s, "## Speed per cell: `{command}`, `{figure}`\n");
            let _ = writeln!(s, "Median (min-max over the timed rounds) per device.\n");
            s += &t.to_markdown();
            s.push('\n');
        }

        let mut commands: Vec<(&str, &str)> = vec![];
        for c in &self.counts {
            push(&mut commands, (c.command.as_str(), c.figure.as_str()));
        }
        for (command, figure) in commands {
            let of: Vec<&CountRow> = self.counts.iter().filter(|c| c.command == command).collect();
            let better = of.iter().flat_map(|c| c.per_device.iter().flatten()).next().map(|f| f.better);
            let way = if better == Some(rows::Better::Higher) { "higher" } else { "lower" };
            let _ = writeln!(s, "## Counts per cell: `{command}`, `{figure}`\n");
            // Columns by their plot series' short names (D1, D2, ...: the Devices table names them).
            let series = series_names(&self.devices);
            let short = |label: &str| {
                self.devices
                    .iter()
                    .position(|d| d.label == label)
                    .map_or(label.to_owned(), |i| series[i].split(':').next().unwrap_or(&series[i]).to_owned())
            };
            let mut wins: BTreeMap<String, usize> = BTreeMap::new();
            for c in &of {
                for b in &c.best {
                    *wins.entry(short(b)).or_default() += 1;
                }
            }
            let equal = of.iter().filter(|c| c.best.is_empty()).count();
            let _ = writeln!(
                s,
                "The cells two devices or more measured (columns D1, D2, ... as the Devices table names them); {way} is \
                 better. Best: {}; equal in {equal} of {} cells.\n",
                if wins.is_empty() {
                    "none".to_owned()
                } else {
                    wins.iter().map(|(d, n)| format!("{d} in {n}")).collect::<Vec<_>>().join(", ")
                },
                of.len()
            );
            let headers = std::iter::once("cell".to_owned())
                .chain(self.devices.iter().map(|d| short(&d.label)))
                .chain(["best".to_owned()]);
            let mut t = Table::new(headers);
            for c in &of {
                let mut row = vec![cell_label(&c.cell)];
                row.extend(c.per_device.iter().map(|f| f.as_ref().map_or("-".into(), |f| sig(f.median))));
                row.push(if c.best.is_empty() {
                    "equal".into()
                } else {
                    c.best.iter().map(|b| short(b)).collect::<Vec<_>>().join(", ")
                });
                t.row(row);
            }
            s += &t.to_markdown();
            s.push('\n');
        }

        if !self.correctness.is_empty() {
            s += "## Correctness: the worst cell per device\n\n";
            let mut t = Table::new(["device", "command", "figure", "worst", "cell", "cells"]);
            for w in &self.correctness {
                t.row([
                    w.device.clone(),
                    w.command.clone(),
                    w.figure.clone(),
                    format!("{} {}", w.value, w.unit),
                    w.cell.clone(),
                    w.cells.to_string(),
                ]);
            }
            s += &t.to_markdown();
            s.push('\n');
        }

        s += "## Missing cells\n\n";
        if self.missing.is_empty() {
            s += "None: every cell of every plan was measured on every device.\n\n";
        } else {
            let _ = writeln!(
                s,
                "{} cell(s) planned but measured by no runner of the device (`own plan`: the device's own plan has \
                 it, so a shard failed or was not run; `other plan`: only another device planned it).\n",
                self.missing.len()
            );
            let mut t = Table::new(["device", "cell", "planned by"]);
            for m in &self.missing {
                t.row([
                    m.device.clone(),
                    format!("{} {}", m.command, cell_label(&m.cell)),
                    if m.planned_by_device { "own plan".into() } else { "other plan".to_string() },
                ]);
            }
            s += &t.to_markdown();
            s.push('\n');
        }
        if !plots.is_empty() {
            s += "## Plots\n\n";
            for p in plots {
                let name = p.path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
                let _ = writeln!(s, "### {}\n\n![{}]({name})\n", p.title, p.title);
            }
        }
        s
    }
}

/// A cell's coordinates in reading order: `scene`, `set`, `leaf`, `method`, `layout`, `kernel`,
/// `traversal`, then any other key by name (`scene=bunny leaf=4 method=mt layout=bvh2`).
pub fn cell_label(cell: &Cell) -> String {
    const ORDER: [&str; 7] = ["scene", "set", "leaf", "method", "layout", "kernel", "traversal"];
    let rank = |k: &str| ORDER.iter().position(|o| *o == k).unwrap_or(ORDER.len());
    let mut keys: Vec<&String> = cell.keys().collect();
    keys.sort_by_key(|k| (rank(k), k.as_str()));
    keys.iter().map(|k| format!("{k}={}", cell[*k])).collect::<Vec<_>>().join(" ")
}

/// Short names for the plots' legend, one per device: `D1`, `D2`, ... and what tells the device
/// apart from the others: the settings whose values differ (`LP_NATIVE_VECTOR_WIDTH` as
/// `WIDTH`; `unset` where a device ran without it, its driver's default) and, where those do not tell every device apart, the words of its name that differ
/// from the others' (its whole name when there is one device), cut to fit the legend.
pub fn series_names(devices: &[Device]) -> Vec<String> {
    let mut keys: Vec<&String> = devices.iter().flat_map(|d| d.settings.keys()).collect();
    keys.sort();
    keys.dedup();
    keys.retain(|k| {
        k.as_str() != "LP_NUM_THREADS" && devices.iter().any(|d| d.settings.get(*k) != devices[0].settings.get(*k))
    });
    // The fewest differing settings (in name order) that tell the devices apart, else all.
    let with = |n: usize| -> Vec<String> {
        devices
            .iter()
            .map(|d| {
                keys.iter()
                    .take(n)
                    .map(|k| {
                        let upper = k.chars().any(|c| c.is_ascii_uppercase());
                        let short = if upper { k.rsplit('_').next().unwrap_or(k) } else { k };
                        format!("{short}={}", d.settings.get(*k).map_or("unset", String::as_str))
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .collect()
    };
    let distinct = |v: &[String]| {
        let mut d = v.to_vec();
        d.sort();
        d.dedup();
        d.len() == devices.len()
    };
    let n = (1..=keys.len()).find(|&n| distinct(&with(n))).unwrap_or(keys.len());
    let settings = with(n);
    let by_settings = !keys.is_empty() && distinct(&settings);
    // The words of each name between the words every name starts and ends with.
    let words: Vec<Vec<&str>> = devices.iter().map(|d| d.device.split_whitespace().collect()).collect();
    let shortest = words.iter().map(Vec::len).min().unwrap_or(0);
    let prefix = (0..shortest).take_while(|&i| words.iter().all(|w| w[i] == words[0][i])).count();
    let suffix = (0..shortest - prefix)
        .take_while(|&i| words.iter().all(|w| w[w.len() - 1 - i] == words[0][words[0].len() - 1 - i]))
        .count();
    devices
        .iter()
        .enumerate()
        .map(|(i, d)| {
            let mut parts = vec![];
            if !by_settings {
                let own = words[i][prefix..words[i].len() - suffix].join(" ");
                parts.push(if own.is_empty() || devices.len() == 1 { d.device.clone() } else { own });
            }
            if !settings[i].is_empty() {
                parts.push(settings[i].clone());
            }
            let text = parts.join(", ");
            let cut: String = text.chars().take(20).collect();
            let cut = if cut.len() < text.len() { format!("{cut}…") } else { cut };
            format!("D{}: {cut}", i + 1)
        })
        .collect()
}

/// Four significant digits.
fn sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.digits$}")
}

impl crate::report::Report for MergeReport {
    fn to_text(&self) -> String {
        self.markdown(&[])
    }
}

/// The files [`write`] writes besides the plots.
pub const FILES: [&str; 2] = ["merge.md", "merge.json"];

/// Writes the plots, `merge.md` and `merge.json` into `dir` (created if needed), each
/// atomically. Returns the paths written.
pub fn write(report: &MergeReport, dir: &Path) -> Result<Vec<PathBuf>> {
    crate::services::results::write_folder(dir, report)
}

/// No rows: merge reads rows and writes none.
impl crate::services::results::Results for MergeReport {
    const STEM: &'static str = "merge";

    const JSON_NEWLINE: bool = true;

    fn markdown(&self, plots: &[crate::services::plots::Plot]) -> String {
        MergeReport::markdown(self, plots)
    }

    fn rows(&self) -> Option<Vec<Row>> {
        None
    }

    fn plots(&self, dir: &Path) -> Result<Vec<crate::services::plots::Plot>> {
        plots::all(self, dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::study::testing::synthetic;
    use crate::commands::study::{self, StudyReport};
    use crate::encoding::Method;

    /// The paper's shape (leaf 4 fastest, MT 3 % faster than unit, Quad unit 12 % faster than
    /// MT) on "gpu-a", the contrary (leaf 16 fastest, unit faster, Quad unit slower) on "gpu-b".
    fn report(device: &str, paper: bool) -> StudyReport {
        let t = move |_: &str, leaf: u32, m: Method, _: Layout| {
            let f = |mt: f64, unit: f64, quad_unit: f64| match m {
                Method::Mt => mt,
                Method::Unit => unit,
                Method::QuadUnit => quad_unit,
                _ => 1.0,
            };
            if paper {
                (1.0 + 0.05 * (leaf as f64 - 4.0).abs()) * f(1.0, 1.03, 1.0 / 1.12)
            } else {
                (20.0 - leaf as f64) * f(1.0, 0.9, 1.1)
            }
        };
        let mut r = synthetic(&["bunny", "dragon"], &[Layout::Bvh2], t, 0.001);
        r.provenance.device = device.into();
        r
    }

    /// The plan of a synthetic report (its options name no scene files): its rows' cells.
    fn plan(r: &StudyReport, shard: Option<Shard>) -> Plan {
        Plan { shard, cells: study::rows(r).into_iter().map(|row| row.cell).collect(), ..study::plan(r) }
    }

    fn file(name: &str) -> PathBuf {
        PathBuf::from(format!("runs/{name}/rows.jsonl"))
    }

    fn merged(parts: &[(&str, &StudyReport, Option<Shard>)]) -> Result<MergeReport> {
        let mut rows = vec![];
        let mut plans = vec![];
        for (name, r, shard) in parts {
            rows.extend(study::rows(r).into_iter().map(|row| (row, file(name))));
            plans.push((plan(r, *shard), file(name)));
        }
        merge(vec![], parts.iter().map(|p| file(p.0)).collect(), rows, plans)
    }

    #[test]
    fn claims_per_device_are_the_claims_of_a_study_report_of_the_same_numbers() {
        let (a, b) = (report("gpu-a", true), report("gpu-b", false));
        let m = merged(&[("a", &a, None), ("b", &b, None)]).unwrap();
        assert_eq!(m.devices.iter().map(|d| d.label.as_str()).collect::<Vec<_>>(), ["gpu-a", "gpu-b"]);
        assert_eq!(m.claims.len(), 2);
        for (d, r) in m.claims.iter().zip([&a, &b]) {
            let want = claims::all(r);
            assert_eq!(serde_json::to_value(&d.claims).unwrap(), serde_json::to_value(&want).unwrap(), "{}", d.device);
            assert_eq!((d.measured, d.planned, d.repeat), (r.rows.len(), r.rows.len(), 3));
        }
        // The paper's numbers hold on gpu-a, the contrary ones fail on gpu-b: one column each.
        let table = m.claims_table().to_markdown();
        assert!(table.contains("| (a) | holds | does not hold |"), "{table}");
        assert!(table.contains("| (c) | holds | does not hold |"), "{table}");
        assert!(m.missing.is_empty(), "{:?}", m.missing);
        // The speed table has every cell once with a figure for both devices.
        assert_eq!(m.speed.len(), a.rows.len());
        assert!(m.speed.iter().all(|r| r.figure == "render_s" && r.per_device.iter().all(Option::is_some)));
    }

    #[test]
    fn a_cell_no_runner_of_a_device_measured_is_listed_and_its_claims_say_partial() {
        let a = report("gpu-a", true);
        let mut b = report("gpu-b", true);
        // gpu-b lost the cell (dragon, leaf 4, quad-unit).
        let lost = b.rows.iter().position(|r| r.scene == "dragon" && r.leaf_size == 4 && r.method == Method::QuadUnit);
        let lost = b.rows.remove(lost.unwrap());
        let mut m = merged(&[("a", &a, None), ("b", &b, None)]).unwrap();
        // gpu-b's own plan is taken from its rows here, so it lacks the cell: the cell is in
        // gpu-a's plan only.
        assert_eq!(m.missing.len(), 1, "{:?}", m.missing);
        let miss = &m.missing[0];
        assert_eq!((miss.device.as_str(), miss.planned_by_device), ("gpu-b", false));
        let dragon = [("layout", "bvh2"), ("leaf", "4"), ("method", "quad-unit"), ("scene", "dragon")];
        assert_eq!(miss.cell, rows::cell(dragon));
        // With gpu-b's full plan (its run planned the cell), the cell is missing from its own plan.
        let full = plan(&a, Some(Shard { index: 1, count: 2 }));
        let full = Plan { source: b.provenance.source(), ..full };
        let mut rows: Vec<(Row, PathBuf)> = study::rows(&a).into_iter().map(|r| (r, file("a"))).collect();
        rows.extend(study::rows(&b).into_iter().map(|r| (r, file("b"))));
        m = merge(vec![], vec![], rows, vec![(plan(&a, None), file("a")), (full, file("b"))]).unwrap();
        assert_eq!(m.missing.len(), 1);
        assert!(m.missing[0].planned_by_device);
        let md = m.markdown(&[]);
        assert!(md.contains("| gpu-b | study scene=dragon leaf=4 method=quad-unit layout=bvh2 | own plan |"), "{md}");
        assert!(md.contains("partial: 47 of 48 planned cells measured"), "{md}");
        // Its plan names shard 1/2; shard 2/2 never reported.
        let b_dev = m.devices.iter().find(|d| d.label == "gpu-b").unwrap();
        assert_eq!(b_dev.shards[0].missing, vec![Shard { index: 2, count: 2 }]);
        assert!(md.contains("study: 1/2 (missing 2/2)"), "{md}");
        assert!(m.speed.iter().any(|r| r.cell == lost_cell(&lost) && r.per_device[1].is_none()));
        assert!(md.contains("| missing |"), "{md}");
    }

    fn lost_cell(r: &study::StudyRow) -> Cell {
        r.cell().coordinates()
    }

    #[test]
    fn a_cell_measured_twice_for_one_device_is_refused_naming_both_files() {
        let a = report("gpu-a", true);
        let e = merged(&[("a1", &a, None), ("a2", &a, None)]).unwrap_err().to_string();
        assert!(e.contains("measured twice") && e.contains("gpu-a"), "{e}");
        assert!(e.contains("runs/a1/rows.jsonl") && e.contains("runs/a2/rows.jsonl"), "{e}");
        assert!(e.contains("study scene=bunny leaf=1 method=mt"), "{e}");
        // The same numbers from another device are another column, not a duplicate.
        assert!(merged(&[("a", &a, None), ("b", &report("gpu-b", true), None)]).is_ok());
    }

    /// Two drivers that name their device alike (Debian's lavapipe 22.3.6 and 25.0.7 are both
    /// "llvmpipe (LLVM 15.0.6, 256 bits)") are two columns, told apart by the driver; one
    /// driver's runs stay one column.
    #[test]
    fn two_drivers_of_one_device_are_two_columns() {
        let mut new = report("llvmpipe", true);
        new.provenance.driver = "llvmpipe Mesa 25.0.7".into();
        let mut old = report("llvmpipe", false);
        old.provenance.driver = "llvmpipe Mesa 22.3.6".into();
        let m = merged(&[("new", &new, None), ("old", &old, None)]).unwrap();
        let labels: Vec<&str> = m.devices.iter().map(|d| d.label.as_str()).collect();
        assert_eq!(labels, ["llvmpipe, driver=llvmpipe Mesa 25.0.7", "llvmpipe, driver=llvmpipe Mesa 22.3.6"]);
        assert_eq!(m.claims_table().to_markdown().lines().next().map(|l| l.matches("driver=").count()), Some(2));
        // One driver twice is still a cell measured twice.
        let e = merged(&[("a", &new, None), ("b", &new, None)]).unwrap_err().to_string();
        assert!(e.contains("measured twice") && !e.contains("driver="), "{e}");
    }

    #[test]
    fn one_device_at_two_driver_settings_is_two_columns() {
        let mut w8 = report("llvmpipe", true);
        w8.provenance.settings.insert("LP_NATIVE_VECTOR_WIDTH".into(), "256".into());
        // LP_NUM_THREADS changes speed but not the device a row belongs to.
        w8.provenance.settings.insert("LP_NUM_THREADS".into(), "2".into());
        let mut w4 = report("llvmpipe", false);
        w4.provenance.settings.insert("LP_NATIVE_VECTOR_WIDTH".into(), "128".into());
        let m = merged(&[("w8", &w8, None), ("w4", &w4, None)]).unwrap();
        let labels: Vec<&str> = m.devices.iter().map(|d| d.label.as_str()).collect();
        assert_eq!(labels, ["llvmpipe, LP_NATIVE_VECTOR_WIDTH=256", "llvmpipe, LP_NATIVE_VECTOR_WIDTH=128"]);
        assert_eq!(series_names(&m.devices), ["D1: WIDTH=256", "D2: WIDTH=128"]);
        // The width alone tells them apart; the subgroup size that follows it is left out.
        let mut both = m.devices.clone();
        for (d, sg) in both.iter_mut().zip(["8", "4"]) {
            d.settings.insert("subgroup_size".into(), sg.into());
        }
        assert_eq!(series_names(&both), ["D1: WIDTH=256", "D2: WIDTH=128"]);
        both[1].settings.insert("LP_NATIVE_VECTOR_WIDTH".into(), "256".into());
        // Equal widths: the subgroup size is what differs.
        assert_eq!(series_names(&both), ["D1: subgroup_size=8", "D2: subgroup_size=4"]);
        // Devices told apart by name only: the words that differ.
        let mut gpus = m.devices.clone();
        gpus[0].device = "NVIDIA GeForce RTX 4090".into();
        gpus[1].device = "NVIDIA GeForce RTX 3060".into();
        for d in &mut gpus {
            d.settings.clear();
        }
        assert_eq!(series_names(&gpus), ["D1: 4090", "D2: 3060"]);
        assert_eq!(series_names(&gpus[..1]), ["D1: NVIDIA GeForce RTX 4…"]);
    }

    #[test]
    fn reads_each_file_once_and_writes_the_report_and_plots() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (report("gpu-a", true), report("gpu-b", false));
        for (name, r) in [("a", &a), ("b/shard1", &b)] {
            let d = dir.path().join(name);
            std::fs::create_dir_all(&d).unwrap();
            rows::write(&d, Some(&plan(r, None)), &study::rows(r)).unwrap();
        }
        // b/ and b/shard1/ reach the same file: read once, not a duplicate.
        let inputs = [dir.path().join("a"), dir.path().join("b"), dir.path().join("b/shard1")];
        let m = run(&inputs).unwrap();
        assert_eq!(m.files.len(), 2);
        let out = dir.path().join("merged");
        let written = write(&m, &out).unwrap();
        for f in ["merge.md", "merge.json", "merge-time-vs-leaf-bunny.png", "merge-methods-vs-mt.png"] {
            assert!(written.contains(&out.join(f)), "{f} not in {written:?}");
        }
        let img = image::open(out.join("merge-time-vs-leaf-bunny.png")).unwrap();
        assert!(img.width() >= 4 * 640, "a panel per method");
        let md = std::fs::read_to_string(out.join("merge.md")).unwrap();
        assert!(md.contains("![") && md.contains("merge-methods-vs-mt.png"), "{md}");
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("merge.json")).unwrap()).unwrap();
        assert_eq!(json["devices"].as_array().unwrap().len(), 2);
        // A folder without rows is refused by name.
        let empty = dir.path().join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        let e = run(std::slice::from_ref(&empty)).unwrap_err().to_string();
        assert!(e.contains("empty") && e.contains("rows.jsonl"), "{e}");
        // Rows files without a measured row (empty, or a plan only) are nothing to merge (issue
        // 24: an empty report and exit 0), refused naming the file, or each file.
        let (blank, planned) = (dir.path().join("blank"), dir.path().join("planned"));
        std::fs::create_dir_all(&blank).unwrap();
        std::fs::write(blank.join("rows.jsonl"), "").unwrap();
        std::fs::create_dir_all(&planned).unwrap();
        rows::write(&planned, Some(&plan(&a, None)), &[]).unwrap();
        let e = run(std::slice::from_ref(&blank)).unwrap_err().to_string();
        assert!(e.contains("blank/rows.jsonl") && e.contains("no measured row"), "{e}");
        let e = run(&[blank.clone(), planned.clone()]).unwrap_err().to_string();
        assert!(e.contains("blank/rows.jsonl") && e.contains("planned/rows.jsonl") && e.contains("nothing"), "{e}");
        // Beside a folder with rows they are merely empty.
        assert!(run(&[dir.path().join("a"), blank]).is_ok());
    }

    #[test]
    fn headline_prefers_the_papers_metric() {
        let s = Source::default();
        let t = Figure::timing(Summary { median: 1.0, min: 1.0, max: 1.0, runs: 1 }, "s", rows::Better::Lower);
        let r1 = Row::new("x", Cell::new(), &s).with("zeta_ms", t.clone()).with("alpha_ms", t.clone());
        assert_eq!(headline([&r1]).as_deref(), Some("alpha_ms"));
        let r2 = Row::new("x", Cell::new(), &s).with("render_s", t.clone());
        assert_eq!(headline([&r1, &r2]).as_deref(), Some("render_s"));
        assert_eq!(
            cell_label(&rows::cell([("layout", "bvh2"), ("leaf", "4"), ("scene", "bunny"), ("x", "1")])),
            "scene=bunny leaf=4 layout=bvh2 x=1"
        );
    }

    /// Two Mesa builds' driver statistics of one chip merged (issue 50): each cell's subgroups
    /// per SIMD side by side, the best by the figure's direction (higher), equal cells said.
    #[test]
    fn counts_of_two_driver_builds_name_the_better_by_direction() {
        let row = |build: &str, method: &str, subgroups: f64, vgprs: f64| {
            let mut src =
                Source { device: "Null hardware (RADV NAVI21)".into(), driver: "radv".into(), ..Source::default() };
            src.settings.insert(rows::DRIVER_BUILD.into(), build.into());
            let c = rows::cell([("kernel", "raycast"), ("method", method), ("chip", "navi21")]);
            (
                Row::new("driver-stats", c, &src)
                    .with("subgroups_per_simd", Figure::count_toward(subgroups, "subgroups", rows::Better::Higher))
                    .with("vgprs", Figure::count(vgprs, "registers")),
                PathBuf::from(format!("{build}/rows.jsonl")),
            )
        };
        let rows = vec![
            row("22.3.6", "mt", 20.0, 48.0),
            row("22.3.6", "quad-unit", 12.0, 80.0),
            row("25.0.7", "mt", 24.0, 40.0),
            row("25.0.7", "quad-unit", 12.0, 80.0),
        ];
        let r = merge(vec![], vec![], rows, vec![]).unwrap();
        assert_eq!(r.counts.len(), 2, "{:?}", r.counts);
        assert!(r.counts.iter().all(|c| c.figure == "subgroups_per_simd"));
        let mt = r.counts.iter().find(|c| c.cell.get("method").map(String::as_str) == Some("mt")).unwrap();
        assert_eq!(mt.best.len(), 1);
        assert!(mt.best[0].contains("25.0.7"), "{:?}", mt.best);
        let q = r.counts.iter().find(|c| c.cell.get("method").map(String::as_str) == Some("quad-unit")).unwrap();
        assert!(q.best.is_empty(), "equal: {:?}", q.best);
        let md = r.markdown(&[]);
        assert!(md.contains("## Counts per cell: `driver-stats`, `subgroups_per_simd`"), "{md}");
        assert!(md.contains("higher is better. Best: D2 in 1; equal in 1 of 2 cells."), "{md}");
    }
}
