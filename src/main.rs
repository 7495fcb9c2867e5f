//! `trilab`: the command line. It only dispatches: each command is one file in `src/cli/` that
//! turns its arguments into a library call and prints the typed report.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod cli;

#[derive(Parser)]
#[command(
    name = "trilab",
    version,
    about = "GPU ray-triangle intersection laboratory: BVH traversal with hand-written Vulkan compute kernels, one per intersection method"
)]
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
    Bvh(cli::bvh::BvhArgs),
    BuildBench(cli::build_bench::BuildBenchArgs),
    Steps(cli::steps::StepsArgs),
    Spirv(cli::spirv::SpirvArgs),
    Bench(cli::bench::BenchArgs),
    Scale(cli::scale::ScaleArgs),
    Render(cli::render::RenderArgs),
    BenchRender(cli::bench_render::BenchRenderArgs),
    Study(cli::study::StudyArgs),
    Profile(cli::profile::ProfileArgs),
    Accuracy(cli::accuracy::AccuracyArgs),
    Analyze(cli::analyze::AnalyzeArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = trilab::scene::set_scene_dir(cli.scene_dir).and_then(|()| match cli.command {
        Cmd::Devices(a) => cli::devices::run(a),
        Cmd::Methods(a) => cli::methods::run(a),
        Cmd::Rays(a) => cli::rays::run(a),
        Cmd::Raycast(a) => cli::raycast::run(a),
        Cmd::Bvh(a) => cli::bvh::run(a),
        Cmd::BuildBench(a) => cli::build_bench::run(a),
        Cmd::Steps(a) => cli::steps::run(a),
        Cmd::Spirv(a) => cli::spirv::run(a),
        Cmd::Bench(a) => cli::bench::run(a),
        Cmd::Scale(a) => cli::scale::run(a),
        Cmd::Render(a) => cli::render::run(a),
        Cmd::BenchRender(a) => cli::bench_render::run(a),
        Cmd::Study(a) => cli::study::run(a),
        Cmd::Profile(a) => cli::profile::run(a),
        Cmd::Accuracy(a) => cli::accuracy::run(a),
        Cmd::Analyze(a) => cli::analyze::run(a),
    });
    cli::exit(result)
}
