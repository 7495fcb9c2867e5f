//! One dispatch of a ray-casting kernel over all rays, optionally inside a pipeline-statistics
//! query, reading back the hits and, for the `clock` variant, the ticks per ray.

use ash::vk;

use crate::error::{Error, Result, VkContext};
use crate::gpu::descriptors::{write_set, DescriptorPool};
use crate::gpu::{Context, Kernel, Resource};
use crate::pipeline::DeviceScene;
use crate::rays::{Hit, Ray};
use crate::shared::{BINDING_CYCLES, BINDING_HITS, BINDING_RAYS};

/// What one dispatch gave back.
#[derive(Clone, Debug)]
pub struct SingleDispatch {
    pub hits: Vec<Hit>,
    /// Shader-clock ticks per ray, when the kernel binds `BINDING_CYCLES`.
    pub cycles: Option<Vec<u32>>,
    /// `VK_QUERY_PIPELINE_STATISTIC_COMPUTE_SHADER_INVOCATIONS_BIT` of the dispatch, when asked.
    pub compute_shader_invocations: Option<u64>,
    /// The workgroup size the pipeline was created with.
    pub local_size: u32,
    pub workgroups: u32,
}

impl SingleDispatch {
    /// Invocations the dispatch launched: whole workgroups, the last one partly idle.
    pub fn dispatched_invocations(&self) -> u64 {
        u64::from(self.workgroups) * u64::from(self.local_size)
    }
}

/// A pipeline-statistics query pool of one query; destroyed on drop (after the submit that used
/// it was waited for).
struct StatisticsQuery<'a> {
    ctx: &'a Context,
    pool: vk::QueryPool,
}

impl Drop for StatisticsQuery<'_> {
    fn drop(&mut self) {
        // SAFETY: the one submit using the pool was waited for (or never made).
        unsafe { self.ctx.device.raw.destroy_query_pool(self.pool, None) };
    }
}

/// Casts every ray in one dispatch with `kernel` (the default `closest` or the `clock` variant);
/// with `pipeline_statistics`, inside a query counting compute-shader invocations (the device
/// must have `pipelineStatisticsQuery`, which the caller checks with `Context::enabled`).
pub fn dispatch_once(
    ctx: &Context,
    kernel: &Kernel,
    scene: &DeviceScene,
    rays: &[Ray],
    pipeline_statistics: bool,
) -> Result<SingleDispatch> {
    scene.check_kernel(kernel)?;
    if pipeline_statistics && !ctx.enabled().pipeline_statistics_query {
        return Err(Error::Usage("pipeline statistics queries are unsupported on this device".into()));
    }
    let info = ctx.info();
    let local = kernel.layout.local_size.0;
    let n = rays.len();
    let workgroups = (n as u64).div_ceil(u64::from(local));
    if n == 0
        || std::mem::size_of_val(rays) as u64 > u64::from(info.max_storage_buffer_range)
        || workgroups > u64::from(info.max_compute_workgroup_count[0])
    {
        return Err(Error::Usage(format!(
            "{n} rays do not fit one dispatch (maxStorageBufferRange {} bytes, maxComputeWorkGroupCount[0] {})",
            info.max_storage_buffer_range, info.max_compute_workgroup_count[0]
        )));
    }
    let workgroups = workgroups as u32;
    let ray_buf = ctx.upload("rays", bytemuck::cast_slice(rays), vk::BufferUsageFlags::STORAGE_BUFFER)?;
    let out_usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
    let hit_bytes = (n * std::mem::size_of::<Hit>()) as u64;
    let hit_buf = ctx.create_buffer("hits", hit_bytes, out_usage, gpu_allocator::MemoryLocation::GpuOnly)?;
    let cycle_bytes = (n * 4) as u64;
    let cycle_buf = if kernel.bindings().contains_key(&BINDING_CYCLES) {
        Some(ctx.create_buffer("cycles", cycle_bytes, out_usage, gpu_allocator::MemoryLocation::GpuOnly)?)
    } else {
        None
    };
    let mut resources: Vec<(u32, Resource)> = scene.resources().collect();
    resources.push((BINDING_RAYS, Resource::whole(&ray_buf)));
    resources.push((BINDING_HITS, Resource::whole(&hit_buf)));
    if let Some(c) = &cycle_buf {
        resources.push((BINDING_CYCLES, Resource::whole(c)));
    }
    let (_pool, sets) = DescriptorPool::new(ctx, kernel, 1)?;
    write_set(ctx, kernel, sets[0], &resources)?;

    let query = if pipeline_statistics {
        let qi = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::PIPELINE_STATISTICS)
            .query_count(1)
            .pipeline_statistics(vk::QueryPipelineStatisticFlags::COMPUTE_SHADER_INVOCATIONS);
        // SAFETY: valid device with pipelineStatisticsQuery enabled (checked above); destroyed on
        // drop.
        let pool = unsafe { ctx.device.raw.create_query_pool(&qi, None) }
            .during("creating a pipeline-statistics query pool")?;
        Some(StatisticsQuery { ctx, pool })
    } else {
        None
    };
    let count = n as u32;
    ctx.one_shot(&format!("{} over {n} rays in one dispatch", kernel.name), |d, cmd| {
        // SAFETY: the pipeline, its layout, the set, the buffers and the query pool all outlive
        // one_shot's wait; the query is reset before it begins, outside any render pass.
        unsafe {
            if let Some(q) = &query {
                d.cmd_reset_query_pool(cmd, q.pool, 0, 1);
            }
            let marker = ctx.mark_begin(d, cmd, format!("{} single dispatch (rays 0..{n})", kernel.name));
            if let Some(q) = &query {
                d.cmd_begin_query(cmd, q.pool, 0, vk::QueryControlFlags::empty());
            }
            // `Push { uint ray_count; }` in raycast.comp (checked by tests/reflection.rs).
            kernel.record(d, cmd, sets[0], &count.to_le_bytes(), workgroups);
            if let Some(q) = &query {
                d.cmd_end_query(cmd, q.pool, 0);
            }
            ctx.mark_end(d, cmd, marker);
        }
    })?;
    let compute_shader_invocations = match &query {
        Some(q) => {
            let mut v = [0u64; 1];
            // SAFETY: the submit that wrote the query was waited for by one_shot.
            unsafe {
                ctx.device.raw.get_query_pool_results(
                    q.pool,
                    0,
                    &mut v,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )
            }
            .during("reading the pipeline-statistics query")?;
            Some(v[0])
        }
        None => None,
    };
    let hits = ctx.download(&hit_buf, hit_bytes)?.chunks_exact(16).map(bytemuck::pod_read_unaligned).collect();
    let cycles = match &cycle_buf {
        Some(c) => Some(ctx.download(c, cycle_bytes)?.chunks_exact(4).map(bytemuck::pod_read_unaligned).collect()),
        None => None,
    };
    Ok(SingleDispatch { hits, cycles, compute_shader_invocations, local_size: local, workgroups })
}
