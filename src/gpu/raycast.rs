//! Ray casting on the GPU: rays dispatched in batches over a scene's bindings, each batch its own
//! submit (short enough for a display GPU's watchdog) with a pair of timestamps.

use std::time::Instant;

use ash::vk;

use super::commands::memory_barrier;
use super::context::Context;
use super::descriptors::{write_set, DescriptorLayout, DescriptorPool, Resource};
use super::device_info::DeviceInfo;
use super::kernel::Kernel;
use super::slowdown::Slowdown;
use super::timestamps::Timestamps;
use super::traversal_stats::TraversalCounts;
use crate::error::{Error, Result, VkContext};
use crate::rays::{Hit, Ray};
use crate::report::Summary;
use crate::shared::{BINDING_HITS, BINDING_RAYS, BINDING_RAY_COUNTER, BINDING_TRAVERSAL_STATS};

/// Workgroups of a persistent-threads kernel's dispatch (one that binds `BINDING_RAY_COUNTER`,
/// glsl/raycast_persistent.comp), fewer where the batch has fewer rays: the invocations loop
/// over the batch's rays, taking indices from the counter. 64 workgroups of 64 invocations keep
/// every lavapipe thread busy (it runs one workgroup per thread at a time, and LP_NUM_THREADS is
/// at most the machine's cores: 8 or more workgroups per thread up to 8 cores) and would fill a
/// small discrete GPU; the count is a measurement setting, not tuned.
pub const PERSISTENT_WORKGROUPS: u32 = 64;

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
        RaycastOptions { warmup: 1, repeat: 1, batch_rays: crate::defaults::BATCH_RAYS }
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

impl RaycastResult {
    /// Kernel time summary (GPU timestamps), or host wall time where there are none. An error
    /// when nothing was timed: an empty ray set (which has no speed) or no timed run.
    pub fn time_ms(&self) -> Result<Summary> {
        Summary::of(&self.kernel_ms).or_else(|| Summary::of(&self.wall_ms)).ok_or_else(|| {
            Error::Usage(if self.hits.is_empty() {
                "no rays to time: the ray set is empty".into()
            } else {
                "no timed run (repeat 0)".into()
            })
        })
    }

    pub fn timed_on_gpu(&self) -> bool {
        !self.kernel_ms.is_empty()
    }
}

/// What [`cast_rays_with`] runs: a pipeline that reads `Ray`s at `BINDING_RAYS` and writes `Hit`s
/// at `BINDING_HITS` for the batch's sub-ranges, with `Push { uint ray_count; }`. The batching,
/// descriptor sets, barriers, timestamps, markers, submits and downloads are the caller's; this
/// is only "bind and dispatch this batch": a compute [`Kernel`] (one invocation per ray, or a
/// persistent kernel's fixed workgroups), or the ray-tracing pipeline (`gpu::rtpipeline`, one
/// launch per ray).
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

/// Casts `rays` with `kernel` over the bindings `scene` (the same in every batch): `warmup`
/// untimed runs, then `repeat` timed ones; the hits are those of the last run, and so are the
/// per-ray traversal counts when `kernel` is a `stats` variant. For every kernel that reads `Ray`s
/// at `BINDING_RAYS` and writes `Hit`s at `BINDING_HITS` with `Push { uint ray_count; }` (our
/// ray-casting kernels through `pipeline::DeviceScene`, and the ray-query peer).
pub fn cast_rays(
    ctx: &Context,
    kernel: &Kernel,
    scene: &[(u32, Resource)],
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    cast_rays_with(ctx, kernel, scene, rays, opts)
}

/// [`cast_rays`] with any [`RayDispatch`]: the same batches, bindings, barriers, timestamps and
/// results, `kernel` only binding and dispatching each batch (the ray-tracing-pipeline peer).
pub fn cast_rays_with(
    ctx: &Context,
    kernel: &(impl RayDispatch + ?Sized),
    scene: &[(u32, Resource)],
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    if opts.batch_rays == 0 {
        return Err(Error::Usage("--batch-rays 0: a batch holds at least one ray".into()));
    }
    if rays.is_empty() {
        let traversal = kernel.bindings().contains_key(&BINDING_TRAVERSAL_STATS).then(Vec::new);
        return Ok(RaycastResult { hits: vec![], kernel_ms: vec![], wall_ms: vec![], batches: 0, traversal });
    }
    let info = ctx.info();
    let dev = &ctx.device.raw;
    let stage = kernel.stage();
    // Batch: within the watchdog budget, the storage-buffer range, the dispatch limit, and a
    // multiple of 256 rays so every sub-range offset is aligned (256 * 16 B >= any
    // minStorageBufferOffsetAlignment, which the spec caps at 256).
    let by_range = info.max_storage_buffer_range as usize / std::mem::size_of::<Ray>();
    let by_dispatch = kernel.max_rays(info);
    let batch = (opts.batch_rays.min(by_range).min(by_dispatch) / 256 * 256).max(256);
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

    // A persistent kernel's next-ray counter: one u32, zeroed before each dispatch.
    let counter = match kernel.bindings().contains_key(&BINDING_RAY_COUNTER) {
        true => Some(ctx.create_buffer(
            "ray counter",
            4,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
            gpu_allocator::MemoryLocation::GpuOnly,
        )?),
        false => None,
    };

    let (_pool, sets) = DescriptorPool::new(ctx, kernel, nbatches as u32)?;
    for (bi, &set) in sets.iter().enumerate() {
        let first = (bi * batch) as u64;
        let count = batch.min(rays.len() - bi * batch) as u64;
        let mut resources: Vec<(u32, Resource)> = scene.to_vec();
        resources.push((BINDING_RAYS, Resource::Buffer { buffer: &ray_buf, offset: first * 32, range: count * 32 }));
        for (binding, size, buf) in &outputs {
            resources.push((*binding, Resource::Buffer { buffer: buf, offset: first * size, range: count * size }));
        }
        if let Some(c) = &counter {
            resources.push((BINDING_RAY_COUNTER, Resource::Buffer { buffer: c, offset: 0, range: 4 }));
        }
        write_set(ctx, kernel, set, &resources)?;
    }
    // A planted slowdown (tests of the regression gate and of `ab`): this kernel's dispatch
    // recorded about F times.
    let slowdown = Slowdown::from_env()?;
    let timestamps = Timestamps::supported(ctx);
    let queries = Timestamps::new(ctx, nbatches as u32)?;
    let mut dispatch = Dispatch { ctx, cmds: vec![] };

    dispatch.cmds = ctx.allocate_command_buffers(nbatches as u32)?;
    // What each batch's submit runs (the dispatch log and crash markers name it).
    let what: Vec<String> = (0..nbatches)
        .map(|bi| {
            let first = bi * batch;
            let end = (first + batch).min(rays.len());
            format!("{} batch {}/{nbatches} (rays {first}..{end})", kernel.name(), bi + 1)
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
            if let Some(c) = &counter {
                // The previous dispatch's atomics finish before the counter is zeroed (the
                // barrier below makes the zero visible to this dispatch).
                memory_barrier(
                    dev,
                    cmd,
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                    ),
                    (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
                );
                dev.cmd_fill_buffer(cmd, c.raw, 0, 4, 0);
            }
            // The previous run's dispatch wrote the same output ranges (and uploads came before).
            memory_barrier(
                dev,
                cmd,
                (
                    vk::PipelineStageFlags::COMPUTE_SHADER | stage | vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                ),
                (stage, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE),
            );
            let marker = ctx.mark_begin(dev, cmd, what[bi].clone());
            let compute = stage == vk::PipelineStageFlags::COMPUTE_SHADER;
            if !compute {
                // The markers order "begun" before the compute stage: this stage comes after.
                memory_barrier(
                    dev,
                    cmd,
                    (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::empty()),
                    (stage, vk::AccessFlags::empty()),
                );
            }
            queries.start(dev, cmd, q);
            kernel.record_rays(dev, cmd, set, count);
            let repeats = Slowdown::repeats_for(slowdown.as_ref(), kernel.name(), count);
            let again = (1..repeats.whole).map(|_| count).chain((repeats.partial > 0).then_some(repeats.partial));
            for rays in again {
                // The same dispatch again over the same outputs, or over its first `rays` (and,
                // for a persistent kernel, a counter zeroed again): the previous one's writes
                // and atomics finish first.
                let shader = (stage, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE);
                if let Some(c) = &counter {
                    memory_barrier(
                        dev,
                        cmd,
                        shader,
                        (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
                    );
                    dev.cmd_fill_buffer(cmd, c.raw, 0, 4, 0);
                    memory_barrier(
                        dev,
                        cmd,
                        (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
                        shader,
                    );
                } else {
                    memory_barrier(dev, cmd, shader, shader);
                }
                kernel.record_rays(dev, cmd, set, rays);
            }
            if !compute {
                // Hands the outputs to the compute stage, where the markers and the downloads
                // (`buffer::read_back`) expect the last shader writes.
                memory_barrier(
                    dev,
                    cmd,
                    (stage, vk::AccessFlags::SHADER_WRITE),
                    (
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                    ),
                );
            }
            queries.end(dev, cmd, q);
            ctx.mark_end(dev, cmd, marker);
            dev.end_command_buffer(cmd).during("recording a dispatch")?;
        }
    }

    let mut kernel_ms = Vec::new();
    let mut wall_ms = Vec::new();
    let runs = opts.warmup + opts.repeat.max(1);
    let tracing = crate::trace::on();
    for run in 0..runs {
        let t0 = Instant::now();
        for (&cmd, what) in dispatch.cmds.iter().zip(&what) {
            ctx.submit_and_wait(cmd, what)?;
        }
        let wall = t0.elapsed().as_secs_f64() * 1e3;
        let warm_up = run < opts.warmup;
        // A warm-up run's timestamps are read only for the trace.
        let batch_ms = match timestamps && (!warm_up || tracing) {
            true => Some(queries.read_ms()?),
            false => None,
        };
        if tracing {
            trace_run(kernel.name(), t0, wall, batch_ms.as_deref(), run, warm_up);
        }
        if warm_up {
            continue;
        }
        wall_ms.push(wall);
        if let Some(ms) = batch_ms {
            kernel_ms.push(ms.iter().sum());
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

/// The labels a dispatch's name in the trace is made of, in this order (the pipeline's, then the
/// caller's); the args carry every label.
const NAME_LABELS: [&str; 7] = ["method", "layout", "traversal", "access", "scene", "set", "round"];

/// One run of a cast on the trace's GPU track: placed at the host time of its first submit
/// (`at`), lasting its batches' GPU time (`batch_ms`, from the timestamps), or the host's wall
/// time where the device has no timestamps; named by the calling thread's labels (the method,
/// layout, traversal and access path `pipeline::DeviceScene` sets, the scene, ray set and round
/// the caller sets), else by the kernel.
fn trace_run(kernel: &str, at: Instant, wall_ms: f64, batch_ms: Option<&[f64]>, run: usize, warm_up: bool) {
    use crate::trace::Arg;
    let labels = crate::trace::current_labels();
    let parts: Vec<String> = NAME_LABELS
        .iter()
        .filter_map(|&k| {
            let v = labels.iter().rev().find(|(l, _)| *l == k)?;
            Some(if k == "round" { format!("round {}", v.1) } else { v.1.to_string() })
        })
        .collect();
    let name = if labels.iter().any(|(k, _)| *k == "method") { parts.join(" ") } else { kernel.to_owned() };
    let (dur, clock) = match batch_ms {
        Some(b) => (b.iter().sum(), "GPU timestamps"),
        None => (wall_ms, "host wall time of the submits and waits (no GPU timestamps)"),
    };
    let mut args: Vec<(&str, Arg)> = vec![
        ("kernel", kernel.into()),
        ("duration", clock.into()),
        ("placement", "host clock at the first submit".into()),
        ("wall_ms", wall_ms.into()),
        ("cast_run", run.into()),
        ("cast_warm_up", warm_up.into()),
    ];
    if let Some(b) = batch_ms {
        args.push(("batches", b.len().into()));
        if b.len() > 1 {
            args.push(("batch_ms", b.to_vec().into()));
        }
    }
    crate::trace::complete(crate::trace::GPU, "dispatch", &name, at, dur, args);
}

/// Most rays per submit such that one submit takes about `target_ms`: times one untimed run
/// (`trace`) of up to 4096 rays spread over the set and scales, within [256, `max`]. The driver's
/// traversal speed is unknown in advance (lavapipe's is some 300x slower than our kernels), and a
/// submit must stay far from the submit timeout and any watchdog.
pub fn batch_for_with(
    rays: &[Ray],
    target_ms: f64,
    max: usize,
    trace: impl FnOnce(&[Ray], &RaycastOptions) -> Result<RaycastResult>,
) -> Result<usize> {
    if rays.is_empty() {
        return Ok(max.max(256));
    }
    // Every k-th ray: a ray set's order is not random (primary rays go row by row, and the top
    // rows of an image may all miss).
    let stride = rays.len().div_ceil(4096);
    let probe: Vec<Ray> = rays.iter().step_by(stride).copied().collect();
    let t = Instant::now();
    trace(&probe, &RaycastOptions { warmup: 0, repeat: 1, batch_rays: probe.len() })?;
    let per_ray_ms = t.elapsed().as_secs_f64() * 1e3 / probe.len() as f64;
    Ok(((target_ms / per_ray_ms) as usize).clamp(256, max.max(256)))
}
