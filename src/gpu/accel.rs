//! The driver's own ray tracing structures (`VK_KHR_acceleration_structure`), built from the same
//! triangles as our BVH so that the driver's ray tracing can run as a peer of the hand-written
//! kernels, through ray query (`glsl/rayquery.comp`, [`super::rayquery`]) or the ray tracing
//! pipeline (`glsl/raytrace/`, [`super::rtpipeline`]): one bottom-level structure (BLAS) over the mesh's triangles
//! (opaque, `PREFER_FAST_TRACE`, f32 vertices, u32 indices) and a top-level one (TLAS) holding one
//! identity instance of it.
//!
//! Zero-area triangles are left out of the BLAS, as they are left out of our BVH (they can never
//! be hit); a table maps the BLAS's primitive index to the OBJ triangle id, bound where the
//! kernels find the slot -> OBJ id table (`BINDING_SLOT_IDS`).
//!
//! Vertex, index, instance and scratch buffers are only build inputs: an acceleration structure
//! does not refer to them once built (Vulkan spec, "Acceleration Structures"), so they are freed
//! when [`AccelStructure::build`] returns. What stays is destroyed in reverse order of creation:
//! TLAS, its buffer, BLAS, its buffer, the id table.

use std::time::Instant;

use ash::vk;
use gpu_allocator::MemoryLocation;
use serde::Serialize;

use super::buffer::{Buffer, TexelBuffer};
use super::commands::memory_barrier;
use super::context::Context;
use super::timestamps::Timestamps;
use crate::error::{Error, Result, VkContext};
use crate::scene::Mesh;
use crate::shared::Texel;

/// One `VkAccelerationStructureInstanceKHR` (64 bytes), as the TLAS build reads it from a buffer.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AsInstance {
    /// Object-to-world transform, a row-major 3x4 matrix.
    pub transform: [f32; 12],
    /// `instanceCustomIndex` (low 24 bits) | `mask` << 24.
    pub custom_index_and_mask: u32,
    /// `instanceShaderBindingTableRecordOffset` (low 24 bits) | `flags` << 24.
    pub sbt_offset_and_flags: u32,
    /// Device address of the BLAS.
    pub blas_address: u64,
}

const _: () = assert!(std::mem::size_of::<AsInstance>() == 64);
const _: () = assert!(std::mem::size_of::<AsInstance>() == std::mem::size_of::<vk::AccelerationStructureInstanceKHR>());

impl AsInstance {
    /// The identity instance of `blas`: custom index 0, visible to every ray mask, no culling.
    pub fn identity(blas_address: u64) -> AsInstance {
        AsInstance {
            transform: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            custom_index_and_mask: 0xFF << 24,
            sbt_offset_and_flags: vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() << 24,
            blas_address,
        }
    }
}

/// Sizes and build times of the driver's structures for one scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AccelStats {
    /// Triangles in the BLAS (the mesh's, less its zero-area ones).
    pub triangles: usize,
    /// `accelerationStructureSize` the driver asked for (the buffer each structure lives in).
    pub blas_bytes: u64,
    pub tlas_bytes: u64,
    /// `buildScratchSize` of each build.
    pub blas_scratch_bytes: u64,
    pub tlas_scratch_bytes: u64,
    /// GPU time of each build (timestamps around `vkCmdBuildAccelerationStructuresKHR`),
    /// milliseconds; `None` where the queue has no timestamps.
    pub blas_build_ms: Option<f64>,
    pub tlas_build_ms: Option<f64>,
    /// Host wall time of the whole build: uploads, both builds, waits.
    pub wall_ms: f64,
}

/// One acceleration structure and the buffer it lives in; the handle goes first on drop.
struct AsHandle {
    loader: ash::khr::acceleration_structure::Device,
    raw: vk::AccelerationStructureKHR,
    address: vk::DeviceAddress,
    /// Dropped after `raw` is destroyed (fields drop after `Drop::drop`).
    _buffer: Buffer,
}

impl Drop for AsHandle {
    fn drop(&mut self) {
        // SAFETY: every submit that built or traced this structure was waited for; the buffer
        // holding it is still alive (it drops after this).
        unsafe { self.loader.destroy_acceleration_structure(self.raw, None) };
    }
}

/// The driver's BLAS + TLAS for one mesh, ready to bind ([`super::Resource::Accel`]).
pub struct AccelStructure {
    // Declaration order is drop order: the reverse of creation.
    tlas: AsHandle,
    blas: AsHandle,
    /// BLAS primitive index -> OBJ triangle id (bound at `BINDING_SLOT_IDS`).
    prim_ids: TexelBuffer,
    pub stats: AccelStats,
}

/// "`what`: unsupported on <device> (<driver>)", as [`Error::Unsupported`].
pub(crate) fn unsupported_feature(ctx: &Context, what: &str) -> Error {
    let info = ctx.info();
    Error::Unsupported(format!("{what}: unsupported on {} ({})", info.name, info.driver_label()))
}

pub(crate) fn device_address(ctx: &Context, buffer: &Buffer) -> vk::DeviceAddress {
    // SAFETY: the buffer was created with SHADER_DEVICE_ADDRESS usage and is bound to memory
    // allocated with the device-address flag (gpu-allocator does so when the context enables
    // bufferDeviceAddress, which it does with ray query).
    unsafe { ctx.device.raw.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(buffer.raw)) }
}

const INPUT_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR.as_raw()
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw(),
);

/// A scratch buffer whose returned address is aligned to `align`
/// (`minAccelerationStructureScratchOffsetAlignment`).
fn scratch(ctx: &Context, name: &str, size: u64, align: u64) -> Result<(Buffer, vk::DeviceAddress)> {
    let buffer = ctx.create_buffer(
        name,
        size + align,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        MemoryLocation::GpuOnly,
    )?;
    let address = device_address(ctx, &buffer).next_multiple_of(align);
    Ok((buffer, address))
}

fn create_as(
    ctx: &Context,
    loader: &ash::khr::acceleration_structure::Device,
    name: &str,
    ty: vk::AccelerationStructureTypeKHR,
    size: u64,
) -> Result<AsHandle> {
    let buffer = ctx.create_buffer(
        name,
        size,
        vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        MemoryLocation::GpuOnly,
    )?;
    let info = vk::AccelerationStructureCreateInfoKHR::default().buffer(buffer.raw).offset(0).size(size).ty(ty);
    // SAFETY: the buffer has ACCELERATION_STRUCTURE_STORAGE usage, is bound to memory and holds
    // `size` bytes at offset 0 (which is 256-byte aligned); destroyed by AsHandle before it.
    let raw = unsafe { loader.create_acceleration_structure(&info, None) }
        .during(&format!("vkCreateAccelerationStructureKHR ({name})"))?;
    // SAFETY: a structure just created from this device.
    let address = unsafe {
        loader.get_acceleration_structure_device_address(
            &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(raw),
        )
    };
    Ok(AsHandle { loader: loader.clone(), raw, address, _buffer: buffer })
}

/// One level about to be built: its structure, its scratch buffer and the driver's sizes.
struct LevelBuild {
    handle: AsHandle,
    scratch: Buffer,
    sizes: vk::AccelerationStructureBuildSizesInfoKHR<'static>,
}

/// Asks the driver how large the build `info` over `primitives` primitives is, creates the
/// structure (`name`) and its scratch buffer, and points `info` at both.
fn prepare_level(
    ctx: &Context,
    loader: &ash::khr::acceleration_structure::Device,
    name: &str,
    info: &mut vk::AccelerationStructureBuildGeometryInfoKHR,
    primitives: u32,
    scratch_align: u64,
) -> Result<LevelBuild> {
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: the build info is complete (addresses are ignored by the size query).
    unsafe {
        loader.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            info,
            &[primitives],
            &mut sizes,
        )
    };
    let handle = create_as(ctx, loader, name, info.ty, sizes.acceleration_structure_size)?;
    let (scratch, scratch_address) =
        scratch(ctx, &format!("{name} build scratch"), sizes.build_scratch_size, scratch_align)?;
    *info = info
        .dst_acceleration_structure(handle.raw)
        .scratch_data(vk::DeviceOrHostAddressKHR { device_address: scratch_address });
    Ok(LevelBuild { handle, scratch, sizes })
}

/// A level's build info and its one build range.
type LevelRecord<'a> =
    (&'a vk::AccelerationStructureBuildGeometryInfoKHR<'a>, &'a [vk::AccelerationStructureBuildRangeInfoKHR; 1]);

/// Records the builds of `levels` in order (the BLAS, then the TLAS that reads it), each timed
/// into its own query when `timestamps`, with the barriers before, between and after them; after
/// them the structures are visible to the shader stages `readers`.
///
/// # Safety
/// `cmd` is recording; every buffer and structure the infos name outlives the submit's wait.
unsafe fn record_builds(
    dev: &ash::Device,
    cmd: vk::CommandBuffer,
    loader: &ash::khr::acceleration_structure::Device,
    queries: &Timestamps,
    timestamps: bool,
    levels: [LevelRecord; 2],
    readers: vk::PipelineStageFlags,
) {
    let build = vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR | vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR;
    let build_stage = vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR;
    queries.reset(dev, cmd, 0);
    queries.reset(dev, cmd, 1);
    // The uploads (earlier submits) wrote the inputs.
    memory_barrier(
        dev,
        cmd,
        (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
        (build_stage, vk::AccessFlags::SHADER_READ | build),
    );
    for (i, (info, range)) in levels.into_iter().enumerate() {
        if i > 0 {
            // The TLAS build reads the BLAS.
            memory_barrier(dev, cmd, (build_stage, build), (build_stage, build));
        }
        if timestamps {
            queries.start(dev, cmd, i as u32);
        }
        loader.cmd_build_acceleration_structures(cmd, std::slice::from_ref(info), &[range]);
        if timestamps {
            queries.end(dev, cmd, i as u32);
        }
    }
    // Ray queries in later compute dispatches, and traces of the ray tracing pipeline, read the
    // structures (`readers`: the stages the context can run).
    memory_barrier(
        dev,
        cmd,
        (build_stage, vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR),
        (readers, vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR),
    );
}

impl AccelStructure {
    /// Builds the BLAS and TLAS of `mesh`, or returns [`Error::Unsupported`] where the context
    /// has neither ray query nor the ray tracing pipeline.
    pub fn build(ctx: &Context, mesh: &Mesh) -> Result<AccelStructure> {
        let enabled = ctx.enabled();
        if !enabled.acceleration_structure() {
            return Err(unsupported_feature(ctx, "ray query and ray tracing pipeline"));
        }
        // Only stages of enabled features may appear in a barrier.
        let mut readers = vk::PipelineStageFlags::empty();
        if enabled.ray_query {
            readers |= vk::PipelineStageFlags::COMPUTE_SHADER;
        }
        if enabled.ray_tracing_pipeline {
            readers |= vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR;
        }
        let t0 = Instant::now();
        let d = &ctx.device;
        let loader = ash::khr::acceleration_structure::Device::new(&d.instance, &d.raw);
        let mut as_props = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
        let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut as_props);
        // SAFETY: the physical device the context's device was created from; the chained struct
        // belongs to an extension the device enabled.
        unsafe { d.instance.get_physical_device_properties2(d.physical, &mut props) };
        let scratch_align = (as_props.min_acceleration_structure_scratch_offset_alignment as u64).max(1);

        let ids: Vec<u32> = (0..mesh.triangle_count()).filter(|&i| !mesh.is_degenerate(i)).map(|i| i as u32).collect();
        let indices: Vec<[u32; 3]> = ids.iter().map(|&i| mesh.triangles[i as usize]).collect();
        let prim_ids =
            ctx.upload_texels("driver AS: BLAS primitive -> OBJ id", bytemuck::cast_slice(&ids), Texel::R32Uint)?;
        let vertices = ctx.upload("driver AS: BLAS vertices", bytemuck::cast_slice(&mesh.positions), INPUT_USAGE)?;
        let index_buffer = ctx.upload("driver AS: BLAS indices", bytemuck::cast_slice(&indices), INPUT_USAGE)?;

        // Bottom level: the triangles.
        let triangles = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
            .vertex_format(vk::Format::R32G32B32_SFLOAT)
            .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: device_address(ctx, &vertices) })
            .vertex_stride(std::mem::size_of::<[f32; 3]>() as u64)
            .max_vertex(mesh.positions.len().saturating_sub(1) as u32)
            .index_type(vk::IndexType::UINT32)
            .index_data(vk::DeviceOrHostAddressConstKHR { device_address: device_address(ctx, &index_buffer) });
        let blas_geometry = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { triangles })
            .flags(vk::GeometryFlagsKHR::OPAQUE)];
        let blas_count = ids.len() as u32;
        let mut blas_info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
            .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(&blas_geometry);
        let blas = prepare_level(ctx, &loader, "driver AS: BLAS", &mut blas_info, blas_count, scratch_align)?;

        // Top level: one identity instance of the BLAS.
        let instances = ctx.upload(
            "driver AS: TLAS instances",
            bytemuck::bytes_of(&AsInstance::identity(blas.handle.address)),
            INPUT_USAGE,
        )?;
        let instance_data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
            .array_of_pointers(false)
            .data(vk::DeviceOrHostAddressConstKHR { device_address: device_address(ctx, &instances) });
        let tlas_geometry = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR { instances: instance_data })];
        let mut tlas_info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
            .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(&tlas_geometry);
        let tlas = prepare_level(ctx, &loader, "driver AS: TLAS", &mut tlas_info, 1, scratch_align)?;

        let timestamps = Timestamps::supported(ctx);
        let queries = Timestamps::new(ctx, 2)?;
        let blas_range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(blas_count)];
        let tlas_range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(1)];
        ctx.one_shot("building the driver's acceleration structures", |dev, cmd| {
            // SAFETY: every buffer and structure named in the build infos is alive until
            // one_shot has waited for the submit; the scratch ranges do not overlap.
            unsafe {
                record_builds(
                    dev,
                    cmd,
                    &loader,
                    &queries,
                    timestamps,
                    [(&blas_info, &blas_range), (&tlas_info, &tlas_range)],
                    readers,
                )
            }
        })?;
        let (blas_build_ms, tlas_build_ms) = if timestamps {
            let ms = queries.read_ms()?;
            (Some(ms[0]), Some(ms[1]))
        } else {
            (None, None)
        };
        drop(queries);
        // Build inputs, freed now (see the module comment), last created first.
        drop(tlas.scratch);
        drop(instances);
        drop(blas.scratch);
        drop(index_buffer);
        drop(vertices);
        let stats = AccelStats {
            triangles: ids.len(),
            blas_bytes: blas.sizes.acceleration_structure_size,
            tlas_bytes: tlas.sizes.acceleration_structure_size,
            blas_scratch_bytes: blas.sizes.build_scratch_size,
            tlas_scratch_bytes: tlas.sizes.build_scratch_size,
            blas_build_ms,
            tlas_build_ms,
            wall_ms: t0.elapsed().as_secs_f64() * 1e3,
        };
        Ok(AccelStructure { tlas: tlas.handle, blas: blas.handle, prim_ids, stats })
    }

    pub(crate) fn tlas(&self) -> vk::AccelerationStructureKHR {
        self.tlas.raw
    }

    /// Device address of the BLAS (what the TLAS instance points at).
    pub fn blas_address(&self) -> vk::DeviceAddress {
        self.blas.address
    }

    /// The primitive index -> OBJ triangle id table, for `BINDING_SLOT_IDS`.
    pub(crate) fn prim_ids(&self) -> &TexelBuffer {
        &self.prim_ids
    }
}
