//! Instance, device, queue, allocator and the validation-message log, torn down in reverse
//! order of creation after `vkDeviceWaitIdle`.
//!
//! Everything that owns a Vulkan object holds an `Arc<Device>`, so the device (and the
//! instance inside it) can only be destroyed after the last buffer, pipeline or query pool.

use crate::spirv::Feature;
use std::ffi::{c_void, CStr, CString};
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::device_info::{self, DeviceInfo};
use super::markers::{Fault, Markers};
use crate::error::{Error, Result, VkContext};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Whether to load the Khronos validation layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Validation {
    Off,
    /// Load it when installed (the default in debug builds).
    IfAvailable,
    /// Fail when it is not installed (tests).
    Required,
}

#[derive(Clone, Debug)]
pub struct ContextOptions {
    /// Device index or a case-insensitive part of its name or driver; `None` picks a discrete
    /// GPU if there is one, else the best other device (lavapipe on a CPU-only machine).
    pub device: Option<String>,
    pub validation: Validation,
    /// Longest a single submit may run before its wait fails.
    pub submit_timeout: Duration,
    /// Enable ray query where the device has it (default); `false` leaves it off, as on a
    /// device without it (tests of the "unsupported" path).
    pub ray_query: bool,
    /// Enable the ray tracing pipeline where the device has it (default); `false` leaves it
    /// off, as on a device without it (tests of the "unsupported" path).
    pub ray_tracing_pipeline: bool,
    /// Enable `shaderFloat64` where the device has it (default); `false` leaves it off, as on a
    /// device without it (tests of the f64 kernel's "unsupported" path).
    pub shader_float64: bool,
    /// A fault to inject (tests of the device-loss and out-of-memory paths; see
    /// `gpu::markers`). `Context::new` also reads `TRILAB_INJECT_FAULT` when this is `None`.
    pub inject_fault: Option<Fault>,
    /// Device limits lowered for tests, as `TRILAB_TEST_LIMITS` gives them
    /// (`encoding::DeviceLimits::with_overrides`): every memory placement on this context is checked
    /// against them. `Context::new` reads the variable when this is `None`.
    pub test_limits: Option<String>,
    /// Enable only what one kernel needs (`trilab repro`: a capture whose `vkCreateDevice`
    /// replays on any device that can run the kernel): none of the optional features above but
    /// those in [`Needs`]; `None` enables every one the device has.
    pub only: Option<Needs>,
    /// What the command will do with the device: run kernels (the default), or only compile
    /// them, which a compile-only device ([`super::device_info::Execution::CompilesOnly`])
    /// allows.
    pub purpose: Purpose,
}

/// What a command does with its device.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Purpose {
    /// It runs kernels: a device that only compiles is refused when the context is made,
    /// before any work.
    #[default]
    Run,
    /// It creates pipelines and reads what the driver made of them, and submits nothing.
    Compile,
}

/// What one kernel needs of a device beyond Vulkan 1.2's core: the features its SPIR-V
/// capabilities name, and full subgroups (`computeFullSubgroups`) for a kernel that hands work
/// to lanes by index ([`crate::spirv::reflect::reads_subgroup_lanes`]).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Needs {
    pub features: Vec<Feature>,
    pub full_subgroups: bool,
}

impl Default for ContextOptions {
    fn default() -> Self {
        ContextOptions {
            device: None,
            validation: if cfg!(debug_assertions) { Validation::IfAvailable } else { Validation::Off },
            submit_timeout: Duration::from_secs(120),
            ray_query: true,
            ray_tracing_pipeline: true,
            shader_float64: true,
            inject_fault: None,
            test_limits: None,
            only: None,
            purpose: Purpose::Run,
        }
    }
}

/// Messages from the validation layer (warnings and errors), collected by the debug-utils
/// callback. Tests fail if any arrive.
#[derive(Debug, Default)]
pub struct ValidationLog {
    messages: Mutex<Vec<String>>,
}

impl ValidationLog {
    pub fn messages(&self) -> Vec<String> {
        self.messages.lock().unwrap().clone()
    }

    fn push(&self, m: String) {
        self.messages.lock().unwrap().push(m);
    }
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    ty: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: `user` is the `ValidationLog` behind an Arc that `Device` keeps alive until after
    // the messenger is destroyed; `data` is valid for the duration of the call (Vulkan spec).
    let log = &*(user as *const ValidationLog);
    let msg = if data.is_null() {
        "<no data>".to_owned()
    } else {
        let d = &*data;
        let id = d.message_id_name_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
        let text = d.message_as_c_str().map(|c| c.to_string_lossy().into_owned()).unwrap_or_default();
        format!("[{severity:?} {ty:?}] {id}: {text}")
    };
    log.push(msg);
    vk::FALSE
}

/// The shared Vulkan objects. Dropped last, when nothing else refers to it.
/// Optional device features trilab enables when the device has them. Anything that needs one
/// checks here and reports "unsupported" when it is off, never a fallback that pretends.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct EnabledFeatures {
    pub pipeline_statistics_query: bool,
    /// `VK_KHR_shader_clock` with `shaderSubgroupClock`.
    pub shader_clock: bool,
    /// `VK_EXT_subgroup_size_control` (core in 1.3) with `subgroupSizeControl`.
    pub subgroup_size_control: bool,
    /// `VK_KHR_pipeline_executable_properties` with `pipelineExecutableInfo`.
    pub pipeline_executable_properties: bool,
    /// `VK_KHR_ray_query` + `VK_KHR_acceleration_structure` (+ deferred host operations and
    /// `bufferDeviceAddress`, which acceleration structures need).
    pub ray_query: bool,
    /// `VK_KHR_ray_tracing_pipeline` with `rayTracingPipeline` + `VK_KHR_acceleration_structure`
    /// (+ deferred host operations and `bufferDeviceAddress`), independent of ray query: NVIDIA's
    /// datacenter GPUs (H100, H200) have the pipeline but no ray query.
    pub ray_tracing_pipeline: bool,
    pub shader_float64: bool,
    pub shader_int64: bool,
    /// Vulkan 1.2 `bufferDeviceAddress`: enabled wherever the device has it (ray query and the
    /// raycast kernels' `*_address` variants, which read scenes beyond one binding's limit, need it).
    pub buffer_device_address: bool,
}

impl EnabledFeatures {
    /// Whether `feature` (one a SPIR-V capability needs) is enabled.
    pub fn has(&self, feature: Feature) -> bool {
        match feature {
            Feature::ShaderFloat64 => self.shader_float64,
            Feature::ShaderInt64 => self.shader_int64,
            Feature::ShaderSubgroupClock => self.shader_clock,
            Feature::RayQuery => self.ray_query,
            Feature::RayTracingPipeline => self.ray_tracing_pipeline,
            Feature::BufferDeviceAddress => self.buffer_device_address,
        }
    }

    /// Whether `VK_KHR_acceleration_structure` is on: the driver's BLAS/TLAS
    /// (`gpu::AccelStructure`), which both ray query and the ray tracing pipeline trace.
    pub fn acceleration_structure(&self) -> bool {
        self.ray_query || self.ray_tracing_pipeline
    }

    /// Of these, only what `needs` asks for (the rest off, as on a device without them).
    pub fn only(self, needs: &Needs) -> EnabledFeatures {
        let wants = |f: Feature| needs.features.contains(&f);
        let ray_query = self.ray_query && wants(Feature::RayQuery);
        let ray_tracing_pipeline = self.ray_tracing_pipeline && wants(Feature::RayTracingPipeline);
        EnabledFeatures {
            pipeline_statistics_query: false,
            shader_clock: self.shader_clock && wants(Feature::ShaderSubgroupClock),
            subgroup_size_control: self.subgroup_size_control && needs.full_subgroups,
            pipeline_executable_properties: false,
            ray_query,
            ray_tracing_pipeline,
            shader_float64: self.shader_float64 && wants(Feature::ShaderFloat64),
            shader_int64: self.shader_int64 && wants(Feature::ShaderInt64),
            buffer_device_address: self.buffer_device_address
                && (wants(Feature::BufferDeviceAddress) || ray_query || ray_tracing_pipeline),
        }
    }

    pub fn for_device(info: &DeviceInfo) -> EnabledFeatures {
        EnabledFeatures {
            pipeline_statistics_query: info.pipeline_statistics_query,
            shader_clock: info.shader_clock.is_some_and(|(subgroup, _)| subgroup),
            subgroup_size_control: info.subgroup_size_control.is_some(),
            pipeline_executable_properties: info.pipeline_executable_properties,
            ray_query: info.ray_query && info.buffer_device_address,
            ray_tracing_pipeline: info.ray_tracing_pipeline.is_some() && info.buffer_device_address,
            shader_float64: info.shader_float64,
            shader_int64: info.shader_int64,
            buffer_device_address: info.buffer_device_address,
        }
    }
}

pub struct Device {
    _entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) raw: ash::Device,
    pub(crate) queue: vk::Queue,
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    pub(crate) command_pool: Mutex<vk::CommandPool>,
    pub(crate) info: DeviceInfo,
    pub(crate) enabled: EnabledFeatures,
    pub(crate) submit_timeout: Duration,
    pub(crate) markers: Markers,
    /// `ContextOptions::test_limits` (or `TRILAB_TEST_LIMITS`), applied by `Context::limits`.
    pub(crate) test_limits: Option<String>,
    sync_validation: bool,
    log: Arc<ValidationLog>,
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: every object created from this device holds an Arc<Device>, so none is alive
        // now; we wait for the queue to drain, then destroy in reverse order of creation:
        // command pool, allocator memory, device, debug messenger, instance. A device that only
        // compiles was never submitted to, and waiting on it would crash in its driver (RADV's
        // null winsys implements no wait).
        unsafe {
            if self.info.execution.runs() {
                let _ = self.raw.device_wait_idle();
            }
            self.raw.destroy_command_pool(*self.command_pool.get_mut().unwrap(), None);
            if let Ok(a) = self.allocator.get_mut() {
                self.markers.destroy(&self.raw, a);
            }
            ManuallyDrop::drop(&mut self.allocator);
            self.raw.destroy_device(None);
            if let Some((loader, messenger)) = self.debug.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// Lowers the device's limits for tests (`DeviceLimits::with_overrides`): for example
/// `TRILAB_TEST_LIMITS=max_texel_buffer_elements=4096` makes every scene of more than 4096 texels
/// per buffer take the address path, in every command.
pub const TEST_LIMITS_VAR: &str = "TRILAB_TEST_LIMITS";

/// The kernels a context created, by variant name and specialisation constants: each is compiled
/// once per context (`Context::kernel`; creating a pipeline runs the driver's compiler, a fraction
/// of a second on lavapipe). The pipelines are `gpu::Kernel`s, kept type-erased here so that the
/// context does not depend on the module that builds them.
pub(crate) type KernelCache = Mutex<std::collections::HashMap<KernelKey, Arc<dyn std::any::Any + Send + Sync>>>;

/// A kernel variant's name and its specialisation constants.
pub(crate) type KernelKey = (&'static str, Vec<(u32, u32)>);

/// Entry point to the GPU: a chosen device with one compute queue, and the kernels created on it
/// so far (each variant and set of specialisation constants is compiled once per context).
#[derive(Clone)]
pub struct Context {
    /// Declared before `device`: dropped first, so the cached pipelines go before the device.
    pub(crate) kernels: Arc<KernelCache>,
    pub(crate) device: Arc<Device>,
}

impl Context {
    pub fn new(options: &ContextOptions) -> Result<Context> {
        let fault = match options.inject_fault {
            Some(f) => Some(f),
            None => Fault::from_env()?,
        };
        // SAFETY: loading the Vulkan loader library runs its initialisers; it is the system's
        // libvulkan.so.1.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| Error::Loader(e.to_string()))?;
        let log = Arc::new(ValidationLog::default());
        let (guard, sync_validation) = InstanceGuard::create(&entry, options.validation, &log)?;

        let instance = guard.instance();
        // SAFETY: valid instance.
        let physicals = unsafe { instance.enumerate_physical_devices() }.during("vkEnumeratePhysicalDevices")?;
        let infos: Vec<DeviceInfo> =
            physicals.iter().enumerate().map(|(i, &pd)| unsafe { device_info::query(instance, pd, i) }).collect();
        let chosen = choose_device(&infos, options.device.as_deref())?;
        let info = infos[chosen].clone();
        // A command that runs kernels asks the device's capabilities whether it runs any, before
        // the device is even created (a device that only compiles would crash at its first wait).
        if options.purpose == Purpose::Run {
            let features = EnabledFeatures::for_device(&info);
            if let Err(u) = super::Capabilities::new(&info, &features).runs() {
                return Err(Error::Unsupported(format!(
                    "device [{chosen}] {}: {}: this command runs kernels, so it cannot use it; `trilab driver-stats` \
                     compiles every kernel there and reports the driver's statistics",
                    u.device, u.why
                )));
            }
        }
        let physical = physicals[chosen];
        let queue_family = info.compute_queue_family.expect("usable device has a compute queue");

        let (raw, enabled) = create_device(instance, physical, &info, options)?;
        // SAFETY: queue family and index 0 were requested by create_device.
        let queue = unsafe { raw.get_device_queue(queue_family, 0) };
        let (command_pool, mut allocator) =
            create_pool_and_allocator(instance, &raw, physical, queue_family, &enabled)?;
        let markers = Markers::new(&raw, &mut allocator, fault);
        let (instance, debug) = guard.release();
        Ok(Context {
            kernels: Arc::default(),
            device: Arc::new(Device {
                _entry: entry,
                instance,
                debug,
                physical,
                raw,
                queue,
                allocator: ManuallyDrop::new(Mutex::new(allocator)),
                command_pool: Mutex::new(command_pool),
                info,
                enabled,
                submit_timeout: options.submit_timeout,
                markers,
                test_limits: options.test_limits.clone().or_else(|| std::env::var(TEST_LIMITS_VAR).ok()),
                sync_validation,
                log,
            }),
        })
    }

    /// Every device the loader reports, usable or not (`trilab devices`).
    pub fn list_devices() -> Result<Vec<DeviceInfo>> {
        let entry = unsafe { ash::Entry::load() }.map_err(|e| Error::Loader(e.to_string()))?;
        let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_2);
        let create = vk::InstanceCreateInfo::default().application_info(&app);
        // SAFETY: minimal instance, destroyed below.
        let instance = unsafe { entry.create_instance(&create, None) }.during("vkCreateInstance")?;
        let guard = InstanceGuard { instance: Some(instance), debug: None };
        let physicals =
            unsafe { guard.instance().enumerate_physical_devices() }.during("vkEnumeratePhysicalDevices")?;
        Ok(physicals
            .iter()
            .enumerate()
            .map(|(i, &pd)| unsafe { device_info::query(guard.instance(), pd, i) })
            .collect())
    }

    /// The crash markers and fault injection (`gpu::markers`).
    pub(crate) fn markers(&self) -> &Markers {
        &self.device.markers
    }

    /// Arms `fault` (counting submits and allocations from now), or disarms with `None`.
    pub fn inject_fault(&self, fault: Option<Fault>) {
        self.markers().inject_fault(fault)
    }

    /// Whether the GPU breadcrumb buffer exists (it does wherever there is host-visible memory).
    pub fn markers_active(&self) -> bool {
        self.markers().markers_active()
    }

    /// Turns a device loss or an out-of-memory error into `Error::GpuFault` naming the
    /// dispatches involved; any other error is returned as it is.
    pub fn fault(&self, e: Error) -> Error {
        self.markers().fault(e)
    }

    /// "last dispatch begun: ...; last completed: ..." from the markers, or the host log.
    pub fn marker_report(&self) -> String {
        self.markers().marker_report()
    }

    /// Records "dispatch `id` begun" into `cmd` and logs `description`; returns the id for
    /// [`Context::mark_end`].
    ///
    /// # Safety
    /// As [`Markers::mark_begin`].
    pub(crate) unsafe fn mark_begin(&self, d: &ash::Device, cmd: vk::CommandBuffer, description: String) -> u32 {
        // SAFETY: the caller keeps mark_begin's contract.
        unsafe { self.markers().mark_begin(d, cmd, description) }
    }

    /// Records "dispatch `id` done" after everything recorded before it in `cmd`.
    ///
    /// # Safety
    /// As [`Markers::mark_begin`].
    pub(crate) unsafe fn mark_end(&self, d: &ash::Device, cmd: vk::CommandBuffer, id: u32) {
        // SAFETY: the caller keeps mark_end's contract.
        unsafe { self.markers().mark_end(d, cmd, id) }
    }

    /// Forgets the dispatches recorded in command buffers being freed.
    pub(crate) fn forget_command_buffers(&self, cmds: &[vk::CommandBuffer]) {
        self.markers().forget_command_buffers(cmds)
    }

    /// Logs a submit of `cmd` (`what`) and injects the armed fault when its turn comes.
    pub(crate) fn before_submit(&self, cmd: vk::CommandBuffer, what: &str) -> Result<()> {
        self.markers().before_submit(cmd, what)
    }

    /// Logs a submit that finished.
    pub(crate) fn after_submit(&self, what: &str) {
        self.markers().after_submit(what)
    }

    /// Counts an allocation named `name` and injects the armed allocation fault.
    pub(crate) fn before_allocation(&self, name: &str) -> Result<()> {
        self.markers().before_allocation(name)
    }

    pub fn info(&self) -> &DeviceInfo {
        &self.device.info
    }

    /// The optional features this context enabled.
    pub fn enabled(&self) -> &EnabledFeatures {
        &self.device.enabled
    }

    /// Validation-layer warnings and errors so far (empty when the layer is off).
    pub fn validation_messages(&self) -> Vec<String> {
        self.device.log.messages()
    }

    /// The log itself, which outlives the context (teardown messages land there too).
    pub fn validation_log(&self) -> Arc<ValidationLog> {
        self.device.log.clone()
    }

    pub fn validation_enabled(&self) -> bool {
        self.device.debug.is_some()
    }

    /// Whether synchronization validation is on (with the layer, wherever it offers
    /// VK_EXT_validation_features).
    pub fn sync_validation_enabled(&self) -> bool {
        self.device.sync_validation
    }
}

/// Destroys a half-built instance if context creation fails part-way.
struct InstanceGuard {
    instance: Option<ash::Instance>,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
}

impl InstanceGuard {
    /// Creates the Vulkan 1.2 instance, with the validation layer as `validation` asks. With the
    /// layer on: synchronization validation where the layer offers it, and a debug messenger
    /// that records warnings and errors in `log`. Returns whether synchronization validation is
    /// on.
    fn create(entry: &ash::Entry, validation: Validation, log: &Arc<ValidationLog>) -> Result<(InstanceGuard, bool)> {
        // SAFETY: plain queries on a loaded entry.
        let layers = unsafe { entry.enumerate_instance_layer_properties() }.during("enumerating instance layers")?;
        let have_validation = layers.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
        let want_validation = match validation {
            Validation::Off => false,
            Validation::IfAvailable => have_validation,
            Validation::Required if !have_validation => {
                return Err(Error::NoDevice(
                    "the Vulkan validation layer (VK_LAYER_KHRONOS_validation) is required but not installed; \
                     install vulkan-validationlayers (scripts/install-deps.sh)"
                        .into(),
                ))
            }
            Validation::Required => true,
        };
        let exts =
            unsafe { entry.enumerate_instance_extension_properties(None) }.during("enumerating instance extensions")?;
        let have_debug_utils = device_info::has_extension(&exts, ash::ext::debug_utils::NAME);

        let app_name = CString::new("trilab").unwrap();
        let app = vk::ApplicationInfo::default()
            .application_name(&app_name)
            .application_version(vk::make_api_version(0, 0, 1, 0))
            .engine_name(&app_name)
            .api_version(vk::API_VERSION_1_2);
        let layer_ptrs: Vec<*const std::ffi::c_char> =
            if want_validation { vec![VALIDATION_LAYER.as_ptr()] } else { vec![] };
        let use_debug = want_validation && have_debug_utils;
        let mut ext_ptrs: Vec<*const std::ffi::c_char> =
            if use_debug { vec![ash::ext::debug_utils::NAME.as_ptr()] } else { vec![] };
        // Synchronization validation whenever the layer is on, through VK_EXT_validation_features
        // (the layer provides the extension; VK_EXT_layer_settings is newer than the 1.3.239
        // layer Debian 12 ships). GPU-assisted validation and best practices stay off: the
        // first instruments every kernel (slow on a CPU driver), the second warns about choices
        // made on purpose (one small allocation per buffer in tests, say).
        let sync_validation = want_validation && {
            // SAFETY: plain query on a loaded entry.
            let layer_exts = unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                .during("enumerating the validation layer's extensions")?;
            device_info::has_extension(&layer_exts, ash::ext::validation_features::NAME)
        };
        if sync_validation {
            ext_ptrs.push(ash::ext::validation_features::NAME.as_ptr());
        }
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        // The callback writes to `log` through this pointer; the Arc outlives the instance
        // (Device keeps it, and drops the instance first).
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback))
            .user_data(Arc::as_ptr(log) as *mut c_void);
        let mut create = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layer_ptrs)
            .enabled_extension_names(&ext_ptrs);
        if use_debug {
            // Also catches messages from vkCreateInstance/vkDestroyInstance themselves.
            create = create.push_next(&mut messenger_info);
        }
        if sync_validation {
            create = create.push_next(&mut features);
        }
        // SAFETY: the create info and everything it points to live until the call returns.
        let instance = unsafe { entry.create_instance(&create, None) }.during("vkCreateInstance")?;
        let mut guard = InstanceGuard { instance: Some(instance), debug: None };

        if use_debug {
            let loader = ash::ext::debug_utils::Instance::new(entry, guard.instance());
            // SAFETY: valid instance with the debug-utils extension enabled.
            let messenger = unsafe { loader.create_debug_utils_messenger(&messenger_info, None) }
                .during("vkCreateDebugUtilsMessengerEXT")?;
            guard.debug = Some((loader, messenger));
        }
        Ok((guard, sync_validation))
    }

    fn instance(&self) -> &ash::Instance {
        self.instance.as_ref().unwrap()
    }

    #[allow(clippy::type_complexity)]
    fn release(mut self) -> (ash::Instance, Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>) {
        (self.instance.take().unwrap(), self.debug.take())
    }
}

impl Drop for InstanceGuard {
    fn drop(&mut self) {
        // SAFETY: only reached on an error path, before any device was kept.
        unsafe {
            if let Some((loader, m)) = self.debug.take() {
                loader.destroy_debug_utils_messenger(m, None);
            }
            if let Some(i) = self.instance.take() {
                i.destroy_instance(None);
            }
        }
    }
}

/// Creates the logical device on `physical` with one queue of its compute family and the
/// optional features the profiling, ray-query, ray-tracing-pipeline and f64 kernels use, wherever the device has them
/// (`info` says which) and `options` allow; returns the device and what is on.
fn create_device(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    info: &DeviceInfo,
    options: &ContextOptions,
) -> Result<(ash::Device, EnabledFeatures)> {
    let queue_family = info.compute_queue_family.expect("usable device has a compute queue");
    let priorities = [1.0f32];
    let queue_info =
        [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
    let mut enabled = EnabledFeatures::for_device(info);
    enabled.ray_query &= options.ray_query;
    enabled.ray_tracing_pipeline &= options.ray_tracing_pipeline;
    enabled.shader_float64 &= options.shader_float64;
    if let Some(needs) = &options.only {
        enabled = enabled.only(needs);
    }
    let mut ext_names: Vec<*const std::ffi::c_char> = Vec::new();
    let core = vk::PhysicalDeviceFeatures::default()
        .pipeline_statistics_query(enabled.pipeline_statistics_query)
        .shader_float64(enabled.shader_float64)
        .shader_int64(enabled.shader_int64);
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(enabled.buffer_device_address);
    let mut clock = vk::PhysicalDeviceShaderClockFeaturesKHR::default().shader_subgroup_clock(true);
    let mut ssc = vk::PhysicalDeviceSubgroupSizeControlFeatures::default()
        .subgroup_size_control(true)
        .compute_full_subgroups(info.compute_full_subgroups);
    let mut pep = vk::PhysicalDevicePipelineExecutablePropertiesFeaturesKHR::default().pipeline_executable_info(true);
    let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
    let mut rq = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
    let mut rtp = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default().ray_tracing_pipeline(true);
    let mut features2 = vk::PhysicalDeviceFeatures2::default().features(core).push_next(&mut f12);
    if enabled.shader_clock {
        ext_names.push(ash::khr::shader_clock::NAME.as_ptr());
        features2 = features2.push_next(&mut clock);
    }
    // The instance asks for Vulkan 1.2, so this is the extension even on a 1.3 device.
    if enabled.subgroup_size_control {
        ext_names.push(ash::ext::subgroup_size_control::NAME.as_ptr());
        features2 = features2.push_next(&mut ssc);
    }
    if enabled.pipeline_executable_properties {
        ext_names.push(ash::khr::pipeline_executable_properties::NAME.as_ptr());
        features2 = features2.push_next(&mut pep);
    }
    // Either way of tracing needs the acceleration structures (and they need deferred host
    // operations); each adds its own extension and feature.
    if enabled.acceleration_structure() {
        ext_names.push(ash::khr::acceleration_structure::NAME.as_ptr());
        ext_names.push(ash::khr::deferred_host_operations::NAME.as_ptr());
        features2 = features2.push_next(&mut accel);
    }
    if enabled.ray_query {
        ext_names.push(ash::khr::ray_query::NAME.as_ptr());
        features2 = features2.push_next(&mut rq);
    }
    if enabled.ray_tracing_pipeline {
        ext_names.push(ash::khr::ray_tracing_pipeline::NAME.as_ptr());
        features2 = features2.push_next(&mut rtp);
    }
    let device_create = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queue_info)
        .enabled_extension_names(&ext_names)
        .push_next(&mut features2);
    // SAFETY: physical device from this instance; create info valid for the call.
    let raw = unsafe { instance.create_device(physical, &device_create, None) }.during("vkCreateDevice")?;
    Ok((raw, enabled))
}

/// The command pool (resettable buffers, on `queue_family`) and the memory allocator of `raw`.
/// On failure it destroys what it created and the device itself, which nothing else owns yet.
fn create_pool_and_allocator(
    instance: &ash::Instance,
    raw: &ash::Device,
    physical: vk::PhysicalDevice,
    queue_family: u32,
    enabled: &EnabledFeatures,
) -> Result<(vk::CommandPool, Allocator)> {
    let pool_info = vk::CommandPoolCreateInfo::default()
        .queue_family_index(queue_family)
        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
    // SAFETY: valid device and create info; on failure the device is destroyed with nothing
    // created from it left.
    let command_pool = match unsafe { raw.create_command_pool(&pool_info, None) } {
        Ok(p) => p,
        Err(e) => {
            unsafe { raw.destroy_device(None) };
            return Err(e).during("vkCreateCommandPool");
        }
    };
    let allocator = match Allocator::new(&AllocatorCreateDesc {
        instance: instance.clone(),
        device: raw.clone(),
        physical_device: physical,
        debug_settings: Default::default(),
        buffer_device_address: enabled.buffer_device_address,
        allocation_sizes: Default::default(),
    }) {
        Ok(a) => a,
        Err(source) => {
            // SAFETY: the pool is unused, and the device has nothing else created from it.
            unsafe {
                raw.destroy_command_pool(command_pool, None);
                raw.destroy_device(None);
            }
            return Err(Error::Allocation { name: "allocator".into(), source });
        }
    };
    Ok((command_pool, allocator))
}

/// Picks the device: by `--device` (index or name/driver substring), else discrete GPU >
/// integrated > virtual > CPU > other, lowest index first, every device that runs kernels before
/// any that only compiles.
pub fn choose_device(infos: &[DeviceInfo], wanted: Option<&str>) -> Result<usize> {
    let list = || {
        infos.iter().map(|d| format!("  [{}] {} ({})", d.index, d.name, d.driver_name)).collect::<Vec<_>>().join("\n")
    };
    if infos.is_empty() {
        return Err(Error::NoDevice(
            "no Vulkan device found; on a machine without a GPU install Mesa's lavapipe \
             (mesa-vulkan-drivers, see scripts/install-deps.sh)"
                .into(),
        ));
    }
    let pick = |i: usize| -> Result<usize> {
        match &infos[i].unusable_reason {
            None => Ok(i),
            Some(r) => Err(Error::NoDevice(format!("device [{i}] {} cannot be used: {r}", infos[i].name))),
        }
    };
    if let Some(w) = wanted {
        if let Ok(i) = w.parse::<usize>() {
            return if i < infos.len() {
                pick(i)
            } else {
                Err(Error::NoDevice(format!("no device with index {i}; devices:\n{}", list())))
            };
        }
        let lw = w.to_lowercase();
        return match infos.iter().position(|d| {
            d.name.to_lowercase().contains(&lw)
                || d.driver_name.to_lowercase().contains(&lw)
                || d.driver_id.to_lowercase().contains(&lw)
        }) {
            Some(i) => pick(i),
            None => Err(Error::NoDevice(format!("no device matches `{w}`; devices:\n{}", list()))),
        };
    }
    // A device that only compiles comes after every device that runs.
    let rank = |d: &DeviceInfo| {
        let kind = match d.device_type.as_str() {
            "DISCRETE_GPU" => 0,
            "INTEGRATED_GPU" => 1,
            "VIRTUAL_GPU" => 2,
            "CPU" => 3,
            _ => 4,
        };
        (!d.execution.runs(), kind)
    };
    infos.iter().filter(|d| d.usable).min_by_key(|d| (rank(d), d.index)).map(|d| d.index).ok_or_else(|| {
        Error::NoDevice(format!("no usable Vulkan 1.2 device with a compute queue; devices:\n{}", list()))
    })
}
