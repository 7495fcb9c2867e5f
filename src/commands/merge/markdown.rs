//! The merge's report as text: `merge.md`, a section per table, and the tables themselves
//! ([`MergeReport::claims_table`], [`MergeReport::speed_tables`]).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::{cell_label, push, series_names, CountRow, MergeReport};
use crate::encoding::Layout;
use crate::report::Table;
use crate::rows::{self, Shard};
use crate::services::plots::Plot;

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

    /// `merge.md`: the devices, the claims per device, speed and counts per cell, the worst
    /// correctness per device, the missing cells and the plots.
    pub fn markdown(&self, plots: &[Plot]) -> String {
        let mut s = String::from("# trilab merge\n\n");
        let _ = writeln!(
            s,
            "{} rows file(s) from {}; one column per device and driver setting (its name and the settings that \
             change a measurement); a cell measured twice for one device is refused.\n",
            self.files.len(),
            self.inputs.iter().map(|p| format!("`{}`", p.display())).collect::<Vec<_>>().join(", ")
        );
        s += &self.devices_section();
        s += &self.claims_section();
        s += &self.speed_sections();
        s += &self.counts_sections();
        s += &self.correctness_section();
        s += &self.missing_section();
        s += &plots_section(plots);
        s
    }

    /// Each column: its plot series, device, drivers, commits, dates, rows and shards.
    fn devices_section(&self) -> String {
        let mut s = String::from("## Devices\n\n");
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
        s
    }

    /// The claims table, then each device's claims in words (none without study rows).
    fn claims_section(&self) -> String {
        let mut s = String::new();
        if self.claims.is_empty() {
            return s;
        }
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
        s
    }

    /// A speed table per command.
    fn speed_sections(&self) -> String {
        let mut s = String::new();
        for (command, figure, t) in self.speed_tables() {
            let _ = writeln!(s, "## Speed per cell: `{command}`, `{figure}`\n");
            let _ = writeln!(s, "Median (min-max over the timed rounds) per device.\n");
            s += &t.to_markdown();
            s.push('\n');
        }
        s
    }

    /// A counts table per command that has counts.
    fn counts_sections(&self) -> String {
        let mut s = String::new();
        let mut commands: Vec<(&str, &str)> = vec![];
        for c in &self.counts {
            push(&mut commands, (c.command.as_str(), c.figure.as_str()));
        }
        for (command, figure) in commands {
            s += &self.counts_section(command, figure);
        }
        s
    }

    /// The counts of one command: how often each device is best, and each cell's counts.
    fn counts_section(&self, command: &str, figure: &str) -> String {
        let mut s = String::new();
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
        s
    }

    /// The worst cell of each correctness figure per device (none without correctness figures).
    fn correctness_section(&self) -> String {
        let mut s = String::new();
        if self.correctness.is_empty() {
            return s;
        }
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
        s
    }

    /// The planned cells a device did not measure, or that there are none.
    fn missing_section(&self) -> String {
        let mut s = String::from("## Missing cells\n\n");
        if self.missing.is_empty() {
            s += "None: every cell of every plan was measured on every device.\n\n";
            return s;
        }
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
        s
    }
}

/// Each plot under its title (none without plots).
fn plots_section(plots: &[Plot]) -> String {
    let mut s = String::new();
    if !plots.is_empty() {
        s += "## Plots\n\n";
        for p in plots {
            let name = p.path.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default();
            let _ = writeln!(s, "### {}\n\n![{}]({name})\n", p.title, p.title);
        }
    }
    s
}

/// Four significant digits.
fn sig(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (3 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.digits$}")
}
