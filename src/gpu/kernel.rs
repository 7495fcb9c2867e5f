//! Compute pipelines built from the kernels' own reflection data: descriptor-set layout,
//! push-constant range and workgroup size all come from the SPIR-V (rspirv-reflect).

use std::collections::BTreeMap;
use std::sync::Arc;

use ash::vk;

use super::context::{Context, Device, Needs};
use crate::error::{Error, Result, VkContext};
use crate::kernels::KernelSource;
use crate::spirv::reflect::{reads_subgroup_lanes, reflect, KernelInterface};
use crate::spirv::required_features;

/// A compute pipeline with its layouts; destroyed on drop.
pub struct Kernel {
    device: Arc<Device>,
    /// The registry's kernel it was made from (`encoding::variants::KernelKey::of` gives its key).
    pub source: &'static KernelSource,
    pub name: &'static str,
    pub layout: KernelInterface,
    module: vk::ShaderModule,
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) pipeline_layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
}

impl Drop for Kernel {
    fn drop(&mut self) {
        // SAFETY: submits using this pipeline were waited for; reverse order of creation.
        unsafe {
            let d = &self.device.raw;
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.pipeline_layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_shader_module(self.module, None);
        }
    }
}

impl Kernel {
    /// Descriptor types of set 0 by binding.
    pub fn bindings(&self) -> BTreeMap<u32, vk::DescriptorType> {
        self.layout.sets.get(&0).map(|s| s.iter().map(|(&b, d)| (b, d.ty)).collect()).unwrap_or_default()
    }

    /// Records binding this pipeline with descriptor set `set` and push constants `push` (none
    /// when empty), and a dispatch of `groups` workgroups.
    ///
    /// # Safety
    /// `cmd` is recording on this kernel's device; `set` was written for this kernel's layout;
    /// the pipeline, the set and what it binds outlive the command buffer's execution.
    pub unsafe fn record(
        &self,
        dev: &ash::Device,
        cmd: vk::CommandBuffer,
        set: vk::DescriptorSet,
        push: &[u8],
        groups: u32,
    ) {
        dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
        dev.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline_layout, 0, &[set], &[]);
        if !push.is_empty() {
            dev.cmd_push_constants(cmd, self.pipeline_layout, vk::ShaderStageFlags::COMPUTE, 0, push);
        }
        dev.cmd_dispatch(cmd, groups, 1, 1);
    }
}

impl Context {
    /// The kernel of `src`, created on first use and shared after that.
    pub fn kernel(&self, src: &'static KernelSource) -> Result<Arc<Kernel>> {
        self.kernel_specialized(src, &[])
    }

    /// [`Context::kernel`] with specialisation constants: `(constant_id, 32-bit value)` pairs.
    pub fn kernel_specialized(&self, src: &'static KernelSource, constants: &[(u32, u32)]) -> Result<Arc<Kernel>> {
        let key = (src.name, constants.to_vec());
        let cached = self.kernels.lock().unwrap_or_else(|e| e.into_inner()).get(&key).cloned();
        if let Some(k) = cached {
            return Ok(k.downcast::<Kernel>().expect("the kernel cache holds kernels"));
        }
        let k = Arc::new(self.create_kernel_specialized(src, constants)?);
        self.kernels.lock().unwrap_or_else(|e| e.into_inner()).insert(key, k.clone());
        Ok(k)
    }

    /// A new pipeline for `src` (not shared: [`Context::kernel`] is the usual way).
    pub fn create_kernel(&self, src: &'static KernelSource) -> Result<Kernel> {
        self.create_kernel_specialized(src, &[])
    }

    /// A pipeline with specialisation constants set: `(constant_id, 32-bit value)` pairs.
    pub fn create_kernel_specialized(&self, src: &'static KernelSource, constants: &[(u32, u32)]) -> Result<Kernel> {
        self.create_kernel_with(src, &PipelineOptions { constants, ..Default::default() })
    }

    /// A pipeline with the profiling options of [`PipelineOptions`]; the caller checks that
    /// the device enabled what they need (`Context::enabled`).
    pub fn create_kernel_with(&self, src: &'static KernelSource, options: &PipelineOptions) -> Result<Kernel> {
        let _span = crate::timeline::span_with("pipeline", || format!("pipeline compile {}", src.name));
        let constants = options.constants;
        let words = src.words();
        self.check_capabilities(src.name, &words)?;
        let mut layout = reflect(src.name, &words)?;
        // Dispatches use the size the pipeline is created with, not the module's default.
        layout.specialize(constants);
        if layout.sets.keys().any(|&s| s != 0) {
            return Err(Error::Spirv { kernel: src.name.into(), message: "only descriptor set 0 is supported".into() });
        }
        let full_subgroups = self.check_full_subgroups(src.name, &words, &layout, options)?;
        let d = &self.device.raw;
        let what = |s: &str| format!("{s} for kernel {}", src.name);

        let bindings: Vec<vk::DescriptorSetLayoutBinding> = layout
            .sets
            .get(&0)
            .map(|set| {
                set.iter()
                    .map(|(&binding, info)| {
                        vk::DescriptorSetLayoutBinding::default()
                            .binding(binding)
                            .descriptor_type(info.ty)
                            .descriptor_count(1)
                            .stage_flags(vk::ShaderStageFlags::COMPUTE)
                    })
                    .collect()
            })
            .unwrap_or_default();
        let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: the words are a SPIR-V module compiled for Vulkan 1.2 by build.rs.
        let module = unsafe { d.create_shader_module(&module_info, None) }.during(&what("vkCreateShaderModule"))?;
        let mut objects = Objects { device: Some(self.device.clone()), module, ..Default::default() };
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        objects.set_layout =
            unsafe { d.create_descriptor_set_layout(&set_info, None) }.during(&what("vkCreateDescriptorSetLayout"))?;
        let ranges: Vec<vk::PushConstantRange> = layout
            .push_constants
            .iter()
            .map(|&(offset, size)| {
                vk::PushConstantRange::default().stage_flags(vk::ShaderStageFlags::COMPUTE).offset(offset).size(size)
            })
            .collect();
        let set_layouts = [objects.set_layout];
        let pl_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges);
        objects.pipeline_layout =
            unsafe { d.create_pipeline_layout(&pl_info, None) }.during(&what("vkCreatePipelineLayout"))?;
        let entries: Vec<vk::SpecializationMapEntry> = constants
            .iter()
            .enumerate()
            .map(|(i, &(id, _))| vk::SpecializationMapEntry::default().constant_id(id).offset(4 * i as u32).size(4))
            .collect();
        let data: Vec<u8> = constants.iter().flat_map(|&(_, v)| v.to_le_bytes()).collect();
        let spec = vk::SpecializationInfo::default().map_entries(&entries).data(&data);
        let mut stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        if !constants.is_empty() {
            stage = stage.specialization_info(&spec);
        }
        let mut required = vk::PipelineShaderStageRequiredSubgroupSizeCreateInfo::default()
            .required_subgroup_size(options.required_subgroup_size.unwrap_or(0));
        if options.required_subgroup_size.is_some() {
            stage = stage.push_next(&mut required);
        }
        if full_subgroups {
            stage = stage.flags(vk::PipelineShaderStageCreateFlags::REQUIRE_FULL_SUBGROUPS);
        }
        let flags = if options.capture_statistics {
            vk::PipelineCreateFlags::CAPTURE_STATISTICS_KHR
        } else {
            vk::PipelineCreateFlags::empty()
        };
        let info = [vk::ComputePipelineCreateInfo::default().flags(flags).stage(stage).layout(objects.pipeline_layout)];
        // SAFETY: layouts and module are valid; the create info lives for the call.
        objects.pipeline = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &info, None) }
            .map_err(|(_, e)| e)
            .during(&what("vkCreateComputePipelines"))?[0];
        let (module, set_layout, pipeline_layout, pipeline) = objects.release();
        Ok(Kernel {
            device: self.device.clone(),
            source: src,
            name: src.name,
            layout,
            module,
            set_layout,
            pipeline_layout,
            pipeline,
        })
    }
}

impl Context {
    /// Whether `kernel` must be created with full subgroups, and an `Error::Unsupported` naming
    /// the kernel and the widths where it cannot be. A kernel that reads `gl_SubgroupSize` or
    /// `gl_SubgroupInvocationID` hands work to lanes by index (glsl/raycast_coop.comp: children,
    /// node texels and leaf triangles), so a subgroup with inactive lanes would silently skip
    /// work: a partial subgroup at the end of a workgroup whose size is not a multiple of the
    /// subgroup size, or a driver that reports more lanes than it runs (Vulkan allows both
    /// unless the stage asks for full subgroups).
    fn check_full_subgroups(
        &self,
        kernel: &str,
        words: &[u32],
        layout: &KernelInterface,
        options: &PipelineOptions,
    ) -> Result<bool> {
        if !reads_subgroup_lanes(words).map_err(|m| Error::Spirv { kernel: kernel.into(), message: m })? {
            return Ok(false);
        }
        let info = self.info();
        let width = options.required_subgroup_size.unwrap_or(info.subgroup_size);
        if !(self.enabled().subgroup_size_control && info.compute_full_subgroups) {
            return Err(Error::Unsupported(format!(
                "kernel {kernel} hands work to subgroup lanes by index and needs full subgroups \
                 (VK_EXT_subgroup_size_control's computeFullSubgroups), which {} lacks (subgroup size {width})",
                info.name
            )));
        }
        let local = layout.local_size.0;
        if width == 0 || !local.is_multiple_of(width) {
            return Err(Error::Unsupported(format!(
                "kernel {kernel} needs full subgroups: its workgroup size {local} is not a multiple of the \
                 subgroup size {width} on {}",
                info.name
            )));
        }
        Ok(true)
    }

    /// Fails with `Error::Unsupported` when the module declares a capability whose device
    /// feature this context did not enable (the device lacks it, or the options left it off):
    /// creating the pipeline anyway would be invalid usage, and may crash a driver.
    pub(crate) fn check_capabilities(&self, kernel: &str, words: &[u32]) -> Result<()> {
        let needs = required_features(words).map_err(|m| Error::Spirv { kernel: kernel.into(), message: m })?;
        Ok(self.capabilities().requirements(kernel, &needs)?)
    }
}

impl Needs {
    /// What the module `words` (kernel `name`) needs of a device: the features its capabilities
    /// name, and full subgroups when it hands work to lanes by index.
    pub fn of(name: &str, words: &[u32]) -> Result<Needs> {
        let spirv = |m: String| Error::Spirv { kernel: name.into(), message: m };
        let features = required_features(words).map_err(spirv)?.iter().map(|r| r.feature).collect();
        let full_subgroups = reads_subgroup_lanes(words).map_err(spirv)?;
        Ok(Needs { features, full_subgroups })
    }
}

/// How to create a pipeline beyond its SPIR-V (`trilab profile` varies these).
#[derive(Clone, Copy, Debug, Default)]
pub struct PipelineOptions<'a> {
    /// `(constant_id, 32-bit value)` specialisation constants.
    pub constants: &'a [(u32, u32)],
    /// `VkPipelineShaderStageRequiredSubgroupSizeCreateInfo` (needs subgroupSizeControl and
    /// COMPUTE in requiredSubgroupSizeStages).
    pub required_subgroup_size: Option<u32>,
    /// `VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR` (needs pipelineExecutableInfo).
    pub capture_statistics: bool,
}

/// Destroys what was created if pipeline creation fails part-way.
#[derive(Default)]
struct Objects {
    device: Option<Arc<Device>>,
    module: vk::ShaderModule,
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
}

impl Objects {
    fn release(mut self) -> (vk::ShaderModule, vk::DescriptorSetLayout, vk::PipelineLayout, vk::Pipeline) {
        self.device = None;
        (self.module, self.set_layout, self.pipeline_layout, self.pipeline)
    }
}

impl Drop for Objects {
    fn drop(&mut self) {
        if let Some(dev) = &self.device {
            // SAFETY: null handles are ignored by vkDestroy*; nothing has used these objects.
            unsafe {
                dev.raw.destroy_pipeline(self.pipeline, None);
                dev.raw.destroy_pipeline_layout(self.pipeline_layout, None);
                dev.raw.destroy_descriptor_set_layout(self.set_layout, None);
                dev.raw.destroy_shader_module(self.module, None);
            }
        }
    }
}
