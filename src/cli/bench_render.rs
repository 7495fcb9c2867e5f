//! `trilab bench-render`.

use std::path::PathBuf;

use clap::Args;
use trilab::error::Result;
use trilab::harness::bench_render::{self, RenderBenchOptions};
use trilab::render::KernelChoice;

use super::choice::choice;
use super::{GpuArgs, MethodsArg};

/// Path-tracing benchmark: samples/s and rays/s per scene, method and kernel choice.
#[derive(Args)]
pub struct BenchRenderArgs {
    /// Scenes (OBJ files); default: the bundled bunny, dragon and buddha.
    #[arg(long, value_delimiter = ',')]
    scenes: Vec<PathBuf>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    /// Kernel choices to time (specialised, general).
    #[arg(long, value_parser = choice::<KernelChoice>(), value_delimiter = ',', default_value = "specialised")]
    kernels: Vec<KernelChoice>,
    #[arg(long, default_value_t = 4)]
    leaf_size: u32,
    #[arg(long, default_value_t = 200)]
    width: u32,
    #[arg(long, default_value_t = 150)]
    height: u32,
    #[arg(long, default_value_t = 16)]
    spp: u32,
    #[arg(long, default_value_t = 16)]
    max_depth: u32,
    /// Timed renders per configuration (after one warm-up).
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    #[arg(long)]
    json_out: Option<PathBuf>,
    #[arg(long)]
    md_out: Option<PathBuf>,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: BenchRenderArgs) -> Result<()> {
    let scenes =
        if a.scenes.is_empty() { ["bunny", "dragon", "buddha"].iter().map(PathBuf::from).collect() } else { a.scenes };
    for out in [&a.json_out, &a.md_out].into_iter().flatten() {
        trilab::io::ensure_not_input(out, &scenes.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    }
    let ctx = a.gpu.context()?;
    let o = RenderBenchOptions {
        scenes,
        methods: a.methods.or_device(&ctx),
        kernels: a.kernels,
        leaf_size: a.leaf_size,
        width: a.width,
        height: a.height,
        spp: a.spp,
        max_depth: a.max_depth,
        env: None,
        repeat: a.repeat,
    };
    let report = bench_render::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    println!("{}", trilab::report::Report::to_text(&report));
    report.write(a.json_out.as_deref(), a.md_out.as_deref())
}
