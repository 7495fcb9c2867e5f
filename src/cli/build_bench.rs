//! `trilab build-bench`.

use super::OutArgs;
use super::ShardArg;
use std::path::{Path, PathBuf};

use clap::Args;
use trilab::commands::build_bench::{self, BuildBenchOptions};
use trilab::encoding::Layout;
use trilab::error::Result;

use super::choice::choice;
use super::{repeat, BuildArgs, JsonArg};

/// BVH build benchmark: seconds, Mtris/s and SAH cost per scene and thread count
///
/// BVH build benchmark: seconds, Mtris/s, SAH cost, nodes and depth per scene and thread
/// count for the parallel and serial binned SAH and the full sweep, optionally beside
/// Embree 3's builder on the same triangles, and each node layout's conversion time and bytes
/// per triangle; build.csv, layouts.csv, build.json, build.md.
#[derive(Args)]
#[command(mut_arg("sah_group", |a| a.help("Triangles the SAH prices as one test (1: classic; Embree's SAH block size)")))]
#[command(mut_arg("out", |a| a.help("Directory for build.csv, layouts.csv, build.json and build.md (e.g. results/<host>/build)")))]
#[command(mut_arg("shard", |a| a.help("Run only shard I of N: every N-th scene, round-robin from scene I. rows.jsonl names the shard and plans the whole matrix; `trilab merge` joins the shards' folders")))]
pub struct BuildBenchArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', required = true, help = super::scenes_help!())]
    scenes: Vec<PathBuf>,
    #[command(flatten)]
    bvh: BuildArgs,
    /// Thread counts, comma-separated, each run in turn (default: one per logical CPU; at most 4
    /// per logical CPU, or 64 where that is fewer).
    #[arg(long, value_name = "N,...", value_delimiter = ',')]
    threads: Vec<usize>,
    /// Timed runs after one warm-up (at least 1).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::REPEAT, value_parser = repeat)]
    repeat: usize,
    /// Leave out the single-threaded reference loop.
    #[arg(long)]
    no_serial: bool,
    /// Full-sweep SAH reference only on scenes of at most this many triangles.
    #[arg(long, value_name = "N", default_value_t = 300_000)]
    sweep_max: usize,
    /// The Embree build peer (`embree_build` from scripts/embree-peer.sh).
    #[arg(long, value_name = "FILE")]
    embree: Option<PathBuf>,
    /// Node layouts whose node buffer is made from the binary tree and timed, comma-separated
    /// (`bvh2`, `bvh4`, `bvh8`, ...; default: every layout).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    #[command(flatten)]
    shard: ShardArg,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: BuildBenchArgs) -> Result<()> {
    let d = BuildBenchOptions::default();
    let o = BuildBenchOptions {
        scenes: a.scenes,
        build: a.bvh.options(),
        threads: if a.threads.is_empty() { d.threads } else { a.threads },
        repeat: a.repeat,
        serial: !a.no_serial,
        sweep_max_triangles: a.sweep_max,
        embree: a.embree,
        layouts: if a.layouts.is_empty() { d.layouts } else { a.layouts },
        shard: a.shard.shard,
    };
    o.check()?;
    let inputs: Vec<&Path> = o.scenes.iter().map(PathBuf::as_path).collect();
    if let Some(out) = &a.out.dir {
        let files = ["build.csv", "layouts.csv", "build.json", "build.md", trilab::rows::FILE];
        OutArgs::check(out, &files, &inputs)?;
    }
    let report = build_bench::run(&o, |m| eprintln!("{m}"))?;
    a.json.print(&report);
    if let Some(out) = &a.out.dir {
        report.write(out)?;
        eprintln!("wrote {}/build.{{csv,json,md}} and layouts.csv", out.display());
    }
    Ok(())
}
