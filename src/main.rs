//! `trilab`: the command line. It only dispatches: each command is one file in `src/cli/` that
//! turns its arguments into a library call and prints the typed report.

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

mod cli;

#[derive(Parser)]
#[command(name = "trilab", version, about = cli::about(), after_help = cli::after_help())]
struct Cli {
    /// Folder searched first for scene names (`--scene bunny`), before TRILAB_SCENES, scenes/ beside the executable, the built-in bunny and the source tree.
    #[arg(long, global = true, value_name = "DIR")]
    scene_dir: Option<std::path::PathBuf>,
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    Devices(cli::devices::DevicesArgs),
    Methods(cli::methods::MethodsArgs),
    Rays(cli::rays::RaysArgs),
    Raycast(cli::raycast::RaycastArgs),
    Repro(cli::repro::ReproArgs),
    Bvh(cli::bvh::BvhArgs),
    BuildBench(cli::build_bench::BuildBenchArgs),
    Steps(cli::steps::StepsArgs),
    Spirv(cli::spirv::SpirvArgs),
    Bench(cli::bench::BenchArgs),
    Scale(cli::scale::ScaleArgs),
    Render(cli::render::RenderArgs),
    BenchRender(cli::bench_render::BenchRenderArgs),
    Study(cli::study::StudyArgs),
    Merge(cli::merge::MergeArgs),
    Profile(cli::profile::ProfileArgs),
    Roofline(cli::roofline::RooflineArgs),
    DriverStats(cli::driver_stats::DriverStatsArgs),
    Accuracy(cli::accuracy::AccuracyArgs),
    Suite(cli::suite::SuiteArgs),
    Analyze(cli::analyze::AnalyzeArgs),
    Compare(cli::compare::CompareArgs),
    Completions(cli::completions::CompletionsArgs),
    Man(cli::man::ManArgs),
    #[command(name = "__dump-cli", hide = true)]
    DumpCli(cli::dump::DumpArgs),
    Hits(cli::hits::HitsArgs),
    Ab(cli::ab::AbArgs),
    Gate(cli::gate::GateArgs),
    #[command(name = "__worker", alias = "__ab-worker", hide = true)]
    Worker(cli::ab::WorkerArgs),
}

/// A closed pipe on stdout (`trilab completions bash | head`) ends the process quietly, as it
/// ends `cat`, instead of a panic in `println!` (Rust ignores SIGPIPE before `main`).
#[cfg(unix)]
fn default_sigpipe() {
    // SAFETY: runs first in `main`, before any thread is started; `signal` with SIG_DFL only
    // restores the default disposition of SIGPIPE and touches no handler state of ours. Only
    // `trilab ab` writes to a child's stdin, and it ignores SIGPIPE while it does (cli/ab.rs).
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> ExitCode {
    #[cfg(unix)]
    default_sigpipe();
    // Before any thread and before the Vulkan loader reads the environment.
    trilab::env::keep_lavapipe_cache_per_target();
    let matches = match Cli::command().try_get_matches() {
        Ok(m) => m,
        Err(e) => return cli::exit_parse_error(e),
    };
    cli::json_errors(cli::asks_for_json(&matches));
    let args = match Cli::from_arg_matches(&matches) {
        Ok(c) => c,
        Err(e) => return cli::exit_parse_error(e),
    };
    let result = trilab::scene::set_scene_dir(args.scene_dir).and_then(|()| match args.command {
        Cmd::Devices(a) => cli::devices::run(a),
        Cmd::Methods(a) => cli::methods::run(a),
        Cmd::Rays(a) => cli::rays::run(a),
        Cmd::Raycast(a) => cli::raycast::run(a),
        Cmd::Repro(a) => cli::repro::run(a),
        Cmd::Bvh(a) => cli::bvh::run(a),
        Cmd::BuildBench(a) => cli::build_bench::run(a),
        Cmd::Steps(a) => cli::steps::run(a),
        Cmd::Spirv(a) => cli::spirv::run(a),
        Cmd::Bench(a) => cli::bench::run(a),
        Cmd::Scale(a) => cli::scale::run(a),
        Cmd::Render(a) => cli::render::run(a),
        Cmd::BenchRender(a) => cli::bench_render::run(a),
        Cmd::Study(a) => cli::study::run(a),
        Cmd::Merge(a) => cli::merge::run(a),
        Cmd::Profile(a) => cli::profile::run(a),
        Cmd::Roofline(a) => cli::roofline::run(a),
        Cmd::DriverStats(a) => cli::driver_stats::run(a),
        Cmd::Accuracy(a) => cli::accuracy::run(a),
        Cmd::Suite(a) => cli::suite::run(a),
        Cmd::Analyze(a) => cli::analyze::run(a),
        Cmd::Compare(a) => cli::compare::run(a),
        Cmd::Completions(a) => cli::completions::run(a, Cli::command()),
        Cmd::Man(a) => cli::man::run(a, Cli::command()),
        Cmd::DumpCli(a) => cli::dump::run(a, Cli::command()),
        Cmd::Hits(a) => cli::hits::run(a),
        Cmd::Ab(a) => cli::ab::run(a),
        Cmd::Gate(a) => cli::gate::run(a),
        Cmd::Worker(a) => cli::ab::run_worker(a),
    });
    cli::exit(result)
}
