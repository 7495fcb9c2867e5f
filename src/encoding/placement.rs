//! GPU memory placement: every buffer a scene (and a ray set) needs, computed from counts alone,
//! before anything is encoded or allocated, and checked against the device's limits. A scene
//! that cannot fit gets [`Error::SceneTooLarge`] naming the buffer, what it needs and what the
//! device allows, never a crash or a driver out-of-memory. The limits are plain data here
//! ([`DeviceLimits`]); `gpu` reads a device's, and higher layers (the path tracer) place their own
//! buffers with [`BufferPlacement`] and check them with [`check_extras`].
//!
//! Limits checked, per buffer: `maxTexelBufferElements` (texel path: one storage texel buffer per
//! scene buffer), 2^31 texels (address path: the kernels index with signed 32-bit integers,
//! `glsl/types.glsl`), `maxBufferSize` (`VK_KHR_maintenance4`, where present) and
//! `maxMemoryAllocationSize`; in all, the device-local heap or, with `VK_EXT_memory_budget`, the
//! heap's budget left. Ray and hit buffers are bound per dispatch in ranges of at most
//! `maxStorageBufferRange` (`gpu::raycast`), so only their whole size is limited.
//!
//! The scene's access path ([`AccessPath`]) is chosen here, from what the device offers: storage
//! texel buffers (the default kernels) when every buffer fits one binding; else buffer device
//! addresses (the raycast kernels' `*_address` variants) where the device has `bufferDeviceAddress`
//! and `shaderInt64`; else storage buffers (the `*_storage` variants: one binding holds
//! `maxStorageBufferRange` bytes; SwiftShader, issue 38).

use super::{Layout, Method, Raycast, Traversal};
use crate::bvh::{Bvh, BvhNode};
use crate::error::{Error, Result, TooLarge};
use crate::named::named_enum;
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_NODES, BINDING_SLOT_IDS};

/// Most texels one scene buffer may hold on the address path: the kernels' indices are signed
/// 32-bit access-chain indices.
pub const MAX_ADDRESS_TEXELS: u64 = 1 << 31;
/// Most nodes and triangle slots the kernels address (27-bit indices).
const MAX_NODE_INDEX: u64 = crate::encoding::MAX_NODE_INDEX as u64;

/// What a placement is checked against: a device's limits (`gpu::Context::limits` reads them), or
/// smaller ones made for tests ([`DeviceLimits::with_overrides`], which `Context::limits` applies
/// from `TRILAB_TEST_LIMITS`) to exercise the address path and the "does not fit" paths.
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
    /// `bufferDeviceAddress` is enabled (the address path needs it).
    pub buffer_device_address: bool,
    /// `shaderInt64` is enabled (the address path loads 64-bit words: `glsl/types.glsl`).
    pub shader_int64: bool,
    /// The path `auto` takes first where the scene fits it (`gpu::Capabilities::preferred_access`:
    /// storage buffers on SwiftShader, measured faster there; texel buffers elsewhere).
    pub preferred_access: AccessPath,
}

impl DeviceLimits {
    /// These limits with some lowered, as `TRILAB_TEST_LIMITS` gives them:
    /// `name=value[,name=value...]` with the field names above (`max_texel_buffer_elements=4096`,
    /// `budget_bytes=1000000`, `buffer_device_address=0`). Only lowering is allowed: a test must
    /// not pretend a device can do more than it can.
    pub fn with_overrides(mut self, spec: &str) -> Result<DeviceLimits> {
        let bad = |m: String| Error::Usage(format!("TRILAB_TEST_LIMITS `{spec}`: {m}"));
        for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (name, value) = item.split_once('=').ok_or_else(|| bad(format!("`{item}` is not name=value")))?;
            let v: u64 = value.trim().parse().map_err(|_| bad(format!("`{value}` is not a number")))?;
            let lower = |field: &mut u64| -> Result<()> {
                if v > *field {
                    return Err(bad(format!("{name}={v} is above the device's {}", *field)));
                }
                *field = v;
                Ok(())
            };
            match name.trim() {
                "max_texel_buffer_elements" => lower(&mut self.max_texel_buffer_elements)?,
                "max_storage_buffer_range" => lower(&mut self.max_storage_buffer_range)?,
                "max_memory_allocation_size" => lower(&mut self.max_memory_allocation_size)?,
                "device_local_bytes" => lower(&mut self.device_local_bytes)?,
                "max_buffer_size" => {
                    let mut b = self.max_buffer_size.unwrap_or(u64::MAX);
                    lower(&mut b)?;
                    self.max_buffer_size = Some(b);
                }
                "budget_bytes" => {
                    let mut b = self.budget_bytes.unwrap_or(self.device_local_bytes);
                    lower(&mut b)?;
                    self.budget_bytes = Some(b);
                }
                "buffer_device_address" if v == 0 => self.buffer_device_address = false,
                "shader_int64" if v == 0 => self.shader_int64 = false,
                "buffer_device_address" | "shader_int64" => {
                    return Err(bad(format!("{} can only be turned off (0)", name.trim())))
                }
                other => return Err(bad(format!("unknown limit `{other}`"))),
            }
        }
        Ok(self)
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

named_enum! {
    /// How `--scene-access` asks the kernels to read the scene.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum SceneAccess: "scene access" {
        /// Texel buffers when every scene buffer fits one binding, else device addresses where
        /// the device has them and 64-bit integers, else storage buffers.
        Auto = "auto" (default),
        /// Storage texel buffers (the default kernels).
        Texel = "texel",
        /// Buffer device addresses (the `*_address` kernels; need shaderInt64).
        Address = "address",
        /// Storage buffers (the `*_storage` kernels: closest, any, stats; while-if).
        Storage = "storage",
    }
}

/// The path a scene is read through, once chosen.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AccessPath {
    Texel,
    Address,
    Storage,
}

impl AccessPath {
    pub const ALL: [AccessPath; 3] = [AccessPath::Texel, AccessPath::Address, AccessPath::Storage];

    pub fn name(self) -> &'static str {
        match self {
            AccessPath::Texel => "texel",
            AccessPath::Address => "address",
            AccessPath::Storage => "storage",
        }
    }

    /// The `--scene-access` choice that asks for this path.
    pub fn requested(self) -> SceneAccess {
        match self {
            AccessPath::Texel => SceneAccess::Texel,
            AccessPath::Address => SceneAccess::Address,
            AccessPath::Storage => SceneAccess::Storage,
        }
    }

    /// Most texels (of the buffer's own size) one scene buffer may hold on this path.
    pub fn max_texels(self, limits: &DeviceLimits, texel_size: u64) -> u64 {
        match self {
            AccessPath::Texel => limits.max_texel_buffer_elements,
            AccessPath::Address => MAX_ADDRESS_TEXELS,
            AccessPath::Storage => (limits.max_storage_buffer_range / texel_size.max(1)).min(MAX_ADDRESS_TEXELS),
        }
    }
}

/// One placed buffer.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct BufferPlacement {
    /// The encoder's name for it (`SceneBuffer::name`).
    pub name: &'static str,
    pub binding: u32,
    /// Bytes the encoder writes (the GPU buffer holds at least one texel more if this is 0).
    pub bytes: u64,
    /// Bytes per texel (16, or 4 for the slot ids).
    pub texel_size: u64,
}

impl BufferPlacement {
    /// `count` structs of `struct_size` bytes read as `texel`s.
    pub fn new(name: &'static str, binding: u32, texel: Texel, count: u64, struct_size: usize) -> BufferPlacement {
        BufferPlacement { name, binding, bytes: count * struct_size as u64, texel_size: texel.size() as u64 }
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

/// The counts a placement is made of (what the BVH and the mesh say, nothing encoded).
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
pub struct Placement {
    pub method: Method,
    /// The node layout whose node buffer is placed ([`Placement::with_layout`]).
    pub layout: Layout,
    pub counts: SceneCounts,
    pub buffers: Vec<BufferPlacement>,
}

impl Placement {
    /// The placement of `method`'s encoding (`Method::encode`) for a scene of `counts`, in the
    /// order `EncodedScene::buffers` lists them.
    pub fn of(method: Method, c: &SceneCounts) -> Placement {
        // Slots come in whole primitives: the Quad forms pad every leaf to whole quads.
        let slot_ids = match method.group_size() {
            1 => c.slots,
            4 => 4 * c.quads,
            n => unreachable!("build.rs allows 1 or 4 triangles per primitive, not {n}"),
        };
        let mut buffers = vec![
            BufferPlacement::new(
                "bvh nodes",
                BINDING_NODES,
                Texel::Rgba32Uint,
                c.nodes,
                std::mem::size_of::<BvhNode>(),
            ),
            BufferPlacement::new("slot ids", BINDING_SLOT_IDS, Texel::R32Uint, slot_ids, 4),
        ];
        buffers.extend((method.intersector().placement)(c));
        Placement { method, layout: Layout::DEFAULT, counts: *c, buffers }
    }

    /// This placement with `layout`'s node buffer in place of the binary nodes, priced by the
    /// layout's bound from counts ([`super::LayoutSpec::placement_bytes`]; the built buffer is
    /// checked against the limits again before it is uploaded).
    pub fn with_layout(mut self, layout: Layout) -> Placement {
        let spec = layout.spec();
        let bytes = (spec.placement_bytes)(&self.counts);
        for b in self.buffers.iter_mut().filter(|b| b.binding == BINDING_NODES) {
            *b = BufferPlacement {
                name: spec.buffer,
                binding: BINDING_NODES,
                bytes,
                texel_size: Texel::Rgba32Uint.size() as u64,
            };
        }
        self.layout = layout;
        self
    }

    /// The placement of an already encoded scene (its real buffer sizes).
    pub fn of_encoded(scene: &crate::encoding::EncodedScene) -> Placement {
        let buffers: Vec<BufferPlacement> = scene
            .buffers()
            .into_iter()
            .map(|b| BufferPlacement {
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
        Placement { method: scene.method, layout: Layout::DEFAULT, counts, buffers }
    }

    pub fn for_bvh(method: Method, mesh: &Mesh, bvh: &Bvh) -> Placement {
        Self::of(method, &SceneCounts::of(mesh, bvh))
    }

    /// Bytes the encoder writes (`EncodedScene::gpu_bytes`).
    pub fn bytes(&self) -> u64 {
        self.buffers.iter().map(|b| b.bytes).sum()
    }

    /// Bytes allocated on the GPU (empty buffers get one texel).
    pub fn gpu_bytes(&self) -> u64 {
        self.buffers.iter().map(BufferPlacement::gpu_bytes).sum()
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
                format!("{MAX_NODE_INDEX} of each (27-bit indices in LEAF_ENTRY, glsl/shared.glsl)"),
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
        let texel_err = |b: &BufferPlacement, hint: &str| {
            err(
                b.name,
                format!("{} texels", b.texels()),
                format!("{} texels per binding (maxTexelBufferElements)", limits.max_texel_buffer_elements),
                hint,
            )
        };
        let address_missing = match (limits.buffer_device_address, limits.shader_int64) {
            (true, true) => None,
            (false, _) => Some("bufferDeviceAddress"),
            (true, false) => Some("shaderInt64"),
        };
        let address = || -> Result<AccessPath> {
            if let Some(feature) = address_missing {
                let b = over_texel.unwrap_or(&self.buffers[0]);
                return Err(texel_err(
                    b,
                    &format!(
                        "--scene-access storage (the address path needs {feature}, which the device lacks), \
                         a method with a smaller encoding, or a smaller scene"
                    ),
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
        let storage = || -> Result<AccessPath> {
            if let Some(b) =
                self.buffers.iter().find(|b| b.texels() > AccessPath::Storage.max_texels(limits, b.texel_size))
            {
                return Err(err(
                    b.name,
                    format!("{} bytes", b.gpu_bytes()),
                    format!(
                        "{} bytes per binding (maxStorageBufferRange; at most 2^31 words on the storage path)",
                        limits.max_storage_buffer_range
                    ),
                    smaller,
                ));
            }
            Ok(AccessPath::Storage)
        };
        if requested == SceneAccess::Auto && limits.preferred_access == AccessPath::Storage {
            if let Ok(path) = storage() {
                return Ok(path);
            }
        }
        match (requested, over_texel) {
            (SceneAccess::Texel, Some(b)) => Err(texel_err(b, "--scene-access address or storage (or auto)")),
            (SceneAccess::Texel, None) | (SceneAccess::Auto, None) => Ok(AccessPath::Texel),
            (SceneAccess::Address, _) => address(),
            (SceneAccess::Storage, _) => storage(),
            (SceneAccess::Auto, Some(_)) if address_missing.is_none() => address(),
            (SceneAccess::Auto, Some(_)) => storage(),
        }
    }

    /// [`Placement::choose`] for the ray-casting kernels of `layout` and `traversal`: the one
    /// place a scene's access path is decided. `auto` may pick a path the traversal has no
    /// kernel for (the storage path a device prefers, or needs for a large scene, where coop and
    /// persistent have only texel kernels): then the texel path where the scene fits it, else
    /// the missing kernel named.
    pub fn choose_for_kernel(
        &self,
        scene: &str,
        requested: SceneAccess,
        limits: &DeviceLimits,
        layout: Layout,
        traversal: Traversal,
    ) -> Result<AccessPath> {
        let access = self.choose(scene, requested, limits)?;
        let has = |a| self.method.traversal_kernel(Raycast::Closest, a, layout, traversal).is_ok();
        if requested != SceneAccess::Auto || has(access) {
            return Ok(access);
        }
        match self.choose(scene, SceneAccess::Texel, limits) {
            Ok(texel) if has(texel) => Ok(texel),
            _ => Err(Error::Unsupported(format!(
                "scene `{scene}` does not fit this device's texel buffers, and the {traversal} traversal on {layout} \
                 has no kernel on the {} path it would take ({traversal} has: {})",
                access.name(),
                super::traversal_support(traversal)
            ))),
        }
    }

    /// [`Placement::choose`] for a reader without the address path (`why` says which, e.g.
    /// "the path tracer reads scenes through texel or storage buffers"): texel buffers where the
    /// scene fits them, else storage buffers; the hint of a "does not fit" error then names what
    /// helps it, not `--scene-access`, and says why.
    pub fn choose_without_address(
        &self,
        scene: &str,
        requested: SceneAccess,
        limits: &DeviceLimits,
        why: &str,
    ) -> Result<AccessPath> {
        if requested == SceneAccess::Address {
            return Err(Error::Usage(format!("scene `{scene}`: --scene-access address is not possible: {why}")));
        }
        let no_address = DeviceLimits { buffer_device_address: false, ..*limits };
        self.choose(scene, requested, &no_address).map_err(|e| match e {
            Error::SceneTooLarge(mut t) => {
                t.hint = format!("a method with a smaller encoding, or a smaller scene ({why})");
                Error::SceneTooLarge(t)
            }
            e => e,
        })
    }

    fn slot_count(&self) -> u64 {
        self.buffers.iter().find(|b| b.binding == BINDING_SLOT_IDS).map_or(0, |b| b.bytes / 4)
    }
}

/// Checks buffers a higher layer uploads beside `method`'s scene (the path tracer's shading,
/// lights, materials and image) against the limit of the binding each is read through: one
/// storage texel buffer (`maxTexelBufferElements`), or, with `storage`, one storage buffer bound
/// whole (`maxStorageBufferRange`).
pub fn check_extras(
    scene: &str,
    method: Method,
    extras: &[(BufferPlacement, bool)],
    limits: &DeviceLimits,
) -> Result<()> {
    for (b, storage) in extras {
        let (limit, name) = if *storage {
            (limits.max_storage_buffer_range, "maxStorageBufferRange")
        } else {
            (limits.max_texel_buffer_elements * b.texel_size, "maxTexelBufferElements")
        };
        if b.gpu_bytes() > limit {
            return Err(Error::SceneTooLarge(Box::new(TooLarge {
                scene: scene.to_owned(),
                method: method.name().to_owned(),
                buffer: b.name.to_owned(),
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
pub(crate) mod tests {
    use super::*;
    use crate::bvh::BuildOptions;

    /// Roomy limits: every test scene fits the texel path.
    pub(crate) fn limits() -> DeviceLimits {
        DeviceLimits {
            max_texel_buffer_elements: 1 << 27,
            max_storage_buffer_range: 1 << 27,
            max_buffer_size: None,
            max_memory_allocation_size: 1 << 32,
            device_local_bytes: 1 << 34,
            budget_bytes: None,
            buffer_device_address: true,
            shader_int64: true,
            preferred_access: AccessPath::Texel,
        }
    }

    use crate::scene::test_grid as grid;

    #[test]
    fn placement_equals_the_encoded_buffers() {
        let m = grid(203);
        for leaf in [1, 3, 4, 7] {
            let bvh = Bvh::build(&m, &BuildOptions::new(leaf));
            for method in Method::ALL {
                let placement = Placement::for_bvh(method, &m, &bvh);
                let enc = method.encode(&m, &bvh);
                let got: Vec<(&str, u32, u64)> =
                    enc.buffers().iter().map(|b| (b.name, b.binding, b.bytes.len() as u64)).collect();
                let want: Vec<(&str, u32, u64)> =
                    placement.buffers.iter().map(|b| (b.name, b.binding, b.bytes)).collect();
                assert_eq!(got, want, "{method} leaf {leaf}");
                assert_eq!(placement.bytes(), enc.gpu_bytes() as u64);
            }
        }
    }

    #[test]
    fn auto_picks_texels_then_addresses_then_fails() {
        let m = grid(100);
        let bvh = Bvh::build(&m, &BuildOptions::new(4));
        let placement = Placement::for_bvh(Method::Unit, &m, &bvh);
        let mut l = limits();
        assert_eq!(placement.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Texel);
        l.max_texel_buffer_elements = 200; // unit triangles: 3 texels each, 300 in all (nodes 130)
        assert_eq!(placement.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Address);
        let e = placement.choose("grid", SceneAccess::Texel, &l).unwrap_err().to_string();
        assert!(e.contains("unit triangles") && e.contains("300 texels") && e.contains("200"), "{e}");
        // Without device addresses or 64-bit integers (SwiftShader), auto takes storage buffers.
        for (no, feature) in [("buffer_device_address=0", "bufferDeviceAddress"), ("shader_int64=0", "shaderInt64")] {
            let l = l.with_overrides(no).unwrap();
            assert_eq!(placement.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Storage, "{no}");
            let e = placement.choose("grid", SceneAccess::Address, &l).unwrap_err().to_string();
            assert!(e.contains(feature) && e.contains("--scene-access storage"), "{e}");
        }
        // ... unless a buffer is beyond one storage binding: 300 texels of 16 bytes.
        l.max_storage_buffer_range = 299 * 16;
        let l = l.with_overrides("shader_int64=0").unwrap();
        let e = placement.choose("grid", SceneAccess::Auto, &l).unwrap_err().to_string();
        assert!(e.contains("unit triangles") && e.contains("4800 bytes") && e.contains("maxStorageBufferRange"), "{e}");
        assert!(matches!(placement.choose("grid", SceneAccess::Storage, &l), Err(Error::SceneTooLarge(_))));
        // A device that prefers storage buffers (SwiftShader) gets them wherever they fit, and
        // the texel path where they do not.
        let mut l = DeviceLimits { preferred_access: AccessPath::Storage, ..limits() };
        assert_eq!(placement.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Storage);
        assert_eq!(placement.choose("grid", SceneAccess::Texel, &l).unwrap(), AccessPath::Texel);
        l.max_storage_buffer_range = 16;
        assert_eq!(placement.choose("grid", SceneAccess::Auto, &l).unwrap(), AccessPath::Texel);
        let mut l = limits();
        l.budget_bytes = Some(1000);
        let e = placement.choose("grid", SceneAccess::Auto, &l).unwrap_err().to_string();
        assert!(e.contains("budget") && e.contains("grid") && e.contains("unit"), "{e}");
        let mut l = limits();
        l.max_buffer_size = Some(4096);
        let e = placement.choose("grid", SceneAccess::Address, &l).unwrap_err().to_string();
        assert!(e.contains("maxBufferSize") && e.contains("unit triangles"), "{e}");
    }

    #[test]
    fn rays_are_checked() {
        let mut l = limits();
        assert_eq!(check_rays(1000, true, &l).unwrap(), 64_000);
        l.max_memory_allocation_size = 20_000;
        assert!(check_rays(1000, false, &l).unwrap_err().to_string().contains("`rays`"));
    }

    #[test]
    fn test_limits_only_lower() {
        let l = limits()
            .with_overrides("max_texel_buffer_elements=4096, budget_bytes=1000,buffer_device_address=0")
            .unwrap();
        assert_eq!(l.max_texel_buffer_elements, 4096);
        assert_eq!(l.budget_bytes, Some(1000));
        assert!(!l.buffer_device_address);
        assert_eq!(limits().with_overrides("").unwrap(), limits());
        for bad in [
            "max_texel_buffer_elements=1099511627776",
            "nodes=3",
            "max_buffer_size",
            "budget_bytes=x",
            "buffer_device_address=1",
            "shader_int64=1",
        ] {
            let e = limits().with_overrides(bad).unwrap_err().to_string();
            assert!(e.contains("TRILAB_TEST_LIMITS") && e.contains(bad), "{bad}: {e}");
        }
    }
}
