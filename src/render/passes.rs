//! The render loop: passes over the image, one dispatch per submit, each sized to a wall-clock
//! target (so no submit comes near a GPU watchdog), with the path tracer's own buffers beside
//! the scene and a host copy of the accumulation after every pass (what a failure later on still
//! writes out).

use std::time::Instant;

use ash::vk;

use super::{
    GpuParams, PartialRender, PathtracePush, Progress, RenderFailure, RenderResult, RenderSettings, RenderTarget,
};
use crate::encoding::AccessPath;
use crate::error::{Error, Result};
use crate::gpu::buffer::{read_back, Buffer, TexelBuffer};
use crate::gpu::commands::memory_barrier;
use crate::gpu::descriptors::{write_set, DescriptorPool, Resource};
use crate::gpu::kernel::Kernel;
use crate::gpu::timestamps::Timestamps;
use crate::gpu::Context;
use crate::shared::Texel;
use crate::shared::{BINDING_ACCUM, BINDING_LIGHTS, BINDING_MATERIALS, BINDING_PARAMS, BINDING_SHADING, BINDING_STATS};

/// Ray and sample counters the path tracer keeps per submit (`stats` in `glsl/pathtrace.comp`):
/// closest-hit rays, occlusion rays, dropped samples, and one spare.
const RENDER_COUNTERS: usize = 4;

/// Shading records or lights: a texel buffer, or on the storage path (`all_storage`) a storage buffer.
enum Extra {
    Texels(TexelBuffer),
    Storage(Buffer),
}

impl Extra {
    fn upload(ctx: &Context, name: &str, bytes: &[u8], storage: bool) -> Result<Extra> {
        if !storage {
            return Ok(Extra::Texels(ctx.upload_texels(name, bytes, Texel::Rgba32Float)?));
        }
        // A binding cannot be empty: one zero texel (no lights), as a texel buffer gets.
        let zero = [0u8; 16];
        let bytes = if bytes.is_empty() { &zero[..] } else { bytes };
        Ok(Extra::Storage(ctx.upload(name, bytes, vk::BufferUsageFlags::STORAGE_BUFFER)?))
    }

    fn resource(&self) -> Resource<'_> {
        match self {
            Extra::Texels(t) => Resource::Texels(t),
            Extra::Storage(b) => Resource::whole(b),
        }
    }
}

/// The path tracer's own buffers beside the scene, and the descriptor set binding them with the
/// scene's. The pool comes first so that it is destroyed first (fields drop in order).
struct RenderBuffers<'a> {
    _pool: DescriptorPool<'a>,
    set: vk::DescriptorSet,
    _materials: TexelBuffer,
    _shading: Extra,
    _lights: Extra,
    _params: Buffer,
    /// Sum of radiance and coverage per pixel (rgba32f), on the device.
    accum: Buffer,
    /// The counters of the running submit, and their host-visible copy.
    stats: Buffer,
    stats_readback: Buffer,
    /// The accumulation as of the last whole pass, copied back after each pass.
    accum_readback: Buffer,
}

impl<'a> RenderBuffers<'a> {
    fn new(ctx: &'a Context, k: &Kernel, target: &RenderTarget, s: &RenderSettings) -> Result<RenderBuffers<'a>> {
        let scene = &target.scene;
        let pixels = s.pixels();
        let materials = ctx.upload_texels("materials", bytemuck::cast_slice(&scene.materials), Texel::Rgba32Float)?;
        let storage = target.device.access == AccessPath::Storage;
        let shading = Extra::upload(ctx, "shading", bytemuck::cast_slice(&scene.shading), storage)?;
        let lights = Extra::upload(ctx, "lights", bytemuck::cast_slice(&scene.lights), storage)?;
        let params = GpuParams::new(s, scene);
        let params = ctx.upload("render params", bytemuck::bytes_of(&params), vk::BufferUsageFlags::UNIFORM_BUFFER)?;
        let accum = ctx.upload(
            "accumulation image",
            &vec![0u8; pixels as usize * 16],
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        )?;
        let counter_bytes = 4 * RENDER_COUNTERS as u64;
        let stats = ctx.create_buffer(
            "render counters",
            counter_bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC
                | vk::BufferUsageFlags::TRANSFER_DST,
            gpu_allocator::MemoryLocation::GpuOnly,
        )?;
        let stats_readback = ctx.create_buffer(
            "render counters (readback)",
            counter_bytes,
            vk::BufferUsageFlags::TRANSFER_DST,
            gpu_allocator::MemoryLocation::GpuToCpu,
        )?;
        let accum_readback = ctx.create_buffer(
            "accumulation image (readback)",
            pixels * 16,
            vk::BufferUsageFlags::TRANSFER_DST,
            gpu_allocator::MemoryLocation::GpuToCpu,
        )?;
        let (pool, sets) = DescriptorPool::new(ctx, k, 1)?;
        let mut resources: Vec<(u32, Resource)> = target.device.resources().collect();
        resources.extend([
            (BINDING_MATERIALS, Resource::Texels(&materials)),
            (BINDING_SHADING, shading.resource()),
            (BINDING_LIGHTS, lights.resource()),
            (BINDING_PARAMS, Resource::whole(&params)),
            (BINDING_ACCUM, Resource::whole(&accum)),
            (BINDING_STATS, Resource::whole(&stats)),
        ]);
        write_set(ctx, k, sets[0], &resources)?;
        drop(resources);
        Ok(RenderBuffers {
            _pool: pool,
            set: sets[0],
            _materials: materials,
            _shading: shading,
            _lights: lights,
            _params: params,
            accum,
            stats,
            stats_readback,
            accum_readback,
        })
    }

    /// The counters of the last submit.
    fn counters(&self) -> Result<[u32; RENDER_COUNTERS]> {
        let bytes = self
            .stats_readback
            .mapped()
            .ok_or_else(|| Error::NoDevice("readback buffer is not host-visible".into()))?;
        Ok(bytemuck::pod_read_unaligned(bytes))
    }

    /// Replaces `into` with the accumulation as of the last whole pass.
    fn read_accumulation(&self, into: &mut Vec<[f32; 4]>) -> Result<()> {
        let copy = self
            .accum_readback
            .mapped()
            .ok_or_else(|| Error::NoDevice("accumulation readback buffer is not host-visible".into()))?;
        into.clear();
        into.extend(copy.chunks_exact(16).map(bytemuck::pod_read_unaligned::<[f32; 4]>));
        Ok(())
    }

    /// Records one dispatch of a pass: clear the counters, run `k` on `push`'s pixels and
    /// samples (timed in query 0 of `queries`), copy the counters back and, after the last
    /// dispatch of a pass (`whole_pass`), the accumulation.
    ///
    /// # Safety
    /// `cmd` is recording, and every object recorded here outlives the submit's wait.
    #[allow(clippy::too_many_arguments)]
    unsafe fn record_dispatch(
        &self,
        ctx: &Context,
        dev: &ash::Device,
        cmd: vk::CommandBuffer,
        k: &Kernel,
        queries: &Timestamps,
        push: &PathtracePush,
        what: &str,
        whole_pass: bool,
    ) {
        queries.reset(dev, cmd, 0);
        // The previous submit's copy of the counters (a transfer read) before this fill
        // overwrites them.
        memory_barrier(
            dev,
            cmd,
            (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::empty()),
            (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
        );
        dev.cmd_fill_buffer(cmd, self.stats.raw, 0, vk::WHOLE_SIZE, 0);
        // The fill, the previous dispatch's accumulation and the previous pass's copy of it (a
        // transfer read) before this dispatch.
        memory_barrier(
            dev,
            cmd,
            (
                vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::AccessFlags::TRANSFER_WRITE | vk::AccessFlags::SHADER_WRITE,
            ),
            (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE),
        );
        let marker = ctx.mark_begin(dev, cmd, what.to_owned());
        queries.start(dev, cmd, 0);
        k.record(dev, cmd, self.set, bytemuck::bytes_of(push), push.pixel_count.div_ceil(k.layout.local_size.0));
        queries.end(dev, cmd, 0);
        ctx.mark_end(dev, cmd, marker);
        read_back(dev, cmd, &self.stats, &self.stats_readback, self.stats.size);
        if whole_pass {
            // The whole pass is in: keep a host copy (what a failure later on still has to
            // write out).
            read_back(dev, cmd, &self.accum, &self.accum_readback, self.accum.size);
        }
    }
}

/// One pass over the image: `samples` per pixel, in dispatches of at most `chunk` pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PassShape {
    samples: u32,
    chunk: u64,
}

impl PassShape {
    /// Sizes the next pass so that one submit takes about `s.submit_ms`, from `cost`, the
    /// measured seconds per pixel-sample (`None` before the first dispatch: then 1 spp in
    /// chunks of at most 65,536 pixels, to measure it safely). `remaining` samples per pixel are
    /// left; `local` is the kernel's workgroup size and `max_groups` the device's limit.
    fn next(s: &RenderSettings, cost: Option<f64>, remaining: u32, local: u32, max_groups: u64) -> PassShape {
        let pixels = s.pixels();
        let target = s.submit_ms * 1e-3;
        let (samples, chunk) = match cost {
            None => (1, 65_536u64),
            Some(c) => {
                let per_pass = c * pixels as f64;
                let samples = ((target / per_pass).floor() as u64).clamp(1, remaining as u64) as u32;
                let chunk = if per_pass > target { ((target / c) as u64).max(local as u64) } else { pixels };
                (samples, chunk)
            }
        };
        let chunk = chunk.min(max_groups * local as u64).max(1);
        // The kernel counts rays in 32-bit counters per submit: a sample traces at most
        // 2 (max_depth + 1) rays, so keep pixels x samples of one submit below 2^32 / that.
        let max_work = (u32::MAX as u64 / (2 * (s.max_depth as u64 + 1))).max(1);
        let samples = (samples as u64).min((max_work / chunk.min(pixels)).max(1)) as u32;
        let chunk = chunk.min(max_work / samples as u64).max(1);
        PassShape { samples, chunk }
    }
}

/// Renders `target` with its kernel. `progress` is called after each pass over the image;
/// returning `false` stops the render there, keeping what it has.
///
/// After each pass the accumulation is copied to a host-visible buffer and from there to
/// `RenderResult::accum`, so when a later submit fails (device lost, out of memory, timeout)
/// the error is [`RenderFailure::Partial`], carrying the last whole pass; a lost device or
/// out-of-memory inside it is an `Error::GpuFault` naming the dispatch (`gpu::markers`).
pub fn render(
    ctx: &Context,
    target: &RenderTarget,
    s: &RenderSettings,
    progress: &mut dyn FnMut(Progress) -> bool,
) -> std::result::Result<RenderResult, RenderFailure> {
    s.check()?;
    let kernel = target.kernel;
    let k = ctx.kernel_specialized(kernel.source, &[(0, kernel.spec_mask)])?;
    let buffers = RenderBuffers::new(ctx, &k, target, s)?;
    let queries = Timestamps::new(ctx, 1)?;
    let mut result = RenderResult {
        width: s.width,
        height: s.height,
        accum: vec![],
        spp: 0,
        interrupted: false,
        failed: None,
        closest_rays: 0,
        shadow_rays: 0,
        dropped_samples: 0,
        gpu_ms: Timestamps::supported(ctx).then_some(0.0),
        wall_ms: 0.0,
        submits: 0,
        kernel: kernel.source.name,
        spec_mask: kernel.spec_mask,
    };
    let start = Instant::now();
    // Any failure part-way (a lost device, out of memory, a timeout) still hands back the last
    // whole pass, which `result.accum` holds.
    let outcome = run_passes(ctx, &k, &buffers, &queries, s, &mut result, progress, start);
    result.wall_ms = start.elapsed().as_secs_f64() * 1e3;
    match outcome {
        Ok(()) => Ok(result),
        Err(e) if result.spp > 0 => {
            let source = ctx.fault(e);
            result.failed = Some(source.to_string());
            Err(RenderFailure::Partial(PartialRender { result: Box::new(result), source }))
        }
        Err(e) => Err(RenderFailure::Error(ctx.fault(e))),
    }
}

/// The render loop: passes over the image until `s.spp` samples per pixel are in or `progress`
/// says stop, one submit per dispatch, each sized by [`PassShape::next`]. Samples accumulate in
/// sample order, so the image does not depend on the batching.
#[allow(clippy::too_many_arguments)]
fn run_passes(
    ctx: &Context,
    k: &Kernel,
    buffers: &RenderBuffers,
    queries: &Timestamps,
    s: &RenderSettings,
    result: &mut RenderResult,
    progress: &mut dyn FnMut(Progress) -> bool,
    start: Instant,
) -> Result<()> {
    let pixels = s.pixels();
    let local = k.layout.local_size.0;
    let max_groups = ctx.info().max_compute_workgroup_count[0] as u64;
    // Seconds per pixel-sample, measured, averaged over the dispatches.
    let mut cost: Option<f64> = None;
    let mut pass = 0u32;
    while result.spp < s.spp {
        let shape = PassShape::next(s, cost, s.spp - result.spp, local, max_groups);
        pass += 1;
        let mut first = 0u64;
        while first < pixels {
            let count = shape.chunk.min(pixels - first);
            let push = PathtracePush {
                sample_first: result.spp,
                sample_count: shape.samples,
                pixel_first: first as u32,
                pixel_count: count as u32,
            };
            let what = format!(
                "{} pass {pass} dispatch {} (samples {}..{}, pixels {}..{})",
                k.name,
                result.submits + 1,
                push.sample_first,
                push.sample_first + shape.samples,
                first,
                first + count
            );
            let whole_pass = first + count == pixels;
            let t0 = Instant::now();
            ctx.one_shot(&what, |dev, cmd| {
                // SAFETY: one_shot records into a fresh command buffer and waits for it; the
                // kernel, buffers and queries outlive that wait.
                unsafe { buffers.record_dispatch(ctx, dev, cmd, k, queries, &push, &what, whole_pass) }
            })?;
            let seconds = t0.elapsed().as_secs_f64();
            if let Some(gpu_ms) = result.gpu_ms.as_mut() {
                *gpu_ms += queries.read_ms()?[0];
            }
            let [closest, shadow, dropped, _] = buffers.counters()?;
            result.closest_rays += closest as u64;
            result.shadow_rays += shadow as u64;
            result.dropped_samples += dropped as u64;
            result.submits += 1;
            let c = seconds / (count as f64 * shape.samples as f64);
            cost = Some(match cost {
                None => c,
                Some(old) => 0.5 * (old + c),
            });
            first += count;
        }
        buffers.read_accumulation(&mut result.accum)?;
        result.spp += shape.samples;
        let keep_going = progress(Progress {
            spp_done: result.spp,
            spp_total: s.spp,
            seconds: start.elapsed().as_secs_f64(),
            accum: &result.accum,
        });
        if !keep_going && result.spp < s.spp {
            result.interrupted = true;
            break;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::rays::Camera;

    fn settings(width: u32, height: u32, spp: u32, max_depth: u32, submit_ms: f64) -> RenderSettings {
        RenderSettings {
            width,
            height,
            spp,
            max_depth,
            rr_depth: 3,
            seed: 1,
            camera: Camera::look(Vec3::ZERO, Vec3::Z, Vec3::Y, 1.0),
            env: [0.0; 3],
            sky: None,
            ray_eps: 1e-4,
            submit_ms,
            next_event: true,
        }
    }

    /// The limits every pass must respect, whatever the measured cost.
    fn check_limits(s: &RenderSettings, p: PassShape, remaining: u32, local: u32, max_groups: u64) {
        assert!(p.samples >= 1 && p.samples <= remaining, "{p:?}: samples outside 1..={remaining}");
        assert!(p.chunk >= 1 && p.chunk <= max_groups * local as u64, "{p:?}: chunk beyond the dispatch limit");
        let rays = 2 * (s.max_depth as u64 + 1) * p.samples as u64 * p.chunk.min(s.pixels());
        assert!(rays <= u32::MAX as u64, "{p:?}: a submit could overflow the 32-bit ray counters ({rays} rays)");
    }

    #[test]
    fn the_first_pass_measures_with_one_sample_in_small_chunks() {
        let s = settings(800, 600, 500, 16, 100.0);
        let p = PassShape::next(&s, None, 500, 64, 65_535);
        assert_eq!(p, PassShape { samples: 1, chunk: 65_536 });
        check_limits(&s, p, 500, 64, 65_535);
    }

    #[test]
    fn a_cheap_scene_takes_many_samples_over_the_whole_image() {
        let s = settings(100, 100, 64, 4, 100.0);
        // 1 us per pixel-sample: a pass of 10,000 pixels takes 10 ms, so ten fit in 100 ms.
        let p = PassShape::next(&s, Some(1e-6), 64, 64, 65_535);
        assert_eq!(p, PassShape { samples: 10, chunk: 10_000 });
        // Never more than what is left.
        assert_eq!(PassShape::next(&s, Some(1e-6), 3, 64, 65_535).samples, 3);
    }

    #[test]
    fn an_expensive_scene_splits_the_image_and_respects_every_limit() {
        let s = settings(4096, 4096, 8, 64, 50.0);
        for cost in [1e-3, 1e-5, 1e-7, 1e-9, 1e-12] {
            for (local, max_groups) in [(64, 65_535), (1, 1), (256, 16)] {
                let p = PassShape::next(&s, Some(cost), 8, local, max_groups);
                check_limits(&s, p, 8, local, max_groups);
            }
        }
        // 1 ms per pixel-sample against a 50 ms target: 50 pixels, but at least a workgroup.
        assert_eq!(PassShape::next(&s, Some(1e-3), 8, 64, 65_535), PassShape { samples: 1, chunk: 64 });
    }
}
