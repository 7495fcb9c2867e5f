//! `trilab driver-stats`.

use super::OutArgs;
use std::path::PathBuf;

use clap::Args;
use trilab::commands::profile::Status;
use trilab::encoding::Layout;
use trilab::error::{Error, Result};
use trilab::named::Named;
use trilab::services::driver_stats::{self, CollectOptions, Selection};
use trilab::services::results::Folder;

use super::choice::choice;
use super::{results_dir, GpuArgs, JsonArg, MethodsArg};

/// What the driver compiled each kernel to: instructions, spills, helper calls
///
/// What the driver compiled each kernel to: on lavapipe, machine instructions, vector spills and
/// reloads and calls into the texel-fetch helpers, from gallivm's disassembly (this executable
/// runs itself again with GALLIVM_DEBUG=asm and MESA_SHADER_CACHE_DISABLE=true); on drivers with
/// VK_KHR_pipeline_executable_properties, their statistics; on other drivers (among them Debian
/// 12's own lavapipe, Mesa 22.3.6, whose release build reads no GALLIVM_DEBUG) it refuses, naming
/// why, after probing one kernel. driver-stats.md, driver-stats.json and rows.jsonl (for
/// `trilab compare`).
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Output directory for driver-stats.md, driver-stats.json and rows.jsonl; default results/<device>/driver-stats")))]
pub struct DriverStatsArgs {
    /// Kernel files, comma-separated: `raycast` (the only one dispatched so far; lavapipe compiles
    /// a shader at its first dispatch).
    #[arg(long, value_name = "K,...", value_delimiter = ',', default_values_t = ["raycast".to_string()])]
    kernels: Vec<String>,
    /// Variants without their layout suffix, comma-separated (`closest`, `any`, `stats`,
    /// `closest_bda`, `closest_ww`, ...); a kernel without the variant is
    /// left out.
    #[arg(long, value_name = "V,...", value_delimiter = ',', default_values_t = ["closest".to_string(), "any".to_string()])]
    variants: Vec<String>,
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

const FILES: [&str; 3] = ["driver-stats.json", "driver-stats.md", trilab::rows::FILE];

pub fn run(a: DriverStatsArgs) -> Result<()> {
    let exe = trilab::services::worker::this_exe()?;
    let ctx = a.gpu.context()?;
    let selection = Selection {
        kernels: a.kernels.clone(),
        variants: a.variants.clone(),
        methods: a.methods.or_device(&ctx),
        layouts: if a.layouts.is_empty() { Layout::ALL.to_vec() } else { a.layouts.clone() },
    };
    let kernels = selection.kernels()?;
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
