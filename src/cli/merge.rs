//! `trilab merge`.

use super::OutArgs;
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
#[command(mut_arg("out", |a| a.help("Output folder for merge.md, merge.json and the plots. Without it the report is only printed")))]
pub struct MergeArgs {
    /// Result folders (searched recursively for rows.jsonl) or rows files.
    #[arg(value_name = "DIR", required = true)]
    dirs: Vec<PathBuf>,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: MergeArgs) -> Result<()> {
    // Merge has no verdict to give a 1 to: every failure is "could not merge", compare's 2.
    super::error_exit(2);
    if let Some(out) = &a.out.dir {
        let inputs: Vec<&Path> = a.dirs.iter().map(PathBuf::as_path).collect();
        OutArgs::check(out, &merge::FILES, &inputs)?;
    }
    let report = merge::run(&a.dirs)?;
    a.json.print(&report);
    if let Some(out) = &a.out.dir {
        for w in merge::write(&report, out)? {
            eprintln!("  wrote {}", w.display());
        }
    }
    Ok(())
}
