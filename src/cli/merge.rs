//! `trilab merge`.

use std::path::{Path, PathBuf};

use clap::Args;
use trilab::commands::merge;
use trilab::error::Result;

use super::JsonArg;

/// Join the rows.jsonl of many runners, shards and devices into one report
///
/// Joins the rows.jsonl of many runners, shards and devices (every one below each folder) into
/// one report: a column per device and driver setting, the paper's claims per device, a speed
/// table per cell, the cells no runner measured; writes merge.md, merge.json and plots with a
/// series per device into --out. A cell measured twice for one device is refused.
/// Exit status: 0 merged; 2 the merge could not be made (a missing folder, no rows at all, a
/// malformed line, a cell twice: the file is named), as `compare`'s 2.
#[derive(Args)]
pub struct MergeArgs {
    /// Result folders (searched recursively for rows.jsonl) or rows files.
    #[arg(value_name = "DIR", required = true)]
    dirs: Vec<PathBuf>,
    /// Output folder for merge.md, merge.json and the plots. Without it the report is only
    /// printed.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: MergeArgs) -> Result<()> {
    // Merge has no verdict to give a 1 to: every failure is "could not merge", compare's 2.
    super::error_exit(2);
    if let Some(out) = &a.out {
        let inputs: Vec<&Path> = a.dirs.iter().map(PathBuf::as_path).collect();
        trilab::io::check_output("--out", trilab::io::Output::Dir(out, &merge::FILES), &inputs)?;
    }
    let report = merge::run(&a.dirs)?;
    a.json.print(&report);
    if let Some(out) = &a.out {
        for w in merge::write(&report, out)? {
            eprintln!("  wrote {}", w.display());
        }
    }
    Ok(())
}
