//! The merge's columns: one per device at one set of settings ([`Source::device_label`], with
//! the driver where two drivers name their device alike), and the refusal of a cell measured
//! twice for one of them.

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use serde::Serialize;

use super::cell_label;
use crate::error::{Error, Result};
use crate::rows::{Plan, Row, Shard, Source};

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

/// The sources of every row, then of every plan.
fn sources<'a>(rows: &'a [(Row, PathBuf)], plans: &'a [(Plan, PathBuf)]) -> impl Iterator<Item = &'a Source> {
    rows.iter().map(|(r, _)| &r.source).chain(plans.iter().map(|(p, _)| &p.source))
}

/// Two drivers of one device are two columns: lavapipe 22.3.6 and 25.0.7 both name their
/// device "llvmpipe (LLVM 15.0.6, 256 bits)". Where one label covers more than one driver,
/// the driver joins the label's settings.
pub(super) fn tell_drivers_apart(rows: &mut [(Row, PathBuf)], plans: &mut [(Plan, PathBuf)]) {
    let mut drivers: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for s in sources(rows, plans) {
        drivers.entry(s.device_label()).or_default().insert(s.driver.clone());
    }
    let by_driver = |s: &mut Source| {
        if drivers.get(&s.device_label()).is_some_and(|d| d.len() > 1) {
            s.settings.insert("driver".into(), s.driver.clone());
        }
    };
    rows.iter_mut().for_each(|(r, _)| by_driver(&mut r.source));
    plans.iter_mut().for_each(|(p, _)| by_driver(&mut p.source));
}

/// The columns' labels, in order of first appearance.
pub(super) fn labels(rows: &[(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> Vec<String> {
    let mut labels: Vec<String> = vec![];
    for s in sources(rows, plans) {
        let l = s.device_label();
        if !labels.contains(&l) {
            labels.push(l);
        }
    }
    labels
}

/// Refuses a cell measured twice for one device, naming the cell and both files.
pub(super) fn refuse_measured_twice(rows: &[(Row, PathBuf)]) -> Result<()> {
    let mut by_cell: BTreeMap<(String, String), &PathBuf> = BTreeMap::new();
    for (r, f) in rows {
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
    Ok(())
}

/// The column `label`: what its rows and plans say of the device, the files and its shards.
pub(super) fn device(label: &str, rows: &[(Row, PathBuf)], plans: &[(Plan, PathBuf)]) -> Device {
    let sources: Vec<&Source> = sources(rows, plans).filter(|s| s.device_label() == label).collect();
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
    Device {
        label: label.to_owned(),
        device: sources.first().map(|s| s.device.clone()).unwrap_or_default(),
        settings: sources.first().map(|s| s.settings.clone()).unwrap_or_default(),
        drivers: distinct(|s| &s.driver),
        commits: distinct(|s| &s.commit),
        dates: distinct(|s| &s.date),
        rows: rows.iter().filter(|(r, _)| r.source.device_label() == label).count(),
        files,
        shards: shards(label, plans),
    }
}

/// Per command, the shards the plans of `label` name, and those of the same count that none
/// of its files holds.
fn shards(label: &str, plans: &[(Plan, PathBuf)]) -> Vec<Shards> {
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
    shards
}
