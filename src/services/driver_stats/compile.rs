//! Kernels compiled for their statistics: each pipeline created once with
//! `VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR` and read back through
//! `VK_KHR_pipeline_executable_properties`, typed ([`crate::gpu::executable`]). Nothing is
//! dispatched, so a device that only compiles (RADV's null device) serves it: a GPU target's
//! worker answers [`crate::services::worker::Request::CompileKernels`] with it, and `trilab
//! driver-stats` on such a device (or on a GPU) calls it in-process.

use serde::Serialize;

use crate::error::{Error, Result};
use crate::gpu::amd::Chip;
use crate::gpu::executable::{self, CompilerStatistic};
use crate::gpu::{Context, PipelineOptions};
use crate::kernels::{KernelSource, KERNELS};
use crate::services::worker::protocol::{CompiledKernel, CompiledKernels};

use super::target::Compiler;

/// Where a kernel's statistics were compiled: the chip and compiler where the driver is RADV,
/// and the subgroup size its executable reports (what it was compiled at, whatever the device's
/// default or a driver variable says).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct CompiledFor {
    pub chip: Option<Chip>,
    pub compiler: Option<Compiler>,
    pub wave: u32,
}

impl CompiledFor {
    /// On the device named `device` (RADV's names carry the chip, and `(LLVM x)` under
    /// `RADV_DEBUG=llvm`), at `wave` lanes.
    pub fn of(device: &str, wave: u32) -> CompiledFor {
        let chip = Chip::of_device_name(device);
        CompiledFor { chip, compiler: chip.map(|_| Compiler::of_device_name(device)), wave }
    }

    /// The coordinates a row adds for it: `chip`, `compiler` (RADV only) and `wave`.
    pub fn coordinates(&self) -> Vec<(&'static str, String)> {
        let mut c = vec![];
        if let Some(chip) = self.chip {
            c.push(("chip", chip.name.to_owned()));
        }
        if let Some(compiler) = self.compiler {
            c.push(("compiler", compiler.to_string()));
        }
        c.push(("wave", self.wave.to_string()));
        c
    }

    /// `navi31 aco wave64`, or `wave32` alone.
    pub fn label(&self) -> String {
        let mut s = String::new();
        if let Some(chip) = self.chip {
            s.push_str(&format!("{chip} "));
        }
        if let Some(c) = self.compiler {
            s.push_str(&format!("{} ", c.to_string().to_uppercase()));
        }
        s.push_str(&format!("wave{}", self.wave));
        s
    }
}

/// The `requiredSubgroupSize` to create pipelines with so that they compile at `wanted` lanes
/// (`None` where the device's own size is `wanted` and it cannot require one); an error where the
/// device cannot compile at `wanted` at all.
pub fn required_size(ctx: &Context, wanted: Option<u32>) -> Result<Option<u32>> {
    let Some(w) = wanted else { return Ok(None) };
    let info = ctx.info();
    let controllable = ctx.enabled().subgroup_size_control
        && info.required_subgroup_size_compute
        && info.subgroup_size_control.is_some_and(|(lo, hi)| (lo..=hi).contains(&w));
    if controllable {
        Ok(Some(w))
    } else if info.subgroup_size == w {
        Ok(None)
    } else {
        Err(Error::Unsupported(format!(
            "{} cannot compile compute kernels at {w} lanes (its subgroup size is {}, size control {})",
            info.name,
            info.subgroup_size,
            info.subgroup_size_control.map_or("none".into(), |(lo, hi)| format!("{lo}..{hi}"))
        )))
    }
}

/// Compiles one kernel for its statistics: `Ok(Err(why))` where the device cannot compile it
/// (a feature it lacks, a subgroup size the kernel cannot run at), an error where compiling
/// failed otherwise.
pub fn compile_one(
    ctx: &Context,
    k: &'static KernelSource,
    required: Option<u32>,
) -> Result<std::result::Result<(u32, Vec<CompilerStatistic>), String>> {
    if let Err(u) = ctx.capabilities().kernel(k) {
        return Ok(Err(u.why));
    }
    let options = PipelineOptions { capture_statistics: true, required_subgroup_size: required, ..Default::default() };
    let kernel = match ctx.create_kernel_with(k, &options) {
        Ok(kernel) => kernel,
        Err(Error::Unsupported(why)) => return Ok(Err(why)),
        Err(e) => return Err(e),
    };
    let stats = executable::executable_statistics(ctx, &kernel)?;
    let wave = stats.first().map_or(0, |s| s.subgroup_size);
    if let Some(r) = required.filter(|&r| r != wave) {
        return Err(Error::Unsupported(format!(
            "{}: asked to compile at {r} lanes (requiredSubgroupSize), the driver reports {wave}",
            k.name
        )));
    }
    Ok(Ok((wave, executable::typed(&stats))))
}

/// A [`crate::services::worker::Request::CompileKernels`]'s answer: each named kernel compiled on
/// `ctx` at `subgroup_size` lanes, or the reason it is not.
pub fn compile_kernels(ctx: &Context, names: &[String], subgroup_size: Option<u32>) -> Result<CompiledKernels> {
    if !ctx.enabled().pipeline_executable_properties {
        return Err(Error::Unsupported(format!(
            "{}: the driver reports no statistics (VK_KHR_pipeline_executable_properties is not enabled)",
            ctx.info().name
        )));
    }
    let required = required_size(ctx, subgroup_size)?;
    let mut kernels = vec![];
    for n in names {
        let k = KERNELS
            .iter()
            .find(|k| k.name == n)
            .ok_or_else(|| Error::Usage(format!("compile-kernels: no kernel {n} in this build")))?;
        kernels.push(match compile_one(ctx, k, required)? {
            Ok((wave, statistics)) => {
                CompiledKernel { name: n.clone(), subgroup_size: wave, statistics, refused: None }
            }
            Err(why) => CompiledKernel {
                name: n.clone(),
                subgroup_size: subgroup_size.unwrap_or(0),
                statistics: vec![],
                refused: Some(why),
            },
        });
    }
    let info = ctx.info();
    Ok(CompiledKernels {
        device: info.name.clone(),
        driver: info.driver_label(),
        driver_info: info.driver_info.clone(),
        mesa_version: info.mesa_version.clone(),
        kernels,
    })
}
