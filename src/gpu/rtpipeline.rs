//! The driver's ray tracing pipeline (`VK_KHR_ray_tracing_pipeline`) as a peer of the
//! hand-written kernels, beside ray query ([`super::rayquery`]): `glsl/raytrace/raygen.rgen`
//! reads the same `Ray`s, `traceRayEXT` walks the driver's acceleration structure
//! ([`AccelStructure`], the same one ray query traces), `closest.rchit` and `miss.rmiss` fill the
//! same `Hit`s. Batched, timed and validated exactly as [`super::raycast`]: [`raycast_rtp`] hands
//! [`cast_rays`] an [`RtPipeline`] that binds and launches each batch.
//!
//! It exists because NVIDIA's datacenter GPUs (H100, H200) expose the ray tracing pipeline but
//! not ray query. Selected with `trilab raycast --peer ray-tracing-pipeline`, reported as its own
//! row by `trilab bench`.
//!
//! The pipeline: three stages in three shader groups (0: ray generation, 1: miss, 2: a triangle
//! hit group with the closest-hit stage), recursion depth 1 (only the ray-generation stage
//! traces). The shader binding table holds one record per group, each a bare group handle:
//!
//! ```text
//! | raygen | pad | miss | pad | hit | pad |     each region aligned to shaderGroupBaseAlignment,
//!   stride = size = region    stride = handle size rounded up to shaderGroupHandleAlignment
//! ```

use std::collections::BTreeMap;
use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::accel::{device_address, AccelStructure};
use super::buffer::Buffer;
use super::commands::memory_barrier;
use super::context::{Context, Device};
use super::descriptors::{DescriptorLayout, Resource};
use super::device_info::{DeviceInfo, RayTracingPipelineProperties};
use super::raycast::{batch_for_with, cast_rays, RayDispatch, RaycastOptions, RaycastResult};
use crate::error::{Error, Result, VkContext};
use crate::kernels::{find_rt, RtShaderSource};
use crate::rays::Ray;
use crate::shared::{BINDING_SLOT_IDS, BINDING_TLAS};
use crate::spirv::reflect::reflect_stage;

/// Where each group's records live in the shader binding table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SbtLayout {
    /// A group handle's bytes (`shaderGroupHandleSize`).
    pub handle_size: u64,
    /// Bytes between records of the miss and hit regions: the handle size rounded up to
    /// `shaderGroupHandleAlignment`.
    pub stride: u64,
    /// Bytes of each region (and the ray-generation region's stride, which Vulkan wants equal
    /// to its size): the stride rounded up to `shaderGroupBaseAlignment`, so every region starts
    /// aligned when the table does.
    pub region: u64,
}

impl SbtLayout {
    /// The table of one record per group for the device's `props`; `None` for properties no
    /// table can satisfy (zero or non-power-of-two alignments, a stride beyond
    /// `maxShaderGroupStride`).
    pub fn new(props: &RayTracingPipelineProperties) -> Option<SbtLayout> {
        let handle_size = props.shader_group_handle_size as u64;
        let handle_align = props.shader_group_handle_alignment as u64;
        let base_align = props.shader_group_base_alignment as u64;
        if handle_size == 0 || !handle_align.is_power_of_two() || !base_align.is_power_of_two() {
            return None;
        }
        let stride = handle_size.next_multiple_of(handle_align);
        let region = stride.next_multiple_of(base_align);
        (stride <= props.max_shader_group_stride as u64).then_some(SbtLayout { handle_size, stride, region })
    }

    /// Bytes of the whole table (three regions).
    pub fn size(&self) -> u64 {
        3 * self.region
    }

    /// The table's bytes: `handles` (one per group, in group order) each at the start of its
    /// region, zeros elsewhere.
    pub fn fill(&self, handles: &[u8]) -> Vec<u8> {
        let h = self.handle_size as usize;
        let mut bytes = vec![0u8; self.size() as usize];
        for (group, handle) in handles.chunks_exact(h).take(3).enumerate() {
            let at = group * self.region as usize;
            bytes[at..at + h].copy_from_slice(handle);
        }
        bytes
    }

    /// The ray-generation, miss and hit regions of a table at `address`.
    pub fn regions(&self, address: vk::DeviceAddress) -> [vk::StridedDeviceAddressRegionKHR; 3] {
        let region = |i: u64, stride: u64| {
            vk::StridedDeviceAddressRegionKHR::default()
                .device_address(address + i * self.region)
                .stride(stride)
                .size(self.region)
        };
        [region(0, self.region), region(1, self.stride), region(2, self.stride)]
    }
}

/// The ray-tracing pipeline of one variant (closest hit, or any hit for occlusion): its shader
/// modules, descriptor-set and pipeline layouts, pipeline and shader binding table, destroyed in
/// reverse order of creation on drop.
pub struct RtPipeline {
    device: Arc<Device>,
    loader: ash::khr::ray_tracing_pipeline::Device,
    /// `raytrace.closest` or `raytrace.any`.
    pub name: &'static str,
    /// Set 0: descriptor type by binding (the union of the stages' bindings).
    bindings: BTreeMap<u32, vk::DescriptorType>,
    /// The stages that read the push constant `ray_count` (empty: none does).
    push_stages: vk::ShaderStageFlags,
    /// Ray generation, miss, hit; the callable region is empty.
    regions: [vk::StridedDeviceAddressRegionKHR; 3],
    /// Most rays one launch may hold (the device's limits).
    max_rays: usize,
    // Created in this order; destroyed in the reverse one by Drop (null handles are ignored,
    // so a pipeline that failed part-way is torn down by the same code).
    modules: Vec<vk::ShaderModule>,
    set_layout: vk::DescriptorSetLayout,
    pipeline_layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    sbt: Option<Buffer>,
}

impl Drop for RtPipeline {
    fn drop(&mut self) {
        // The table first (created last).
        drop(self.sbt.take());
        // SAFETY: every submit that used the pipeline was waited for; handles are destroyed in
        // reverse order of creation, and null ones (a creation that failed part-way) are ignored
        // by vkDestroy*.
        unsafe {
            let d = &self.device.raw;
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.pipeline_layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            for &m in self.modules.iter().rev() {
                d.destroy_shader_module(m, None);
            }
        }
    }
}

/// The stage flag of a `glsl/raytrace/` file's extension.
fn stage_flag(src: &RtShaderSource) -> Result<vk::ShaderStageFlags> {
    match src.stage {
        "rgen" => Ok(vk::ShaderStageFlags::RAYGEN_KHR),
        "rchit" => Ok(vk::ShaderStageFlags::CLOSEST_HIT_KHR),
        "rmiss" => Ok(vk::ShaderStageFlags::MISS_KHR),
        other => Err(Error::Spirv { kernel: src.name.into(), message: format!("unknown ray-tracing stage `{other}`") }),
    }
}

fn find_stage(shader: &str, stage: &str, variant: &str) -> Result<&'static RtShaderSource> {
    find_rt(shader, stage, variant).ok_or_else(|| Error::Spirv {
        kernel: format!("{shader}.{variant}.{stage}"),
        message: format!("not compiled (glsl/raytrace/{shader}.{stage})"),
    })
}

/// Set 0 of every stage together: binding -> (type, stages that use it); and the push-constant
/// range with the stages that read it. A binding declared with two types, another set, or two
/// different push-constant ranges is an error.
#[allow(clippy::type_complexity)]
fn merged_layout(
    stages: &[(&RtShaderSource, vk::ShaderStageFlags, Vec<u32>)],
) -> Result<(BTreeMap<u32, (vk::DescriptorType, vk::ShaderStageFlags)>, Option<((u32, u32), vk::ShaderStageFlags)>)> {
    let mut bindings: BTreeMap<u32, (vk::DescriptorType, vk::ShaderStageFlags)> = BTreeMap::new();
    let mut push: Option<((u32, u32), vk::ShaderStageFlags)> = None;
    for (src, flag, words) in stages {
        let err = |message: String| Error::Spirv { kernel: src.name.into(), message };
        let (sets, range) = reflect_stage(src.name, words)?;
        if sets.keys().any(|&s| s != 0) {
            return Err(err("only descriptor set 0 is supported".into()));
        }
        for (&binding, d) in sets.get(&0).into_iter().flatten() {
            let entry = bindings.entry(binding).or_insert((d.ty, vk::ShaderStageFlags::empty()));
            if entry.0 != d.ty {
                return Err(err(format!("binding {binding} is a {:?} here, a {:?} in another stage", d.ty, entry.0)));
            }
            entry.1 |= *flag;
        }
        if let Some(range) = range {
            match &mut push {
                Some((r, stages)) if *r == range => *stages |= *flag,
                Some((r, _)) => return Err(err(format!("push constants {range:?}, another stage's {r:?}"))),
                None => push = Some((range, *flag)),
            }
        }
    }
    Ok((bindings, push))
}

/// A stage of the pipeline: its source, stage flag and SPIR-V words.
type Stage = (&'static RtShaderSource, vk::ShaderStageFlags, Vec<u32>);

/// The three groups, in group order (the SBT regions' order): 0 ray generation, 1 miss, 2 the
/// triangle hit group with the closest-hit stage.
fn groups() -> [vk::RayTracingShaderGroupCreateInfoKHR<'static>; 3] {
    let general = |stage: u32| {
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
            .general_shader(stage)
            .closest_hit_shader(vk::SHADER_UNUSED_KHR)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR)
    };
    [
        general(0),
        general(1),
        vk::RayTracingShaderGroupCreateInfoKHR::default()
            .ty(vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP)
            .general_shader(vk::SHADER_UNUSED_KHR)
            .closest_hit_shader(2)
            .any_hit_shader(vk::SHADER_UNUSED_KHR)
            .intersection_shader(vk::SHADER_UNUSED_KHR),
    ]
}

impl RtPipeline {
    /// The pipeline of the closest-hit variant, or with `any_hit` the occlusion one (the first
    /// hit the driver accepts ends the trace); [`Error::Unsupported`] where the context has no
    /// ray tracing pipeline.
    pub fn new(ctx: &Context, any_hit: bool) -> Result<RtPipeline> {
        let props = Self::properties(ctx)?;
        let sbt_layout = SbtLayout::new(&props).ok_or_else(|| {
            Error::Unsupported(format!(
                "ray tracing pipeline: no shader binding table fits {}'s properties {props:?}",
                ctx.info().name
            ))
        })?;
        let (variant, name) = if any_hit { ("any", "raytrace.any") } else { ("closest", "raytrace.closest") };
        let stages = Self::stages(ctx, variant)?;
        let (bindings, push) = merged_layout(&stages)?;

        let d = &ctx.device;
        let loader = ash::khr::ray_tracing_pipeline::Device::new(&d.instance, &d.raw);
        let mut p = RtPipeline {
            device: d.clone(),
            loader,
            name,
            bindings: bindings.iter().map(|(&b, &(ty, _))| (b, ty)).collect(),
            push_stages: push.map_or(vk::ShaderStageFlags::empty(), |(_, s)| s),
            regions: Default::default(),
            max_rays: max_rays(ctx.info(), &props),
            modules: vec![],
            set_layout: vk::DescriptorSetLayout::null(),
            pipeline_layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            sbt: None,
        };
        p.create_modules(&stages)?;
        p.create_layouts(&bindings, push)?;
        p.create_pipeline(&stages)?;
        p.upload_table(ctx, &sbt_layout, &props)?;
        Ok(p)
    }

    /// The device's ray tracing pipeline properties, where the context enabled the pipeline.
    fn properties(ctx: &Context) -> Result<RayTracingPipelineProperties> {
        match ctx.info().ray_tracing_pipeline {
            Some(p) if ctx.enabled().ray_tracing_pipeline => Ok(p),
            _ => Err(ctx.capabilities().peer(super::Peer::RayTracingPipeline).err().map_or_else(
                || Error::Unsupported(format!("ray tracing pipeline: no properties reported by {}", ctx.info().name)),
                Error::from,
            )),
        }
    }

    /// The three stages of `variant` in group order, each checked against the context's
    /// capabilities.
    fn stages(ctx: &Context, variant: &str) -> Result<Vec<Stage>> {
        let sources = [
            find_stage("raygen", "rgen", variant)?,
            find_stage("miss", "rmiss", "main")?,
            find_stage("closest", "rchit", "main")?,
        ];
        let mut stages = Vec::new();
        for src in sources {
            let words = src.words();
            ctx.check_capabilities(src.name, &words)?;
            stages.push((src, stage_flag(src)?, words));
        }
        Ok(stages)
    }

    /// What a failing Vulkan call `s` was doing.
    fn what(&self, s: &str) -> String {
        format!("{s} for {}", self.name)
    }

    /// A shader module per stage.
    fn create_modules(&mut self, stages: &[Stage]) -> Result<()> {
        for (_, _, words) in stages {
            let info = vk::ShaderModuleCreateInfo::default().code(words);
            // SAFETY: the words are a SPIR-V module compiled for Vulkan 1.2 by build.rs whose
            // capabilities the context enabled (checked above); destroyed by Drop.
            let module = unsafe { self.device.raw.create_shader_module(&info, None) }
                .during(&self.what("vkCreateShaderModule"))?;
            self.modules.push(module);
        }
        Ok(())
    }

    /// The descriptor-set layout of the stages' bindings, and the pipeline layout with it and
    /// the push-constant range.
    #[allow(clippy::type_complexity)]
    fn create_layouts(
        &mut self,
        bindings: &BTreeMap<u32, (vk::DescriptorType, vk::ShaderStageFlags)>,
        push: Option<((u32, u32), vk::ShaderStageFlags)>,
    ) -> Result<()> {
        let layout_bindings: Vec<vk::DescriptorSetLayoutBinding> = bindings
            .iter()
            .map(|(&binding, &(ty, stages))| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(binding)
                    .descriptor_type(ty)
                    .descriptor_count(1)
                    .stage_flags(stages)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings);
        // SAFETY: valid device and create info; destroyed by Drop.
        self.set_layout = unsafe { self.device.raw.create_descriptor_set_layout(&set_info, None) }
            .during(&self.what("vkCreateDescriptorSetLayout"))?;
        let ranges: Vec<vk::PushConstantRange> = push
            .iter()
            .map(|&((offset, size), stages)| {
                vk::PushConstantRange::default().stage_flags(stages).offset(offset).size(size)
            })
            .collect();
        let set_layouts = [self.set_layout];
        let pl_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts).push_constant_ranges(&ranges);
        // SAFETY: the set layout is alive; destroyed by Drop.
        self.pipeline_layout = unsafe { self.device.raw.create_pipeline_layout(&pl_info, None) }
            .during(&self.what("vkCreatePipelineLayout"))?;
        Ok(())
    }

    /// The pipeline of the stages' modules in [`groups`], recursion depth 1.
    fn create_pipeline(&mut self, stages: &[Stage]) -> Result<()> {
        let stage_infos: Vec<vk::PipelineShaderStageCreateInfo> = stages
            .iter()
            .zip(&self.modules)
            .map(|((_, flag, _), &module)| {
                vk::PipelineShaderStageCreateInfo::default().stage(*flag).module(module).name(c"main")
            })
            .collect();
        let groups = groups();
        let info = [vk::RayTracingPipelineCreateInfoKHR::default()
            .stages(&stage_infos)
            .groups(&groups)
            .max_pipeline_ray_recursion_depth(1)
            .layout(self.pipeline_layout)];
        // SAFETY: modules and layout are alive; no deferred operation or cache; the create info
        // lives for the call. Recursion depth 1 <= maxRayRecursionDepth (at least 1 by spec).
        self.pipeline = unsafe {
            self.loader.create_ray_tracing_pipelines(
                vk::DeferredOperationKHR::null(),
                vk::PipelineCache::null(),
                &info,
                None,
            )
        }
        .map_err(|(_, e)| e)
        .during(&self.what("vkCreateRayTracingPipelinesKHR"))?[0];
        Ok(())
    }

    /// The shader binding table of the pipeline's group handles, uploaded, and its regions.
    fn upload_table(
        &mut self,
        ctx: &Context,
        sbt_layout: &SbtLayout,
        props: &RayTracingPipelineProperties,
    ) -> Result<()> {
        let groups = groups().len();
        let handle_bytes = groups * sbt_layout.handle_size as usize;
        // SAFETY: the pipeline has exactly these 3 groups; the size is 3 handles.
        let handles =
            unsafe { self.loader.get_ray_tracing_shader_group_handles(self.pipeline, 0, groups as u32, handle_bytes) }
                .during(&self.what("vkGetRayTracingShaderGroupHandlesKHR"))?;
        let (sbt, address) =
            upload_sbt(ctx, sbt_layout, &sbt_layout.fill(&handles), props.shader_group_base_alignment)?;
        self.regions = sbt_layout.regions(address);
        self.sbt = Some(sbt);
        Ok(())
    }
}

/// Most rays one `vkCmdTraceRaysKHR` may launch (width x 1 x 1): `maxRayDispatchInvocationCount`
/// and the width limit `maxComputeWorkGroupCount[0] * maxComputeWorkGroupSize[0]`
/// (VUID-vkCmdTraceRaysKHR-width-03638, -03641).
pub fn max_rays(info: &DeviceInfo, props: &RayTracingPipelineProperties) -> usize {
    let width = info.max_compute_workgroup_count[0] as u64 * info.max_compute_workgroup_size[0] as u64;
    width.min(props.max_ray_dispatch_invocation_count as u64) as usize
}

/// A device-local buffer holding `table` at an address aligned to `base_align`
/// (VUID-vkCmdTraceRaysKHR-pRayGenShaderBindingTable-03682 and the like: allocations guarantee
/// no such alignment, so the buffer is `base_align` bytes larger and the table starts where the
/// address is aligned); returns the buffer and the table's address.
fn upload_sbt(ctx: &Context, layout: &SbtLayout, table: &[u8], base_align: u32) -> Result<(Buffer, vk::DeviceAddress)> {
    let align = base_align as u64;
    let sbt = ctx.create_buffer(
        "ray tracing pipeline: shader binding table",
        layout.size() + align,
        vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
            | vk::BufferUsageFlags::TRANSFER_DST,
        MemoryLocation::GpuOnly,
    )?;
    let base = device_address(ctx, &sbt);
    let address = base.next_multiple_of(align);
    let mut staging = ctx.create_buffer(
        "ray tracing pipeline: shader binding table (staging)",
        table.len() as u64,
        vk::BufferUsageFlags::TRANSFER_SRC,
        MemoryLocation::CpuToGpu,
    )?;
    staging
        .mapped_mut()
        .ok_or_else(|| Error::NoDevice("the shader binding table's staging buffer is not host-visible".into()))?
        [..table.len()]
        .copy_from_slice(table);
    let region = vk::BufferCopy::default().dst_offset(address - base).size(table.len() as u64);
    ctx.one_shot("uploading the shader binding table", |d, cmd| {
        // SAFETY: both buffers are alive until one_shot has waited for the submit; the copy
        // stays inside `sbt` (offset < align, table + align bytes).
        unsafe {
            d.cmd_copy_buffer(cmd, staging.raw, sbt.raw, &[region]);
            // Later launches read the table (shader binding table reads are SHADER_READ in the
            // ray-tracing stage).
            memory_barrier(
                d,
                cmd,
                (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
                (vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR, vk::AccessFlags::SHADER_READ),
            );
        }
    })?;
    Ok((sbt, address))
}

impl DescriptorLayout for RtPipeline {
    fn name(&self) -> &'static str {
        self.name
    }

    fn bindings(&self) -> BTreeMap<u32, vk::DescriptorType> {
        self.bindings.clone()
    }

    fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.set_layout
    }
}

impl RayDispatch for RtPipeline {
    fn stage(&self) -> vk::PipelineStageFlags {
        vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR
    }

    fn max_rays(&self, _info: &DeviceInfo) -> usize {
        self.max_rays
    }

    unsafe fn record_rays(&self, dev: &ash::Device, cmd: vk::CommandBuffer, set: vk::DescriptorSet, count: u32) {
        let bind = vk::PipelineBindPoint::RAY_TRACING_KHR;
        dev.cmd_bind_pipeline(cmd, bind, self.pipeline);
        dev.cmd_bind_descriptor_sets(cmd, bind, self.pipeline_layout, 0, &[set], &[]);
        if !self.push_stages.is_empty() {
            // `Push { uint ray_count; }` in raygen.rgen (tests/rtpipeline.rs checks its layout).
            dev.cmd_push_constants(cmd, self.pipeline_layout, self.push_stages, 0, &count.to_le_bytes());
        }
        let [raygen, miss, hit] = &self.regions;
        let callable = vk::StridedDeviceAddressRegionKHR::default();
        self.loader.cmd_trace_rays(cmd, raygen, miss, hit, &callable, count, 1, 1);
    }
}

/// The ray-tracing pipeline of the closest-hit variant, or with `any_hit` the occlusion one
/// ([`RtPipeline::new`]).
pub fn pipeline(ctx: &Context, any_hit: bool) -> Result<RtPipeline> {
    RtPipeline::new(ctx, any_hit)
}

/// Casts `rays` through `accel` with `pipeline`: `warmup` untimed runs, then `repeat` timed ones,
/// exactly as [`super::raycast`] and [`super::rayquery::raycast_rq`] (the same
/// [`cast_rays`]). Hits carry OBJ triangle ids and the driver's barycentrics.
pub fn raycast_rtp(
    ctx: &Context,
    pipeline: &RtPipeline,
    accel: &AccelStructure,
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    ctx.capabilities().peer(super::Peer::RayTracingPipeline)?;
    let resources = [(BINDING_TLAS, Resource::Accel(accel)), (BINDING_SLOT_IDS, Resource::Texels(accel.prim_ids()))];
    cast_rays(ctx, pipeline, &resources, rays, opts)
}

/// [`super::rayquery::batch_for`] for the ray tracing pipeline: most rays per submit such that
/// one submit takes about `target_ms`, within [256, `max`].
pub fn batch_for(
    ctx: &Context,
    pipeline: &RtPipeline,
    accel: &AccelStructure,
    rays: &[Ray],
    target_ms: f64,
    max: usize,
) -> Result<usize> {
    batch_for_with(rays, target_ms, max, |probe, opts| raycast_rtp(ctx, pipeline, accel, probe, opts))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn props(size: u32, align: u32, base: u32) -> RayTracingPipelineProperties {
        RayTracingPipelineProperties {
            shader_group_handle_size: size,
            shader_group_handle_alignment: align,
            shader_group_base_alignment: base,
            max_shader_group_stride: 4096,
            max_ray_recursion_depth: 1,
            max_ray_dispatch_invocation_count: 1 << 30,
        }
    }

    #[test]
    fn sbt_regions_respect_the_handle_and_base_alignments() {
        // lavapipe (Mesa 25.0): 32-byte handles, alignment 16, base 32; NVIDIA: 32, 32, 64.
        let l = SbtLayout::new(&props(32, 16, 32)).unwrap();
        assert_eq!((l.stride, l.region, l.size()), (32, 32, 96));
        let l = SbtLayout::new(&props(32, 32, 64)).unwrap();
        assert_eq!((l.stride, l.region, l.size()), (32, 64, 192));
        // A handle that is not a multiple of the alignment is padded.
        let l = SbtLayout::new(&props(20, 16, 64)).unwrap();
        assert_eq!((l.stride, l.region), (32, 64));
        let r = l.regions(0x1000);
        assert_eq!([r[0].device_address, r[1].device_address, r[2].device_address], [0x1000, 0x1040, 0x1080]);
        // Ray generation: stride == size (VUID-vkCmdTraceRaysKHR-size-04023); the others: the
        // handle stride, every region starting at a multiple of the base alignment.
        assert_eq!((r[0].stride, r[0].size), (64, 64));
        assert_eq!((r[1].stride, r[2].stride), (32, 32));
        assert!(r.iter().all(|r| r.device_address % 64 == 0 && r.stride % 16 == 0));
        // Each handle at its region's start, zeros between.
        let handles: Vec<u8> = (0..60u8).collect();
        let t = l.fill(&handles);
        assert_eq!(t.len(), 192);
        assert_eq!(&t[..20], &handles[..20]);
        assert_eq!(&t[64..84], &handles[20..40]);
        assert_eq!(&t[128..148], &handles[40..60]);
        assert!(t[20..64].iter().all(|&b| b == 0));
        // Properties no table can satisfy.
        assert_eq!(SbtLayout::new(&props(0, 16, 32)), None);
        assert_eq!(SbtLayout::new(&props(32, 24, 32)), None);
        assert_eq!(
            SbtLayout::new(&RayTracingPipelineProperties { max_shader_group_stride: 16, ..props(32, 16, 32) }),
            None
        );
    }
}
