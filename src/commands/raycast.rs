//! `trilab raycast`: casts a ray file through a scene, with one of our methods (through the
//! scene pipeline) or a peer (the driver's ray query or ray tracing pipeline), writes the hits, times the kernel and,
//! when asked, checks every hit against the f64 reference.

use std::path::PathBuf;

use serde::Serialize;

use crate::agreement::{compare_any, compare_closest};
use crate::bvh::BuildOptions;
use crate::conditioning::{MethodChoice, Recommendation};
use crate::encoding::{AccessPath, Layout, Method, Raycast, SceneAccess, Traversal};
use crate::error::{Error, Result};
use crate::gpu::{AccelStats, AccelStructure, Context, Peer, PeerTracer, RaycastOptions, RaycastResult};
use crate::pipeline::{HostScene, SceneRequest};
use crate::rays::{self, Ray};
use crate::report::Report;
use crate::scene::load_obj;

/// What to cast.
#[derive(Clone, Debug)]
pub struct RaycastRequest {
    pub scene: PathBuf,
    pub rays: PathBuf,
    /// The hit file to write.
    pub out: PathBuf,
    pub method: MethodChoice,
    /// A peer instead of our kernels (`method` is then ignored).
    pub peer: Option<Peer>,
    /// Translate the scene and the ray origins to the scene's centre, in f64, before upload.
    pub recentre: bool,
    pub build: BuildOptions,
    pub any_hit: bool,
    pub access: SceneAccess,
    /// How the BVH's nodes are laid out for the kernel (every kind and access path has every
    /// layout with the while-if traversal).
    pub layout: Layout,
    /// How the kernel walks the tree (`while-if` unless asked).
    pub traversal: Traversal,
    /// Timed runs after one warm-up.
    pub repeat: usize,
    pub batch_rays: usize,
    /// Check every hit against the f64 reference.
    pub validate: bool,
}

/// The f64 reference's verdict on the hits.
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum Validation {
    /// Closest hits: agreement, and whether every disagreement is explained by rounding.
    Closest {
        agreement: f64,
        disagreements: usize,
        unexplained: usize,
        max_ambiguity_ulps: f64,
        invalid: usize,
        passes: bool,
        summary: String,
    },
    /// Any hits: hit exactly where the closest-hit reference hits, each a real intersection.
    Any { any_hit_status_mismatches: usize, bogus: usize, passes: bool },
}

impl Validation {
    pub fn passes(&self) -> bool {
        match self {
            Validation::Closest { passes, .. } | Validation::Any { passes, .. } => *passes,
        }
    }

    /// The verdict as `reference:` lines of the text report.
    pub fn to_text(&self) -> String {
        let verdict = if self.passes() { "agrees" } else { "DISAGREES" };
        format!("reference: {verdict} with the f64 reference: {}\n", self.summary())
    }

    /// What the reference found, without the verdict.
    pub fn summary(&self) -> String {
        match self {
            Validation::Closest { summary, .. } => summary.clone(),
            Validation::Any { any_hit_status_mismatches, bogus, .. } => format!(
                "{any_hit_status_mismatches} rays hit where the reference misses or miss where it hits; {bogus} hits \
                 are not real intersections"
            ),
        }
    }
}

/// What `trilab raycast` reports (`--json` prints it).
/// What a report's kernel times were measured with (serialised as `gpu timestamps` or `host
/// wall clock`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum TimedWith {
    #[serde(rename = "gpu timestamps")]
    GpuTimestamps,
    #[serde(rename = "host wall clock")]
    HostWallClock,
}

impl TimedWith {
    /// GPU timestamps where the queue has them, else the host's wall clock.
    pub fn of(timed_on_gpu: bool) -> TimedWith {
        if timed_on_gpu {
            TimedWith::GpuTimestamps
        } else {
            TimedWith::HostWallClock
        }
    }

    /// How the text report says it.
    pub fn label(self) -> &'static str {
        match self {
            TimedWith::GpuTimestamps => "GPU timestamps",
            TimedWith::HostWallClock => "host wall clock",
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct RaycastReport {
    /// The method that traced the rays (`None` for a peer).
    pub method: Option<Method>,
    /// `--method` as given (`None` for a peer).
    pub method_choice: Option<String>,
    /// Why `auto` picked the method.
    pub auto: Option<Recommendation>,
    pub peer: Option<Peer>,
    /// The driver's structures, for a peer.
    pub accel: Option<AccelStats>,
    /// The BVH built (as `leaf_size`, `leaf_policy`, `sah_group`).
    #[serde(flatten, serialize_with = "BuildOptions::serialize_fields")]
    pub build: BuildOptions,
    pub any_hit: bool,
    pub recentred: bool,
    pub rays: usize,
    pub hits: usize,
    pub kernel_ms: f64,
    pub kernel_ms_min: f64,
    pub kernel_ms_max: f64,
    pub runs: usize,
    pub timed_with: TimedWith,
    pub mrays_per_s: f64,
    pub batches: usize,
    pub scene_bytes: usize,
    /// How our kernels read the scene (`None` for a peer).
    pub scene_access: Option<AccessPath>,
    /// The BVH node layout our kernels traversed (`None` for a peer).
    pub layout: Option<Layout>,
    /// How our kernel walked the tree (`None` for a peer).
    pub traversal: Option<Traversal>,
    /// The device's subgroup size (the lanes `--traversal coop` shares a ray among).
    pub subgroup_size: u32,
    pub triangles: usize,
    pub degenerate_triangles: usize,
    pub device: String,
    pub driver: String,
    pub mesa_version: Option<String>,
    pub validation: Option<Validation>,
    #[serde(skip)]
    scene: PathBuf,
    #[serde(skip)]
    out: PathBuf,
    /// "mt leaf size 4 (fill)", or the peer.
    #[serde(skip)]
    tracer: String,
}

impl RaycastReport {
    /// An error when the hits were checked and disagree with the f64 reference.
    pub fn verdict(&self) -> Result<()> {
        match &self.validation {
            Some(v) if !v.passes() => Err(Error::Usage("hits disagree with the f64 reference (see above)".into())),
            _ => Ok(()),
        }
    }
}

impl Report for RaycastReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let mut s = format!("device:    {} ({})\n", self.device, self.driver);
        s += &format!(
            "scene:     {} ({} triangles, {} degenerate never hit), {}, {:.2} MB on the GPU\n",
            self.scene.display(),
            self.triangles,
            self.degenerate_triangles,
            self.tracer,
            self.scene_bytes as f64 / 1e6
        );
        if let Some(a) = &self.accel {
            let ms = |m: Option<f64>| m.map(|m| format!("{m:.2} ms")).unwrap_or_else(|| "no timestamps".into());
            s += &format!(
                "driver AS: BLAS {} B, TLAS {} B; build {} + {} (GPU), {:.1} ms wall\n",
                a.blas_bytes,
                a.tlas_bytes,
                ms(a.blas_build_ms),
                ms(a.tlas_build_ms),
                a.wall_ms
            );
        }
        s += &format!("rays:      {} ({} hit) -> {}\n", self.rays, self.hits, self.out.display());
        s += &format!(
            "kernel:    {:.3} ms median of {} (min {:.3}, max {:.3}; {}), {:.2} Mrays/s\n",
            self.kernel_ms,
            self.runs,
            self.kernel_ms_min,
            self.kernel_ms_max,
            self.timed_with.label(),
            self.mrays_per_s
        );
        if let Some(v) = &self.validation {
            s += &v.to_text();
        }
        s
    }
}

/// What traced the rays: the result, a label, the bytes on the GPU, our scene's method, access
/// path and `auto` reasoning, or the peer's structures.
struct Traced {
    result: RaycastResult,
    tracer: String,
    bytes: usize,
    method: Option<(Method, AccessPath, Option<Recommendation>)>,
    accel: Option<AccelStats>,
}

/// Casts `req.rays` through `req.scene` and writes the hits; `note` gets what the user should
/// know on the way (recentring, what `auto` picked and why, triangles a method cannot
/// represent).
pub fn run(ctx: &Context, req: &RaycastRequest, mut note: impl FnMut(&str)) -> Result<RaycastReport> {
    req.build.check()?;
    let mut mesh = load_obj(&req.scene)?;
    crate::io::ensure_not_inputs(&req.out, &req.scene, &mesh.mtl_files, &[&req.rays])?;
    let mut rays = rays::read_rays(&req.rays)?;
    rays::check_reach(&req.rays, &rays, &mesh.bounds())?;
    if let Some(w) = rays::check_sidecar(&req.rays, rays.len(), &crate::scene::scene_name(&req.scene), &mesh) {
        note(&w);
    }
    if req.recentre {
        let (m, shift) = crate::conditioning::recentre(&mesh);
        crate::conditioning::recentre_rays(&mut rays, shift);
        note(&format!("recentred: scene and ray origins translated by -({}, {}, {})", shift.x, shift.y, shift.z));
        mesh = m;
    }
    let host = HostScene::build(crate::scene::scene_name(&req.scene), &mesh, &req.build)?;
    let opts = RaycastOptions { warmup: 1, repeat: req.repeat.max(1), batch_rays: req.batch_rays };
    let traced = match req.peer {
        Some(peer) => trace_peer(ctx, peer, &host, &rays, req, &opts)?,
        None => trace_ours(ctx, &host, &rays, req, &opts, &mut note)?,
    };
    rays::write_hits(&req.out, &traced.result.hits)?;
    let validation = req.validate.then(|| validate(&host, &rays, &traced.result, req.any_hit));
    let t = traced.result.time_ms()?;
    let mrays = |ms: f64| crate::services::validate::mrays_per_s(rays.len(), ms);
    let info = ctx.info();
    let (method, access, auto) = match traced.method {
        Some((m, a, r)) => (Some(m), Some(a), r),
        None => (None, None, None),
    };
    Ok(RaycastReport {
        method,
        method_choice: req.peer.is_none().then(|| req.method.to_string()),
        auto,
        peer: req.peer,
        accel: traced.accel,
        build: req.build,
        any_hit: req.any_hit,
        recentred: req.recentre,
        rays: rays.len(),
        hits: traced.result.hits.iter().filter(|h| h.is_hit()).count(),
        kernel_ms: t.median,
        kernel_ms_min: t.min,
        kernel_ms_max: t.max,
        runs: t.runs,
        timed_with: TimedWith::of(traced.result.timed_on_gpu()),
        mrays_per_s: mrays(t.median),
        batches: traced.result.batches,
        scene_bytes: traced.bytes,
        scene_access: access,
        layout: req.peer.is_none().then_some(req.layout),
        traversal: req.peer.is_none().then_some(req.traversal),
        subgroup_size: info.subgroup_size,
        triangles: mesh.triangle_count(),
        degenerate_triangles: host.bvh.degenerate_excluded,
        device: info.name.clone(),
        driver: info.driver_label(),
        mesa_version: info.mesa_version.clone(),
        validation,
        scene: req.scene.clone(),
        out: req.out.clone(),
        tracer: traced.tracer,
    })
}

/// Our kernels, through the scene pipeline: one placement picks the access path, and the kernel
/// comes from the scene uploaded for it.
fn trace_ours(
    ctx: &Context,
    host: &HostScene,
    rays: &[Ray],
    req: &RaycastRequest,
    opts: &RaycastOptions,
    note: &mut impl FnMut(&str),
) -> Result<Traced> {
    let request = SceneRequest::new(req.method).access(req.access).layout(req.layout).traversal(req.traversal);
    let placement = host.place(ctx, &request)?;
    let kind = if req.any_hit { Raycast::Any } else { Raycast::Closest };
    // A traversal without this kernel, or that the device cannot run, is refused before upload.
    placement.key(kind).source()?;
    ctx.capabilities().traversal(placement.traversal)?;
    if let Some(r) = &placement.auto {
        note(&format!("--method auto picked {}:", placement.method));
        for line in &r.reasons {
            note(&format!("  {line}"));
        }
    }
    let scene = placement.upload(ctx)?;
    if let Some(first) = scene.unrepresentable.first() {
        note(&format!(
            "warning: {} triangles cannot be represented by {} (their map overflows f32) and are never hit, e.g. id {first}",
            scene.unrepresentable.len(),
            scene.method
        ));
    }
    let result = scene.cast(ctx, kind, rays, opts)?;
    let mut tracer =
        format!("{} leaf size {} ({}), {}", scene.method, req.build.max_leaf_size, req.build.leaf_policy, req.layout);
    if req.traversal != Traversal::DEFAULT {
        tracer.push_str(&format!(", {} traversal", req.traversal));
    }
    Ok(Traced {
        result,
        tracer,
        bytes: scene.bytes,
        method: Some((scene.method, scene.access, scene.auto)),
        accel: None,
    })
}

/// The driver's own ray tracing (`peer`: ray query or the ray tracing pipeline) through its
/// acceleration structure over the same triangles.
fn trace_peer(
    ctx: &Context,
    peer: Peer,
    host: &HostScene,
    rays: &[Ray],
    req: &RaycastRequest,
    opts: &RaycastOptions,
) -> Result<Traced> {
    // The peer's own "unsupported" before building a structure it cannot trace.
    ctx.capabilities().peer(peer)?;
    let accel = AccelStructure::build(ctx, host.mesh)?;
    let tracer = PeerTracer::new(ctx, peer, req.any_hit)?;
    // Submits of about a second, whatever the driver's speed (--batch-rays caps them).
    let batch = tracer.batch_for(ctx, &accel, rays, 1000.0, req.batch_rays)?;
    let result = tracer.cast(ctx, &accel, rays, &RaycastOptions { batch_rays: batch, ..*opts })?;
    let s = accel.stats;
    Ok(Traced {
        result,
        tracer: peer.to_string(),
        bytes: (s.blas_bytes + s.tlas_bytes) as usize,
        method: None,
        accel: Some(s),
    })
}

/// The f64 reference's verdict on `result`'s hits.
pub fn validate(host: &HostScene, rays: &[Ray], result: &RaycastResult, any_hit: bool) -> Validation {
    let reference = host.reference().trace_all(rays, false);
    if any_hit {
        let closest: Vec<_> = reference.iter().map(|h| h.to_hit()).collect();
        let c = compare_any(host.mesh, rays, &closest, &result.hits);
        Validation::Any { any_hit_status_mismatches: c.status_mismatch.len(), bogus: c.bogus.len(), passes: c.passes() }
    } else {
        let a = compare_closest(host.mesh, rays, &result.hits, &reference);
        Validation::Closest {
            agreement: a.fraction(),
            disagreements: a.disagreements.len(),
            unexplained: a.unexplained,
            max_ambiguity_ulps: a.max_ambiguity_ulps,
            invalid: a.invalid.len(),
            passes: a.all_explained(),
            summary: a.summary(),
        }
    }
}
