//! The driver's own ray tracing as peers of our kernels: [`Peer`] names them, [`PeerTracer`] is
//! one ready on a context (ray query's compute kernel, [`super::rayquery`], or the ray tracing
//! pipeline, [`super::rtpipeline`]), both tracing the same [`AccelStructure`] with the same
//! batching, timing and `Hit`s ([`super::raycast::cast_rays_with`]).
//!
//! A peer is not one of our [`Method`](crate::encoding::Method)s: a method is an encoding of
//! *our* BVH with one of *our* intersectors, and every method-shaped option (leaf size, leaf
//! policy, SAH grouping, scene bytes) means nothing for the driver's black-box structure. So it is
//! selected with `trilab raycast --peer <peer>` and reported as its own row by `trilab bench`.

use serde::Serialize;

use super::accel::AccelStructure;
use super::context::Context;
use super::kernel::Kernel;
use super::raycast::{batch_for_with, RaycastOptions, RaycastResult};
use super::rayquery;
use super::rtpipeline::{self, RtPipeline};
use crate::error::Result;
use crate::named::named_enum;
use crate::rays::Ray;

named_enum! {
    /// A tracer that is not an encoding of our BVH: the driver's own ray tracing.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum Peer: "peer" {
        /// `VK_KHR_ray_query` from a compute kernel through the driver's BLAS/TLAS.
        RayQuery = "ray-query",
        /// `VK_KHR_ray_tracing_pipeline`: ray generation, closest-hit and miss stages through the
        /// driver's BLAS/TLAS (NVIDIA's datacenter GPUs have it but no ray query).
        RayTracingPipeline = "ray-tracing-pipeline",
    }
}

impl Peer {
    /// The feature in words: `ray query`, `ray tracing pipeline`.
    pub fn feature(self) -> &'static str {
        match self {
            Peer::RayQuery => "ray query",
            Peer::RayTracingPipeline => "ray tracing pipeline",
        }
    }
}

/// A peer ready to trace on one context: its kernel or pipeline, closest or any hit.
pub enum PeerTracer {
    RayQuery(Kernel),
    RayTracingPipeline(Box<RtPipeline>),
}

impl PeerTracer {
    /// `peer`'s tracer (closest hit, or with `any_hit` occlusion), or [`Error::Unsupported`]
    /// where the context lacks it.
    pub fn new(ctx: &Context, peer: Peer, any_hit: bool) -> Result<PeerTracer> {
        Ok(match peer {
            Peer::RayQuery => PeerTracer::RayQuery(rayquery::kernel(ctx, any_hit)?),
            Peer::RayTracingPipeline => PeerTracer::RayTracingPipeline(Box::new(rtpipeline::pipeline(ctx, any_hit)?)),
        })
    }

    pub fn peer(&self) -> Peer {
        match self {
            PeerTracer::RayQuery(_) => Peer::RayQuery,
            PeerTracer::RayTracingPipeline(_) => Peer::RayTracingPipeline,
        }
    }

    /// Casts `rays` through `accel`: `warmup` untimed runs, then `repeat` timed ones.
    pub fn cast(
        &self,
        ctx: &Context,
        accel: &AccelStructure,
        rays: &[Ray],
        opts: &RaycastOptions,
    ) -> Result<RaycastResult> {
        match self {
            PeerTracer::RayQuery(k) => rayquery::raycast_rq(ctx, k, accel, rays, opts),
            PeerTracer::RayTracingPipeline(p) => rtpipeline::raycast_rtp(ctx, p, accel, rays, opts),
        }
    }

    /// Most rays per submit such that one submit takes about `target_ms` ([`batch_for_with`]).
    pub fn batch_for(
        &self,
        ctx: &Context,
        accel: &AccelStructure,
        rays: &[Ray],
        target_ms: f64,
        max: usize,
    ) -> Result<usize> {
        batch_for_with(rays, target_ms, max, |probe, opts| self.cast(ctx, accel, probe, opts))
    }
}
