//! What a physical device offers: the driver, and the features trilab's profiling and later
//! kernels need. `trilab devices` prints this.

use std::ffi::CStr;

use ash::vk;
use serde::Serialize;

#[derive(Clone, Debug, Serialize)]
pub struct FloatControls {
    pub denorm_behavior_independence: String,
    pub rounding_mode_independence: String,
    pub signed_zero_inf_nan_preserve_f32: bool,
    pub signed_zero_inf_nan_preserve_f64: bool,
    pub denorm_preserve_f32: bool,
    pub denorm_flush_to_zero_f32: bool,
    pub rounding_mode_rte_f32: bool,
    pub rounding_mode_rtz_f32: bool,
}

/// `VkPhysicalDeviceRayTracingPipelinePropertiesKHR`: what the shader binding table and
/// `vkCmdTraceRaysKHR` of the ray-tracing-pipeline peer (`gpu::rtpipeline`) must respect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct RayTracingPipelineProperties {
    pub shader_group_handle_size: u32,
    pub shader_group_handle_alignment: u32,
    pub shader_group_base_alignment: u32,
    pub max_shader_group_stride: u32,
    pub max_ray_recursion_depth: u32,
    /// Most invocations (width x height x depth) one `vkCmdTraceRaysKHR` may launch.
    pub max_ray_dispatch_invocation_count: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct DeviceInfo {
    /// Index in `vkEnumeratePhysicalDevices` order (what `--device N` selects).
    pub index: usize,
    pub name: String,
    pub device_type: String,
    pub vendor_id: u32,
    pub device_id: u32,
    pub api_version: String,
    pub driver_id: String,
    pub driver_name: String,
    pub driver_info: String,
    /// Raw `driverVersion` (encoding is vendor-specific).
    pub driver_version: u32,
    /// "25.0.7" for Mesa drivers, parsed from `driver_info`.
    pub mesa_version: Option<String>,
    pub subgroup_size: u32,
    /// `subgroupSupportedOperations` (`VkSubgroupFeatureFlags` bits), 0 where compute shaders
    /// get none (`subgroupSupportedStages` without COMPUTE).
    pub subgroup_operations: u32,
    /// `VK_EXT_subgroup_size_control` (or Vulkan 1.3): (min, max) subgroup size.
    pub subgroup_size_control: Option<(u32, u32)>,
    pub compute_full_subgroups: bool,
    /// `requiredSubgroupSizeStages` includes COMPUTE: a compute pipeline may require a size.
    pub required_subgroup_size_compute: bool,
    /// `maxComputeWorkgroupSubgroups` (0 without subgroup size control).
    pub max_compute_workgroup_subgroups: u32,
    /// `VK_KHR_shader_clock`: (subgroup clock, device clock).
    pub shader_clock: Option<(bool, bool)>,
    /// Valid bits of timestamps on the compute queue (0: no timestamps).
    pub timestamp_valid_bits: u32,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period_ns: f32,
    pub pipeline_statistics_query: bool,
    /// `VK_KHR_ray_query` with `rayQuery` (and `VK_KHR_acceleration_structure`).
    pub ray_query: bool,
    /// `VK_KHR_ray_tracing_pipeline` with `rayTracingPipeline` (and
    /// `VK_KHR_acceleration_structure`): its properties; `None` without it.
    pub ray_tracing_pipeline: Option<RayTracingPipelineProperties>,
    /// `VK_KHR_pipeline_executable_properties` with `pipelineExecutableInfo`.
    pub pipeline_executable_properties: bool,
    pub shader_float64: bool,
    pub shader_int64: bool,
    /// Vulkan 1.2 `bufferDeviceAddress` (required: the kernels read scenes through it).
    pub buffer_device_address: bool,
    pub float_controls: FloatControls,
    pub max_storage_buffer_range: u32,
    pub max_texel_buffer_elements: u32,
    /// Vulkan 1.1 `maxMemoryAllocationSize`: the largest single allocation.
    pub max_memory_allocation_size: u64,
    /// `VK_KHR_maintenance4` `maxBufferSize` (`None` where the device lacks the extension).
    pub max_buffer_size: Option<u64>,
    /// Size of the largest DEVICE_LOCAL memory heap.
    pub device_local_heap_bytes: u64,
    /// `VK_EXT_memory_budget` is supported (a placement then reads the heap's current budget).
    pub memory_budget: bool,
    pub min_storage_buffer_offset_alignment: u64,
    pub max_compute_workgroup_invocations: u32,
    pub max_compute_workgroup_count: [u32; 3],
    pub max_compute_workgroup_size: [u32; 3],
    /// Queue family used for compute.
    pub compute_queue_family: Option<u32>,
    pub usable: bool,
    /// Why the device cannot be used, if it cannot.
    pub unusable_reason: Option<String>,
    /// Whether the device runs what it compiles ([`Execution`]).
    pub execution: Execution,
    /// On lavapipe: the CPU features its JIT compiles for (this host, less what
    /// `GALLIUM_OVERRIDE_CPU_CAPS` removes); `None` on other drivers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compiles_for: Option<super::LavapipeCpu>,
}

/// Whether a device runs kernels, or only compiles them.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Execution {
    /// It compiles and runs: every command may use it.
    Runs,
    /// It creates pipelines and reports what its compiler made of them, and executes nothing:
    /// any submission or wait would crash in the driver. Only commands that compile use it
    /// (`trilab driver-stats`, `trilab devices`); every other refuses it before any work.
    CompilesOnly {
        /// Why, in words.
        why: String,
    },
}

impl Execution {
    /// What a device of this name and driver does. The one compile-only device known is Mesa's
    /// RADV on its null winsys: `RADV_FORCE_FAMILY=<chip>` with no AMD GPU present makes a
    /// device named "Null hardware (RADV <CHIP>)" whose compiler is the real one (ACO, or LLVM
    /// under `RADV_DEBUG=llvm`) and whose command submission is not implemented
    /// (vkDeviceWaitIdle jumps to a null function: issue 50).
    pub fn of(name: &str, driver_id: &str) -> Execution {
        if driver_id == "MESA_RADV" && name.starts_with("Null hardware") {
            return Execution::CompilesOnly {
                why: "RADV's null device (RADV_FORCE_FAMILY without the GPU): it compiles for the chip with the \
                      real compiler and reports its statistics, but has no hardware to run on"
                    .into(),
            };
        }
        Execution::Runs
    }

    pub fn runs(&self) -> bool {
        matches!(self, Execution::Runs)
    }
}

fn cstr(bytes: &[std::ffi::c_char]) -> String {
    // SAFETY-free: Vulkan fixed-size strings are NUL-terminated; fall back to the whole array.
    let b: Vec<u8> = bytes.iter().map(|&c| c as u8).collect();
    CStr::from_bytes_until_nul(&b)
        .map(|c| c.to_string_lossy().into_owned())
        .unwrap_or_else(|_| String::from_utf8_lossy(&b).into_owned())
}

fn version(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

fn mesa_version(driver_info: &str) -> Option<String> {
    let rest = driver_info.split("Mesa ").nth(1)?;
    let v: String = rest.chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    (!v.is_empty()).then_some(v)
}

pub(crate) fn has_extension(exts: &[vk::ExtensionProperties], name: &CStr) -> bool {
    exts.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
}

/// Queries everything `DeviceInfo` reports.
///
/// # Safety
/// `instance` must be a live instance and `pd` one of its physical devices.
pub(crate) unsafe fn query(instance: &ash::Instance, pd: vk::PhysicalDevice, index: usize) -> DeviceInfo {
    let base = instance.get_physical_device_properties(pd);
    let exts = instance.enumerate_device_extension_properties(pd).unwrap_or_default();
    let api = base.api_version;
    let has = |n: &CStr| has_extension(&exts, n);
    let ext = Extensions::of(&exts, api);
    let Properties { v11, v12, ssc, m4, rtp: rtp_props } = Properties::query(instance, pd, api, &ext);
    let Features { clock, rq, rtp, pep, sscf, f12, features } = Features::query(instance, pd, api, &ext);
    let Extensions { ssc: has_ssc, m4: has_m4, rtp: has_rtp, clock: has_clock, rq: has_rq, pep: has_pep } = ext;
    let (compute_family, ts_bits) = compute_queue(instance, pd);

    let unusable_reason = if api < vk::API_VERSION_1_2 {
        Some(format!("Vulkan {} < 1.2", version(api)))
    } else if compute_family.is_none() {
        Some("no compute queue".into())
    } else {
        None
    };
    let driver_info = cstr(&v12.driver_info);
    let limits = base.limits;
    DeviceInfo {
        index,
        name: cstr(&base.device_name),
        device_type: format!("{:?}", base.device_type),
        vendor_id: base.vendor_id,
        device_id: base.device_id,
        api_version: version(api),
        driver_id: format!("{:?}", v12.driver_id),
        driver_name: cstr(&v12.driver_name),
        mesa_version: mesa_version(&driver_info),
        driver_info,
        driver_version: base.driver_version,
        subgroup_size: v11.subgroup_size,
        subgroup_operations: if v11.subgroup_supported_stages.contains(vk::ShaderStageFlags::COMPUTE) {
            v11.subgroup_supported_operations.as_raw()
        } else {
            0
        },
        subgroup_size_control: (has_ssc && sscf.subgroup_size_control == vk::TRUE)
            .then_some((ssc.min_subgroup_size, ssc.max_subgroup_size)),
        compute_full_subgroups: sscf.compute_full_subgroups == vk::TRUE,
        required_subgroup_size_compute: has_ssc
            && ssc.required_subgroup_size_stages.contains(vk::ShaderStageFlags::COMPUTE),
        max_compute_workgroup_subgroups: if has_ssc { ssc.max_compute_workgroup_subgroups } else { 0 },
        shader_clock: has_clock
            .then_some((clock.shader_subgroup_clock == vk::TRUE, clock.shader_device_clock == vk::TRUE)),
        timestamp_valid_bits: ts_bits,
        timestamp_period_ns: limits.timestamp_period,
        pipeline_statistics_query: features.pipeline_statistics_query == vk::TRUE,
        ray_query: has_rq && rq.ray_query == vk::TRUE,
        ray_tracing_pipeline: (has_rtp && rtp.ray_tracing_pipeline == vk::TRUE)
            .then(|| RayTracingPipelineProperties::of(&rtp_props)),
        pipeline_executable_properties: has_pep && pep.pipeline_executable_info == vk::TRUE,
        shader_float64: features.shader_float64 == vk::TRUE,
        shader_int64: features.shader_int64 == vk::TRUE,
        buffer_device_address: f12.buffer_device_address == vk::TRUE,
        float_controls: FloatControls::of(&v12),
        max_storage_buffer_range: limits.max_storage_buffer_range,
        max_texel_buffer_elements: limits.max_texel_buffer_elements,
        max_memory_allocation_size: v11.max_memory_allocation_size,
        max_buffer_size: has_m4.then_some(m4.max_buffer_size),
        device_local_heap_bytes: device_local_heap_bytes(instance, pd),
        memory_budget: has(ash::ext::memory_budget::NAME),
        min_storage_buffer_offset_alignment: limits.min_storage_buffer_offset_alignment,
        max_compute_workgroup_invocations: limits.max_compute_work_group_invocations,
        max_compute_workgroup_count: limits.max_compute_work_group_count,
        max_compute_workgroup_size: limits.max_compute_work_group_size,
        compute_queue_family: compute_family,
        usable: unusable_reason.is_none(),
        unusable_reason,
        execution: Execution::of(&cstr(&base.device_name), &format!("{:?}", v12.driver_id)),
        // lavapipe's JIT compiles for this CPU as Mesa sees it (gpu::lavapipe_cpu).
        compiles_for: (v12.driver_id == vk::DriverId::MESA_LLVMPIPE).then(super::LavapipeCpu::current).flatten(),
    }
}

/// The extensions whose properties or features [`query`] chains in.
#[derive(Clone, Copy)]
struct Extensions {
    /// `VK_EXT_subgroup_size_control`.
    ssc: bool,
    /// `VK_KHR_maintenance4`.
    m4: bool,
    /// `VK_KHR_ray_tracing_pipeline` and `VK_KHR_acceleration_structure`, on Vulkan 1.2.
    rtp: bool,
    /// `VK_KHR_shader_clock`.
    clock: bool,
    /// `VK_KHR_ray_query` and `VK_KHR_acceleration_structure`.
    rq: bool,
    /// `VK_KHR_pipeline_executable_properties`.
    pep: bool,
}

impl Extensions {
    fn of(exts: &[vk::ExtensionProperties], api: u32) -> Extensions {
        let has = |n: &CStr| has_extension(exts, n);
        Extensions {
            // trilab's instances ask for Vulkan 1.2, so a device's effective version is at most
            // 1.2 and subgroup size control needs the extension even where the device has
            // Vulkan 1.3.
            ssc: has(ash::ext::subgroup_size_control::NAME),
            m4: has(ash::khr::maintenance4::NAME),
            rtp: has(ash::khr::ray_tracing_pipeline::NAME)
                && has(ash::khr::acceleration_structure::NAME)
                && api >= vk::API_VERSION_1_2,
            clock: has(ash::khr::shader_clock::NAME),
            rq: has(ash::khr::ray_query::NAME) && has(ash::khr::acceleration_structure::NAME),
            pep: has(ash::khr::pipeline_executable_properties::NAME),
        }
    }
}

/// The property structures [`query`] reads (each left at its default where the device lacks
/// it, and all of them below Vulkan 1.2). Their `p_next` is not followed.
struct Properties {
    v11: vk::PhysicalDeviceVulkan11Properties<'static>,
    v12: vk::PhysicalDeviceVulkan12Properties<'static>,
    ssc: vk::PhysicalDeviceSubgroupSizeControlProperties<'static>,
    m4: vk::PhysicalDeviceMaintenance4Properties<'static>,
    rtp: vk::PhysicalDeviceRayTracingPipelinePropertiesKHR<'static>,
}

impl Properties {
    /// # Safety
    /// As [`query`].
    unsafe fn query(instance: &ash::Instance, pd: vk::PhysicalDevice, api: u32, ext: &Extensions) -> Properties {
        let mut v11 = vk::PhysicalDeviceVulkan11Properties::default();
        let mut v12 = vk::PhysicalDeviceVulkan12Properties::default();
        let mut ssc = vk::PhysicalDeviceSubgroupSizeControlProperties::default();
        let mut m4 = vk::PhysicalDeviceMaintenance4Properties::default();
        let mut rtp = vk::PhysicalDeviceRayTracingPipelinePropertiesKHR::default();
        let mut props2 = vk::PhysicalDeviceProperties2::default();
        if api >= vk::API_VERSION_1_2 {
            props2 = props2.push_next(&mut v11).push_next(&mut v12);
            if ext.ssc {
                props2 = props2.push_next(&mut ssc);
            }
            if ext.m4 {
                props2 = props2.push_next(&mut m4);
            }
            if ext.rtp {
                props2 = props2.push_next(&mut rtp);
            }
            instance.get_physical_device_properties2(pd, &mut props2);
        }
        Properties { v11, v12, ssc, m4, rtp }
    }
}

/// The feature structures [`query`] reads (each left at its default where the device lacks
/// it), and the core features. Their `p_next` is not followed.
struct Features {
    clock: vk::PhysicalDeviceShaderClockFeaturesKHR<'static>,
    rq: vk::PhysicalDeviceRayQueryFeaturesKHR<'static>,
    rtp: vk::PhysicalDeviceRayTracingPipelineFeaturesKHR<'static>,
    pep: vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR<'static>,
    sscf: vk::PhysicalDeviceSubgroupSizeControlFeatures<'static>,
    f12: vk::PhysicalDeviceVulkan12Features<'static>,
    features: vk::PhysicalDeviceFeatures,
}

impl Features {
    /// # Safety
    /// As [`query`].
    unsafe fn query(instance: &ash::Instance, pd: vk::PhysicalDevice, api: u32, ext: &Extensions) -> Features {
        let mut clock = vk::PhysicalDeviceShaderClockFeaturesKHR::default();
        let mut rq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
        let mut rtp = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default();
        let mut pep = vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default();
        let mut sscf = vk::PhysicalDeviceSubgroupSizeControlFeatures::default();
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default();
        if api >= vk::API_VERSION_1_2 {
            f2 = f2.push_next(&mut f12);
        }
        if ext.clock {
            f2 = f2.push_next(&mut clock);
        }
        if ext.rq {
            f2 = f2.push_next(&mut rq);
        }
        if ext.rtp {
            f2 = f2.push_next(&mut rtp);
        }
        if ext.pep {
            f2 = f2.push_next(&mut pep);
        }
        if ext.ssc {
            f2 = f2.push_next(&mut sscf);
        }
        instance.get_physical_device_features2(pd, &mut f2);
        let features = f2.features;
        Features { clock, rq, rtp, pep, sscf, f12, features }
    }
}

/// The queue family used for compute (a compute-only family first) and its timestamps' valid
/// bits (0 without one).
///
/// # Safety
/// As [`query`].
unsafe fn compute_queue(instance: &ash::Instance, pd: vk::PhysicalDevice) -> (Option<u32>, u32) {
    let families = instance.get_physical_device_queue_family_properties(pd);
    let compute_family = families
        .iter()
        .position(|f| {
            f.queue_flags.contains(vk::QueueFlags::COMPUTE) && !f.queue_flags.contains(vk::QueueFlags::GRAPHICS)
        })
        .or_else(|| families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)))
        .map(|i| i as u32);
    let ts_bits = compute_family.map(|f| families[f as usize].timestamp_valid_bits).unwrap_or(0);
    (compute_family, ts_bits)
}

/// The size of the largest DEVICE_LOCAL memory heap.
///
/// # Safety
/// As [`query`].
unsafe fn device_local_heap_bytes(instance: &ash::Instance, pd: vk::PhysicalDevice) -> u64 {
    let memory = instance.get_physical_device_memory_properties(pd);
    memory
        .memory_heaps_as_slice()
        .iter()
        .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .map(|h| h.size)
        .max()
        .unwrap_or(0)
}

impl FloatControls {
    fn of(v12: &vk::PhysicalDeviceVulkan12Properties) -> FloatControls {
        FloatControls {
            denorm_behavior_independence: format!("{:?}", v12.denorm_behavior_independence),
            rounding_mode_independence: format!("{:?}", v12.rounding_mode_independence),
            signed_zero_inf_nan_preserve_f32: v12.shader_signed_zero_inf_nan_preserve_float32 == vk::TRUE,
            signed_zero_inf_nan_preserve_f64: v12.shader_signed_zero_inf_nan_preserve_float64 == vk::TRUE,
            denorm_preserve_f32: v12.shader_denorm_preserve_float32 == vk::TRUE,
            denorm_flush_to_zero_f32: v12.shader_denorm_flush_to_zero_float32 == vk::TRUE,
            rounding_mode_rte_f32: v12.shader_rounding_mode_rte_float32 == vk::TRUE,
            rounding_mode_rtz_f32: v12.shader_rounding_mode_rtz_float32 == vk::TRUE,
        }
    }
}

impl RayTracingPipelineProperties {
    fn of(p: &vk::PhysicalDeviceRayTracingPipelinePropertiesKHR) -> RayTracingPipelineProperties {
        RayTracingPipelineProperties {
            shader_group_handle_size: p.shader_group_handle_size,
            shader_group_handle_alignment: p.shader_group_handle_alignment,
            shader_group_base_alignment: p.shader_group_base_alignment,
            max_shader_group_stride: p.max_shader_group_stride,
            max_ray_recursion_depth: p.max_ray_recursion_depth,
            max_ray_dispatch_invocation_count: p.max_ray_dispatch_invocation_count,
        }
    }
}

impl DeviceInfo {
    /// The driver and its version as users recognise it: "llvmpipe, Mesa 25.0.7".
    pub fn driver_label(&self) -> String {
        if self.driver_info.is_empty() {
            self.driver_name.clone()
        } else {
            format!("{} {}", self.driver_name, self.driver_info)
        }
    }

    /// The device's folder under `results/`: `lavapipe` or `swiftshader` for those drivers, else the device
    /// name in lower case with runs of other characters as `-` ("nvidia-h100-80gb-hbm3").
    pub fn results_dir(&self) -> String {
        if let Some(dir) = super::DriverKind::of(self).results_dir() {
            return dir.into();
        }
        let mut s = String::new();
        for c in self.name.to_lowercase().chars() {
            if c.is_ascii_alphanumeric() {
                s.push(c);
            } else if !s.ends_with('-') {
                s.push('-');
            }
        }
        s.trim_matches('-').to_owned()
    }

    /// Human-readable multi-line report (`trilab devices`).
    pub fn report(&self) -> String {
        let yn = |b: bool| if b { "yes" } else { "no" };
        let opt = |o: Option<String>| o.unwrap_or_else(|| "unsupported".into());
        let mut s = String::new();
        use std::fmt::Write;
        let _ = writeln!(s, "[{}] {} ({}, Vulkan {})", self.index, self.name, self.device_type, self.api_version);
        if let Some(r) = &self.unusable_reason {
            let _ = writeln!(s, "    not usable: {r}");
        }
        let _ =
            writeln!(s, "    driver:                   {} ({}) {}", self.driver_name, self.driver_id, self.driver_info);
        if let Some(cpu) = &self.compiles_for {
            let _ = writeln!(s, "    compiles for (CPU):       {}", cpu.summary());
        }
        let _ = writeln!(s, "    subgroup size:            {}", self.subgroup_size);
        let _ = writeln!(
            s,
            "    subgroup size control:    {}",
            opt(self.subgroup_size_control.map(|(a, b)| format!(
                "{a}..{b} (full subgroups: {}, compute may require a size: {})",
                yn(self.compute_full_subgroups),
                yn(self.required_subgroup_size_compute)
            )))
        );
        let _ = writeln!(
            s,
            "    shader clock:             {}",
            opt(self.shader_clock.map(|(sg, dev)| format!("subgroup {}, device {}", yn(sg), yn(dev))))
        );
        let _ = writeln!(
            s,
            "    timestamps (compute):     {}",
            if self.timestamp_valid_bits > 0 {
                format!("{} bits, {} ns/tick", self.timestamp_valid_bits, self.timestamp_period_ns)
            } else {
                "unsupported".into()
            }
        );
        let _ = writeln!(s, "    pipeline statistics:      {}", yn(self.pipeline_statistics_query));
        let _ = writeln!(s, "    ray query:                {}", yn(self.ray_query));
        let _ = writeln!(
            s,
            "    ray tracing pipeline:     {}",
            self.ray_tracing_pipeline.map_or_else(
                || "no".into(),
                |p| format!(
                    "yes (handle {} B, alignment {}, base {}, recursion <= {}, <= {} rays per launch)",
                    p.shader_group_handle_size,
                    p.shader_group_handle_alignment,
                    p.shader_group_base_alignment,
                    p.max_ray_recursion_depth,
                    p.max_ray_dispatch_invocation_count
                )
            )
        );
        let _ = writeln!(s, "    pipeline executable info: {}", yn(self.pipeline_executable_properties));
        let _ = writeln!(s, "    shaderFloat64/Int64:      {}/{}", yn(self.shader_float64), yn(self.shader_int64));
        let fc = &self.float_controls;
        let _ = writeln!(
            s,
            "    float controls (f32):     signed zero/inf/nan preserve {}, denorm preserve {}, flush {}, RTE {}, RTZ {}",
            yn(fc.signed_zero_inf_nan_preserve_f32),
            yn(fc.denorm_preserve_f32),
            yn(fc.denorm_flush_to_zero_f32),
            yn(fc.rounding_mode_rte_f32),
            yn(fc.rounding_mode_rtz_f32)
        );
        let _ = writeln!(
            s,
            "    maxStorageBufferRange:    {} bytes ({} MiB)",
            self.max_storage_buffer_range,
            self.max_storage_buffer_range >> 20
        );
        let _ = writeln!(s, "    maxTexelBufferElements:   {}", self.max_texel_buffer_elements);
        let _ = writeln!(s, "    maxMemoryAllocationSize:  {} MiB", self.max_memory_allocation_size >> 20);
        let _ = writeln!(
            s,
            "    maxBufferSize:            {}",
            opt(self.max_buffer_size.map(|b| format!("{} MiB", b >> 20)))
        );
        let _ = writeln!(
            s,
            "    device-local heap:        {} MiB (memory budget: {})",
            self.device_local_heap_bytes >> 20,
            yn(self.memory_budget)
        );
        let _ = writeln!(s, "    bufferDeviceAddress:      {}", yn(self.buffer_device_address));
        s
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn mesa_version_is_parsed() {
        assert_eq!(super::mesa_version("Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)").as_deref(), Some("25.0.7"));
        assert_eq!(super::mesa_version("535.104.05"), None);
    }

    #[test]
    fn radv_null_hardware_compiles_only() {
        use super::Execution;
        assert!(!Execution::of("Null hardware (RADV NAVI31)", "MESA_RADV").runs());
        assert!(!Execution::of("Null hardware (RADV PITCAIRN (LLVM 15.0.6))", "MESA_RADV").runs());
        assert!(Execution::of("AMD Radeon RX 7900 XTX (RADV NAVI31)", "MESA_RADV").runs());
        assert!(Execution::of("llvmpipe (LLVM 15.0.6, 256 bits)", "MESA_LLVMPIPE").runs());
    }
}
