//! Descriptor sets from a kernel's reflected bindings, and one-off dispatches.

use std::collections::BTreeMap;

use ash::vk;

use super::accel::AccelStructure;
use super::buffer::{Buffer, TexelBuffer};
use super::context::Context;
use super::kernel::Kernel;
use crate::error::{Error, Result, VkContext};

/// A pipeline's descriptor set 0, as descriptor sets are allocated and written for it: a compute
/// [`Kernel`], or the ray-tracing pipeline (`gpu::rtpipeline`).
pub trait DescriptorLayout {
    /// Names it in errors.
    fn name(&self) -> &'static str;
    /// Descriptor types of set 0 by binding.
    fn bindings(&self) -> BTreeMap<u32, vk::DescriptorType>;
    /// The layout of set 0.
    fn set_layout(&self) -> vk::DescriptorSetLayout;
}

impl DescriptorLayout for Kernel {
    fn name(&self) -> &'static str {
        self.name
    }

    fn bindings(&self) -> BTreeMap<u32, vk::DescriptorType> {
        Kernel::bindings(self)
    }

    fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.set_layout
    }
}

/// What is bound at one binding.
#[derive(Clone, Copy)]
pub enum Resource<'a> {
    /// A storage buffer range.
    Buffer { buffer: &'a Buffer, offset: u64, range: u64 },
    /// A storage texel buffer.
    Texels(&'a TexelBuffer),
    /// The top-level acceleration structure of the driver's ray tracing (ray query).
    Accel(&'a AccelStructure),
}

impl<'a> Resource<'a> {
    pub fn whole(buffer: &'a Buffer) -> Self {
        Resource::Buffer { buffer, offset: 0, range: vk::WHOLE_SIZE }
    }
}

/// Writes `resources` into `set`, checking that every binding the kernel declares is provided,
/// with the kind of resource it declares. Resources at bindings the kernel does not use (a scene
/// provides all its buffers; a kernel may read a subset) are skipped.
pub(crate) fn write_set(
    ctx: &Context,
    kernel: &(impl DescriptorLayout + ?Sized),
    set: vk::DescriptorSet,
    resources: &[(u32, Resource)],
) -> Result<()> {
    let bindings = kernel.bindings();
    let missing: Vec<u32> = bindings.keys().copied().filter(|b| !resources.iter().any(|(r, _)| r == b)).collect();
    if !missing.is_empty() {
        return Err(Error::Usage(format!("kernel {}: nothing bound at binding(s) {missing:?}", kernel.name())));
    }
    let mut buffer_infos = Vec::new();
    let mut views = Vec::new();
    let mut accels = Vec::new();
    for (binding, r) in resources {
        let Some(&ty) = bindings.get(binding) else { continue };
        match r {
            Resource::Buffer { buffer, offset, range }
                if ty == vk::DescriptorType::STORAGE_BUFFER || ty == vk::DescriptorType::UNIFORM_BUFFER =>
            {
                buffer_infos.push((
                    *binding,
                    ty,
                    vk::DescriptorBufferInfo::default().buffer(buffer.raw).offset(*offset).range(*range),
                ))
            }
            Resource::Texels(t) if ty == vk::DescriptorType::STORAGE_TEXEL_BUFFER => views.push((*binding, ty, t.view)),
            Resource::Accel(a) if ty == vk::DescriptorType::ACCELERATION_STRUCTURE_KHR => {
                accels.push((*binding, [a.tlas()]))
            }
            _ => {
                return Err(Error::Usage(format!(
                    "kernel {}: binding {binding} is a {ty:?}, given a different kind of resource",
                    kernel.name()
                )))
            }
        }
    }
    let mut writes: Vec<vk::WriteDescriptorSet> = buffer_infos
        .iter()
        .map(|(b, ty, info)| {
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(*b)
                .descriptor_type(*ty)
                .buffer_info(std::slice::from_ref(info))
        })
        .collect();
    writes.extend(views.iter().map(|(b, ty, view)| {
        vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(*b)
            .descriptor_type(*ty)
            .texel_buffer_view(std::slice::from_ref(view))
    }));
    let mut accel_infos: Vec<vk::WriteDescriptorSetAccelerationStructureKHR> = accels
        .iter()
        .map(|(_, handle)| vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(handle))
        .collect();
    writes.extend(accels.iter().zip(accel_infos.iter_mut()).map(|((b, _), info)| {
        // The count is not implied by a pointer of the write itself (the handles hang off pNext).
        vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(*b)
            .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
            .descriptor_count(1)
            .push_next(info)
    }));
    // SAFETY: the set is not in use by any pending submit; every handle is alive.
    unsafe { ctx.device.raw.update_descriptor_sets(&writes, &[]) };
    Ok(())
}

/// A descriptor pool sized for `sets` sets of `kernel`'s layout; destroyed on drop.
pub(crate) struct DescriptorPool<'a> {
    ctx: &'a Context,
    pub(crate) pool: vk::DescriptorPool,
}

impl Drop for DescriptorPool<'_> {
    fn drop(&mut self) {
        // SAFETY: submits using its sets were waited for.
        unsafe { self.ctx.device.raw.destroy_descriptor_pool(self.pool, None) };
    }
}

impl<'a> DescriptorPool<'a> {
    pub(crate) fn new(
        ctx: &'a Context,
        kernel: &(impl DescriptorLayout + ?Sized),
        sets: u32,
    ) -> Result<(DescriptorPool<'a>, Vec<vk::DescriptorSet>)> {
        let mut counts: std::collections::BTreeMap<i32, u32> = Default::default();
        for ty in kernel.bindings().values() {
            *counts.entry(ty.as_raw()).or_default() += sets;
        }
        let sizes: Vec<vk::DescriptorPoolSize> = counts
            .iter()
            .map(|(&ty, &n)| vk::DescriptorPoolSize::default().ty(vk::DescriptorType::from_raw(ty)).descriptor_count(n))
            .collect();
        let info = vk::DescriptorPoolCreateInfo::default().max_sets(sets).pool_sizes(&sizes);
        // SAFETY: valid device and create info.
        let pool =
            unsafe { ctx.device.raw.create_descriptor_pool(&info, None) }.during("creating a descriptor pool")?;
        let pool = DescriptorPool { ctx, pool };
        let layouts = vec![kernel.set_layout(); sets as usize];
        let alloc = vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool.pool).set_layouts(&layouts);
        // SAFETY: the pool was sized for exactly these sets.
        let sets = unsafe { ctx.device.raw.allocate_descriptor_sets(&alloc) }.during("allocating descriptor sets")?;
        Ok((pool, sets))
    }
}

impl Context {
    /// Runs `kernel` once over `groups` workgroups with `resources` bound and `push` as its push
    /// constants, and waits for it (tests and small jobs; ray casting has its own batched path).
    pub fn dispatch(&self, kernel: &Kernel, resources: &[(u32, Resource)], push: &[u8], groups: u32) -> Result<()> {
        let (_pool, sets) = DescriptorPool::new(self, kernel, 1)?;
        write_set(self, kernel, sets[0], resources)?;
        if let Some((_, size)) = kernel.layout.push_constants {
            if size as usize != push.len() {
                return Err(Error::Usage(format!(
                    "kernel {} takes {size} bytes of push constants, given {}",
                    kernel.name,
                    push.len()
                )));
            }
        }
        self.one_shot(&format!("dispatching {}", kernel.name), |d, cmd| unsafe {
            // SAFETY: pipeline, layout and set are alive until one_shot's wait returns.
            let marker = self.mark_begin(d, cmd, format!("{} ({groups} workgroups)", kernel.name));
            kernel.record(d, cmd, sets[0], push, groups);
            self.mark_end(d, cmd, marker);
        })
    }
}

/// One dispatch of [`Context::dispatch_chain`]: kernel, bindings, push constants, workgroups.
pub type ChainStep<'a> = (&'a Kernel, &'a [(u32, Resource<'a>)], &'a [u8], u32);

impl Context {
    /// Runs `steps` in order in one command buffer and waits. With `barriers`, a full compute
    /// barrier separates consecutive dispatches (what any chain of kernels sharing buffers
    /// needs); without, none does: that exists so tests can prove synchronization validation
    /// reports the hazard (`tests/validation.rs`).
    pub fn dispatch_chain(&self, steps: &[ChainStep], barriers: bool) -> Result<()> {
        let mut pools = Vec::new();
        let mut sets = Vec::new();
        for (kernel, resources, push, _) in steps {
            if kernel.layout.push_constants.map(|(_, n)| n as usize).unwrap_or(0) != push.len() {
                return Err(Error::Usage(format!("kernel {}: wrong push-constant size {}", kernel.name, push.len())));
            }
            let (pool, s) = DescriptorPool::new(self, *kernel, 1)?;
            write_set(self, *kernel, s[0], resources)?;
            pools.push(pool);
            sets.push(s[0]);
        }
        let names: Vec<&str> = steps.iter().map(|s| s.0.name).collect();
        self.one_shot(&format!("dispatch chain {}", names.join(" -> ")), |d, cmd| {
            for (i, ((kernel, _, push, groups), set)) in steps.iter().zip(&sets).enumerate() {
                // SAFETY: pipelines, layouts, sets and the buffers behind them outlive one_shot's
                // wait; `cmd` is recording.
                unsafe {
                    if i > 0 && barriers {
                        super::commands::memory_barrier(
                            d,
                            cmd,
                            (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::SHADER_WRITE),
                            (
                                vk::PipelineStageFlags::COMPUTE_SHADER,
                                vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                            ),
                        );
                    }
                    kernel.record(d, cmd, *set, push, *groups);
                }
            }
        })
    }
}
