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
//!
//! Read, join, report: [`run`] reads the rows files (`read.rs`), [`merge`] joins their rows into
//! columns (`devices.rs`), the claims per device (`claims.rs`) and the tables per command
//! (`cells.rs`), and the [`MergeReport`] (`report.rs`) is written as text (`markdown.rs`) and
//! plots (`plots.rs`); `names.rs` names cells and devices for both.

mod cells;
mod claims;
mod devices;
mod markdown;
mod names;
pub mod plots;
mod read;
mod report;
#[cfg(test)]
mod tests;

use std::path::PathBuf;

pub use cells::{headline, headline_count, CountRow, Missing, SpeedRow, Worst};
pub use claims::{grid, DeviceClaims};
pub use devices::{Device, Shards};
pub use names::{cell_label, series_names};
pub use report::{write, MergeReport, FILES};

use crate::error::Result;
use crate::rows::{Plan, Row};

/// Reads every rows file under `inputs` (each file once) and merges them.
pub fn run(inputs: &[PathBuf]) -> Result<MergeReport> {
    let input = read::read(inputs)?;
    merge(inputs.to_vec(), input.files, input.rows, input.plans)
}

/// Merges rows and plans already read (each with the file it came from).
pub fn merge(
    inputs: Vec<PathBuf>,
    files: Vec<PathBuf>,
    mut rows: Vec<(Row, PathBuf)>,
    mut plans: Vec<(Plan, PathBuf)>,
) -> Result<MergeReport> {
    devices::tell_drivers_apart(&mut rows, &mut plans);
    let labels = devices::labels(&rows, &plans);
    devices::refuse_measured_twice(&rows)?;
    let devices: Vec<Device> = labels.iter().map(|l| devices::device(l, &rows, &plans)).collect();
    let claims =
        labels.iter().filter_map(|l| claims::device_claims(l, &rows, &plans).transpose()).collect::<Result<_>>()?;
    let cells::Tables { speed, counts, correctness, missing } = cells::Tables::of(&labels, &rows, &plans);
    Ok(MergeReport { inputs, files, devices, claims, speed, counts, correctness, missing })
}

/// Appends `x` unless `v` holds it already.
fn push<T: PartialEq>(v: &mut Vec<T>, x: T) {
    if !v.contains(&x) {
        v.push(x);
    }
}
