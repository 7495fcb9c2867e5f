//! `VK_KHR_pipeline_executable_properties`: the statistics a driver reports about the code it
//! compiled for a pipeline (registers, spills, instruction counts... whatever it chooses).
//!
//! Untested on lavapipe, which does not offer the extension: there the profile reports
//! "unsupported". The code follows the specification's query sequence and nothing else.

use ash::vk;
use serde::Serialize;

use crate::error::{Result, VkContext};
use crate::gpu::{Context, Kernel};

/// One statistic of one executable of a pipeline.
#[derive(Clone, Debug, Serialize)]
pub struct ExecutableStatistic {
    /// Index of the executable in the pipeline and its name, description and subgroup size.
    pub executable: u32,
    pub executable_name: String,
    pub executable_description: String,
    pub subgroup_size: u32,
    pub name: String,
    pub description: String,
    /// The value as the driver typed it (bool, signed, unsigned or float), as text.
    pub value: String,
}

fn text(s: std::result::Result<&std::ffi::CStr, std::ffi::FromBytesUntilNulError>) -> String {
    s.map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
}

/// Every statistic of every executable of `kernel`, which must have been created with
/// `PipelineOptions::capture_statistics` on a device with `pipeline_executable_properties`
/// enabled (the caller checks `Context::enabled`).
pub fn executable_statistics(ctx: &Context, kernel: &Kernel) -> Result<Vec<ExecutableStatistic>> {
    let loader = ash::khr::pipeline_executable_properties::Device::new(&ctx.device.instance, &ctx.device.raw);
    let pipeline_info = vk::PipelineInfoKHR::default().pipeline(kernel.pipeline);
    // SAFETY: the extension and pipelineExecutableInfo are enabled on this device (caller's
    // check) and the pipeline is alive for the call.
    let executables = unsafe { loader.get_pipeline_executable_properties(&pipeline_info) }
        .during("vkGetPipelineExecutablePropertiesKHR")?;
    let mut out = Vec::new();
    for (i, e) in executables.iter().enumerate() {
        let exec_info = vk::PipelineExecutableInfoKHR::default().pipeline(kernel.pipeline).executable_index(i as u32);
        // SAFETY: as above; the index is below the count the driver just returned, and the
        // pipeline was created with CAPTURE_STATISTICS.
        let stats = unsafe { loader.get_pipeline_executable_statistics(&exec_info) }
            .during("vkGetPipelineExecutableStatisticsKHR")?;
        for s in &stats {
            // SAFETY: `format` says which member of the value union the driver wrote.
            let value = unsafe {
                match s.format {
                    vk::PipelineExecutableStatisticFormatKHR::BOOL32 => (s.value.b32 != vk::FALSE).to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64.to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::UINT64 => s.value.u64.to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::FLOAT64 => s.value.f64.to_string(),
                    f => format!("(unknown format {f:?})"),
                }
            };
            out.push(ExecutableStatistic {
                executable: i as u32,
                executable_name: text(e.name_as_c_str()),
                executable_description: text(e.description_as_c_str()),
                subgroup_size: e.subgroup_size,
                name: text(s.name_as_c_str()),
                description: text(s.description_as_c_str()),
                value,
            });
        }
    }
    Ok(out)
}
