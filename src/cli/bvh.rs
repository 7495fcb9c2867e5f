//! `trilab bvh`.

use std::path::PathBuf;

use clap::Args;
use trilab::bvh::LeafPolicy;
use trilab::error::Result;
use trilab::harness::{build_bench, bvh_stats};

use super::choice::choice;
use super::JsonArg;

/// Build the BVH and report its statistics (nodes, depth, leaf sizes, SAH cost, end-point
/// overlap, time).
#[derive(Args)]
pub struct BvhArgs {
    #[arg(long)]
    scene: PathBuf,
    /// Max triangles per leaf; repeat or omit for 1, 2, 3, 4, 8, 16.
    #[arg(long = "leaf-size")]
    leaf_sizes: Vec<u32>,
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    leaf_policy: LeafPolicy,
    /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
    /// Quad kernels test them.
    #[arg(long, default_value_t = 1)]
    sah_group: u32,
    /// Build threads (default: one per logical CPU). The tree does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: BvhArgs) -> Result<()> {
    let build = || bvh_stats::run(&a.scene, &a.leaf_sizes, a.leaf_policy, a.sah_group);
    let report = match a.threads {
        Some(t) => build_bench::pool(t)?.install(build)?,
        None => build()?,
    };
    report.warnings.iter().for_each(|w| super::note(w));
    a.json.print(&report);
    Ok(())
}
