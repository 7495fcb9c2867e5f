//! `trilab hits`.

use std::path::PathBuf;

use clap::{Args, Subcommand};
use trilab::commands::hits::{self, DiffTolerance};
use trilab::error::{Error, Result};

use super::{scene_help, BuildArgs, JsonArg};

/// Hit files: print one, check one against the f64 reference, or diff two
///
/// Hit files (`raycast --out`): print one, check one against the CPU f64 reference, or diff two
/// (exit status 1 when they differ, as `diff`'s).
#[derive(Args)]
pub struct HitsArgs {
    #[command(subcommand)]
    command: HitsCmd,
}

#[derive(Subcommand)]
enum HitsCmd {
    /// Print a hit file, then its counts of hits and misses
    ///
    /// Print a hit file: ray index, t, u, v, triangle (or miss), and the counts of hits and misses.
    Show {
        /// The hit file.
        file: PathBuf,
        /// Records to print (0: only the counts).
        #[arg(long, default_value_t = 20)]
        limit: usize,
        #[command(flatten)]
        json: JsonArg,
    },
    /// Check a hit file against the CPU f64 reference, as `raycast --reference` does
    ///
    /// Check a hit file against the CPU f64 reference as `raycast --reference` does: agreement,
    /// and the disagreements rounding explains (near an edge or a tie) or does not. Exit status
    /// 1 when any is unexplained or a record is impossible.
    Check {
        #[arg(long, value_name = "S", help = concat!(scene_help!(), "; the scene the rays were cast against"))]
        scene: PathBuf,
        /// The ray file the hits answer (32-byte rays, docs/formats.md).
        #[arg(long, value_name = "FILE")]
        rays: PathBuf,
        /// The hit file.
        file: PathBuf,
        /// The file holds any-hit results (`raycast --any-hit`).
        #[arg(long)]
        any_hit: bool,
        #[command(flatten)]
        bvh: BuildArgs,
        #[command(flatten)]
        json: JsonArg,
    },
    /// Print the rays whose hit changed between two hit files, then the totals
    ///
    /// Print the rays whose hit changed between two hit files (a different triangle, miss <->
    /// hit, t or u/v beyond the tolerances) and the totals; exit status 1 when any differ.
    Diff {
        /// The first (base) hit file.
        #[arg(value_name = "BASE")]
        a: PathBuf,
        /// The second (new) hit file, compared with BASE ray by ray.
        #[arg(value_name = "NEW")]
        b: PathBuf,
        /// Relative difference in t still counted as the same hit.
        #[arg(long, default_value_t = 0.0)]
        t_tolerance: f64,
        /// Absolute difference in u and v still counted as the same hit.
        #[arg(long, default_value_t = 0.0)]
        uv_tolerance: f64,
        /// Changed rays to print (the totals count them all).
        #[arg(long, default_value_t = 50)]
        limit: usize,
        #[command(flatten)]
        json: JsonArg,
    },
}

pub fn run(a: HitsArgs) -> Result<()> {
    match a.command {
        HitsCmd::Show { file, limit, json } => json.print(&hits::show(&file, limit)?),
        HitsCmd::Check { scene, rays, file, any_hit, bvh, json } => {
            let report = hits::check(&scene, &rays, &file, any_hit, &bvh.options())?;
            report.warnings.iter().for_each(|w| super::note(w));
            json.print(&report);
            if !report.passes {
                return Err(Error::Usage(format!(
                    "{}: {} unexplained disagreements and {} impossible records against the f64 reference",
                    file.display(),
                    report.unexplained,
                    report.invalid
                )));
            }
        }
        HitsCmd::Diff { a, b, t_tolerance, uv_tolerance, limit, json } => {
            let report = hits::diff(&a, &b, DiffTolerance { t: t_tolerance, uv: uv_tolerance }, limit)?;
            json.print(&report);
            if report.differ() {
                // As `diff`: 1 means "they differ", not a failure to compare.
                use std::io::Write;
                let _ = std::io::stdout().flush();
                std::process::exit(1);
            }
        }
    }
    Ok(())
}
