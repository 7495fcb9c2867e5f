//! `trilab driver-stats`.

use super::OutArgs;
use std::path::PathBuf;

use clap::Args;
use trilab::commands::profile::Status;
use trilab::encoding::{Layout, Method};
use trilab::error::{Error, Result};
use trilab::gpu::Statistic;
use trilab::matrix::TargetAxes;
use trilab::named::Named;
use trilab::services::driver_stats::target::MesaBuild;
use trilab::services::driver_stats::{self, CollectOptions, Selection, TargetOptions};
use trilab::services::results::Folder;

use super::choice::choice;
use super::{results_dir, GpuArgs, JsonArg, MethodsArg};

/// What the driver compiled each kernel to: registers, occupancy, spills, code
///
/// What the driver compiled each kernel to: on lavapipe, machine instructions, vector spills and
/// reloads and calls into the texel-fetch helpers, from gallivm's disassembly (this executable
/// runs itself again with GALLIVM_DEBUG=asm and MESA_SHADER_CACHE_DISABLE=true); on drivers with
/// VK_KHR_pipeline_executable_properties (RADV, NVIDIA), the compiler's own statistics, typed
/// (VGPRs, SGPRs, spills, scratch, subgroups per SIMD, instructions, code bytes; hashes as
/// identities), with each kernel's occupancy cliffs on AMD chips; on other drivers (among them
/// Debian 12's own lavapipe, Mesa 22.3.6, whose release build reads no GALLIVM_DEBUG) it refuses,
/// naming why, after probing one kernel.
///
/// With --targets, every kernel is compiled for real AMD GPUs on this machine, without one,
/// through RADV's null device: each target (chip x compiler x subgroup size x Mesa build) in a
/// worker of its own (`--targets default`: pitcairn, polaris10, vega10, navi21, navi31, gfx1201;
/// ACO and LLVM; wave32 and wave64 on RDNA). driver-stats.md, driver-stats.json, driver-stats.csv
/// and rows.jsonl (for `trilab compare`).
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Output directory for driver-stats.md, driver-stats.json, driver-stats.csv and rows.jsonl; default results/<device>/driver-stats, with --targets results/radv/driver-stats")))]
pub struct DriverStatsArgs {
    /// Kernel files, comma-separated (`raycast`, `pathtrace`, `raycast_coop`, `rayquery`, ...),
    /// `all`, or `studied` (each method's closest- and any-hit kernels on bvh2, closest-hit on
    /// the other layouts, and the ray-query peer, whatever --variants says). Default: `raycast` on lavapipe (whose statistics need a dispatch, and only
    /// `raycast` kernels are dispatched), `all` where the compiler reports them.
    #[arg(long, value_name = "K,...", value_delimiter = ',')]
    kernels: Vec<String>,
    /// Variants without their layout suffix, comma-separated (`closest`, `any`, `stats`,
    /// `closest_address`, `closest_while_while`, ...), or `all`; a kernel without the variant is left out.
    /// Default: `closest,any` on lavapipe, `all` where the compiler reports statistics.
    #[arg(long, value_name = "V,...", value_delimiter = ',')]
    variants: Vec<String>,
    /// GPU targets, comma-separated `CHIP[:COMPILER[:WAVE]]` (Mesa's family names: pitcairn,
    /// navi31, gfx1201...; aco or llvm; 32 or 64), a part left out meaning every one the chip
    /// allows, or `default`. Each is compiled in a worker of its own through RADV's null device
    /// (RADV_FORCE_FAMILY), for each Mesa build of --mesa.
    #[arg(long, value_name = "T,...")]
    targets: Option<String>,
    /// The Mesa builds whose RADV compiles the targets, comma-separated: `installed` (the
    /// system's), `stock` (Debian 12's own 22.3.6, unpacked by scripts/stock-mesa.sh), or a RADV
    /// ICD file. Default: installed.
    #[arg(long, value_name = "M,...", value_delimiter = ',', requires = "targets", value_parser = |s: &str| s.parse::<MesaBuild>())]
    mesa: Vec<MesaBuild>,
    /// Targets compiled at once, each in its worker (default: the host's logical CPUs).
    #[arg(long, value_name = "N", requires = "targets")]
    jobs: Option<usize>,
    /// Methods (default: every method the device runs).
    #[command(flatten)]
    methods: MethodsArg,
    /// Node layouts, comma-separated (default: all).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    #[command(flatten)]
    out: OutArgs,
    /// Also keep each kernel's disassembly as `<DIR>/<kernel>.txt` (lavapipe).
    #[arg(long, value_name = "DIR")]
    asm_dir: Option<PathBuf>,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

const FILES: [&str; 4] = ["driver-stats.json", "driver-stats.md", "driver-stats.csv", trilab::rows::FILE];

/// The selection the options name, `default` (kernels and variants) where they name none.
fn selection(a: &DriverStatsArgs, methods: Vec<Method>, default: Selection) -> Selection {
    Selection {
        kernels: if a.kernels.is_empty() { default.kernels } else { a.kernels.clone() },
        variants: if a.variants.is_empty() { default.variants } else { a.variants.clone() },
        methods,
        layouts: if a.layouts.is_empty() { Layout::ALL.to_vec() } else { a.layouts.clone() },
    }
}

pub fn run(a: DriverStatsArgs) -> Result<()> {
    if a.targets.is_some() {
        return run_targets(a);
    }
    let exe = trilab::services::worker::this_exe()?;
    let ctx = a.gpu.compile_context()?;
    // lavapipe's statistics need a dispatch of each kernel (raycast only); a compiler that
    // reports its own compiles anything.
    let default = match ctx.capabilities().statistic(Statistic::MachineCode) {
        Ok(()) => Selection::default(),
        Err(_) => Selection::everything(),
    };
    let kernels = selection(&a, a.methods.or_device(&ctx), default).kernels()?;
    let out = results_dir(&ctx, a.out.dir.clone(), "driver-stats");
    OutArgs::check(&out, &FILES, &[])?;
    if let Some(dir) = &a.asm_dir {
        trilab::io::check_output("--asm-dir", trilab::io::Output::Dir(dir, &[]), &[])?;
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    eprintln!("  {} kernel variants", kernels.len());
    let o = CollectOptions {
        exe,
        device_index: ctx.info().index,
        validation: a.gpu.validation,
        asm_dir: a.asm_dir.clone(),
    };
    let report = driver_stats::collect(&ctx, &kernels, &o)?;
    // A driver without statistics is told after one kernel's probe, before the others are
    // compiled and before any file is written: an empty report would read as "no kernels".
    if report.status != Status::Measured {
        return Err(Error::Unsupported(format!("driver-stats: {}", report.note)));
    }
    let mut folder = Folder::create(&out)?;
    a.json.print(&report);
    folder.results(&report)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

/// `--targets`: every selected kernel compiled for each GPU target in a worker of its own; no
/// device is opened here.
fn run_targets(a: DriverStatsArgs) -> Result<()> {
    let exe = trilab::services::worker::this_exe()?;
    let axes = TargetAxes::parse(a.targets.as_deref().unwrap_or_default(), &a.mesa).map_err(Error::Usage)?;
    let targets = axes.targets().map_err(Error::Usage)?;
    // Every Mesa build is found before any work.
    for m in &axes.mesa() {
        m.icd()?;
    }
    let methods = if a.methods.methods.is_empty() { Method::ALL.to_vec() } else { a.methods.methods.clone() };
    let kernels = selection(&a, methods, Selection::everything()).kernels()?;
    let out = a.out.dir.clone().unwrap_or_else(|| PathBuf::from("results/radv/driver-stats"));
    OutArgs::check(&out, &FILES, &[])?;
    let jobs = a.jobs.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    eprintln!("  {} kernel variants x {} targets, {jobs} at a time", kernels.len(), targets.len());
    let o = TargetOptions {
        exe,
        validation: a.gpu.validation_required(),
        timeout: std::time::Duration::from_secs(1800),
        jobs,
    };
    let done = std::sync::atomic::AtomicUsize::new(0);
    let results = driver_stats::collect_targets(&targets, &kernels, &o, &|t| {
        let n = done.fetch_add(1, std::sync::atomic::Ordering::SeqCst) + 1;
        match t.status {
            Status::Measured => {
                eprintln!(
                    "  [{n}/{}] {}: {} kernels, {} not compiled",
                    targets.len(),
                    t.target,
                    t.kernels.len(),
                    t.refused.len()
                )
            }
            _ => eprintln!("  [{n}/{}] {}: failed: {}", targets.len(), t.target, t.note),
        }
    });
    if results.iter().all(|t| t.status != Status::Measured) {
        let why: Vec<String> = results.iter().map(|t| format!("{}: {}", t.target, t.note)).collect();
        return Err(Error::Unsupported(format!("driver-stats: no target compiled: {}", why.join("; "))));
    }
    let report = driver_stats::targets_report(results);
    let mut folder = Folder::create(&out)?;
    a.json.print(&report);
    folder.results(&report)?;
    eprintln!("wrote {}", out.display());
    Ok(())
}
