//! `trilab profile`.

use super::OutArgs;
use std::path::PathBuf;

use clap::Args;
use trilab::commands::profile::{self, ProfileOptions};
use trilab::encoding::Layout;
use trilab::error::{Error, Result};
use trilab::services::driver_stats::CollectOptions;
use trilab::services::rayset::RaySet;
use trilab::services::roofline::RooflineOptions;

use super::choice::choice;
use super::{repeat, results_dir, scene_help, GpuArgs, JsonArg, LeafSizeArg, MethodsArg, RaySetArgs};

/// Driver-level profile of the ray-casting kernels: timings, statistics, sweeps
///
/// Driver-level profile of the ray-casting kernels: timestamps, pipeline statistics,
/// shader-clock heat maps, executable statistics, subgroup/workgroup-size sweeps,
/// LP_NUM_THREADS scaling, driver statistics (lavapipe's machine code); profile.md,
/// profile.json, rows.jsonl and PNGs.
#[derive(Args)]
#[command(
    mut_arg("width", |a| a.help("Primary rays: a width x height camera image (also the heat maps' size)")),
    mut_arg("diffuse_per_hit", |a| a.default_value("2")),
    mut_arg("random_rays", |a| a.default_value("250000"))
)]
#[command(mut_arg("out", |a| a.help("Output directory for profile.md, profile.json and the PNGs; default results/<device>/profile (lavapipe for Mesa's llvmpipe)")))]
pub struct ProfileArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    #[command(flatten)]
    leaf: LeafSizeArg,
    /// BVH node layout every kernel traverses (`bvh2`, `bvh4`, `bvh8`, ...).
    #[arg(long, value_parser = choice::<Layout>(), default_value_t = Layout::DEFAULT)]
    layout: Layout,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    rays: RaySetArgs,
    /// Timed runs after one warm-up (at least 1); median, min and max are reported.
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::REPEAT, value_parser = repeat)]
    repeat: usize,
    /// The ray set the subgroup- and workgroup-size sweeps time.
    #[arg(long, value_parser = choice::<RaySet>(), default_value_t = RaySet::Random)]
    sweep_set: RaySet,
    /// Workgroup sizes the workgroup-size sweep times, comma-separated.
    #[arg(long, value_name = "N,...", value_delimiter = ',', default_values_t = [32u32, 64, 128, 256])]
    workgroup_sizes: Vec<u32>,
    /// LP_NUM_THREADS values to run, comma-separated (lavapipe only); default 1..=host cores; at
    /// most 4 per logical CPU, or 64 where that is fewer.
    #[arg(long, value_name = "N,...", value_delimiter = ',')]
    threads: Vec<usize>,
    /// Leave out the LP_NUM_THREADS section.
    #[arg(long)]
    no_threads: bool,
    /// Leave out the driver statistics (lavapipe: this executable run again with
    /// GALLIVM_DEBUG=asm; `trilab driver-stats` gives them alone).
    #[arg(long)]
    no_driver_stats: bool,
    /// Also measure the traversal roofline at the scene's working set on the access path its
    /// kernels read, and add to each kernel's timing its fetches per ray (its stats variant on
    /// the same rays) and its share of the roofline, as `bench --roofline` does.
    #[arg(long)]
    roofline: bool,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: ProfileArgs) -> Result<()> {
    trilab::commands::build_bench::check_threads(&a.threads)?;
    let this_exe = trilab::services::worker::this_exe;
    let exe = if a.no_threads { None } else { Some(this_exe()?) };
    let ctx = a.gpu.context()?;
    let driver_stats = if a.no_driver_stats {
        None
    } else {
        Some(CollectOptions {
            exe: this_exe()?,
            device_index: ctx.info().index,
            validation: a.gpu.validation,
            asm_dir: None,
        })
    };
    let o = ProfileOptions {
        scene: a.scene.clone(),
        methods: a.methods.or_device(&ctx),
        build: a.leaf.options(),
        layout: a.layout,
        sizes: a.rays.sizes(),
        repeat: a.repeat,
        sweep_set: a.sweep_set,
        workgroup_sizes: a.workgroup_sizes.clone(),
        thread_counts: a.threads.clone(),
        exe,
        driver_stats,
        command: format!("trilab {}", std::env::args().skip(1).collect::<Vec<_>>().join(" ")),
        roofline: a.roofline.then(|| RooflineOptions { rounds: a.repeat, ..Default::default() }),
        ..Default::default()
    };
    let out = results_dir(&ctx, a.out.dir.clone(), "profile");
    let files = ["profile.json", "profile.md", trilab::rows::FILE];
    OutArgs::check(&out, &files, &[&a.scene])?;
    o.sizes.require_all()?;
    std::fs::create_dir_all(&out).map_err(|e| Error::io(&out, e))?;
    let report = profile::run(&ctx, &o, Some(&out), |m| eprintln!("  {m}"))?;
    a.json.print(&report);
    profile::write(&report, &out)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}
