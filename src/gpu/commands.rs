//! Command-buffer recording helpers every dispatch shares.

use ash::vk;

/// Records one global memory barrier: `src` (stages, accesses) before `dst`.
///
/// # Safety
/// `cmd` is a command buffer of `d` in the recording state.
pub(crate) unsafe fn memory_barrier(
    d: &ash::Device,
    cmd: vk::CommandBuffer,
    src: (vk::PipelineStageFlags, vk::AccessFlags),
    dst: (vk::PipelineStageFlags, vk::AccessFlags),
) {
    let barrier = vk::MemoryBarrier::default().src_access_mask(src.1).dst_access_mask(dst.1);
    d.cmd_pipeline_barrier(cmd, src.0, dst.0, vk::DependencyFlags::empty(), &[barrier], &[], &[]);
}
