//! What a cast dispatches ([`super::raycast::cast_rays_with`]): [`RayDispatch`], a pipeline that
//! binds and dispatches one batch of rays, and our compute kernels as one. It lives apart from
//! the batching so that a wrapper around a kernel (the planted slowdown, [`super::slowdown`])
//! can be one too.

use ash::vk;

use super::descriptors::DescriptorLayout;
use super::device_info::DeviceInfo;
use super::kernel::Kernel;
use crate::shared::BINDING_RAY_COUNTER;

/// Workgroups of a persistent-threads kernel's dispatch (one that binds `BINDING_RAY_COUNTER`,
/// glsl/raycast_persistent.comp), fewer where the batch has fewer rays: the invocations loop
/// over the batch's rays, taking indices from the counter. 64 workgroups of 64 invocations keep
/// every lavapipe thread busy (it runs one workgroup per thread at a time, and LP_NUM_THREADS is
/// at most the machine's cores: 8 or more workgroups per thread up to 8 cores) and would fill a
/// small discrete GPU; the count is a measurement setting, not tuned.
pub const PERSISTENT_WORKGROUPS: u32 = 64;

/// One batch of a cast, as [`RayDispatch::record_batch`] records it between the batch's
/// timestamps.
#[derive(Clone, Copy, Debug)]
pub struct Batch {
    /// The batch's descriptor set (the scene, and its ranges of the rays and outputs).
    pub set: vk::DescriptorSet,
    /// Its rays.
    pub count: u32,
    /// A persistent kernel's next-ray counter (one u32, zeroed before the batch's first
    /// dispatch); `None` for the others.
    pub counter: Option<vk::Buffer>,
}

/// What [`super::raycast::cast_rays_with`] runs: a pipeline that reads `Ray`s at `BINDING_RAYS`
/// and writes `Hit`s at `BINDING_HITS` for the batch's sub-ranges, with `Push { uint ray_count;
/// }`. The batching, descriptor sets, barriers, timestamps, markers, submits and downloads are
/// the caller's; this is only "bind and dispatch this batch": a compute [`Kernel`] (one
/// invocation per ray, or a persistent kernel's fixed workgroups), or the ray-tracing pipeline
/// (`gpu::rtpipeline`, one launch per ray).
pub trait RayDispatch: DescriptorLayout {
    /// The pipeline stage its shaders run in (the barriers around each dispatch name it).
    fn stage(&self) -> vk::PipelineStageFlags;

    /// Most rays one dispatch may hold on `info`'s device (its dispatch limits).
    fn max_rays(&self, info: &DeviceInfo) -> usize;

    /// Records binding the pipeline with `set` and the push constant `count`, and the dispatch
    /// of `count` rays.
    ///
    /// # Safety
    /// `cmd` is recording on the pipeline's device; `set` was written for its layout; the
    /// pipeline, the set and what it binds outlive the command buffer's execution.
    unsafe fn record_rays(&self, dev: &ash::Device, cmd: vk::CommandBuffer, set: vk::DescriptorSet, count: u32);

    /// Records one batch between its timestamps: its dispatch ([`RayDispatch::record_rays`]),
    /// once. A wrapper may record more (the planted slowdown records it again, zeroing
    /// `batch.counter` again before each further dispatch).
    ///
    /// # Safety
    /// As [`RayDispatch::record_rays`]; the counter, where there is one, outlives the command
    /// buffer's execution too.
    unsafe fn record_batch(&self, dev: &ash::Device, cmd: vk::CommandBuffer, batch: &Batch) {
        self.record_rays(dev, cmd, batch.set, batch.count);
    }
}

impl RayDispatch for Kernel {
    fn stage(&self) -> vk::PipelineStageFlags {
        vk::PipelineStageFlags::COMPUTE_SHADER
    }

    fn max_rays(&self, info: &DeviceInfo) -> usize {
        info.max_compute_workgroup_count[0] as usize * self.layout.local_size.0 as usize
    }

    unsafe fn record_rays(&self, dev: &ash::Device, cmd: vk::CommandBuffer, set: vk::DescriptorSet, count: u32) {
        let local = self.layout.local_size.0;
        // `Push { uint ray_count; }` in raycast.comp (checked by tests/reflection.rs).
        // One invocation per ray, or a persistent kernel's fixed workgroups.
        let groups = match self.bindings().contains_key(&BINDING_RAY_COUNTER) {
            true => count.div_ceil(local).min(PERSISTENT_WORKGROUPS),
            false => count.div_ceil(local),
        };
        self.record(dev, cmd, set, &count.to_le_bytes(), groups);
    }
}
