//! Ray casting on the GPU: upload a scene once, then dispatch rays in batches, each its own
//! submit (short enough for a display GPU's watchdog) with a pair of timestamps.

use std::time::Instant;

use ash::vk;

use super::buffer::{memory_barrier, Buffer, TexelBuffer};
use super::context::Context;
use super::descriptors::{write_set, DescriptorPool, Resource};
use super::kernel::Kernel;
use super::plan::{AccessPath, DeviceLimits, MemoryPlan, SceneAccess};
use super::timestamps::Timestamps;
use super::traversal_stats::TraversalCounts;
use crate::encoding::{EncodedScene, Method, SceneBufferRef};
use crate::error::{Result, VkContext};
use crate::rays::{Hit, Ray};
use crate::shared::{BINDING_HITS, BINDING_RAYS, BINDING_TRAVERSAL_STATS};

/// One scene buffer as the kernels reach it.
enum SceneBinding {
    /// A storage texel buffer (the default kernels).
    Texels(TexelBuffer),
    /// The texel path's limit does not apply: the data in a device-address buffer, and a
    /// uniform buffer holding its address, bound where the texel buffer would be (the `*_bda`
    /// kernels, `SCENE_ADDRESS` in `glsl/types.glsl`).
    Address { data: Buffer, pointer: Buffer },
}

/// A scene's buffers on the GPU, read through the access path it was uploaded for.
pub struct GpuScene {
    pub method: Method,
    pub leaf_size: u32,
    /// (binding, buffer)
    buffers: Vec<(u32, SceneBinding)>,
    /// Bytes uploaded.
    pub bytes: usize,
    /// How the kernels must read it: texel scenes bind to `kernels::raycast`, address scenes
    /// to `kernels::raycast_via(.., AccessPath::Address)`.
    pub access: AccessPath,
}

impl GpuScene {
    /// Uploads for the texel path (the default kernels).
    pub fn upload(ctx: &Context, scene: &EncodedScene) -> Result<GpuScene> {
        Self::upload_filtered(ctx, scene, AccessPath::Texel, |_| true)
    }

    /// Uploads for `access` (chosen by `MemoryPlan::choose` before encoding).
    pub fn upload_with(ctx: &Context, scene: &EncodedScene, access: AccessPath) -> Result<GpuScene> {
        Self::upload_filtered(ctx, scene, access, |_| true)
    }

    /// Plans `scene` as encoded, chooses its access path (`requested`, against `limits`), and
    /// uploads it; `name` names the scene in a "does not fit" error.
    pub fn upload_planned(
        ctx: &Context,
        name: &str,
        scene: &EncodedScene,
        requested: SceneAccess,
        limits: &DeviceLimits,
    ) -> Result<GpuScene> {
        let access = MemoryPlan::of_encoded(scene).choose(name, requested, limits)?;
        Self::upload_with(ctx, scene, access)
    }

    /// Uploads only the buffers `kernel` reads (the path tracer, say, never reads the slot ->
    /// OBJ id table).
    pub fn upload_for(ctx: &Context, scene: &EncodedScene, kernel: &crate::kernels::KernelSource) -> Result<GpuScene> {
        let layout = crate::spirv::reflect::reflect(kernel.name, &kernel.words())?;
        let read = layout.sets.get(&0).cloned().unwrap_or_default();
        Self::upload_filtered(ctx, scene, AccessPath::Texel, |b| read.contains_key(&b))
    }

    fn upload_filtered(
        ctx: &Context,
        scene: &EncodedScene,
        access: AccessPath,
        keep: impl Fn(u32) -> bool,
    ) -> Result<GpuScene> {
        scene.check_limits().map_err(|e| {
            crate::error::Error::Usage(format!("scene too large for the {} kernels: {e}", scene.method))
        })?;
        let upload = |SceneBufferRef { name, binding, texel, bytes }: SceneBufferRef| -> Result<(u32, SceneBinding)> {
            Ok((
                binding,
                match access {
                    AccessPath::Texel => SceneBinding::Texels(ctx.upload_texels(name, bytes, texel)?),
                    AccessPath::Address => {
                        let (data, address) = ctx.upload_addressed(name, bytes)?;
                        // `uniform <name>Address { Scene.. <name>; }` (std140): the 8-byte address.
                        let pointer = ctx.upload(
                            &format!("{name} (address)"),
                            &address.to_le_bytes(),
                            vk::BufferUsageFlags::UNIFORM_BUFFER,
                        )?;
                        SceneBinding::Address { data, pointer }
                    }
                },
            ))
        };
        let buffers: Vec<(u32, SceneBinding)> =
            scene.buffers().into_iter().filter(|b| keep(b.binding)).map(upload).collect::<Result<Vec<_>>>()?;
        let bytes = buffers
            .iter()
            .map(|(_, b)| match b {
                SceneBinding::Texels(t) => t.buffer.size as usize,
                SceneBinding::Address { data, .. } => data.size as usize,
            })
            .sum();
        Ok(GpuScene { method: scene.method, leaf_size: scene.leaf_size, buffers, bytes, access })
    }

    /// The scene's bindings, for a descriptor set.
    pub fn resources(&self) -> impl Iterator<Item = (u32, Resource<'_>)> {
        self.buffers.iter().map(|(b, t)| {
            (
                *b,
                match t {
                    SceneBinding::Texels(t) => Resource::Texels(t),
                    SceneBinding::Address { pointer, .. } => Resource::whole(pointer),
                },
            )
        })
    }
}

#[derive(Clone, Debug)]
pub struct RaycastOptions {
    /// Untimed runs before the timed ones.
    pub warmup: usize,
    /// Timed runs (at least 1).
    pub repeat: usize,
    /// Most rays per dispatch/submit.
    pub batch_rays: usize,
}

impl Default for RaycastOptions {
    fn default() -> Self {
        RaycastOptions { warmup: 1, repeat: 1, batch_rays: 1 << 20 }
    }
}

/// Hits and kernel times of one `raycast` call.
#[derive(Clone, Debug)]
pub struct RaycastResult {
    pub hits: Vec<Hit>,
    /// GPU time of each timed run (sum over its dispatches), milliseconds; empty when the
    /// device has no timestamps on its compute queue.
    pub kernel_ms: Vec<f64>,
    /// Host wall time of each timed run (submits and waits included), milliseconds.
    pub wall_ms: Vec<f64>,
    pub batches: usize,
    /// Per-ray traversal work of the last run, when the kernel is a `stats` variant (it declares
    /// `BINDING_TRAVERSAL_STATS`); `None` for the others.
    pub traversal: Option<Vec<TraversalCounts>>,
}

/// Median, min and max of a sample.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Summary {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    pub runs: usize,
}

impl Summary {
    pub fn of(xs: &[f64]) -> Option<Summary> {
        if xs.is_empty() {
            return None;
        }
        let mut v = xs.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        Some(Summary { median, min: v[0], max: v[n - 1], runs: n })
    }
}

impl RaycastResult {
    /// Kernel time summary (GPU timestamps), or host wall time where there are none.
    pub fn time_ms(&self) -> Summary {
        Summary::of(&self.kernel_ms).or_else(|| Summary::of(&self.wall_ms)).expect("at least one timed run")
    }

    pub fn timed_on_gpu(&self) -> bool {
        !self.kernel_ms.is_empty()
    }
}

/// Command buffers of one batched run; freed on drop (after all its submits finished).
struct Dispatch<'a> {
    ctx: &'a Context,
    cmds: Vec<vk::CommandBuffer>,
}

impl Drop for Dispatch<'_> {
    fn drop(&mut self) {
        if !self.cmds.is_empty() {
            self.ctx.free_command_buffers(&self.cmds);
        }
    }
}

/// Casts `rays` with `kernel` over `scene`: `warmup` untimed runs, then `repeat` timed ones.
/// The hits are those of the last run; so are the per-ray traversal counts when `kernel` is a
/// `stats` variant (`kernels::raycast_stats`).
pub fn raycast(
    ctx: &Context,
    kernel: &Kernel,
    scene: &GpuScene,
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    let resources: Vec<(u32, Resource)> = scene.resources().collect();
    cast_rays(ctx, kernel, &resources, rays, opts)
}

/// The batched, timed dispatch behind [`raycast`] and every kernel that reads `Ray`s at
/// `BINDING_RAYS` and writes `Hit`s at `BINDING_HITS` with `Push { uint ray_count; }`:
/// `scene` are the kernel's other bindings (the same in every batch).
pub(crate) fn cast_rays(
    ctx: &Context,
    kernel: &Kernel,
    scene: &[(u32, Resource)],
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    if rays.is_empty() {
        let traversal = kernel.bindings().contains_key(&BINDING_TRAVERSAL_STATS).then(Vec::new);
        return Ok(RaycastResult { hits: vec![], kernel_ms: vec![], wall_ms: vec![], batches: 0, traversal });
    }
    let info = ctx.info();
    let dev = &ctx.device.raw;
    let local = kernel.layout.local_size.0 as usize;
    // Batch: within the watchdog budget, the storage-buffer range, the dispatch limit, and a
    // multiple of 256 rays so every sub-range offset is aligned (256 * 16 B >= any
    // minStorageBufferOffsetAlignment, which the spec caps at 256).
    let by_range = info.max_storage_buffer_range as usize / std::mem::size_of::<Ray>();
    let by_groups = info.max_compute_workgroup_count[0] as usize * local;
    let batch = (opts.batch_rays.min(by_range).min(by_groups) / 256 * 256).max(256);
    let nbatches = rays.len().div_ceil(batch);

    let ray_buf = ctx.upload("rays", bytemuck::cast_slice(rays), vk::BufferUsageFlags::STORAGE_BUFFER)?;
    // Per-ray outputs: (binding, bytes per ray, buffer); hits, and the counters of a stats kernel.
    let output = |name: &str, per_ray: usize| {
        ctx.create_buffer(
            name,
            (rays.len() * per_ray) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
            gpu_allocator::MemoryLocation::GpuOnly,
        )
    };
    let mut outputs = vec![(BINDING_HITS, std::mem::size_of::<Hit>() as u64, output("hits", 16)?)];
    if kernel.bindings().contains_key(&BINDING_TRAVERSAL_STATS) {
        let size = std::mem::size_of::<TraversalCounts>();
        outputs.push((BINDING_TRAVERSAL_STATS, size as u64, output("traversal counts", size)?));
    }

    let (_pool, sets) = DescriptorPool::new(ctx, kernel, nbatches as u32)?;
    for (bi, &set) in sets.iter().enumerate() {
        let first = (bi * batch) as u64;
        let count = batch.min(rays.len() - bi * batch) as u64;
        let mut resources: Vec<(u32, Resource)> = scene.to_vec();
        resources.push((BINDING_RAYS, Resource::Buffer { buffer: &ray_buf, offset: first * 32, range: count * 32 }));
        for (binding, size, buf) in &outputs {
            resources.push((*binding, Resource::Buffer { buffer: buf, offset: first * size, range: count * size }));
        }
        write_set(ctx, kernel, set, &resources)?;
    }
    let timestamps = Timestamps::supported(ctx);
    let queries = Timestamps::new(ctx, nbatches as u32)?;
    let mut dispatch = Dispatch { ctx, cmds: vec![] };

    dispatch.cmds = ctx.allocate_command_buffers(nbatches as u32)?;
    // What each batch's submit runs (the dispatch log and crash markers name it).
    let what: Vec<String> = (0..nbatches)
        .map(|bi| {
            let first = bi * batch;
            let end = (first + batch).min(rays.len());
            format!("{} batch {}/{nbatches} (rays {first}..{end})", kernel.name, bi + 1)
        })
        .collect();
    for (bi, (&cmd, &set)) in dispatch.cmds.iter().zip(&sets).enumerate() {
        let count = batch.min(rays.len() - bi * batch) as u32;
        let q = bi as u32;
        // SAFETY: recording into freshly allocated command buffers; every object referenced
        // outlives the submits (all waited for before this function returns).
        unsafe {
            dev.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default()).during("recording a dispatch")?;
            queries.reset(dev, cmd, q);
            // The previous run's dispatch wrote the same output ranges (and uploads came before).
            memory_barrier(
                dev,
                cmd,
                (
                    vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                ),
                (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE),
            );
            let marker = ctx.mark_begin(dev, cmd, what[bi].clone());
            queries.start(dev, cmd, q);
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, kernel.pipeline);
            dev.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, kernel.pipeline_layout, 0, &[set], &[]);
            // `Push { uint ray_count; }` in raycast.comp (checked by tests/reflection.rs).
            dev.cmd_push_constants(cmd, kernel.pipeline_layout, vk::ShaderStageFlags::COMPUTE, 0, &count.to_le_bytes());
            dev.cmd_dispatch(cmd, count.div_ceil(local as u32), 1, 1);
            queries.end(dev, cmd, q);
            ctx.mark_end(dev, cmd, marker);
            dev.end_command_buffer(cmd).during("recording a dispatch")?;
        }
    }

    let mut kernel_ms = Vec::new();
    let mut wall_ms = Vec::new();
    let runs = opts.warmup + opts.repeat.max(1);
    for run in 0..runs {
        let t0 = Instant::now();
        for (&cmd, what) in dispatch.cmds.iter().zip(&what) {
            ctx.submit_and_wait(cmd, what)?;
        }
        let wall = t0.elapsed().as_secs_f64() * 1e3;
        if run < opts.warmup {
            continue;
        }
        wall_ms.push(wall);
        if timestamps {
            kernel_ms.push(queries.read_ms()?.iter().sum());
        }
    }
    let mut downloads = Vec::new();
    for (_, size, buf) in &outputs {
        downloads.push(ctx.download(buf, rays.len() as u64 * size)?);
    }
    drop(dispatch);
    drop(queries);
    let hits = downloads[0].chunks_exact(16).map(bytemuck::pod_read_unaligned).collect();
    let traversal = downloads
        .get(1)
        .map(|b| b.chunks_exact(std::mem::size_of::<TraversalCounts>()).map(bytemuck::pod_read_unaligned).collect());
    Ok(RaycastResult { hits, kernel_ms, wall_ms, batches: nbatches, traversal })
}

#[cfg(test)]
mod tests {
    use super::Summary;

    #[test]
    fn summary_median_min_max() {
        let s = Summary::of(&[3.0, 1.0, 2.0]).unwrap();
        assert_eq!((s.median, s.min, s.max, s.runs), (2.0, 1.0, 3.0, 3));
        assert_eq!(Summary::of(&[4.0, 1.0, 2.0, 3.0]).unwrap().median, 2.5);
        assert!(Summary::of(&[]).is_none());
    }
}
