//! `trilab render` as one library call: a scene file to an EXR, a tone-mapped PNG and a JSON
//! sidecar, written after the last pass, every `checkpoint_secs` on the way, when the caller
//! asks it to stop (Ctrl-C) and when the device fails part-way (the last whole pass), each file
//! atomically and never over an input.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use serde::Serialize;

use super::{
    output, render, EnvSpec, KernelChoice, PartialRender, Progress, RenderFailure, RenderResult, RenderSettings,
    RenderTarget, Sky,
};
use crate::bvh::BuildOptions;
use crate::conditioning::{MethodChoice, Recommendation};
use crate::encoding::{Layout, Method};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::pipeline::{HostScene, SceneRequest};
use crate::rays::CameraSpec;
use crate::report::Report;
use crate::scene::{load_obj, BsdfKind};

/// Everything `trilab render` is asked for.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    pub scene: PathBuf,
    /// The OpenEXR file; the PNG and JSON go beside it (same stem).
    pub out: PathBuf,
    pub method: MethodChoice,
    /// The node layout the path tracer traverses.
    pub layout: Layout,
    pub build: BuildOptions,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub rr_depth: u32,
    pub seed: u32,
    /// The camera: `front` (the default), `peer` or explicit.
    pub camera: CameraSpec,
    /// The environment; `None`: none for a scene with emitters, else the sky.
    pub env: Option<EnvSpec>,
    /// Direction towards the sun of the sky (default [`Sky::default`]'s).
    pub sun_dir: Option<[f32; 3]>,
    /// PNG exposure in stops.
    pub exposure: f32,
    pub kernel: KernelChoice,
    pub submit_ms: f64,
    /// Seconds between checkpoints (0: none).
    pub checkpoint_secs: f64,
}

/// The camera as the sidecar records it.
#[derive(Clone, Debug, Serialize)]
pub struct CameraRecord {
    pub eye: [f32; 3],
    pub forward: [f32; 3],
    pub up: [f32; 3],
    pub fov_y_degrees: f32,
}

/// The JSON sidecar: the request, the scene as rendered, and how far the render got.
#[derive(Clone, Debug, Serialize)]
pub struct RenderReport {
    pub scene: String,
    /// SHA-256 of the scene as rendered (positions, triangles, materials).
    pub scene_sha256: String,
    pub triangles: usize,
    pub method: Method,
    pub method_choice: String,
    /// The node layout traversed.
    pub layout: Layout,
    pub auto: Option<Recommendation>,
    /// The BVH built (as `leaf_size`, `leaf_policy`, `sah_group`).
    #[serde(flatten, serialize_with = "BuildOptions::serialize_fields")]
    pub build: BuildOptions,
    pub kernel: &'static str,
    pub kernel_choice: KernelChoice,
    pub bsdfs_in_kernel: Vec<&'static str>,
    pub bsdfs_in_scene: Vec<&'static str>,
    pub settings: RenderSettings,
    /// `--camera` as asked (`front`, `peer` or the numbers).
    pub camera_choice: String,
    pub camera: CameraRecord,
    /// The environment: `sky` (its parameters are `settings.sky`) or the constant radiance.
    pub environment: String,
    pub emissive_triangles: u32,
    pub gpu_scene_bytes: usize,
    pub device: String,
    pub driver: String,
    pub build_ms: f64,
    pub warnings: Vec<String>,
    pub spp_done: u32,
    /// Written by a checkpoint (the render went on).
    pub checkpoint: bool,
    pub interrupted: bool,
    /// Why the render stopped on an error (the image holds the passes before it).
    pub failed: Option<String>,
    /// Checkpoints: seconds into the render.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub submits: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wall_ms: Option<f64>,
    /// The finished render's rates.
    #[serde(flatten, skip_serializing_if = "Option::is_none")]
    pub finished: Option<Finished>,
    /// The EXR written.
    #[serde(skip)]
    pub out: PathBuf,
}

/// What a render that ran to its end (or to an interrupt) adds to the sidecar.
#[derive(Clone, Debug, Serialize)]
pub struct Finished {
    pub gpu_ms: Option<f64>,
    pub samples: u64,
    pub samples_per_second: f64,
    pub closest_rays: u64,
    pub shadow_rays: u64,
    pub mrays_per_second: f64,
    pub ray_definition: &'static str,
    pub dropped_samples_nan_or_inf: u64,
    #[serde(skip)]
    pub seconds: f64,
    #[serde(skip)]
    pub width: u32,
    #[serde(skip)]
    pub height: u32,
    #[serde(skip)]
    pub spp_asked: u32,
}

const RAY_DEFINITION: &str = "every BVH traversal counts: camera and bounce rays (closest hit) and next-event \
                              occlusion rays (any hit); rates use GPU timestamp time when available, else wall time";

impl Report for RenderReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let Some(f) = &self.finished else {
            return format!("{}: {} spp written\n", self.out.display(), self.spp_done);
        };
        format!(
            "{}: {}x{}, {} spp{} with {} ({}), {:.1} s: {:.3} Msamples/s, {:.2} Mrays/s{}\n",
            self.out.display(),
            f.width,
            f.height,
            self.spp_done,
            if self.interrupted { format!(" of {} (interrupted)", f.spp_asked) } else { String::new() },
            self.kernel,
            self.bsdfs_in_kernel.join("+"),
            f.seconds,
            f.samples_per_second * 1e-6,
            f.mrays_per_second,
            if f.gpu_ms.is_some() { " (GPU time)" } else { " (wall time)" },
        )
    }
}

/// The three outputs of a render and what they must never overwrite.
struct Outputs<'a> {
    exr: &'a Path,
    png: PathBuf,
    json: PathBuf,
    width: u32,
    height: u32,
    exposure: f32,
}

impl Outputs<'_> {
    /// EXR, PNG and JSON of `spp` samples per pixel accumulated in `accum`, each atomically.
    fn write(&self, accum: &[[f32; 4]], spp: u32, report: &RenderReport) -> Result<()> {
        let inv = 1.0 / spp.max(1) as f32;
        let image: Vec<[f32; 4]> = accum.iter().map(|p| p.map(|c| c * inv)).collect();
        let exr = output::encode_exr(self.width, self.height, &image)?;
        let png = output::encode_png(self.width, self.height, &image, self.exposure)?;
        crate::io::write_atomic(self.exr, &exr)?;
        crate::io::write_atomic(&self.png, &png)?;
        crate::io::write_atomic(&self.json, report.to_json().as_bytes())
    }
}

/// The settings `req` asks for on `mesh`, and the environment chosen: the camera `req` names
/// (front by default) and, unless `req` names one, no environment for a scene with emitters
/// and the sky for one without. Warns (`note`) when nothing can light the scene.
fn settings(
    req: &RenderRequest,
    mesh: &crate::scene::Mesh,
    note: &mut dyn FnMut(&str),
) -> Result<(RenderSettings, EnvSpec)> {
    let mut s = RenderSettings::paper(mesh);
    (s.width, s.height, s.spp, s.max_depth, s.rr_depth, s.seed) =
        (req.width, req.height, req.spp, req.max_depth, req.rr_depth, req.seed);
    s.submit_ms = req.submit_ms;
    s.camera = req.camera.camera(&mesh.bounds())?;
    let emitters = (0..mesh.triangle_count())
        .any(|id| !mesh.is_degenerate(id) && mesh.materials[mesh.material_ids[id] as usize].is_emissive());
    let env = req.env.unwrap_or(EnvSpec::default_for(emitters));
    match env {
        EnvSpec::Sky => {
            let mut sky = Sky::default();
            if let Some(d) = req.sun_dir {
                sky.sun_dir = d;
            }
            sky.check().map_err(|e| Error::Usage(format!("--sun-dir: {e}")))?;
            (s.env, s.sky) = ([0.0; 3], Some(sky));
        }
        EnvSpec::Constant(c) => {
            if req.sun_dir.is_some() {
                return Err(Error::Usage(format!("--sun-dir is for --env sky, not --env {env}")));
            }
            (s.env, s.sky) = (c, None);
        }
    }
    if env.is_black() && !emitters {
        note(&format!(
            "warning: --env {env} on {}, which has no emitting material: nothing lights the scene and the image \
             will be black (--env sky or a constant radiance lights it)",
            req.scene.display()
        ));
    }
    Ok((s, env))
}

/// The PNG exposures accepted, in stops: 2^EV is a finite, normal f32 scale throughout.
pub const EXPOSURE_RANGE: std::ops::RangeInclusive<f32> = -100.0..=100.0;

/// Refuses an exposure outside [`EXPOSURE_RANGE`] (NaN included), saying why.
pub fn check_exposure(ev: f32) -> std::result::Result<(), String> {
    if EXPOSURE_RANGE.contains(&ev) {
        return Ok(());
    }
    Err(format!("{ev}: must be a finite number of stops from {} to {}", EXPOSURE_RANGE.start(), EXPOSURE_RANGE.end()))
}

/// Renders `req`: writes the outputs and returns the sidecar. `interrupted` stops the render
/// after the pass in flight (what has accumulated is written, `interrupted: true`); `on_pass`
/// sees every pass (a progress bar); `note` gets warnings. A failure part-way writes the last
/// whole pass (`failed: <reason>`) and then returns the error.
pub fn run(
    ctx: &Context,
    req: &RenderRequest,
    interrupted: &AtomicBool,
    on_pass: &mut dyn FnMut(&Progress),
    note: &mut dyn FnMut(&str),
) -> Result<RenderReport> {
    check_request(req)?;
    let (png, json) = output::sidecar_paths(&req.out);
    let mesh = load_obj(&req.scene)?;
    for out in [&req.out, &png, &json] {
        crate::io::ensure_not_inputs(out, &req.scene, &mesh.mtl_files, &[])?;
    }
    for w in &mesh.warnings {
        note(&format!("warning: {w}"));
    }
    let (settings, env) = settings(req, &mesh, note)?;
    let t_build = Instant::now();
    let host = HostScene::build(crate::scene::scene_name(&req.scene), &mesh, &req.build)?;
    // The placement refuses, before anything is encoded, a scene or image that cannot fit.
    let target = RenderTarget::new(
        ctx,
        &host,
        SceneRequest::new(req.method).layout(req.layout),
        req.kernel,
        settings.pixels(),
        false,
    )?;
    let build_ms = t_build.elapsed().as_secs_f64() * 1e3;
    if let Some(r) = &target.device.auto {
        note(&format!("--method auto picked {}:", target.device.method));
        for line in &r.reasons {
            note(&format!("  {line}"));
        }
    }
    let mut report = RenderReport::before(ctx, req, &mesh, &target, &settings, env, build_ms);
    let outputs =
        Outputs { exr: &req.out, png, json, width: settings.width, height: settings.height, exposure: req.exposure };
    let mut last_checkpoint = Instant::now();
    let rendered = render(ctx, &target, &settings, &mut |p| {
        on_pass(&p);
        if req.checkpoint_secs > 0.0 && last_checkpoint.elapsed().as_secs_f64() >= req.checkpoint_secs {
            last_checkpoint = Instant::now();
            let r = RenderReport { spp_done: p.spp_done, checkpoint: true, seconds: Some(p.seconds), ..report.clone() };
            if let Err(e) = outputs.write(p.accum, p.spp_done, &r) {
                note(&format!("warning: checkpoint not written: {e}"));
            }
        }
        !interrupted.load(Ordering::SeqCst)
    });
    let result = match rendered {
        Ok(r) => r,
        // A lost device (say) part-way: write the last whole pass, then report the error.
        Err(RenderFailure::Partial(PartialRender { result, source })) => {
            report.spp_done = result.spp;
            report.failed = Some(source.to_string());
            (report.submits, report.wall_ms) = (Some(result.submits), Some(result.wall_ms));
            outputs.write(&result.accum, result.spp, &report)?;
            note(&format!("wrote the {} spp completed before the failure to {}", result.spp, req.out.display()));
            return Err(source);
        }
        Err(RenderFailure::Error(e)) => return Err(e),
    };
    report.spp_done = result.spp;
    report.interrupted = result.interrupted;
    (report.submits, report.wall_ms) = (Some(result.submits), Some(result.wall_ms));
    report.finished = Some(Finished::of(&result, settings.spp));
    outputs.write(&result.accum, result.spp, &report)?;
    if result.dropped_samples > 0 {
        note(&format!(
            "warning: {} samples had NaN or infinite radiance and were left out of the image",
            result.dropped_samples
        ));
    }
    Ok(report)
}

/// Refuses, before any work, an output that is not an EXR, an exposure, submit time or
/// checkpoint interval that cannot be meant, and an image larger than the memory holds.
fn check_request(req: &RenderRequest) -> Result<()> {
    if req.out.extension().and_then(|e| e.to_str()) != Some("exr") {
        return Err(Error::Usage(format!("--out {}: the output must be an .exr file", req.out.display())));
    }
    check_exposure(req.exposure).map_err(|e| Error::Usage(format!("--exposure {e}")))?;
    if !(req.submit_ms > 0.0 && req.submit_ms.is_finite()) {
        return Err(Error::Usage(format!("--submit-ms {}: must be a positive number of milliseconds", req.submit_ms)));
    }
    if !(req.checkpoint_secs >= 0.0 && req.checkpoint_secs.is_finite()) {
        return Err(Error::Usage(format!("--checkpoint-secs {}: must be a finite number >= 0", req.checkpoint_secs)));
    }
    // The image read back (RGBA f32) and written (RGB f32): 28 bytes a pixel at least.
    let pixels = u64::from(req.width) * u64::from(req.height);
    let option = format!("--width {} --height {}", req.width, req.height);
    crate::memory::check(&[crate::memory::Need::new(option, "pixels", Some(pixels), 28)])
}

impl RenderReport {
    /// The sidecar before the first pass: the request, the scene as rendered, no sample yet.
    fn before(
        ctx: &Context,
        req: &RenderRequest,
        mesh: &crate::scene::Mesh,
        target: &RenderTarget,
        settings: &RenderSettings,
        env: EnvSpec,
        build_ms: f64,
    ) -> RenderReport {
        let info = ctx.info();
        let c = &settings.camera;
        RenderReport {
            scene: req.scene.display().to_string(),
            scene_sha256: output::scene_hash(mesh),
            triangles: mesh.triangle_count(),
            method: target.device.method,
            method_choice: req.method.to_string(),
            layout: target.device.layout,
            auto: target.device.auto.clone(),
            build: req.build,
            kernel: target.kernel.source.name,
            kernel_choice: req.kernel,
            bsdfs_in_kernel: target.kernel.bsdfs(),
            bsdfs_in_scene: BsdfKind::in_mask(target.scene.bsdf_mask).map(|k| k.name()).collect(),
            settings: settings.clone(),
            camera_choice: req.camera.to_string(),
            environment: env.to_string(),
            camera: CameraRecord {
                eye: c.eye.to_array(),
                forward: c.forward.to_array(),
                up: c.up.to_array(),
                fov_y_degrees: c.fov_y.to_degrees(),
            },
            emissive_triangles: target.scene.light_count,
            gpu_scene_bytes: target.gpu_bytes(),
            device: info.name.clone(),
            driver: info.driver_label(),
            build_ms,
            warnings: mesh.warnings.clone(),
            spp_done: 0,
            checkpoint: false,
            interrupted: false,
            failed: None,
            seconds: None,
            submits: None,
            wall_ms: None,
            finished: None,
            out: req.out.clone(),
        }
    }
}

impl Finished {
    /// The rates of a render that ran to its end (or to an interrupt) of `spp_asked` asked.
    fn of(result: &RenderResult, spp_asked: u32) -> Finished {
        Finished {
            gpu_ms: result.gpu_ms,
            samples: result.samples(),
            samples_per_second: result.samples_per_second(),
            closest_rays: result.closest_rays,
            shadow_rays: result.shadow_rays,
            mrays_per_second: result.mrays_per_second(),
            ray_definition: RAY_DEFINITION,
            dropped_samples_nan_or_inf: result.dropped_samples,
            seconds: result.seconds(),
            width: result.width,
            height: result.height,
            spp_asked,
        }
    }
}
