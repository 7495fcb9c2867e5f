//! GPU memory plans: every buffer a scene (and a ray set, and the path tracer) needs, computed
//! from counts alone, before anything is encoded or allocated, and checked against the device's
//! limits. A scene that cannot fit gets [`Error::SceneTooLarge`] naming the buffer, what it needs
//! and what the device allows, never a crash or a driver out-of-memory.
//!
//! Limits checked, per buffer: `maxTexelBufferElements` (texel path: one storage texel buffer per
//! scene buffer), 2^31 texels (address path: the kernels index with signed 32-bit integers,
//! `glsl/types.glsl`), `maxBufferSize` (`VK_KHR_maintenance4`, where present) and
//! `maxMemoryAllocationSize`; in all, the device-local heap or, with `VK_EXT_memory_budget`, the
//! heap's budget left. Ray and hit buffers are bound per dispatch in ranges of at most
//! `maxStorageBufferRange` (`gpu::raycast`), so only their whole size is limited.
//!
//! The scene's access path ([`AccessPath`]) is chosen here: storage texel buffers (the default
//! kernels) when every buffer fits one binding, else buffer device addresses (the raycast
//! kernels' `*_bda` variants).

use ash::vk;

use super::context::Context;
use crate::bvh::{Bvh, BvhNode};
use crate::encoding::{Method, MtTriangle, QuadMt, QuadUnit, UnitTriangle};
use crate::error::{Error, Result, TooLarge};
use crate::named::named_enum;
use crate::scene::Mesh;
use crate::shared::Texel;
use crate::shared::{BINDING_INDICES, BINDING_NODES, BINDING_PRIMS, BINDING_SLOT_IDS};

/// Most texels one scene buffer may hold on the address path: the kernels' indices are signed
/// 32-bit access-chain indices.
pub const MAX_ADDRESS_TEXELS: u64 = 1 << 31;
/// Most nodes and triangle slots the kernels address (27-bit indices).
const MAX_NODE_INDEX: u64 = crate::encoding::MAX_NODE_INDEX as u64;

/// What the planner checks against. [`DeviceLimits::of`] reads a device's; tests and
/// `trilab scale --limit-*` shrink them to exercise the "does not fit" paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct DeviceLimits {
    pub max_texel_buffer_elements: u64,
    pub max_storage_buffer_range: u64,
    /// `maxBufferSize` (`VK_KHR_maintenance4`); `None` where the device does not report one.
    pub max_buffer_size: Option<u64>,
    pub max_memory_allocation_size: u64,
    /// The largest device-local heap.
    pub device_local_bytes: u64,
    /// `VK_EXT_memory_budget`: that heap's budget minus its current usage.
    pub budget_bytes: Option<u64>,
    /// `bufferDeviceAddress` is enabled (the address path is possible).
    pub buffer_device_address: bool,
}

impl DeviceLimits {
    /// The limits of `ctx`'s device, with the memory budget read now (where supported).
    pub fn of(ctx: &Context) -> DeviceLimits {
        let info = ctx.info();
        DeviceLimits {
            max_texel_buffer_elements: u64::from(info.max_texel_buffer_elements),
            max_storage_buffer_range: u64::from(info.max_storage_buffer_range),
            max_buffer_size: info.max_buffer_size,
            max_memory_allocation_size: info.max_memory_allocation_size,
            device_local_bytes: info.device_local_heap_bytes,
            budget_bytes: if info.memory_budget { budget(ctx) } else { None },
            buffer_device_address: ctx.enabled().buffer_device_address,
        }
    }

    /// The largest single buffer: `maxBufferSize` and `maxMemoryAllocationSize`, and which of
    /// the two is the smaller.
    pub fn max_single_buffer(&self) -> (u64, &'static str) {
        match self.max_buffer_size {
            Some(b) if b < self.max_memory_allocation_size => (b, "maxBufferSize"),
            _ => (self.max_memory_allocation_size, "maxMemoryAllocationSize"),
        }
    }

    /// Device memory available to a new scene: the budget where known, else the heap size.
    pub fn available_device_bytes(&self) -> (u64, &'static str) {
        match self.budget_bytes {
            Some(b) => (b, "the device-local heap's memory budget (VK_EXT_memory_budget)"),
            None => (self.device_local_bytes, "the device-local heap"),
        }
    }
}

/// The largest device-local heap's budget left, from `VK_EXT_memory_budget`.
fn budget(ctx: &Context) -> Option<u64> {
    let d = &ctx.device;
    let mut b = vk::PhysicalDeviceMemoryBudgetPropertiesEXT::default();
    let mut p2 = vk::PhysicalDeviceMemoryProperties2::default().push_next(&mut b);
    // SAFETY: live instance and physical device; the device reports VK_EXT_memory_budget
    // (DeviceInfo::memory_budget), whose physical-device query needs no enabling on Vulkan 1.1+.
    unsafe { d.instance.get_physical_device_memory_properties2(d.physical, &mut p2) };
    let props = p2.memory_properties;
    let heaps = &props.memory_heaps[..props.memory_heap_count as usize];
    (0..heaps.len())
        .filter(|&i| heaps[i].flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .max_by_key(|&i| heaps[i].size)
        .map(|i| b.heap_budget[i].saturating_sub(b.heap_usage[i]))
        .filter(|&left| left > 0)
}

named_enum! {
    /// How `--scene-access` asks the kernels to read the scene.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum SceneAccess: "scene access" {
        /// Texel buffers when every scene buffer fits one binding, else device addresses.
        Auto = "auto" (default),
        /// Storage texel buffers (the default kernels).
        Texel = "texel",
        /// Buffer device addresses (the `*_bda` kernels).
        Address = "address",
    }
}

/// The path a scene is read through, once chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum AccessPath {
    Texel,
    Address,
}

impl AccessPath {
    pub fn name(self) -> &'static str {
        match self {
            AccessPath::Texel => "texel",
            AccessPath::Address => "address",
        }
    }
}

/// One planned buffer.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct BufferPlan {
    /// The encoder's name for it (`SceneBuffer::name`).
    pub name: &'static str,
    pub binding: u32,
    /// Bytes the encoder writes (the GPU buffer holds at least one texel more if this is 0).
    pub bytes: u64,
    /// Bytes per texel (16, or 4 for the slot ids).
    pub texel_size: u64,
}

impl BufferPlan {
    fn new(name: &'static str, binding: u32, texel: Texel, count: u64, struct_size: usize) -> BufferPlan {
        BufferPlan { name, binding, bytes: count * struct_size as u64, texel_size: texel.size() as u64 }
    }

    /// Texels bound (at least one: a view cannot be empty).
    pub fn texels(&self) -> u64 {
        (self.bytes / self.texel_size).max(1)
    }

    /// Bytes allocated on the GPU.
    pub fn gpu_bytes(&self) -> u64 {
        self.texels() * self.texel_size
    }
}

/// The counts a plan is made of (what the BVH and the mesh say, nothing encoded).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SceneCounts {
    pub triangles: u64,
    pub vertices: u64,
    pub nodes: u64,
    /// BVH triangle slots (`Bvh::prim_ids`, padding included).
    pub slots: u64,
    /// Groups of four slots when every leaf is padded to whole quads (the Quad encodings).
    pub quads: u64,
}

impl SceneCounts {
    pub fn of(mesh: &Mesh, bvh: &Bvh) -> SceneCounts {
        let quads = bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| u64::from(n.count).div_ceil(4)).sum();
        SceneCounts {
            triangles: mesh.triangle_count() as u64,
            vertices: mesh.positions.len() as u64,
            nodes: bvh.nodes.len() as u64,
            slots: bvh.prim_ids.len() as u64,
            quads,
        }
    }
}

/// Every buffer one method's encoding of a scene uploads.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct MemoryPlan {
    pub method: Method,
    pub counts: SceneCounts,
    pub buffers: Vec<BufferPlan>,
}

impl MemoryPlan {
    /// The plan of `method`'s encoding (`Method::encode`) for a scene of `counts`, in the order
    /// `EncodedScene::buffers` lists them.
    pub fn of(method: Method, c: &SceneCounts) -> MemoryPlan {
        let node = std::mem::size_of::<BvhNode>();
        let (slot_ids, prims) = match method {
            Method::Mt | Method::Watertight | Method::F64 => (
                c.slots,
                vec![
                    // An empty mesh still uploads one vertex (src/encoding/mt.rs).
                    BufferPlan::new("mt vertices", BINDING_PRIMS, Texel::Rgba32Float, c.vertices.max(1), 16),
                    BufferPlan::new(
                        "mt triangles",
                        BINDING_INDICES,
                        Texel::Rgba32Uint,
                        c.slots,
                        std::mem::size_of::<MtTriangle>(),
                    ),
                ],
            ),
            Method::Unit | Method::BaldwinWeber => {
                let name = if method == Method::Unit { "unit triangles" } else { "baldwin-weber triangles" };
                let size = std::mem::size_of::<UnitTriangle>();
                (c.slots, vec![BufferPlan::new(name, BINDING_PRIMS, Texel::Rgba32Float, c.slots, size)])
            }
            Method::QuadMt => (
                4 * c.quads,
                vec![BufferPlan::new(
                    "quad mt",
                    BINDING_PRIMS,
                    Texel::Rgba32Float,
                    c.quads,
                    std::mem::size_of::<QuadMt>(),
                )],
            ),
            Method::QuadUnit => (
                4 * c.quads,
                vec![BufferPlan::new(
                    "quad unit",
                    BINDING_PRIMS,
                    Texel::Rgba32Float,
                    c.quads,
                    std::mem::size_of::<QuadUnit>(),
                )],
            ),
        };
        let mut buffers = vec![
            BufferPlan::new("bvh nodes", BINDING_NODES, Texel::Rgba32Uint, c.nodes, node),
            BufferPlan::new("slot ids", BINDING_SLOT_IDS, Texel::R32Uint, slot_ids, 4),
        ];
        buffers.extend(prims);
        MemoryPlan { method, counts: *c, buffers }
    }

    /// The plan of an already encoded scene (its real buffer sizes).
    pub fn of_encoded(scene: &crate::encoding::EncodedScene) -> MemoryPlan {
        let buffers: Vec<BufferPlan> = scene
            .buffers()
            .into_iter()
            .map(|b| BufferPlan {
                name: b.name,
                binding: b.binding,
                bytes: b.bytes.len() as u64,
                texel_size: b.texel.size() as u64,
            })
            .collect();
        let real = scene.slot_ids.len() - scene.padding_slots();
        let counts = SceneCounts {
            triangles: real as u64,
            nodes: scene.nodes.len() as u64,
            slots: scene.slot_ids.len() as u64,
            ..Default::default()
        };
        MemoryPlan { method: scene.method, counts, buffers }
    }

    pub fn for_bvh(method: Method, mesh: &Mesh, bvh: &Bvh) -> MemoryPlan {
        Self::of(method, &SceneCounts::of(mesh, bvh))
    }

    /// Bytes the encoder writes (`EncodedScene::gpu_bytes`).
    pub fn bytes(&self) -> u64 {
        self.buffers.iter().map(|b| b.bytes).sum()
    }

    /// Bytes allocated on the GPU (empty buffers get one texel).
    pub fn gpu_bytes(&self) -> u64 {
        self.buffers.iter().map(BufferPlan::gpu_bytes).sum()
    }

    pub fn bytes_per_triangle(&self) -> f64 {
        self.bytes() as f64 / self.counts.triangles.max(1) as f64
    }

    /// Chooses how the kernels read this scene (`requested`), or says why it cannot fit.
    /// `scene` names the scene in the error.
    pub fn choose(&self, scene: &str, requested: SceneAccess, limits: &DeviceLimits) -> Result<AccessPath> {
        let err = |buffer: &str, needed: String, available: String, hint: &str| {
            Error::SceneTooLarge(Box::new(TooLarge {
                scene: scene.to_owned(),
                method: self.method.name().to_owned(),
                buffer: buffer.to_owned(),
                needed,
                available,
                hint: hint.to_owned(),
            }))
        };
        let smaller = "a method with a smaller encoding (bytes per triangle: `trilab scale`), or a smaller scene";
        if self.counts.nodes > MAX_NODE_INDEX || self.slot_count() > MAX_NODE_INDEX {
            return Err(err(
                "bvh nodes / slot ids",
                format!("{} nodes and {} slots", self.counts.nodes, self.slot_count()),
                format!("{MAX_NODE_INDEX} of each (27-bit indices in glsl/traverse.glsl)"),
                "a larger leaf size (fewer nodes), or a smaller scene",
            ));
        }
        let (max_buf, max_buf_name) = limits.max_single_buffer();
        for b in &self.buffers {
            if b.gpu_bytes() > max_buf {
                return Err(err(
                    b.name,
                    format!("{} bytes", b.gpu_bytes()),
                    format!("{max_buf} bytes ({max_buf_name})"),
                    smaller,
                ));
            }
        }
        let (avail, avail_name) = limits.available_device_bytes();
        if self.gpu_bytes() > avail {
            return Err(err(
                "all scene buffers",
                format!("{} bytes", self.gpu_bytes()),
                format!("{avail} bytes ({avail_name})"),
                smaller,
            ));
        }
        let over_texel = self.buffers.iter().find(|b| b.texels() > limits.max_texel_buffer_elements);
        let texel_err = |b: &BufferPlan, hint: &str| {
            err(
                b.name,
                format!("{} texels", b.texels()),
                format!("{} texels per binding (maxTexelBufferElements)", limits.max_texel_buffer_elements),
                hint,
            )
        };
        let address = || -> Result<AccessPath> {
            if !limits.buffer_device_address {
                let b = over_texel.unwrap_or(&self.buffers[0]);
                return Err(texel_err(
                    b,
                    "a device with bufferDeviceAddress (the address path), a method with a smaller encoding, \
                     or a smaller scene",
                ));
            }
            if let Some(b) = self.buffers.iter().find(|b| b.texels() > MAX_ADDRESS_TEXELS) {
                return Err(err(
                    b.name,
                    format!("{} texels", b.texels()),
                    format!("{MAX_ADDRESS_TEXELS} texels (signed 32-bit indices on the address path)"),
                    smaller,
                ));
            }
            Ok(AccessPath::Address)
        };
        match (requested, over_texel) {
            (SceneAccess::Texel, Some(b)) => Err(texel_err(b, "--scene-access address (or auto)")),
            (SceneAccess::Texel, None) | (SceneAccess::Auto, None) => Ok(AccessPath::Texel),
            (SceneAccess::Address, _) | (SceneAccess::Auto, Some(_)) => address(),
        }
    }

    fn slot_count(&self) -> u64 {
        self.buffers.iter().find(|b| b.binding == BINDING_SLOT_IDS).map_or(0, |b| b.bytes / 4)
    }
}

/// The path tracer's buffers beyond the encoded scene (`render::render`): per-slot shading,
/// emissive triangles, materials (storage texel buffers: the path tracer has no address path)
/// and the accumulation image (one storage buffer bound whole).
pub fn pathtrace_extras(slots: u64, emissive: u64, materials: u64, pixels: u64) -> Vec<BufferPlan> {
    vec![
        BufferPlan::new("shading", crate::shared::BINDING_SHADING, Texel::Rgba32Float, slots, 16),
        BufferPlan::new("lights", crate::shared::BINDING_LIGHTS, Texel::Rgba32Float, emissive.max(1), 48),
        BufferPlan::new("materials", crate::shared::BINDING_MATERIALS, Texel::Rgba32Float, materials, 64),
        BufferPlan::new("accumulation image", crate::shared::BINDING_ACCUM, Texel::Rgba32Float, pixels, 16),
    ]
}

/// Checks a render of `mesh` with `method` on `bvh` at `pixels` against `limits`, before
/// anything is encoded: the scene (texel path) and the path tracer's own buffers.
pub fn check_render(
    scene: &str,
    mesh: &Mesh,
    bvh: &Bvh,
    method: Method,
    pixels: u64,
    limits: &DeviceLimits,
) -> Result<()> {
    let plan = MemoryPlan::for_bvh(method, mesh, bvh);
    check_pathtrace(scene, &plan, &pathtrace_extras_for(mesh, method, &plan.counts, pixels), limits)
}

/// [`pathtrace_extras`] for `method`'s encoding of `mesh` (`counts` from its BVH): a shading
/// record per slot (whole quads for the Quad methods), a light record per emissive triangle,
/// and an image of `pixels`.
pub fn pathtrace_extras_for(mesh: &Mesh, method: Method, counts: &SceneCounts, pixels: u64) -> Vec<BufferPlan> {
    let slots = if method.group_size() > 1 { 4 * counts.quads } else { counts.slots };
    let emissive =
        mesh.material_ids.iter().filter(|&&m| mesh.materials.get(m as usize).is_some_and(|m| m.is_emissive())).count();
    pathtrace_extras(slots, emissive as u64, mesh.materials.len() as u64, pixels)
}

/// Checks the path tracer's scene (texel path only) and extras against `limits`.
pub fn check_pathtrace(scene: &str, plan: &MemoryPlan, extras: &[BufferPlan], limits: &DeviceLimits) -> Result<()> {
    plan.choose(scene, SceneAccess::Texel, limits).map_err(|e| match e {
        Error::SceneTooLarge(mut t) if t.hint.starts_with("--scene-access") => {
            t.hint = "the path tracer reads scenes through texel buffers only: a method with a smaller encoding, \
                      or a smaller scene"
                .into();
            Error::SceneTooLarge(t)
        }
        e => e,
    })?;
    for b in extras {
        let (limit, name) = if b.binding == crate::shared::BINDING_ACCUM {
            (limits.max_storage_buffer_range, "maxStorageBufferRange")
        } else {
            (limits.max_texel_buffer_elements * b.texel_size, "maxTexelBufferElements")
        };
        if b.gpu_bytes() > limit {
            return Err(Error::SceneTooLarge(Box::new(TooLarge {
                scene: scene.to_owned(),
                method: plan.method.name().to_owned(),
                buffer: format!("path tracer {}", b.name),
                needed: format!("{} bytes", b.gpu_bytes()),
                available: format!("{limit} bytes ({name})"),
                hint: "a smaller image (accumulation) or scene".into(),
            })));
        }
    }
    Ok(())
}

/// Per-ray buffers of a cast: rays (32 B) and hits (16 B), plus traversal counts (16 B) for a
/// `stats` kernel; each is one buffer bound in per-dispatch ranges, so only its whole size is
/// limited (by the largest single buffer). Host-visible staging of the same sizes is made too.
pub fn check_rays(rays: u64, stats: bool, limits: &DeviceLimits) -> Result<u64> {
    let (max_buf, name) = limits.max_single_buffer();
    let mut total = 0;
    for (buffer, per_ray) in [("rays", 32), ("hits", 16), ("traversal counts", if stats { 16 } else { 0 })] {
        let bytes = rays * per_ray;
        if bytes > max_buf {
            return Err(Error::Usage(format!(
                "{rays} rays: the `{buffer}` buffer needs {bytes} bytes, more than this device's {name} \
                 ({max_buf} bytes); cast fewer rays per call"
            )));
        }
        total += bytes;
    }
    Ok(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildOptions;

    fn limits() -> DeviceLimits {
        DeviceLimits {
            max_texel_buffer_elements: 1 << 27,
            max_storage_buffer_range: 1 << 27,
            max_buffer_size: None,
            max_memory_allocation_size: 1 << 32,
            device_local_bytes: 1 << 34,
            budget_bytes: None,
            buffer_device_address: true,
        }
    }

    fn grid(n: u32) -> Mesh {
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for i in 0..n {
            let (x, y) = ((i % 17) as f32, (i / 17) as f32);
            pos.extend([[x, y, 0.0], [x + 0.9, y, 0.3], [x, y + 0.9, 0.6]]);
            tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        Mesh::from_triangles(pos, tris)
    }

    #[test]
    fn plan_equals_the_encoded_buffers() {
        let m = grid(203);
        for leaf in [1, 3, 4, 7] {
            let bvh = Bvh::build(&m, &BuildOptions::new(leaf));
            for method in Method::ALL {
                let plan = MemoryPlan::for_bvh(method, &m, &bvh);
                let enc = method.encode(&m, &bvh);
                let got: Vec<(&str, u32, u64)> =
                    enc.buffers().iter().map(|b| (b.name, b.binding, b.bytes.len() as u64)).collect();
                let want: Vec<(&str, u32, u64)> = plan.buffers.iter().map(|b| (b.name, b.binding, b.bytes)).collect();
                assert_eq!(got, want, "{method} leaf {leaf}");
                assert_eq!(plan.bytes(), enc.gpu_bytes() as u64);
            }
        }
    }

    #[test]
    fn auto_picks_texels_then_addresses_then_fails() {
        let m = grid(100);
        let bvh = Bvh::build(&m, &BuildOptions::new(4));
        let plan = MemoryPlan::for_bvh(Method::Unit, &m, &bvh);
        let mut l = limits();
        assert_eq!(plan.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Texel);
        l.max_texel_buffer_elements = 200; // unit triangles: 3 texels each, 300 in all (nodes 130)
        assert_eq!(plan.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Address);
        let e = plan.choose("grid", SceneAccess::Texel, &l).unwrap_err().to_string();
        assert!(e.contains("unit triangles") && e.contains("300 texels") && e.contains("200"), "{e}");
        l.buffer_device_address = false;
        assert!(matches!(plan.choose("grid", SceneAccess::Auto, &l), Err(Error::SceneTooLarge(_))));
        let mut l = limits();
        l.budget_bytes = Some(1000);
        let e = plan.choose("grid", SceneAccess::Auto, &l).unwrap_err().to_string();
        assert!(e.contains("budget") && e.contains("grid") && e.contains("unit"), "{e}");
        let mut l = limits();
        l.max_buffer_size = Some(4096);
        let e = plan.choose("grid", SceneAccess::Address, &l).unwrap_err().to_string();
        assert!(e.contains("maxBufferSize") && e.contains("unit triangles"), "{e}");
    }

    #[test]
    fn rays_and_path_tracer_extras_are_checked() {
        let mut l = limits();
        assert_eq!(check_rays(1000, true, &l).unwrap(), 64_000);
        l.max_memory_allocation_size = 20_000;
        assert!(check_rays(1000, false, &l).unwrap_err().to_string().contains("`rays`"));
        let m = grid(50);
        let bvh = Bvh::build(&m, &BuildOptions::new(4));
        let plan = MemoryPlan::for_bvh(Method::Mt, &m, &bvh);
        let mut l = limits();
        let extras = pathtrace_extras(plan.counts.slots, 0, 1, 1 << 20);
        assert!(check_pathtrace("grid", &plan, &extras, &l).is_ok());
        l.max_storage_buffer_range = 1 << 20;
        let e = check_pathtrace("grid", &plan, &extras, &l).unwrap_err().to_string();
        assert!(e.contains("accumulation"), "{e}");
        let mut l = limits();
        l.max_texel_buffer_elements = 16;
        let e = check_pathtrace("grid", &plan, &extras, &l).unwrap_err().to_string();
        assert!(e.contains("texel buffers only"), "{e}");
    }
}
