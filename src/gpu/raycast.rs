//! Ray casting on the GPU: rays dispatched in batches over a scene's bindings, each batch its own
//! submit (short enough for a display GPU's watchdog) with a pair of timestamps.

use std::time::Instant;

use ash::vk;

use super::buffer::Buffer;
use super::commands::memory_barrier;
use super::context::Context;
use super::descriptors::{write_set, DescriptorPool, Resource};
use super::slowdown::Slowdown;
use super::timestamps::Timestamps;
use super::traversal_stats::TraversalCounts;
use crate::error::{Error, Result, VkContext};
use crate::rays::{Hit, Ray};
use crate::report::Summary;
use crate::shared::{BINDING_HITS, BINDING_RAYS, BINDING_RAY_COUNTER, BINDING_TRAVERSAL_STATS};

pub use super::dispatch::{Batch, RayDispatch, PERSISTENT_WORKGROUPS};

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
/// per-ray traversal counts when `kernel` is a `stats` variant. For every [`RayDispatch`] that
/// reads `Ray`s at `BINDING_RAYS` and writes `Hit`s at `BINDING_HITS` with `Push { uint
/// ray_count; }` (our ray-casting kernels through `pipeline::DeviceScene`, the ray-query peer,
/// and the ray-tracing-pipeline peer, whose dispatch only binds and launches each batch).
///
/// The one place a planted slowdown (`TRILAB_INJECT_SLOWDOWN`, [`super::slowdown`]: tests of
/// the regression gate and of `ab`) is installed, around `kernel`, when the environment asks
/// for one; [`cast_rays_with`] is the cast itself.
pub fn cast_rays(
    ctx: &Context,
    kernel: &(impl RayDispatch + ?Sized),
    scene: &[(u32, Resource)],
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    if let Some(nothing) = nothing_to_cast(kernel, rays, opts)? {
        return Ok(nothing);
    }
    match Slowdown::from_env()? {
        Some(slowdown) => cast_rays_with(ctx, &slowdown.around(kernel), scene, rays, opts),
        None => cast_rays_with(ctx, kernel, scene, rays, opts),
    }
}

/// The cast [`cast_rays`] describes, with no planted slowdown: the batches, bindings, barriers,
/// timestamps, submits and results, `kernel` only binding and dispatching each batch.
pub fn cast_rays_with(
    ctx: &Context,
    kernel: &(impl RayDispatch + ?Sized),
    scene: &[(u32, Resource)],
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    if let Some(nothing) = nothing_to_cast(kernel, rays, opts)? {
        return Ok(nothing);
    }
    let batching = Batching::new(ctx, kernel, rays.len(), opts);
    let buffers = CastBuffers::new(ctx, kernel, rays)?;
    let (_pool, sets) = descriptor_sets(ctx, kernel, scene, &buffers, &batching)?;
    let nbatches = batching.count;
    let queries = Timestamps::new(ctx, nbatches as u32)?;
    let mut dispatch = Dispatch { ctx, cmds: vec![] };
    dispatch.cmds = ctx.allocate_command_buffers(nbatches as u32)?;
    // What each batch's submit runs (the dispatch log and crash markers name it).
    let what: Vec<String> = (0..nbatches)
        .map(|bi| {
            let (first, count) = batching.range(bi);
            format!("{} batch {}/{nbatches} (rays {first}..{})", kernel.name(), bi + 1, first + count)
        })
        .collect();
    for (bi, (&cmd, &set)) in dispatch.cmds.iter().zip(&sets).enumerate() {
        let count = batching.range(bi).1 as u32;
        let batch = Batch { set, count, counter: buffers.counter.as_ref().map(|c| c.raw) };
        record_batch(ctx, kernel, cmd, &batch, &queries, bi as u32, &what[bi])?;
    }
    let (kernel_ms, wall_ms) = timed_runs(ctx, kernel.name(), &dispatch.cmds, &what, &queries, opts)?;
    let mut downloads = Vec::new();
    for (_, size, buf) in &buffers.outputs {
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

/// A cast's answer before any work: an error for batches of no ray, and for no ray an empty
/// result (with empty traversal counts for a `stats` kernel); `None` when there is work.
fn nothing_to_cast(
    kernel: &(impl RayDispatch + ?Sized),
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<Option<RaycastResult>> {
    if opts.batch_rays == 0 {
        return Err(Error::Usage("--batch-rays 0: a batch holds at least one ray".into()));
    }
    if rays.is_empty() {
        let traversal = kernel.bindings().contains_key(&BINDING_TRAVERSAL_STATS).then(Vec::new);
        return Ok(Some(RaycastResult { hits: vec![], kernel_ms: vec![], wall_ms: vec![], batches: 0, traversal }));
    }
    Ok(None)
}

/// How a cast's rays split into batches: `size` rays each but the last, `count` batches.
struct Batching {
    size: usize,
    count: usize,
    rays: usize,
}

impl Batching {
    /// Batch: within the watchdog budget, the storage-buffer range, the dispatch limit, and a
    /// multiple of 256 rays so every sub-range offset is aligned (256 * 16 B >= any
    /// minStorageBufferOffsetAlignment, which the spec caps at 256).
    fn new(ctx: &Context, kernel: &(impl RayDispatch + ?Sized), rays: usize, opts: &RaycastOptions) -> Batching {
        let info = ctx.info();
        let by_range = info.max_storage_buffer_range as usize / std::mem::size_of::<Ray>();
        let by_dispatch = kernel.max_rays(info);
        let size = (opts.batch_rays.min(by_range).min(by_dispatch) / 256 * 256).max(256);
        Batching { size, count: rays.div_ceil(size), rays }
    }

    /// Batch `bi`'s first ray and its number of rays.
    fn range(&self, bi: usize) -> (usize, usize) {
        let first = bi * self.size;
        (first, self.size.min(self.rays - first))
    }
}

/// A cast's buffers: its rays; its per-ray outputs (binding, bytes per ray, buffer): the hits,
/// and the counters of a stats kernel; a persistent kernel's next-ray counter (one u32, zeroed
/// before each dispatch).
struct CastBuffers {
    rays: Buffer,
    outputs: Vec<(u32, u64, Buffer)>,
    counter: Option<Buffer>,
}

impl CastBuffers {
    fn new(ctx: &Context, kernel: &(impl RayDispatch + ?Sized), rays: &[Ray]) -> Result<CastBuffers> {
        let ray_buf = ctx.upload("rays", bytemuck::cast_slice(rays), vk::BufferUsageFlags::STORAGE_BUFFER)?;
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
        let counter = match kernel.bindings().contains_key(&BINDING_RAY_COUNTER) {
            true => Some(ctx.create_buffer(
                "ray counter",
                4,
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_DST,
                gpu_allocator::MemoryLocation::GpuOnly,
            )?),
            false => None,
        };
        Ok(CastBuffers { rays: ray_buf, outputs, counter })
    }
}

/// One descriptor set per batch: `scene`'s bindings, the batch's ranges of the rays and the
/// outputs, and the counter.
fn descriptor_sets<'c>(
    ctx: &'c Context,
    kernel: &(impl RayDispatch + ?Sized),
    scene: &[(u32, Resource)],
    buffers: &CastBuffers,
    batching: &Batching,
) -> Result<(DescriptorPool<'c>, Vec<vk::DescriptorSet>)> {
    let (pool, sets) = DescriptorPool::new(ctx, kernel, batching.count as u32)?;
    for (bi, &set) in sets.iter().enumerate() {
        let (first, count) = batching.range(bi);
        let (first, count) = (first as u64, count as u64);
        let mut resources: Vec<(u32, Resource)> = scene.to_vec();
        resources
            .push((BINDING_RAYS, Resource::Buffer { buffer: &buffers.rays, offset: first * 32, range: count * 32 }));
        for (binding, size, buf) in &buffers.outputs {
            resources.push((*binding, Resource::Buffer { buffer: buf, offset: first * size, range: count * size }));
        }
        if let Some(c) = &buffers.counter {
            resources.push((BINDING_RAY_COUNTER, Resource::Buffer { buffer: c, offset: 0, range: 4 }));
        }
        write_set(ctx, kernel, set, &resources)?;
    }
    Ok((pool, sets))
}

/// Records `batch` into `cmd` (a fresh command buffer): timestamp pair `q` reset, a persistent
/// kernel's counter zeroed, the barriers, and the kernel's batch between the crash marker
/// `what` and the timestamps.
fn record_batch(
    ctx: &Context,
    kernel: &(impl RayDispatch + ?Sized),
    cmd: vk::CommandBuffer,
    batch: &Batch,
    queries: &Timestamps,
    q: u32,
    what: &str,
) -> Result<()> {
    let dev = &ctx.device.raw;
    let stage = kernel.stage();
    // SAFETY: recording into a freshly allocated command buffer; every object referenced
    // outlives the submits (all waited for before `cast_rays_with` returns).
    unsafe {
        dev.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default()).during("recording a dispatch")?;
        queries.reset(dev, cmd, q);
        if let Some(c) = batch.counter {
            // The previous dispatch's atomics finish before the counter is zeroed (the
            // barrier below makes the zero visible to this dispatch).
            memory_barrier(
                dev,
                cmd,
                (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE),
                (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
            );
            dev.cmd_fill_buffer(cmd, c, 0, 4, 0);
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
        let marker = ctx.mark_begin(dev, cmd, what.to_owned());
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
        kernel.record_batch(dev, cmd, batch);
        if !compute {
            // Hands the outputs to the compute stage, where the markers and the downloads
            // (`buffer::read_back`) expect the last shader writes.
            memory_barrier(
                dev,
                cmd,
                (stage, vk::AccessFlags::SHADER_WRITE),
                (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE),
            );
        }
        queries.end(dev, cmd, q);
        ctx.mark_end(dev, cmd, marker);
        dev.end_command_buffer(cmd).during("recording a dispatch")?;
    }
    Ok(())
}

/// Submits the recorded batches `opts.warmup` times untimed, then `opts.repeat` (at least once)
/// timed, each submit waited for; every run goes on the trace. Each timed run's GPU time (the
/// sum over its batches; none where the device has no timestamps) and host wall time, ms.
fn timed_runs(
    ctx: &Context,
    kernel: &str,
    cmds: &[vk::CommandBuffer],
    what: &[String],
    queries: &Timestamps,
    opts: &RaycastOptions,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let timestamps = Timestamps::supported(ctx);
    let mut kernel_ms = Vec::new();
    let mut wall_ms = Vec::new();
    let runs = opts.warmup + opts.repeat.max(1);
    let tracing = crate::timeline::on();
    for run in 0..runs {
        let t0 = Instant::now();
        for (&cmd, what) in cmds.iter().zip(what) {
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
            trace_run(kernel, t0, wall, batch_ms.as_deref(), run, warm_up);
        }
        if warm_up {
            continue;
        }
        wall_ms.push(wall);
        if let Some(ms) = batch_ms {
            kernel_ms.push(ms.iter().sum());
        }
    }
    Ok((kernel_ms, wall_ms))
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
    use crate::timeline::Arg;
    let labels = crate::timeline::current_labels();
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
    crate::timeline::complete(crate::timeline::GPU, "dispatch", &name, at, dur, args);
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
