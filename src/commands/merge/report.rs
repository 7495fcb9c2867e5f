//! The merge's report, and its outputs ([`write`]): `merge.md`, `merge.json` and the plots
//! ([`super::plots`]), each atomically.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::{CountRow, Device, DeviceClaims, Missing, SpeedRow, Worst};
use crate::error::Result;
use crate::rows::Row;

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
        super::plots::all(self, dir)
    }
}
