//! `trilab roofline`.

use super::OutArgs;

use clap::Args;
use trilab::error::Result;
use trilab::gpu::roofline::RooflineAccess;
use trilab::named::Named;
use trilab::services::roofline::{self, RooflineOptions};

use super::choice::choice;
use super::{GpuArgs, JsonArg};

/// The device's traversal roofline: dependent node steps/s per working-set size
///
/// The device's traversal roofline: node steps per second of a dependent walk through 32-byte
/// nodes (two 16-byte loads, a slab test, the next index from the loaded words) per working-set
/// size, from the caches to DRAM, and per way of reading the nodes (texel buffer, storage buffer,
/// buffer device address); sizes and paths interleaved round by round, medians with min-max of
/// GPU timestamps, each cell's checksums checked against the CPU's walk first.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Directory for roofline.json, roofline.md and rows.jsonl (default: results/<device>/roofline)")))]
pub struct RooflineArgs {
    /// Working-set sizes, comma-separated: powers of two of at least 64 bytes, in bytes or with
    /// K, M, G (binary). Sizes the device cannot hold are skipped, naming why.
    #[arg(
        long,
        value_name = "SIZE,...",
        value_delimiter = ',',
        value_parser = roofline::parse_size,
        allow_negative_numbers = true,
        default_value = "16K,64K,256K,1M,4M,16M,64M,256M"
    )]
    sizes: Vec<u64>,
    /// Access paths, comma-separated (default: all three).
    #[arg(long, value_name = "A,...", value_parser = choice::<RooflineAccess>(), value_delimiter = ',')]
    access: Vec<RooflineAccess>,
    /// Timed rounds, each running every size and path once, after one warm-up round.
    #[arg(long, value_name = "N", default_value_t = 5, value_parser = super::repeat, allow_negative_numbers = true)]
    rounds: usize,
    /// Invocations per dispatch.
    #[arg(long, value_name = "N", default_value_t = roofline::DEFAULT_INVOCATIONS, allow_negative_numbers = true)]
    invocations: u32,
    /// Dependent node steps per invocation.
    #[arg(long, value_name = "N", default_value_t = roofline::DEFAULT_STEPS, allow_negative_numbers = true)]
    steps: u32,
    /// Seed of the node buffers, start nodes and ray state.
    #[arg(long, value_name = "N", default_value_t = 1, allow_negative_numbers = true)]
    seed: u32,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: RooflineArgs) -> Result<()> {
    // A size or path named twice is measured once (the sweep's cells are named by them): say so.
    for (option, given) in [
        ("--sizes", a.sizes.iter().map(|&b| roofline::show_size(b)).collect::<Vec<_>>()),
        ("--access", a.access.iter().map(|x| x.to_string()).collect()),
    ] {
        let mut repeated: Vec<&str> = vec![];
        for (i, g) in given.iter().enumerate() {
            if given[..i].contains(g) && !repeated.contains(&g.as_str()) {
                repeated.push(g);
            }
        }
        if !repeated.is_empty() {
            super::note(&format!("{option}: {} given more than once; each is measured once", repeated.join(", ")));
        }
    }
    let o = RooflineOptions {
        sizes: a.sizes,
        access: if a.access.is_empty() { RooflineAccess::ALL.to_vec() } else { a.access },
        rounds: a.rounds,
        invocations: a.invocations,
        steps: a.steps,
        seed: a.seed,
        ..RooflineOptions::default()
    };
    o.check()?;
    if let Some(out) = &a.out.dir {
        OutArgs::check(out, &roofline::FILES, &[])?;
    }
    let ctx = a.gpu.context()?;
    let out = super::results_dir(&ctx, a.out.dir.clone(), "roofline");
    OutArgs::check(&out, &roofline::FILES, &[])?;
    let report = roofline::run(&ctx, &o, |m| eprintln!("  {m}"))?;
    a.json.print(&report);
    report.write(&out)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}
