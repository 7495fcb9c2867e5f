//! A repro's dispatch on the device in front of us: a context with only what its kernel needs,
//! its buffers uploaded from the folder's files, every ray in one dispatch (no warm-up), the hits
//! read back. The same code runs under the capture layer when a repro is made (so the capture
//! holds exactly this) and in `trilab repro --check`.

use crate::encoding::AccessPath;
use crate::error::Result;
use crate::gpu::{cast_rays, Context, ContextOptions, Needs, RaycastOptions, RaycastResult, Validation};
use crate::kernels::KernelSource;
use crate::pipeline::{BoundScene, HostBinding};
use crate::rays::{Hit, Ray};

use super::folder::Repro;

/// What `kernel` needs of a device (its SPIR-V's capabilities, full subgroups).
pub fn needs(kernel: &KernelSource) -> Result<Needs> {
    Needs::of(kernel.name, &kernel.words())
}

/// A context on `device` (index or name; `None`: trilab's usual choice) that enables only what
/// `kernel` needs, so that a capture of it replays on any device that can run the kernel.
pub fn context(kernel: &KernelSource, device: Option<String>, validation: Validation) -> Result<Context> {
    Context::new(&ContextOptions { device, validation, only: Some(needs(kernel)?), ..Default::default() })
}

/// The repro's rays through its kernel over its buffers, once; their hits.
pub fn dispatch(ctx: &Context, repro: &Repro) -> Result<Vec<Hit>> {
    ctx.capabilities().traversal(repro.manifest.cell.traversal)?;
    Ok(cast(ctx, repro.kernel, repro.manifest.cell.access, &repro.bindings, &repro.rays)?.hits)
}

/// `rays` through `kernel` over `bindings` uploaded for `access`: every ray in one dispatch
/// (as many as the device's dispatch limits allow), no warm-up.
pub fn cast(
    ctx: &Context,
    kernel: &'static KernelSource,
    access: AccessPath,
    bindings: &[HostBinding],
    rays: &[Ray],
) -> Result<RaycastResult> {
    let kernel = ctx.kernel(kernel)?;
    let scene = BoundScene::upload(ctx, access, bindings)?;
    let resources: Vec<_> = scene.resources().collect();
    let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays: rays.len() };
    cast_rays(ctx, &*kernel, &resources, rays, &opts)
}
