//! `trilab gate`: the regression gate (scripts/ci-gate.sh builds the base and measures, then
//! calls it).

use super::OutArgs;
use std::path::PathBuf;

use clap::Args;
use trilab::commands::ab::{AbOptions, Judge, Side};
use trilab::commands::gate::{self, BaseBuild, GateOptions};
use trilab::error::{Error, Result};

use super::ab::{env_pair, sigpipe, RoundsArgs, WorkloadArgs};
use super::{GpuArgs, JsonArg};

/// The regression gate: counts and correctness exact, timings by an in-run A/B
///
/// The regression gate: counts and correctness against a committed baseline, exact; timings
/// only by an A/B of the baseline's build against this one in this run (each kernel over its
/// cells; a failure must repeat). Exit 0 pass, 1 fail, 2 could not gate.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Folder for gate.md, gate.json, rows.jsonl (the A/B's ratios)")))]
pub struct GateArgs {
    /// The committed baseline: a folder of `trilab suite` and `trilab spirv --out` rows.
    #[arg(value_name = "BASELINE")]
    baseline: PathBuf,
    /// The same measured on this build.
    #[arg(value_name = "NEW")]
    new: PathBuf,
    /// The trilab executable built from the baseline's commit (side A of the timings' A/B).
    #[arg(long, value_name = "FILE", requires = "base_commit", conflicts_with = "no_base")]
    base_bin: Option<PathBuf>,
    /// The commit --base-bin was built from.
    #[arg(long, value_name = "COMMIT", requires = "base_bin")]
    base_commit: Option<String>,
    /// There is no base build, and why: the gate judges counts and correctness alone and says
    /// so (it never compares timings across runs).
    #[arg(long, value_name = "WHY", required_unless_present = "base_bin")]
    no_base: Option<String>,
    /// A kernel fails when this build is slower than the base build by more than this many
    /// percent with its whole 95 % interval, twice.
    #[arg(long, value_name = "PCT", default_value_t = gate::DEFAULT_THRESHOLD_PCT)]
    threshold: f64,
    /// Judge a kernel's timing failure on the first A/B alone (no second measurement).
    #[arg(long)]
    no_repeat: bool,
    #[command(flatten)]
    workload: WorkloadArgs,
    #[command(flatten)]
    rounds: RoundsArgs,
    /// A variable for side A (the base build) only, repeatable.
    #[arg(long, value_name = "K=V", value_parser = env_pair)]
    a_env: Vec<(String, String)>,
    /// A variable for side B (this build) only, repeatable: `--b-env
    /// TRILAB_INJECT_SLOWDOWN=raycast.unit.closest:2` plants a slowdown the gate must catch.
    #[arg(long, value_name = "K=V", value_parser = env_pair)]
    b_env: Vec<(String, String)>,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: GateArgs) -> Result<()> {
    super::error_exit(2);
    a.rounds.check(a.threshold)?;
    if let Some(dir) = &a.out.dir {
        let files = ["gate.json", "gate.md", trilab::rows::FILE];
        OutArgs::check(dir, &files, &[])?;
    }
    let base = match (a.base_bin, a.base_commit, a.no_base) {
        (Some(exe), Some(commit), _) => BaseBuild::Built { exe, commit },
        (_, _, Some(why)) => BaseBuild::Missing { why },
        _ => return Err(Error::Usage("give --base-bin FILE --base-commit C, or --no-base WHY".into())),
    };
    let exe = trilab::services::worker::this_exe()?;
    let validation = a.gpu.validation_required();
    let defaults = gate::default_workload(a.workload.workload().sizes, a.workload.workload().build);
    let o = GateOptions {
        baseline: a.baseline,
        new: a.new,
        base,
        ab: AbOptions {
            workload: a.workload.workload_or(defaults),
            a: Side { exe: None, icd: None, env: a.a_env, layout: None },
            b: Side { exe: None, icd: None, env: a.b_env, layout: None },
            exe,
            rounds: a.rounds.rounds,
            max_rounds: a.rounds.max_rounds,
            target: a.rounds.target / 100.0,
            time_cap_s: a.rounds.time_cap,
            threshold: a.threshold / 100.0,
            judge: Judge::Kernels,
            validation,
            driver_stats: false,
            repro: None,
        },
        repeat_failures: !a.no_repeat,
    };
    sigpipe(true);
    let report = gate::run(&o, |m| eprintln!("  {m}"));
    sigpipe(false);
    let report = report?;
    if let Some(dir) = &a.out.dir {
        trilab::services::results::write_folder(dir, &report)?;
        eprintln!("wrote {}", dir.display());
    }
    a.json.print(&report);
    let code = report.exit_code();
    if code != 0 {
        use std::io::Write;
        let _ = std::io::stdout().flush();
        std::process::exit(code.into());
    }
    Ok(())
}
