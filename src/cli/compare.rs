//! `trilab compare`.

use std::path::PathBuf;

use clap::Args;
use trilab::commands::compare::{self, TimingRule, DEFAULT_COMMAND_THRESHOLD_PCT, DEFAULT_THRESHOLD_PCT};
use trilab::error::Result;

use super::{note, GpuArgs, JsonArg};

/// Compare two result folders cell by cell: only what changed, then the totals
///
/// Two result folders (or rows files) cell by cell, as shader-db compares two driver builds:
/// every rows.jsonl below BASE and NEW (written by bench, accuracy, spirv --out, build-bench and
/// every other command that writes results), matched by command and cell; prints only what changed, then the totals.
/// A timing is faster or slower only when the two runs' min-max ranges do not overlap; a count
/// (instructions, bytes) or correctness figure (agreement, leaks, NaN hits) is compared exactly.
/// Exit status: 0 no regression; 1 a real slowdown or count increase beyond --threshold, or any
/// correctness figure worse; 2 the comparison could not be made (a missing folder, no rows, a
/// malformed line: the file is named).
#[derive(Args)]
pub struct CompareArgs {
    /// The baseline: a result folder (searched for rows.jsonl) or a rows file.
    #[arg(value_name = "BASE")]
    base: PathBuf,
    /// The run judged against it.
    #[arg(value_name = "NEW")]
    new: PathBuf,
    /// A real change (ranges apart; counts: any) is printed, and a slowdown or count increase
    /// fails, beyond this percentage; a rate is judged as its time (x1.10 the time is 10 %).
    #[arg(long, value_name = "PCT", default_value_t = DEFAULT_THRESHOLD_PCT)]
    threshold: f64,
    /// The counts' own threshold (instructions, spills, bytes: exact, so they can be held tighter
    /// than timings on a noisy machine); default: --threshold's.
    #[arg(long, value_name = "PCT")]
    count_threshold: Option<f64>,
    /// How the two sides' timings are set against each other. `calibrated` (what `auto` picks
    /// when both sides carry the host calibration `trilab suite` writes) takes the host's speed
    /// and load out: a command's timings as a whole are judged over the calibration's speed,
    /// each timing against its command's mean change.
    #[arg(long, value_name = "RULE", default_value_t = TimingRule::Auto, value_parser = super::choice::choice::<TimingRule>())]
    timings: TimingRule,
    /// Under the calibrated rule: a command's timings as a whole, over the host calibration,
    /// fail when slower by more than this percentage.
    #[arg(long, value_name = "PCT", default_value_t = DEFAULT_COMMAND_THRESHOLD_PCT)]
    command_threshold: f64,
    /// After comparing, make the changed bench cells of trilab's kernels (at most 3: correctness
    /// changes, then the timings that moved most) into repros in this new folder, on this device
    /// with this build (`trilab repro`'s folders, rays made from each run's bench.json); its
    /// README says which side's device and driver this one is.
    #[arg(long, value_name = "DIR")]
    repro: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: CompareArgs) -> Result<()> {
    super::error_exit(2);
    let options = compare::CompareOptions {
        threshold_pct: a.threshold,
        count_threshold_pct: a.count_threshold,
        command_threshold_pct: a.command_threshold,
        timings: a.timings,
        counts_across_driver_builds: true,
    };
    if let Some(dir) = &a.repro {
        trilab::commands::repro::refuse_existing("--repro", dir)?;
    }
    let mut report = compare::run(&a.base, &a.new, &options)?;
    if let Some(dir) = &a.repro {
        report.repros = compare::repro::make(|| a.gpu.context(), &report, dir, note)?;
    }
    a.json.print(&report);
    if report.exit_code() != 0 {
        // As `diff`: 1 means "a regression", not a failure to compare (that is 2).
        use std::io::Write;
        let _ = std::io::stdout().flush();
        std::process::exit(report.exit_code().into());
    }
    Ok(())
}
