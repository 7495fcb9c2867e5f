//! Path tracing (`glsl/pathtrace.comp`): what a render needs besides the encoded scene, the
//! kernel chosen for the scene's materials, and the batched render loop.
//!
//! - [`RenderScene`]: per-slot shading records (geometric normal and material), the materials,
//!   and the emissive triangles with their sampling distribution; only what the scene uses.
//! - [`KernelChoice`]: the BSDF set the kernel carries. `Specialised` (the default) picks the
//!   single-BSDF variant when a scene uses one BSDF, and otherwise the all-BSDF variant narrowed
//!   by a specialisation constant; `General` is the all-BSDF kernel as compiled.
//! - [`render`]: one dispatch per submit, each a pass of `k` samples over a range of pixels,
//!   sized to a wall-clock target so no submit comes near a GPU watchdog; samples accumulate
//!   in sample order, so the image does not depend on the batching.

pub mod bsdf;
pub mod env;
pub mod output;
mod passes;
pub mod placement;
pub mod rng;
pub mod session;

pub use passes::render;

use glam::{DVec3, Vec3};

use crate::encoding::{AccessPath, BsdfSet, EncodedScene, Layout, Method, PathtraceKey};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::kernels::KernelSource;
use crate::named::named_enum;
use crate::pipeline::{DeviceScene, HostScene, SceneRequest};
use crate::rays::Camera;
use crate::scene::{BsdfKind, GpuMaterial, Mesh};

use crate::shared::{BSDF_MASK_ALL, MISS_ID};
pub use env::{EnvSpec, Sky};

/// Everything a render is asked for.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Most scattering events per path.
    pub max_depth: u32,
    /// Russian roulette from this many scattering events on.
    pub rr_depth: u32,
    pub seed: u32,
    #[serde(skip)]
    pub camera: Camera,
    /// Constant environment radiance (linear RGB), when `sky` is `None`.
    pub env: [f32; 3],
    /// A sky with a sun instead of the constant environment (`render`'s default for scenes
    /// without emitters); the benchmarks keep the constant one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sky: Option<Sky>,
    /// Ray spawn offset, relative to max(|p|, scene extent).
    pub ray_eps: f32,
    /// Wall-clock target per submit, milliseconds.
    pub submit_ms: f64,
    /// Next-event estimation towards emissive triangles (with MIS). Off: emitters are found
    /// by BSDF sampling alone (unbiased too, much noisier; tests compare the two).
    pub next_event: bool,
}

impl RenderSettings {
    /// The paper's setting (800x600, 500 spp, depth 16) with the benchmarks' camera (the peer's
    /// 3/4 view, [`Camera::framing`]) and a white constant environment: what bench-render and the
    /// study measure. `trilab render`'s defaults (front camera, sky) are `session`'s.
    pub fn paper(mesh: &Mesh) -> RenderSettings {
        RenderSettings {
            width: 800,
            height: 600,
            spp: 500,
            max_depth: 16,
            rr_depth: 3,
            seed: 1,
            camera: Camera::framing(&mesh.bounds()),
            env: [1.0; 3],
            sky: None,
            ray_eps: 1e-5,
            submit_ms: 250.0,
            next_event: true,
        }
    }

    pub fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Usage(m));
        if self.width == 0 || self.height == 0 {
            return bad(format!(
                "--width {} --height {}: the image is empty; both must be at least 1",
                self.width, self.height
            ));
        }
        if self.pixels() > u32::MAX as u64 / 2 {
            return bad(format!(
                "--width {} --height {}: {} pixels is too many (at most {})",
                self.width,
                self.height,
                self.pixels(),
                u32::MAX / 2
            ));
        }
        if self.spp == 0 {
            return bad("--spp must be at least 1".into());
        }
        if !self.env.iter().all(|c| c.is_finite() && *c >= 0.0) {
            return bad(format!("environment radiance {:?} must be finite and non-negative", self.env));
        }
        if let Some(sky) = &self.sky {
            sky.check().map_err(Error::Usage)?;
        }
        let c = &self.camera;
        let finite = [c.eye, c.forward, c.right, c.up].iter().all(|v| v.is_finite());
        if !(finite && c.fov_y > 0.0 && c.fov_y < std::f32::consts::PI) {
            return bad("camera: eye, target and up must be finite, target != eye, up not along the view direction, 0 < fov < 180 degrees".into());
        }
        if !((0.0..1.0).contains(&self.ray_eps) && self.submit_ms.is_finite() && self.submit_ms > 0.0) {
            return bad("ray offset must be in [0, 1) and the submit target positive".into());
        }
        Ok(())
    }
}

named_enum! {
    /// The kernel's BSDF set.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum KernelChoice: "kernel" {
        /// Only the BSDFs the scene's materials use.
        Specialised = "specialised",
        /// Every BSDF, whatever the scene uses.
        General = "general",
    }
}

/// A path-trace kernel: its SPIR-V variant and the BSDF mask given as specialisation constant.
#[derive(Clone, Copy, Debug)]
pub struct PathtraceKernel {
    pub source: &'static KernelSource,
    pub spec_mask: u32,
}

impl PathtraceKernel {
    /// The kernel for `method` and a scene whose materials use the BSDFs in `mask`.
    pub fn choose(method: Method, mask: u32, choice: KernelChoice) -> PathtraceKernel {
        Self::choose_on(method, Layout::DEFAULT, mask, choice)
    }

    /// [`PathtraceKernel::choose`] for a scene whose nodes are in `layout`: the single-BSDF
    /// kernel where the scene uses one BSDF and one was compiled (the binary nodes), else the
    /// all-BSDF kernel narrowed to the scene's BSDFs by the specialisation constant (a wide
    /// layout has that one only: `// trilab:layouts all` in `glsl/pathtrace.comp`).
    pub fn choose_on(method: Method, layout: Layout, mask: u32, choice: KernelChoice) -> PathtraceKernel {
        Self::choose_for(method, layout, AccessPath::Texel, mask, choice)
    }

    /// [`PathtraceKernel::choose_on`] for a scene read through `access` (the storage path has
    /// the all-BSDF kernel only).
    pub fn choose_for(
        method: Method,
        layout: Layout,
        access: AccessPath,
        mask: u32,
        choice: KernelChoice,
    ) -> PathtraceKernel {
        let key = |bsdfs| PathtraceKey { method, bsdfs, layout, access };
        let single = BsdfKind::ALL.into_iter().find(|k| k.bit() == mask);
        let (bsdfs, spec_mask) = match (choice, single) {
            (KernelChoice::Specialised, Some(kind)) if key(BsdfSet::One(kind)).source().is_ok() => {
                (BsdfSet::One(kind), mask)
            }
            (KernelChoice::Specialised, _) => (BsdfSet::All, mask.max(1)),
            (KernelChoice::General, _) => (BsdfSet::All, BSDF_MASK_ALL),
        };
        PathtraceKernel { source: key(bsdfs).source().unwrap_or_else(|e| panic!("{e}")), spec_mask }
    }

    /// BSDFs carried, by name.
    pub fn bsdfs(&self) -> Vec<&'static str> {
        BsdfKind::in_mask(self.spec_mask).map(BsdfKind::name).collect()
    }
}

/// What the path tracer reads besides the encoded scene.
#[derive(Clone, Debug)]
pub struct RenderScene {
    /// Per triangle slot of the encoding: unit geometric normal and material index (as bits).
    pub shading: Vec<[f32; 4]>,
    pub materials: Vec<GpuMaterial>,
    /// Emissive triangles, three texels each (see `glsl/pathtrace.comp`).
    pub lights: Vec<[f32; 4]>,
    pub light_count: u32,
    /// Sum over emissive triangles of area x mean emitted radiance.
    pub light_weight: f32,
    /// BSDFs used by at least one (non-degenerate) triangle, one bit per `BsdfKind::code()`.
    pub bsdf_mask: u32,
    /// Largest side of the scene's bounds.
    pub extent: f32,
}

impl RenderScene {
    pub fn new(mesh: &Mesh, encoded: &EncodedScene) -> RenderScene {
        let normal = |id: usize| -> Option<Vec3> {
            let [a, b, c] = mesh.vertices_f64(id);
            let n: DVec3 = (b - a).cross(c - a);
            (n != DVec3::ZERO).then(|| n.normalize().as_vec3())
        };
        let shading = encoded
            .slot_ids
            .iter()
            .map(|&id| {
                if id == MISS_ID {
                    return [0.0; 4];
                }
                let n = normal(id as usize).unwrap_or(Vec3::ZERO);
                [n.x, n.y, n.z, f32::from_bits(mesh.material_ids[id as usize])]
            })
            .collect();
        let mut lights = Vec::new();
        let mut weights = Vec::new();
        for id in 0..mesh.triangle_count() {
            if mesh.is_degenerate(id) {
                continue;
            }
            let mi = mesh.material_ids[id] as usize;
            let m = &mesh.materials[mi];
            if !m.is_emissive() {
                continue;
            }
            let [a, b, c] = mesh.vertices_f64(id);
            let area = 0.5 * (b - a).cross(c - a).length();
            let mean = m.gpu.emission.iter().map(|&e| e as f64).sum::<f64>() / 3.0;
            let (e1, e2) = ((b - a).as_vec3(), (c - a).as_vec3());
            let a = a.as_vec3();
            lights.extend([
                [a.x, a.y, a.z, 0.0],
                [e1.x, e1.y, e1.z, f32::from_bits(mi as u32)],
                [e2.x, e2.y, e2.z, area as f32],
            ]);
            weights.push(area * mean);
        }
        let total: f64 = weights.iter().sum();
        let mut acc = 0.0;
        for (i, w) in weights.iter().enumerate() {
            acc += w;
            // The last cdf is exactly 1 so the search always finds a light.
            lights[3 * i][3] = if i + 1 == weights.len() { 1.0 } else { (acc / total) as f32 };
        }
        let light_count = weights.len() as u32;
        if lights.is_empty() {
            lights.push([0.0; 4]); // a binding cannot be empty; never read (light_count = 0)
        }
        RenderScene {
            shading,
            materials: mesh.materials.iter().map(|m| m.gpu).collect(),
            lights,
            light_count,
            light_weight: total as f32,
            bsdf_mask: RenderScene::bsdf_mask(mesh),
            extent: mesh.bounds().extent().max_element(),
        }
    }

    /// The BSDFs used by at least one non-degenerate triangle of `mesh`, one bit per
    /// `BsdfKind::code()`.
    pub fn bsdf_mask(mesh: &Mesh) -> u32 {
        (0..mesh.triangle_count())
            .filter(|&id| !mesh.is_degenerate(id))
            .fold(0, |mask, id| mask | mesh.materials[mesh.material_ids[id] as usize].kind.bit())
    }

    /// GPU bytes beyond the encoded scene.
    pub fn gpu_bytes(&self) -> usize {
        16 * (self.shading.len() + self.lights.len()) + 64 * self.materials.len()
    }
}

/// `uniform Params` in `glsl/pathtrace.comp` (std140; every member is 16-byte or 4-byte
/// aligned as laid out here).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuParams {
    pub cam_eye: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub cam_forward: [f32; 4],
    pub env: [f32; 4],
    pub width: u32,
    pub height: u32,
    pub max_depth: u32,
    pub rr_depth: u32,
    pub seed: u32,
    pub light_count: u32,
    pub ray_eps: f32,
    pub scene_extent: f32,
    pub sky_zenith: [f32; 4],
    pub sky_horizon: [f32; 4],
    pub sun_dir: [f32; 4],
    pub sun_radiance: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<GpuParams>() == 176);

impl GpuParams {
    pub fn new(s: &RenderSettings, scene: &RenderScene) -> GpuParams {
        let c = &s.camera;
        let v4 = |v: Vec3, w: f32| [v.x, v.y, v.z, w];
        // A constant environment is a sky whose three colours are equal and whose sun is dark.
        let (zenith, horizon, ground, sun_dir, sun_radiance) = match &s.sky {
            None => (s.env, s.env, s.env, [0.0, 1.0, 0.0, 1.0], [0.0; 4]),
            Some(sky) => {
                let d = sky.sun_dir_f64().as_vec3();
                let radius = f64::from(sky.sun_radius_degrees).to_radians();
                let l = sky.sun_radiance().map(|x| x as f32);
                // w: the density of next-event estimation's uniform cone sampling, 0 when off
                // (the sun is then found by BSDF sampling alone).
                let pdf = if s.next_event { (1.0 / sky.sun_solid_angle()) as f32 } else { 0.0 };
                (sky.zenith, sky.horizon, sky.ground, v4(d, radius.cos() as f32), [l[0], l[1], l[2], pdf])
            }
        };
        GpuParams {
            cam_eye: v4(c.eye, (c.fov_y / 2.0).tan()),
            cam_right: v4(c.right, s.width as f32 / s.height as f32),
            cam_up: v4(c.up, 0.0),
            cam_forward: v4(c.forward, 0.0),
            env: [ground[0], ground[1], ground[2], scene.light_weight],
            width: s.width,
            height: s.height,
            max_depth: s.max_depth,
            rr_depth: s.rr_depth,
            seed: s.seed,
            light_count: if s.next_event { scene.light_count } else { 0 },
            ray_eps: s.ray_eps,
            scene_extent: scene.extent,
            sky_zenith: [zenith[0], zenith[1], zenith[2], 0.0],
            sky_horizon: [horizon[0], horizon[1], horizon[2], 0.0],
            sun_dir,
            sun_radiance,
        }
    }
}

/// Random-number dimensions of one path vertex (`DIMS_PER_VERTEX` and `DIM_*` in
/// `glsl/pathtrace.comp`): draw `DIMS_PER_VERTEX * depth + DIM_*`.
pub const DIMS_PER_VERTEX: u32 = 12;
pub const DIM_PIXEL_X: u32 = 0;
pub const DIM_PIXEL_Y: u32 = 1;

/// The camera ray of sample `sample` of pixel (`px`, `py`), computed as `pathtrace.comp` does
/// (same draws, same f32 operations in the same order; the GPU's `normalize` may differ in
/// the last bits).
pub fn camera_ray(s: &RenderSettings, px: u32, py: u32, sample: u32) -> crate::rays::Ray {
    let key = rng::path_key(s.seed, py * s.width + px, sample);
    let sx = (px as f32 + rng::rand01(key, DIM_PIXEL_X)) / s.width as f32;
    let sy = (py as f32 + rng::rand01(key, DIM_PIXEL_Y)) / s.height as f32;
    let (nx, ny) = (2.0 * sx - 1.0, 1.0 - 2.0 * sy);
    let c = &s.camera;
    let th = (c.fov_y / 2.0).tan();
    let aspect = s.width as f32 / s.height as f32;
    let d = (c.forward + c.right * (nx * th * aspect) + c.up * (ny * th)).normalize();
    crate::rays::Ray::new(c.eye.to_array(), d.to_array())
}

/// `Push` in `glsl/pathtrace.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PathtracePush {
    pub sample_first: u32,
    pub sample_count: u32,
    pub pixel_first: u32,
    pub pixel_count: u32,
}

const _: () = assert!(std::mem::size_of::<PathtracePush>() == 16);

/// Where a render stands, after each completed pass over the image.
#[derive(Clone, Copy, Debug)]
pub struct Progress<'a> {
    pub spp_done: u32,
    pub spp_total: u32,
    pub seconds: f64,
    /// The accumulation so far (as `RenderResult::accum`: `spp_done` samples per pixel), for
    /// periodic checkpoints.
    pub accum: &'a [[f32; 4]],
}

/// A finished (or interrupted) render.
#[derive(Clone, Debug)]
pub struct RenderResult {
    pub width: u32,
    pub height: u32,
    /// Sum over samples of radiance (rgb) and primary coverage (a), per pixel, row by row.
    pub accum: Vec<[f32; 4]>,
    /// Samples per pixel completed (every pixel has the same count).
    pub spp: u32,
    /// Stopped early by the progress callback (Ctrl-C).
    pub interrupted: bool,
    /// Why the render stopped early on an error (a lost device, say); set only in the result an
    /// [`PartialRender`] carries.
    pub failed: Option<String>,
    /// Closest-hit rays (camera and bounce rays) and occlusion rays traced.
    pub closest_rays: u64,
    pub shadow_rays: u64,
    /// Samples dropped because their radiance was NaN or infinite.
    pub dropped_samples: u64,
    /// Sum of the dispatches' GPU times (timestamps), ms; `None` without timestamps.
    pub gpu_ms: Option<f64>,
    /// Wall time of the render loop (submits and waits), ms.
    pub wall_ms: f64,
    pub submits: usize,
    pub kernel: &'static str,
    pub spec_mask: u32,
}

impl RenderResult {
    /// Mean radiance (rgb) and coverage (a) per pixel.
    pub fn image(&self) -> Vec<[f32; 4]> {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.accum.iter().map(|p| p.map(|c| c * inv)).collect()
    }

    /// Time the rates are computed over: GPU time when measured, else wall time.
    pub fn seconds(&self) -> f64 {
        self.gpu_ms.unwrap_or(self.wall_ms) * 1e-3
    }

    pub fn samples(&self) -> u64 {
        self.width as u64 * self.height as u64 * self.spp as u64
    }

    pub fn samples_per_second(&self) -> f64 {
        self.samples() as f64 / self.seconds()
    }

    /// Rays per second, counting every traversal: camera, bounce and occlusion rays.
    pub fn mrays_per_second(&self) -> f64 {
        (self.closest_rays + self.shadow_rays) as f64 / self.seconds() * 1e-6
    }
}

/// A scene ready to render: on the device (the texel path; only what the path tracer reads,
/// unless ray casts share it), its shading, lights and materials, and the kernel carrying the
/// BSDFs its materials use.
pub struct RenderTarget {
    pub device: DeviceScene,
    pub scene: RenderScene,
    pub kernel: PathtraceKernel,
}

impl RenderTarget {
    /// Places `host` for `request` (a method or `auto`, and the node layout) with the path tracer's own buffers for an image of
    /// `pixels` (refusing, before anything is encoded, what does not fit), picks the kernel for
    /// its materials (`choice`), and uploads it. With `raycast_too` every buffer of the scene is
    /// uploaded, so that the ray-casting kernels can read it as well (the study).
    pub fn new(
        ctx: &Context,
        host: &HostScene,
        request: SceneRequest,
        choice: KernelChoice,
        pixels: u64,
        raycast_too: bool,
    ) -> Result<RenderTarget> {
        let placed = host.place(ctx, &request.without_address(placement::NO_ADDRESS))?;
        placed.check_extras(&placement::extras_for(
            host.mesh,
            placed.method,
            placed.access,
            &placed.memory.counts,
            pixels,
        ))?;
        let kernel = PathtraceKernel::choose_for(
            placed.method,
            placed.layout,
            placed.access,
            RenderScene::bsdf_mask(host.mesh),
            choice,
        );
        let reader = if raycast_too { None } else { Some(kernel.source) };
        let mut scene = None;
        let device = placed.upload_with(ctx, reader, |e| scene = Some(RenderScene::new(host.mesh, e)))?;
        Ok(RenderTarget { device, scene: scene.expect("upload_with hands over the encoding"), kernel })
    }

    /// GPU bytes of the scene and the path tracer's buffers beside it.
    pub fn gpu_bytes(&self) -> usize {
        self.device.bytes + self.scene.gpu_bytes()
    }
}

/// Why [`render`] returned no finished image.
#[derive(Debug, thiserror::Error)]
pub enum RenderFailure {
    /// It failed part-way; the samples completed before the failure are kept.
    #[error(transparent)]
    Partial(PartialRender),
    /// It failed before completing a pass (or was asked for something it cannot do).
    #[error(transparent)]
    Error(#[from] Error),
}

/// A render that failed part-way (`source`: a lost device, say); `result` holds the samples
/// completed before it (the last whole pass), for the caller to write out.
#[derive(Debug, thiserror::Error)]
#[error("{source} (the render had completed {} spp)", result.spp)]
pub struct PartialRender {
    pub result: Box<RenderResult>,
    #[source]
    pub source: Error,
}

impl From<RenderFailure> for Error {
    /// The error alone, for callers that keep no partial image (benchmarks, the study).
    fn from(f: RenderFailure) -> Error {
        match f {
            RenderFailure::Partial(p) => p.source,
            RenderFailure::Error(e) => e,
        }
    }
}
