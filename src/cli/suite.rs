//! `trilab suite`.

use super::OutArgs;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use clap::Args;
use trilab::commands::suite::{self, Part, SuiteOptions};
use trilab::encoding::Layout;
use trilab::error::{Error, Result};
use trilab::named::Named;
use trilab::services::driver_stats::CollectOptions;

use super::choice::choice;
use super::{results_dir, signals, GpuArgs, JsonArg, TimelineArg};

/// What to run once on a new device: every part, scaled to a time budget
///
/// What to run once on a new device: the devices, bench (with the peers when given), the
/// paper's study, accuracy and profile, each scaled to fit the budget, then summary.md (device
/// and driver, the headline speed table, the claims' verdicts, the speed/accuracy frontier, links
/// to the rest). Every part validates against the f64 reference before it reports.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Output folder (default: results/<device>/suite/). Each part writes into its own subfolder")))]
pub struct SuiteArgs {
    /// Wall-clock budget in minutes. A probe measures this device against the reference machine
    /// and each part takes the largest size predicted to fit its share (bench 25 %, study 45 %,
    /// accuracy 18 %, profile 12 %); a part's smallest size always runs.
    #[arg(long, value_name = "N", default_value_t = 30.0)]
    budget_minutes: f64,
    #[command(flatten)]
    out: OutArgs,
    /// The parts to run, comma-separated (default: all).
    #[arg(long, value_name = "P,...", value_parser = choice::<Part>(), value_delimiter = ',')]
    parts: Vec<Part>,
    /// Embree peer executable for the bench (scripts/embree-peer.sh builds it), run with bench's
    /// default calls: rtcIntersect1 and rtcIntersect8.
    #[arg(long, value_name = "FILE")]
    embree: Option<PathBuf>,
    /// tinybvh peer executable for the bench (scripts/tinybvh-peer.sh builds it).
    #[arg(long, value_name = "FILE")]
    tinybvh: Option<PathBuf>,
    /// Skip the profile's LP_NUM_THREADS section (it re-runs trilab once per thread count).
    #[arg(long)]
    no_threads: bool,
    /// Skip the profile's driver statistics (lavapipe: this executable run again with
    /// GALLIVM_DEBUG=asm; other drivers: the executable properties).
    #[arg(long)]
    no_driver_stats: bool,
    /// Run every part at this step of its size ladder whatever the budget (0: the smoke sizes,
    /// seconds on lavapipe; a larger step is capped at a part's largest): for a run that must
    /// match a stored baseline cell for cell, as CI's does.
    #[arg(long, value_name = "N")]
    size: Option<usize>,
    /// BVH node layouts for the bench and the study, comma-separated (`bvh2,bvh4,cwbvh`): every
    /// method runs on each, and the sizes are scaled to fit with all of them (default: bvh2).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    #[command(flatten)]
    trace: TimelineArg,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: SuiteArgs) -> Result<()> {
    // The trace is neither a peer program nor one of the suite's own files.
    let inputs: Vec<&std::path::Path> = a.embree.as_deref().into_iter().chain(a.tinybvh.as_deref()).collect();
    let own = ["summary.md", "suite.json", "devices.txt", "devices.json"];
    let outputs: Vec<PathBuf> = a.out.dir.iter().flat_map(|d| own.map(|f| d.join(f))).collect();
    a.trace.check(&inputs, &outputs)?;
    let run = a.trace.start("suite");
    // Ctrl-C, SIGTERM or SIGHUP: say what the run leaves in its folder (and write the trace as
    // far as it got), then exit 128 + the signal's number at once (the part under way cannot
    // stop half-way and be kept).
    let kept = Arc::new(Mutex::new(suite::Kept::default()));
    let k = kept.clone();
    let trace_file = a.trace.file.clone();
    let handler = signals::on_stop(move |signal| {
        let k = k.lock().unwrap_or_else(|e| e.into_inner());
        // The part under way may run trilab again (bench per LP_NUM_THREADS, the driver
        // statistics): each child's process group gets the signal too.
        let children = trilab::children::signal_all(signal);
        let forwarded = if children > 0 { format!(" (and {children} child process(es))") } else { String::new() };
        eprintln!("suite: stopped by {}{forwarded}; {}", signals::name(signal), k.describe());
        if let Some(file) = &trace_file {
            // The spans still open (the run, the part under way) end here, marked unfinished.
            match TimelineArg::write(file) {
                Ok(w) => eprintln!("suite: trace of the run so far: {w} in {}", file.display()),
                Err(e) => eprintln!("suite: the trace was not written: {e}"),
            }
        }
        signals::exit_now(signal);
    });
    if let Err(e) = handler {
        super::note(&format!("warning: cannot catch Ctrl-C or SIGTERM ({e}); a stopped run will not say what it kept"));
    }
    let result = run_suite(&a, &kept);
    let written = a.trace.finish(run, &result);
    result?;
    written
}

/// The suite itself, after the signal handler is in place.
fn run_suite(a: &SuiteArgs, kept: &Mutex<suite::Kept>) -> Result<()> {
    let this_exe = trilab::services::worker::this_exe;
    let exe = if a.no_threads { None } else { Some(this_exe()?) };
    let mut o = SuiteOptions {
        budget_minutes: a.budget_minutes,
        out: a.out.dir.clone().unwrap_or_default(),
        parts: if a.parts.is_empty() { Part::ALL.to_vec() } else { a.parts.clone() },
        embree: a.embree.clone(),
        tinybvh: a.tinybvh.clone(),
        exe,
        driver_stats: None,
        force_size: a.size,
        layouts: a.layouts.clone(),
    };
    suite::check(&o)?;
    let ctx = {
        let _span = trilab::timeline::span("device", "device context");
        a.gpu.context()?
    };
    TimelineArg::device(&ctx);
    if !a.no_driver_stats {
        o.driver_stats = Some(CollectOptions {
            exe: this_exe()?,
            device_index: ctx.info().index,
            validation: a.gpu.validation,
            asm_dir: None,
        });
    }
    o.out = results_dir(&ctx, a.out.dir.clone(), "suite");
    OutArgs::check(&o.out, &["summary.md", "suite.json"], &[])?;
    let report = suite::run(&ctx, &o, kept, |m| eprintln!("suite: {m}"))?;
    a.json.print(&report);
    let failed: Vec<String> =
        report.parts.iter().filter_map(|p| p.failed.as_ref().map(|why| format!("{}: {why}", p.part))).collect();
    if !failed.is_empty() {
        // The others completed and are summarised; the exit status still says not all did.
        return Err(Error::Unsupported(format!(
            "suite: {} of {} parts did not complete (the others did; {} says why): {}",
            failed.len(),
            report.parts.len(),
            report.out.join("summary.md").display(),
            failed.join("; ")
        )));
    }
    Ok(())
}
