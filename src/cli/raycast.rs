//! `trilab raycast`.

use std::path::PathBuf;

use clap::Args;
use trilab::analyze::MethodChoice;
use trilab::encoding::SceneAccess;
use trilab::error::Result;
use trilab::gpu::Peer;
use trilab::harness::raycast::{self, RaycastRequest};

use super::choice::choice;
use super::{note, BuildArgs, GpuArgs, JsonArg};

/// Cast rays from a ray file; write hits and report kernel time.
#[derive(Args)]
pub struct RaycastArgs {
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    rays: PathBuf,
    /// Hit file to write (../shared/formats.md).
    #[arg(long)]
    out: PathBuf,
    /// Intersection method, or `auto`: the cheapest that meets the default accuracy target on
    /// this scene (see `trilab analyze`); what it picked and why goes to stderr and the JSON.
    #[arg(long, default_value = "mt")]
    method: MethodChoice,
    /// Translate the scene to its bounding-box centre, and the ray origins with it, in f64
    /// before rounding to f32 and uploading (t, ids and barycentrics are unchanged in exact
    /// arithmetic; `trilab analyze` says when this helps).
    #[arg(long)]
    recentre: bool,
    /// Trace with a peer instead of our kernels: `ray-query` is the driver's own ray tracing
    /// (VK_KHR_ray_query through its acceleration structure, built from the same triangles).
    /// Not a method: it uses none of our BVH, so the BVH options only shape the f64 reference.
    #[arg(long, value_parser = choice::<Peer>(), conflicts_with = "method")]
    peer: Option<Peer>,
    #[command(flatten)]
    bvh: BuildArgs,
    /// Occlusion query: any hit in [tmin, tmax] instead of the closest.
    #[arg(long)]
    any_hit: bool,
    /// How the kernels read the scene: `auto` plans its GPU memory and uses texel buffers when
    /// every buffer fits one binding, else buffer device addresses (the JSON says which).
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::Auto)]
    scene_access: SceneAccess,
    /// Timed runs after one warm-up; the median is reported.
    #[arg(long, default_value_t = 5)]
    repeat: usize,
    /// Most rays per dispatch (each dispatch is its own submit).
    #[arg(long, default_value_t = 1 << 20)]
    batch_rays: usize,
    /// Also check every hit against the f64 reference and report agreement.
    #[arg(long)]
    validate: bool,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: RaycastArgs) -> Result<()> {
    let req = RaycastRequest {
        scene: a.scene,
        rays: a.rays,
        out: a.out,
        method: a.method,
        peer: a.peer,
        recentre: a.recentre,
        build: a.bvh.options(),
        any_hit: a.any_hit,
        access: a.scene_access,
        repeat: a.repeat,
        batch_rays: a.batch_rays,
        validate: a.validate,
    };
    let report = raycast::run(&a.gpu.context()?, &req, note)?;
    a.json.print(&report);
    report.verdict()
}
