//! A repro's dispatch on the device in front of us: a context with only what its kernel needs,
//! its buffers uploaded from the folder's files, every ray in one dispatch (no warm-up), the hits
//! read back. The same code runs under the capture layer when a repro is made (so the capture
//! holds exactly this) and in `trilab repro --check`.

use crate::error::Result;
use crate::gpu::{cast_rays, Context, ContextOptions, Needs, RaycastOptions, Validation};
use crate::kernels::KernelSource;
use crate::pipeline::BoundScene;
use crate::rays::Hit;

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
    let cell = &repro.manifest.cell;
    ctx.capabilities().traversal(cell.traversal)?;
    let kernel = ctx.kernel(repro.kernel)?;
    let scene = BoundScene::upload(ctx, cell.access, &repro.bindings)?;
    let resources: Vec<_> = scene.resources().collect();
    let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays: repro.rays.len() };
    Ok(cast_rays(ctx, &kernel, &resources, &repro.rays, &opts)?.hits)
}
