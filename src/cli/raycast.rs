//! `trilab raycast`.

use std::path::PathBuf;

use clap::Args;
use trilab::commands::raycast::{self, RaycastRequest};
use trilab::conditioning::MethodChoice;
use trilab::encoding::{Layout, SceneAccess, Traversal};
use trilab::error::Result;
use trilab::gpu::Peer;

use super::choice::{choice, method_choice, method_help, traversal_choice};
use super::{note, repeat, scene_help, BuildArgs, GpuArgs, JsonArg};

/// Which kernel casts the rays and over which tree: the options `raycast` and `repro` share.
#[derive(Args)]
pub struct KernelArgs {
    #[arg(long, value_name = "M", default_value = trilab::defaults::METHOD, value_parser = method_choice(), hide_possible_values = true,
          help = method_help("Intersection method:"))]
    pub method: MethodChoice,
    #[command(flatten)]
    pub bvh: BuildArgs,
    /// Occlusion query: any hit in [tmin, tmax] instead of the closest.
    #[arg(long)]
    pub any_hit: bool,
    /// How the kernels read the scene: `auto` places the scene in GPU memory and uses texel
    /// buffers when every buffer fits one binding, else buffer device addresses (the JSON says
    /// which).
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::DEFAULT)]
    pub scene_access: SceneAccess,
    /// BVH node layout: `bvh2` (the paper's binary tree) or a wide one (`trilab methods` lists
    /// them); every kernel exists for every layout.
    #[arg(long, value_parser = choice::<Layout>(), default_value_t = Layout::DEFAULT)]
    pub layout: Layout,
    /// How the kernel walks the tree; each value lists the layouts, access paths and kinds it has
    /// kernels for (from the compiled variants).
    #[arg(long, value_parser = traversal_choice(), default_value_t = Traversal::DEFAULT)]
    pub traversal: Traversal,
}

/// Cast rays from a ray file; write hits and report kernel time.
#[derive(Args)]
pub struct RaycastArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    /// Ray file to cast (32-byte rays, docs/formats.md; `trilab rays` makes one).
    #[arg(long, value_name = "FILE")]
    rays: PathBuf,
    /// Hit file to write (16-byte hits, docs/formats.md).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Translate the scene to its bounding-box centre, and the ray origins with it, in f64
    /// before rounding to f32 and uploading (t, ids and barycentrics are unchanged in exact
    /// arithmetic; `trilab analyze` says when this helps).
    #[arg(long)]
    recentre: bool,
    /// Trace with a peer instead of our kernels, the driver's own ray tracing through its
    /// acceleration structure (built from the same triangles): `ray-query` (VK_KHR_ray_query from
    /// a compute kernel) or `ray-tracing-pipeline` (VK_KHR_ray_tracing_pipeline: ray generation,
    /// closest-hit and miss stages).
    /// Not a method: it uses none of our BVH, so the BVH options only shape the f64 reference.
    #[arg(long, value_parser = choice::<Peer>(), conflicts_with = "method")]
    peer: Option<Peer>,
    #[command(flatten)]
    kernel: KernelArgs,
    /// Timed runs after one warm-up (at least 1); the median is reported.
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::REPEAT, value_parser = repeat)]
    repeat: usize,
    /// Most rays per dispatch (each dispatch is its own submit).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::BATCH_RAYS)]
    batch_rays: usize,
    /// Also check every hit against the f64 reference and report agreement (was `--validate`).
    #[arg(long, alias = "validate")]
    reference: bool,
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
        method: a.kernel.method,
        peer: a.peer,
        recentre: a.recentre,
        build: a.kernel.bvh.options(),
        any_hit: a.kernel.any_hit,
        access: a.kernel.scene_access,
        layout: a.kernel.layout,
        traversal: a.kernel.traversal,
        repeat: a.repeat,
        batch_rays: a.batch_rays,
        validate: a.reference,
    };
    let report = raycast::run(&a.gpu.context()?, &req, note)?;
    a.json.print(&report);
    report.verdict()
}
