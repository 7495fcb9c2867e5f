//! The driver's ray tracing as a peer of the hand-written kernels: `glsl/rayquery.comp` traces
//! the same `Ray`s through the driver's acceleration structure ([`AccelStructure`]) with
//! `VK_KHR_ray_query` and writes the same `Hit`s, batched and timed exactly as [`super::raycast`]
//! (they share [`super::raycast::cast_rays`]).
//!
//! It is not one of our [`Method`](crate::encoding::Method)s: a method is an encoding of *our*
//! BVH with one of *our* intersectors, and every method-shaped option (leaf size, leaf policy,
//! SAH grouping, scene bytes) means nothing for the driver's black-box structure. So it is a
//! [`Peer`](super::peer::Peer) (`gpu::peer`, beside the ray tracing pipeline,
//! [`super::rtpipeline`]), selected with `trilab raycast --peer ray-query` and reported as its
//! own row by `trilab bench`.

use super::accel::AccelStructure;
use super::context::Context;
use super::descriptors::Resource;
use super::kernel::Kernel;
use super::raycast::{batch_for_with, cast_rays, RaycastOptions, RaycastResult};
use crate::error::Result;
use crate::rays::Ray;
use crate::shared::{BINDING_SLOT_IDS, BINDING_TLAS};

/// The ray-query kernel (`rayquery.none.closest`, or `.any` for occlusion), or
/// [`Error::Unsupported`](crate::error::Error::Unsupported) where the context has no ray query.
pub fn kernel(ctx: &Context, any_hit: bool) -> Result<Kernel> {
    ctx.capabilities().peer(super::Peer::RayQuery)?;
    let variant = if any_hit { "any" } else { "closest" };
    let src = crate::kernels::find("rayquery", crate::kernels::NO_INTERSECTOR, variant)
        .unwrap_or_else(|| panic!("rayquery.none.{variant} was not compiled (glsl/rayquery.comp)"));
    ctx.create_kernel(src)
}

/// Casts `rays` through `accel` with a [`kernel`]: `warmup` untimed runs, then `repeat` timed
/// ones, as [`super::raycast`]. Hits carry OBJ triangle ids and the driver's barycentrics.
pub fn raycast_rq(
    ctx: &Context,
    kernel: &Kernel,
    accel: &AccelStructure,
    rays: &[Ray],
    opts: &RaycastOptions,
) -> Result<RaycastResult> {
    ctx.capabilities().peer(super::Peer::RayQuery)?;
    let resources = [(BINDING_TLAS, Resource::Accel(accel)), (BINDING_SLOT_IDS, Resource::Texels(accel.prim_ids()))];
    cast_rays(ctx, kernel, &resources, rays, opts)
}

/// Most rays per submit such that one submit takes about `target_ms`, within [256, `max`]
/// ([`batch_for_with`]: one untimed run of up to 4096 rays spread over the set, scaled).
pub fn batch_for(
    ctx: &Context,
    kernel: &Kernel,
    accel: &AccelStructure,
    rays: &[Ray],
    target_ms: f64,
    max: usize,
) -> Result<usize> {
    batch_for_with(rays, target_ms, max, |probe, opts| raycast_rq(ctx, kernel, accel, probe, opts))
}
