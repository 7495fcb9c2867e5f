//! `trilab bench-render`.

use std::path::PathBuf;

use clap::Args;
use trilab::commands::bench_render::{self, RenderBenchOptions, RenderBenchReport};
use trilab::error::Result;
use trilab::render::KernelChoice;
use trilab::services::results::Results;

use super::choice::choice;
use super::{repeat, scenes_help, GpuArgs, JsonArg, LeafSizeArg, MethodsArg, ReportOutArgs};

/// Path-tracing benchmark: samples/s and rays/s per scene, method and kernel choice.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Folder for bench.json (the report), bench.md (its tables) and rows.jsonl, made when missing")))]
pub struct BenchRenderArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', help = concat!(scenes_help!(), "; default: bunny, dragon, buddha"))]
    scenes: Vec<PathBuf>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    /// Kernel choices to time (specialised, general).
    #[arg(long, value_parser = choice::<KernelChoice>(), value_delimiter = ',', default_value = "specialised")]
    kernels: Vec<KernelChoice>,
    #[command(flatten)]
    leaf: LeafSizeArg,
    /// Image width in pixels.
    #[arg(long, value_name = "W", default_value_t = 200)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, value_name = "H", default_value_t = 150)]
    height: u32,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 16)]
    spp: u32,
    /// Most scattering events per path.
    #[arg(long, value_name = "N", default_value_t = 16)]
    max_depth: u32,
    /// Timed renders per configuration after one warm-up (at least 1).
    #[arg(long, value_name = "N", default_value_t = 3, value_parser = repeat)]
    repeat: usize,
    #[command(flatten)]
    out: ReportOutArgs,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: BenchRenderArgs) -> Result<()> {
    let scenes =
        if a.scenes.is_empty() { ["bunny", "dragon", "buddha"].iter().map(PathBuf::from).collect() } else { a.scenes };
    let (json_out, md_out) = a.out.files(<RenderBenchReport as Results>::STEM, &scenes)?;
    let ctx = a.gpu.context()?;
    let o = RenderBenchOptions {
        scenes,
        methods: a.methods.or_device(&ctx),
        kernels: a.kernels,
        build: a.leaf.options(),
        width: a.width,
        height: a.height,
        spp: a.spp,
        max_depth: a.max_depth,
        env: None,
        repeat: a.repeat,
    };
    let report = bench_render::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    if a.json.json {
        a.json.print(&report);
    } else {
        println!("{}", trilab::report::Report::to_text(&report));
    }
    a.out.create_dir()?;
    report.write(json_out.as_deref(), md_out.as_deref())
}
