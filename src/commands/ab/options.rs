//! What `trilab ab` is given: the two sides (build, driver, environment), the workload, the
//! rounds and what the verdict judges, and the checks made on them before any side starts.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::interval;
use super::worker::Workload;
use crate::encoding::Layout;
use crate::error::{Error, Result};
use crate::named::named_enum;
use crate::services::worker::Launch;

/// One side: the trilab build it runs, the driver the loader is given and the environment it
/// runs in.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Side {
    /// The trilab executable this side runs (`None`: the one running `ab`): two builds of the
    /// kernels timed side by side, as the regression gate times the baseline's build against the
    /// build under test.
    pub exe: Option<PathBuf>,
    /// The ICD JSON given to the loader as `VK_DRIVER_FILES` (`None`: the loader's own choice).
    pub icd: Option<PathBuf>,
    /// Variables set for this side only, in order.
    pub env: Vec<(String, String)>,
    /// The node layout this side runs in place of the workload's one layout (`--b-layout`).
    pub layout: Option<Layout>,
}

impl Side {
    /// `bin=... VK_DRIVER_FILES=... K=V`, or "trilab's own environment".
    pub fn describe(&self) -> String {
        let mut parts: Vec<String> = self.exe.iter().map(|p| format!("bin={}", p.display())).collect();
        parts.extend(self.icd.iter().map(|p| format!("VK_DRIVER_FILES={}", p.display())));
        parts.extend(self.env.iter().map(|(k, v)| format!("{k}={v}")));
        parts.extend(self.layout.iter().map(|l| format!("layout={l}")));
        if parts.is_empty() {
            "trilab's own environment".into()
        } else {
            parts.join(" ")
        }
    }

    /// The executable this side runs: its own, or `default` (the running trilab).
    pub fn exe<'a>(&'a self, default: &'a Path) -> &'a Path {
        self.exe.as_deref().unwrap_or(default)
    }

    /// This side's executable (its own, or `default`: the running trilab) in its driver and
    /// environment.
    pub fn launch(&self, default: &Path) -> Launch {
        let mut l = Launch::new(self.exe(default));
        if let Some(icd) = &self.icd {
            l = l.env("VK_DRIVER_FILES", icd).env("VK_ICD_FILENAMES", icd);
        }
        for (k, v) in &self.env {
            l = l.env(k, v);
        }
        l
    }
}

/// What `trilab ab` runs and when it stops.
#[derive(Clone, Debug)]
pub struct AbOptions {
    pub workload: Workload,
    pub a: Side,
    pub b: Side,
    /// The trilab executable a side runs (`__ab-worker`) unless it names its own.
    pub exe: PathBuf,
    /// Rounds per side at least (at least 2: an interval needs a spread).
    pub rounds: usize,
    /// Rounds per side at most.
    pub max_rounds: usize,
    /// Stop adding rounds once every cell's interval half-width (log scale) is below this.
    pub target: f64,
    /// Stop adding rounds past this many seconds.
    pub time_cap_s: f64,
    /// A cell (or kernel, by `judge`) whose whole interval is past 1 + threshold fails the run.
    pub threshold: f64,
    /// What the verdict judges: each cell, or each kernel over its cells.
    pub judge: Judge,
    /// Load the validation layer in the workers (any message fails the side).
    pub validation: bool,
    /// After the rounds, each side's driver statistics of the ray-casting kernels, diffed.
    pub driver_stats: bool,
    /// After the rounds, the changed ray-casting cells made into repros of both sides here
    /// ([`super::repro`]; a new folder).
    pub repro: Option<PathBuf>,
}

named_enum! {
    /// What `ab`'s verdict judges.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Judge: "judge" {
        /// each cell alone (a scene, ray set and kernel): one that slowed on one ray set shows
        Cells = "cells" (default),
        /// each kernel over its cells (its scenes and ray sets, pooled round by round): a narrower interval, so a smaller slowdown of a kernel is told from noise (the regression gate's)
        Kernels = "kernels",
    }
}

impl Judge {
    /// `cell` or `kernel`.
    pub(super) fn unit(self) -> &'static str {
        match self {
            Judge::Cells => "cell",
            Judge::Kernels => "kernel",
        }
    }
}

/// The options checked before any side starts: each side's ICD file and executable, and the
/// rounds (a warning when too few to judge time).
pub(super) fn check_options(o: &AbOptions, progress: &mut impl FnMut(&str)) -> Result<()> {
    if let Some(dir) = &o.repro {
        crate::commands::repro::refuse_existing("--repro", dir)?;
    }
    if let Some(l) = o.b.layout {
        if o.workload.layouts.len() != 1 {
            return Err(Error::Usage(format!(
                "--b-layout {l}: side B runs it in place of side A's one layout; give --layouts one layout"
            )));
        }
    }
    for (name, flag, side) in [("A", "--a-icd", &o.a), ("B", "--b-icd", &o.b)] {
        if let Some(icd) = &side.icd {
            check_icd(name, flag, icd)?;
        }
    }
    for (name, flag, side) in [("A", "--a-bin", &o.a), ("B", "--b-bin", &o.b)] {
        if let Some(exe) = &side.exe {
            if exe.is_dir() {
                return Err(Error::Usage(format!(
                    "side {name}: {flag} {}: a directory, not a trilab executable",
                    exe.display()
                )));
            }
            if !exe.is_file() {
                return Err(Error::Usage(format!(
                    "side {name}: {flag} {}: no such file (a trilab executable)",
                    exe.display()
                )));
            }
        }
    }
    if o.rounds < 2 || o.max_rounds < o.rounds {
        return Err(Error::Usage(format!(
            "--rounds {} --max-rounds {}: at least 2 rounds a side, and no more than the maximum",
            o.rounds, o.max_rounds
        )));
    }
    if o.max_rounds < interval::MIN_JUDGED_ROUNDS {
        progress(&format!(
            "warning: --max-rounds {}: fewer than {} rounds a side, so time is shown but not judged \
             (hits and correctness still are)",
            o.max_rounds,
            interval::MIN_JUDGED_ROUNDS
        ));
    }
    Ok(())
}

/// Refuses a side's ICD file (`flag`: `--a-icd`) the loader could not use, naming the side, the
/// file and why, before any side starts: missing, a directory, empty, not JSON, naming no
/// driver library, or naming one by a path that does not exist (a bare library name is the
/// loader's to find on the library path).
fn check_icd(side: &str, flag: &str, icd: &Path) -> Result<()> {
    let refuse = |why: String| Error::Usage(format!("side {side}: {flag} {}: {why}", icd.display()));
    let meta = std::fs::metadata(icd).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => refuse("no such file (an ICD JSON naming a driver)".into()),
        _ => refuse(format!("cannot be read ({e})")),
    })?;
    if meta.is_dir() {
        return Err(refuse("a directory, not an ICD JSON file (an ICD JSON naming a driver)".into()));
    }
    let text = std::fs::read(icd).map_err(|e| refuse(format!("cannot be read ({e})")))?;
    if text.iter().all(u8::is_ascii_whitespace) {
        return Err(refuse("the file is empty, not an ICD JSON naming a driver".into()));
    }
    let json: serde_json::Value = serde_json::from_slice(&text)
        .map_err(|e| refuse(format!("not JSON ({e}), so not an ICD JSON naming a driver")))?;
    let Some(library) = json.get("ICD").and_then(|d| d.get("library_path")).and_then(|l| l.as_str()) else {
        return Err(refuse("names no driver: an ICD JSON has {\"ICD\": {\"library_path\": \"...\", ...}}".into()));
    };
    if library.contains('/') {
        // A relative path is relative to the JSON file, as the loader reads it.
        let lib = icd.parent().unwrap_or(Path::new(".")).join(library);
        if !lib.is_file() {
            return Err(refuse(format!("its driver library {library} does not exist")));
        }
    }
    Ok(())
}

/// Gives each scene spec as the parent resolves it: a file by its path, so both sides read the
/// same file whatever build each runs and wherever it looks for names (a base build kept in a
/// cache has no `scenes/` beside it); the compiled-in bunny and `synth:` specs as given.
pub(super) fn resolved_workload(w: &Workload) -> Result<Workload> {
    let mut w = w.clone();
    for spec in &mut w.scenes {
        let source = crate::scene::find::resolve(spec)?;
        if matches!(source.found.as_str(), "synthetic" | "built into trilab") {
            continue;
        }
        *spec = std::path::absolute(&source.path).map_err(|e| Error::io(&source.path, e))?;
    }
    Ok(w)
}
