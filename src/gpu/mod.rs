//! Vulkan: device selection, buffers, kernels (pipelines), dispatch and GPU timing.
//!
//! - [`accel`]: the driver's acceleration structures (BLAS + TLAS) for ray query and the ray
//!   tracing pipeline.
//! - [`amd`]: AMD chips as Mesa's RADV knows them, and the occupancy (subgroups per SIMD) its
//!   compiler's statistics report, with the cliffs one more register would cost.
//! - [`capabilities`]: one home for what a device can run ([`Capabilities`]: per kernel, method,
//!   access path, traversal, driver peer and statistic, each "no" with its reason).
//! - [`context`]: instance, device, queue, allocator, validation log, teardown.
//! - [`device_info`]: what a device and its driver offer (`trilab devices`), and whether it runs
//!   kernels or only compiles them.
//! - [`executable`]: what the driver's compiler reports about a pipeline
//!   (`VK_KHR_pipeline_executable_properties`), typed: unit, direction, or identity.
//! - [`buffer`]: named buffers and texel buffers, uploads, downloads, one-shot submits.
//! - [`descriptors`]: descriptor sets checked against the kernel's reflected bindings.
//! - [`dispatch`]: what a cast dispatches ([`RayDispatch`]: one batch of rays bound and
//!   dispatched), our compute kernels as one.
//! - [`kernel`]: compute pipelines built from SPIR-V reflection.
//! - [`limits`]: the device's limits as `encoding::placement` checks them (`TRILAB_TEST_LIMITS` lowers them).
//! - [`markers`]: crash markers (GPU breadcrumbs + dispatch log), device-loss and out-of-memory
//!   errors that name the dispatch, fault injection for testing them.
//! - [`raycast`]: batched ray casting with timestamp queries.
//! - [`roofline`]: the traversal roofline's pointer chase (`glsl/roofline.comp`), its node
//!   buffer and its CPU reference.
//! - [`slowdown`]: a planted slowdown of one kernel (`TRILAB_INJECT_SLOWDOWN`), for tests of the
//!   regression gate: a [`RayDispatch`] around the kernel, which [`cast_rays`] installs.
//! - [`traversal_stats`]: per-ray traversal work from the kernels' `stats` variant.
//! - [`peer`]: the driver's own ray tracing as peers of our kernels ([`Peer`], [`PeerTracer`]).
//! - [`rayquery`]: the same ray casting through the driver's ray query, a peer of our kernels.
//! - [`rtpipeline`]: the same through the driver's ray tracing pipeline (ray generation,
//!   closest-hit and miss stages, shader binding table), the other peer.
//! - `timestamps`: timestamp query pairs read back as milliseconds.

pub mod accel;
pub mod amd;
pub mod buffer;
pub mod capabilities;
pub mod commands;
pub mod context;
pub mod descriptors;
pub mod dispatch;
pub mod device_info;
pub mod executable;
pub mod kernel;
pub mod lavapipe_cpu;
pub mod limits;
pub mod markers;
pub mod peer;
pub mod raycast;
pub mod rayquery;
pub mod roofline;
pub mod rtpipeline;
pub mod slowdown;
pub(crate) mod timestamps;
pub mod traversal_stats;

pub use accel::{AccelStats, AccelStructure};
pub use buffer::{Buffer, TexelBuffer};
pub use capabilities::{Capabilities, DriverKind, Statistic, Unsupported};
pub use context::{Context, ContextOptions, EnabledFeatures, Needs, Purpose, Validation, ValidationLog};
pub use descriptors::Resource;
pub use device_info::{DeviceInfo, Execution, RayTracingPipelineProperties};
pub use kernel::{Kernel, PipelineOptions};
pub use lavapipe_cpu::LavapipeCpu;
pub use markers::{Fault, FaultKind};
pub use peer::{Peer, PeerTracer};
pub use raycast::{cast_rays, cast_rays_with, RayDispatch, RaycastOptions, RaycastResult, PERSISTENT_WORKGROUPS};
pub use rayquery::raycast_rq;
pub use rtpipeline::{raycast_rtp, RtPipeline};
pub use traversal_stats::{MeanMax, TraversalCounts, TraversalSummary};
