//! `trilab bvh`.

use std::path::PathBuf;

use clap::Args;
use trilab::bvh::NodeOrder;
use trilab::commands::{build_bench, bvh_stats};
use trilab::encoding::Layout;
use trilab::error::Result;

use super::choice::choice;
use super::{scene_help, JsonArg, TreeShapeArgs};

/// Build the BVH and report its statistics: nodes, depth, SAH cost, EPO, time
///
/// Build the BVH and report its statistics (nodes, depth, leaf sizes, SAH cost, end-point
/// overlap, time).
#[derive(Args)]
pub struct BvhArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    /// Max triangles per leaf, comma-separated, each built in turn (default: 1,2,3,4,8,16; the
    /// old repeatable `--leaf-size N` still works).
    #[arg(long, value_name = "N,...", value_delimiter = ',', alias = "leaf-size")]
    leaf_sizes: Vec<u32>,
    #[command(flatten)]
    shape: TreeShapeArgs,
    /// Build threads, comma-separated, each run in turn (default: one per logical CPU; at most 4
    /// per logical CPU, or 64 where that is fewer). The tree does not depend on them; the build
    /// time does.
    #[arg(long, value_name = "N,...", value_delimiter = ',')]
    threads: Vec<usize>,
    /// Node layouts, comma-separated (`bvh2`, `bvh4`, `bvh8`, `cwbvh`, `qbvh4`): per leaf size, each
    /// layout of the binned tree with its nodes and bytes per triangle (the node buffer, and the
    /// node buffer plus each method's leaf bytes), and per node order the locality of a descent
    /// (default with --node-orders: every layout; without either, no layout table).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    /// Node orders whose locality is reported per layout, comma-separated (`built`,
    /// `depth-first`, `breadth-first`, `treelets`): the new 64-byte lines and 4 KiB pages a
    /// step from a node to its child reads, weighted by the child's surface area (default with
    /// --layouts: every order).
    #[arg(long, value_name = "O,...", value_parser = choice::<NodeOrder>(), value_delimiter = ',')]
    node_orders: Vec<NodeOrder>,
    #[command(flatten)]
    json: JsonArg,
}

pub fn run(a: BvhArgs) -> Result<()> {
    // Every count before the first build, not when its turn comes.
    build_bench::check_threads(&a.threads)?;
    // The tree's shape; its leaf size is each of --leaf-sizes in turn.
    let shape = a.shape.options(0);
    let node_orders = super::bench::distinct_node_orders(a.node_orders.clone());
    let build = || bvh_stats::run_with_layouts(&a.scene, &a.leaf_sizes, shape, &a.layouts, &node_orders);
    let report = if a.threads.is_empty() {
        build()?
    } else {
        let mut report: Option<bvh_stats::BvhReport> = None;
        for &t in &a.threads {
            let r = build_bench::pool(t)?.install(build)?;
            match &mut report {
                // The trees, so their layouts, do not depend on the threads: the first run's.
                Some(all) => all.rows.extend(r.rows),
                None => report = Some(r),
            }
        }
        report.expect("at least one thread count")
    };
    report.warnings.iter().for_each(|w| super::note(w));
    a.json.print(&report);
    Ok(())
}
