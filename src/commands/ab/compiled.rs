//! `trilab ab --driver-stats`: what each side's driver compiled the cells' kernels to, diffed
//! kernel by kernel (Mesa shader-db's report: only what changed, then totals).
//!
//! Each side's worker ([`crate::services::worker`], in that side's environment, after the timed
//! rounds: its compiles would otherwise time the rounds) is asked for the driver statistics of
//! the cells' kernels, and answers with `driver-stats`' rows: lavapipe's machine-code counts
//! from `GALLIVM_DEBUG=asm`, or the executable statistics of a driver with
//! `VK_KHR_pipeline_executable_properties`. A driver without either (Debian 12's Mesa 22.3.6)
//! gives that side's reason instead, and no cell is compared. Only ray-casting kernels are
//! collected: `driver-stats` dispatches those alone. A build older than the typed requests
//! (ab protocol 2) runs its own `trilab driver-stats` command instead.

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::Path;

use serde::Serialize;

use super::worker::{CellInfo, CellKind};
use super::{AbOptions, Side};
use crate::encoding::{Layout, Method};
use crate::kernels::KERNELS;
use crate::report::Status;
use crate::rows::Row;
use crate::services::driver_stats::{KernelCell, COMMAND};
use crate::services::worker::protocol::{DriverStatsRequest, PROTOCOL_TYPED};
use crate::services::worker::{self, Message, Request};

/// One figure of one kernel that differs between the sides, and which way it is better (fewer
/// instructions; more subgroups per SIMD).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StatChange {
    pub figure: String,
    pub a: f64,
    pub b: f64,
    pub better: crate::rows::Better,
}

impl StatChange {
    /// B is better than A by the figure's direction.
    pub fn helped(&self) -> bool {
        match self.better {
            crate::rows::Better::Lower => self.b < self.a,
            crate::rows::Better::Higher => self.b > self.a,
        }
    }

    /// B is worse than A by the figure's direction.
    pub fn hurt(&self) -> bool {
        match self.better {
            crate::rows::Better::Lower => self.b > self.a,
            crate::rows::Better::Higher => self.b < self.a,
        }
    }
}

/// One side's statistics: its `driver-stats` rows, or why there are none.
#[derive(Clone, Debug)]
pub struct SideStats {
    pub rows: Vec<Row>,
    /// The driver-stats note, or the reason the side has none.
    pub note: String,
}

/// The `driver-stats` cell of a cell's kernel.
fn kernel_cell(c: &CellInfo) -> Option<KernelCell> {
    KERNELS.iter().find(|k| k.name == c.kernel).map(KernelCell::of)
}

/// Asks `side`'s worker (ab protocol `protocol`) for the driver statistics of the ray-casting
/// cells' kernels; `rows` is empty and `note` says why when the driver has none. The rows carry
/// the side's `name` (setting `ab_side`, as its bench rows do), so `merge` keeps both sides'
/// measurements of one kernel apart. `dir`: where an older build writes its files.
pub fn collect(o: &AbOptions, name: &str, side: &Side, protocol: u32, cells: &[CellInfo], dir: &Path) -> SideStats {
    let none = |note: String| SideStats { rows: vec![], note };
    let coords: Vec<KernelCell> =
        cells.iter().filter(|c| c.kind == CellKind::Raycast).filter_map(kernel_cell).collect();
    if coords.is_empty() {
        return none("no ray-casting cell (driver-stats dispatches ray-casting kernels only)".into());
    }
    let list = |field: fn(&KernelCell) -> &str| {
        let mut v: Vec<String> = coords.iter().map(|c| field(c).to_owned()).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let methods: Result<Vec<Method>, String> = list(|c| &c.method).iter().map(|n| n.parse()).collect();
    let layouts: Result<Vec<Layout>, String> = list(|c| &c.layout).iter().map(|n| n.parse()).collect();
    let (methods, layouts) = match (methods, layouts) {
        (Ok(m), Ok(l)) => (m, l),
        (Err(e), _) | (_, Err(e)) => return none(format!("a cell's kernel names no method or layout: {e}")),
    };
    let request = DriverStatsRequest { kernels: list(|c| &c.kernel), variants: list(|c| &c.variant), methods, layouts };
    let launch = side.launch(&o.exe).validation(o.validation);
    let (mut rows, note) = if protocol < PROTOCOL_TYPED {
        match older_build(&launch, &request, dir) {
            Ok(got) => got,
            Err(note) => return none(note),
        }
    } else {
        let who = format!("side {name}");
        match worker::call(&launch, &who, &Request::DriverStats(request)).map(|a| a.message) {
            Ok(Message::DriverStats { status: Status::Measured, note, rows }) => (rows, note),
            Ok(Message::DriverStats { note, .. }) => return none(format!("{COMMAND}: {note}")),
            Ok(other) => return none(worker::unexpected(&who, "driver-stats", &other).to_string()),
            Err(e) => return none(format!("{COMMAND} failed: {e}")),
        }
    };
    for r in &mut rows {
        r.source.settings.insert(super::SIDE_SETTING.into(), name.into());
    }
    SideStats { rows, note }
}

/// A build older than the typed requests: its own `trilab driver-stats` command, writing into
/// `dir`; its rows and note, or why there are none.
fn older_build(
    launch: &worker::Launch,
    r: &DriverStatsRequest,
    dir: &Path,
) -> std::result::Result<(Vec<Row>, String), String> {
    let join = |v: Vec<String>| v.join(",");
    let mut args: Vec<OsString> = vec![COMMAND.into()];
    for (flag, v) in [
        ("--kernels", r.kernels.join(",")),
        ("--variants", r.variants.join(",")),
        ("--methods", join(r.methods.iter().map(ToString::to_string).collect())),
        ("--layouts", join(r.layouts.iter().map(ToString::to_string).collect())),
    ] {
        args.extend([flag.into(), v.into()]);
    }
    args.extend([OsString::from("--out"), dir.into()]);
    let out =
        launch.run_command(&args).map_err(|e| format!("could not run {} {COMMAND}: {e}", launch.exe.display()))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("(no message)");
        let why = last.trim().trim_start_matches("trilab: error: ").trim_start_matches(&format!("{COMMAND}: "));
        return Err(format!("{COMMAND} failed ({}): {why}", out.status));
    }
    /// The one field of its `driver-stats.json` read here.
    #[derive(serde::Deserialize)]
    struct Note {
        #[serde(default)]
        note: String,
    }
    let note = std::fs::read_to_string(dir.join("driver-stats.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<Note>(&t).ok())
        .map(|n| n.note)
        .unwrap_or_default();
    let set = crate::rows::read(dir).map_err(|e| format!("{COMMAND} wrote no readable rows: {e}"))?;
    Ok((set.rows, note))
}

/// The figures of `cell`'s kernel in `rows`, name to value and direction.
fn figures_of(rows: &[Row], cell: &CellInfo) -> Option<BTreeMap<String, (f64, crate::rows::Better)>> {
    let want = kernel_cell(cell)?;
    let row = rows.iter().find(|r| KernelCell::try_from(&r.cell).as_ref() == Ok(&want))?;
    Some(row.figures.iter().map(|(n, f)| (n.clone(), (f.median, f.better))).collect())
}

/// The figures of a cell's kernel that differ between the sides (each side's cell: with
/// `--b-layout` the two ran different kernels); `None` when a side has no statistics for it.
pub fn diff([a, b]: [&SideStats; 2], [cell_a, cell_b]: [&CellInfo; 2]) -> Option<Vec<StatChange>> {
    let (fa, fb) = (figures_of(&a.rows, cell_a)?, figures_of(&b.rows, cell_b)?);
    let names: std::collections::BTreeSet<&String> = fa.keys().chain(fb.keys()).collect();
    Some(
        names
            .into_iter()
            .filter_map(|n| {
                let (x, y) = (fa.get(n).map_or(f64::NAN, |f| f.0), fb.get(n).map_or(f64::NAN, |f| f.0));
                let better = fa.get(n).or(fb.get(n)).map_or(crate::rows::Better::Lower, |f| f.1);
                // A figure only one side reports differs too (NaN on the other).
                (x != y).then(|| StatChange { figure: n.clone(), a: x, b: y, better })
            })
            .collect(),
    )
}

/// `instructions 1234 -> 1250 (+1.3 %)`.
pub fn describe(changes: &[StatChange]) -> String {
    changes
        .iter()
        .map(|c| {
            let pct = if c.a != 0.0 && c.a.is_finite() && c.b.is_finite() {
                format!(" ({:+.1} %)", (c.b / c.a - 1.0) * 100.0)
            } else {
                String::new()
            };
            let v = |x: f64| if x.is_finite() { format!("{x}") } else { "-".into() };
            format!("{} {} -> {}{pct}", c.figure, v(c.a), v(c.b))
        })
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rows::{cell, Figure, Source};

    fn info(kernel: &str) -> CellInfo {
        CellInfo {
            kind: CellKind::Raycast,
            scene: "bunny".into(),
            set: "primary".into(),
            method: "mt".into(),
            layout: "bvh2".into(),
            traversal: "while-if".into(),
            rays: 10,
            kernel: kernel.into(),
            coordinates: Default::default(),
        }
    }

    fn row(instructions: f64, spills: Option<f64>) -> Row {
        let c = cell([("kernel", "raycast"), ("variant", "closest"), ("method", "mt"), ("layout", "bvh2")]);
        let r = Row::new(COMMAND, c, &Source::default()).with("instructions", Figure::count(instructions, "n"));
        match spills {
            Some(s) => r.with("vector_spills", Figure::count(s, "n")),
            None => r,
        }
    }

    #[test]
    fn only_changed_figures_and_figures_one_side_lacks() {
        let k =
            KERNELS.iter().find(|k| k.kernel == "raycast" && k.intersector == "mt" && k.variant == "closest").unwrap();
        let c = info(k.name);
        let side = |rows| SideStats { rows, note: String::new() };
        let same = diff([&side(vec![row(100.0, Some(2.0))]), &side(vec![row(100.0, Some(2.0))])], [&c, &c]).unwrap();
        assert!(same.is_empty(), "{same:?}");
        let d = diff([&side(vec![row(100.0, Some(2.0))]), &side(vec![row(110.0, None)])], [&c, &c]).unwrap();
        assert_eq!(d.len(), 2, "{d:?}");
        assert_eq!(
            d[0],
            StatChange { figure: "instructions".into(), a: 100.0, b: 110.0, better: crate::rows::Better::Lower }
        );
        assert!(d[0].hurt() && !d[0].helped());
        assert!(d[1].figure == "vector_spills" && d[1].a == 2.0 && d[1].b.is_nan());
        assert_eq!(describe(&d[..1]), "instructions 100 -> 110 (+10.0 %)");
        // A side without statistics, or a kernel it did not compile: nothing to compare.
        assert!(diff([&side(vec![]), &side(vec![row(1.0, None)])], [&c, &c]).is_none());
        assert!(diff(
            [&side(vec![row(1.0, None)]), &side(vec![row(1.0, None)])],
            [&info("raycast.nope"), &info("raycast.nope")]
        )
        .is_none());
    }
}
