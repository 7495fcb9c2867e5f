//! Triangle encodings: each method's GPU layout of the same BVH.
//!
//! | method | per-triangle data | leaf unit |
//! |---|---|---|
//! | [`Method::Mt`] | vertex list (vec4) + index triple and material (16 B) | triangle slot |
//! | [`Method::Unit`] | Woop's affine map to the unit triangle, 3 x vec4 (48 B) | triangle slot |
//! | [`Method::QuadMt`] | 4 triangles' vertices in SoA form (144 B per quad) | quad |
//! | [`Method::QuadUnit`] | 4 triangles' affine maps in SoA form (192 B per quad) | quad |
//! | [`Method::Watertight`] | as [`Method::Mt`] (the same buffers) | triangle slot |
//! | [`Method::BaldwinWeber`] | Baldwin & Weber's map: 9 coefficients + fixed column, 3 x vec4 (48 B) | triangle slot |
//! | [`Method::F64`] | MT's layout; the kernel widens to double (a GPU reference, needs `shaderFloat64`) | triangle slot |
//!
//! Every encoding also uploads the nodes (32 B each) and a slot -> OBJ triangle id table
//! (4 B per slot), so hits report OBJ ids whatever order the BVH stores triangles in.
//! Adding a method: one `glsl/intersect/<name>.glsl`, one [`Method`] arm, one encoder here.

mod baldwin_weber;
mod mt;
mod quad_mt;
mod quad_unit;
mod unit;

pub use baldwin_weber::{bw_transform, BwTriangle, BW_NEVER_HIT, BW_PAD};
pub use mt::MtTriangle;
pub use quad_mt::QuadMt;
pub use quad_unit::QuadUnit;
pub use unit::{unit_transform, UnitTriangle};

use crate::bvh::{Bvh, BvhNode, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::Texel;
use crate::shared::{BINDING_INDICES, BINDING_NODES, BINDING_PRIMS, BINDING_SLOT_IDS, MISS_ID};

/// A ray-triangle intersection method (and with it, a GPU data layout).
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Möller–Trumbore, one triangle at a time.
    Mt,
    /// Woop's unit-triangle test, one triangle at a time.
    Unit,
    /// Möller–Trumbore on four triangles at once (SoA quads).
    QuadMt,
    /// Woop's unit-triangle test on four triangles at once (SoA quads).
    QuadUnit,
    /// Woop, Benthin & Wald's watertight test (JCGT 2013), one triangle at a time, on MT's data.
    Watertight,
    /// Baldwin & Weber's precomputed transformation with a fixed column, one triangle at a time.
    BaldwinWeber,
    /// Möller–Trumbore in double precision on MT's data: a GPU reference where the device has
    /// `shaderFloat64` (elsewhere its kernels fail to create with `Error::Unsupported`).
    F64,
}

impl Method {
    /// Every method.
    pub const ALL: [Method; 7] = [
        Method::Mt,
        Method::Unit,
        Method::QuadMt,
        Method::QuadUnit,
        Method::Watertight,
        Method::BaldwinWeber,
        Method::F64,
    ];

    /// The paper's four (Shumskiy & Parshin): what `trilab study` compares by default.
    pub const PAPER: [Method; 4] = [Method::Mt, Method::Unit, Method::QuadMt, Method::QuadUnit];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Mt => "mt",
            Method::Unit => "unit",
            Method::QuadMt => "quad-mt",
            Method::QuadUnit => "quad-unit",
            Method::Watertight => "watertight",
            Method::BaldwinWeber => "baldwin-weber",
            Method::F64 => "f64",
        }
    }

    /// Name of the intersector file `glsl/intersect/<name>.glsl` (and of its kernels).
    pub fn glsl_name(self) -> &'static str {
        match self {
            Method::Mt => "mt",
            Method::Unit => "unit",
            Method::QuadMt => "quad_mt",
            Method::QuadUnit => "quad_unit",
            Method::Watertight => "watertight",
            Method::BaldwinWeber => "baldwin_weber",
            Method::F64 => "f64",
        }
    }

    /// The paper's column title.
    pub fn title(self) -> &'static str {
        match self {
            Method::Mt => "Moller-Trumbore",
            Method::Unit => "Unit Triangle",
            Method::QuadMt => "Quad Moller-Trumbore",
            Method::QuadUnit => "Quad Unit Triangle",
            Method::Watertight => "Watertight",
            Method::BaldwinWeber => "Baldwin-Weber",
            Method::F64 => "Moller-Trumbore f64",
        }
    }

    /// Triangles tested together (the SIMD width of the intersector).
    pub fn group_size(self) -> usize {
        match self {
            Method::Mt | Method::Unit | Method::Watertight | Method::BaldwinWeber | Method::F64 => 1,
            Method::QuadMt | Method::QuadUnit => 4,
        }
    }

    /// Whether the kernels traverse with the conservative box test (`CONSERVATIVE_TRAVERSAL` in
    /// `glsl/traverse.glsl`, defined by the intersector).
    pub fn conservative_traversal(self) -> bool {
        self == Method::Watertight
    }

    pub fn encode(self, mesh: &Mesh, bvh: &Bvh) -> EncodedScene {
        match self {
            Method::Unit => unit::encode(mesh, bvh),
            Method::QuadMt => quad_mt::encode(mesh, bvh),
            Method::QuadUnit => quad_unit::encode(mesh, bvh),
            Method::BaldwinWeber => baldwin_weber::encode(mesh, bvh),
            // Watertight and f64 read MT's buffers (glsl/mt_layout.glsl; f64 widens the f32
            // vertices exactly), so comparing them with MT measures the arithmetic only.
            Method::Mt | Method::Watertight | Method::F64 => EncodedScene { method: self, ..mt::encode(mesh, bvh) },
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// One buffer of an encoded scene.
#[derive(Clone, Debug)]
pub struct SceneBuffer {
    /// Allocation name (shows up in allocator reports and validation messages).
    pub name: &'static str,
    pub binding: u32,
    pub texel: Texel,
    pub bytes: Vec<u8>,
}

/// A [`SceneBuffer`] or the BVH's own buffers, borrowed from an [`EncodedScene`].
#[derive(Clone, Copy, Debug)]
pub struct SceneBufferRef<'a> {
    pub name: &'static str,
    pub binding: u32,
    pub texel: Texel,
    pub bytes: &'a [u8],
}

/// Most nodes and most triangle slots the kernels address: traversal packs a node's
/// `left_or_first` into 27 bits (`pack_node` in `glsl/traverse.glsl`).
pub const MAX_NODE_INDEX: usize = 1 << 27;

/// A scene in one method's GPU layout.
#[derive(Clone, Debug)]
pub struct EncodedScene {
    pub method: Method,
    pub leaf_size: u32,
    /// The BVH with leaf `left_or_first` in this encoding's units.
    pub nodes: Vec<BvhNode>,
    /// Slot -> OBJ triangle id (`MISS_ID` for padding slots).
    pub slot_ids: Vec<u32>,
    /// Method-specific buffers (bound at `BINDING_PRIMS`, and `BINDING_INDICES` for MT).
    /// Every struct in them is a whole number of 16-byte texels.
    pub prims: Vec<SceneBuffer>,
    /// Triangles that the encoding could not represent (their map overflows f32) and that
    /// were replaced by padding. Empty for every real scene so far.
    pub unrepresentable: Vec<u32>,
}

impl EncodedScene {
    /// All buffers the kernels read, with their bindings, borrowed (large scenes upload from
    /// these without a copy).
    pub fn buffers(&self) -> Vec<SceneBufferRef<'_>> {
        let mut v = vec![
            SceneBufferRef {
                name: "bvh nodes",
                binding: BINDING_NODES,
                texel: Texel::Rgba32Uint,
                bytes: bytemuck::cast_slice(&self.nodes),
            },
            SceneBufferRef {
                name: "slot ids",
                binding: BINDING_SLOT_IDS,
                texel: Texel::R32Uint,
                bytes: bytemuck::cast_slice(&self.slot_ids),
            },
        ];
        v.extend(self.prims.iter().map(|b| SceneBufferRef {
            name: b.name,
            binding: b.binding,
            texel: b.texel,
            bytes: &b.bytes,
        }));
        v
    }

    /// Bytes the scene occupies on the GPU (the paper's "GPU Scene Size").
    pub fn gpu_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BvhNode>()
            + self.slot_ids.len() * 4
            + self.prims.iter().map(|b| b.bytes.len()).sum::<usize>()
    }

    /// The buffer of the method's primitive structs (`PRIM_STRUCT` in its intersector):
    /// `MtTriangle` for MT, watertight and f64, `UnitTriangle`, `QuadMt`, `QuadUnit`, `BwTriangle` for the others.
    pub fn prim_structs(&self) -> (&SceneBuffer, usize) {
        let (binding, size) = match self.method {
            Method::Mt | Method::Watertight | Method::F64 => (BINDING_INDICES, std::mem::size_of::<MtTriangle>()),
            Method::Unit => (BINDING_PRIMS, std::mem::size_of::<UnitTriangle>()),
            Method::QuadMt => (BINDING_PRIMS, std::mem::size_of::<QuadMt>()),
            Method::QuadUnit => (BINDING_PRIMS, std::mem::size_of::<QuadUnit>()),
            Method::BaldwinWeber => (BINDING_PRIMS, std::mem::size_of::<BwTriangle>()),
        };
        (self.prims.iter().find(|b| b.binding == binding).expect("every encoding has its primitive buffer"), size)
    }

    /// Checks what the kernels assume about the data: traversal packs a node's `left_or_first`
    /// into 27 bits and its `count` into 5 (`pack_node` in `glsl/traverse.glsl`).
    pub fn check_limits(&self) -> Result<(), String> {
        if self.nodes.len() > MAX_NODE_INDEX || self.slot_ids.len() > MAX_NODE_INDEX {
            return Err(format!(
                "{} nodes and {} triangle slots: the kernels address at most {MAX_NODE_INDEX} of each",
                self.nodes.len(),
                self.slot_ids.len()
            ));
        }
        if let Some(n) = self.nodes.iter().find(|n| n.count >= 32) {
            return Err(format!("a leaf holds {} triangles; the kernels allow at most 31", n.count));
        }
        Ok(())
    }

    /// Padding slots (quad encodings fill partial quads with never-hit triangles).
    pub fn padding_slots(&self) -> usize {
        self.slot_ids.iter().filter(|&&s| s == MISS_ID).count()
    }
}

/// The OBJ id of a BVH slot, `MISS_ID` for padding.
fn slot_id(prim: u32) -> u32 {
    if prim == PAD_SLOT {
        MISS_ID
    } else {
        prim
    }
}

/// Per-slot encodings (MT, unit) keep the BVH's leaves as they are.
fn slot_layout(bvh: &Bvh) -> (Vec<BvhNode>, Vec<u32>) {
    (bvh.nodes.clone(), bvh.prim_ids.iter().map(|&p| slot_id(p)).collect())
}

/// Quad encodings: every leaf's triangles in groups of four, the last group padded.
/// Returns the nodes with leaf `left_or_first` counting quads, and 4 slots per quad
/// (triangle id or `PAD_SLOT`).
fn quad_layout(bvh: &Bvh) -> (Vec<BvhNode>, Vec<[u32; 4]>) {
    let mut nodes = bvh.nodes.clone();
    let mut quads = Vec::new();
    for node in nodes.iter_mut().filter(|n| n.is_leaf()) {
        let first = node.left_or_first as usize;
        let prims = &bvh.prim_ids[first..first + node.count as usize];
        node.left_or_first = quads.len() as u32;
        for chunk in prims.chunks(4) {
            let mut q = [PAD_SLOT; 4];
            q[..chunk.len()].copy_from_slice(chunk);
            quads.push(q);
        }
    }
    (nodes, quads)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildOptions;

    fn mesh() -> Mesh {
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for i in 0..97u32 {
            let x = (i % 10) as f32;
            let y = (i / 10) as f32;
            pos.extend([[x, y, 0.0], [x + 0.9, y, 0.1], [x, y + 0.9, 0.2]]);
            tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        Mesh::from_triangles(pos, tris)
    }

    #[test]
    fn every_encoding_covers_every_triangle_once() {
        let m = mesh();
        for leaf in [1, 2, 3, 4, 8, 16] {
            let bvh = Bvh::build(&m, &BuildOptions::new(leaf));
            for method in Method::ALL {
                let e = method.encode(&m, &bvh);
                let mut ids: Vec<u32> = e.slot_ids.iter().copied().filter(|&s| s != MISS_ID).collect();
                ids.sort_unstable();
                assert_eq!(ids, (0..97).collect::<Vec<_>>(), "{method} leaf {leaf}");
                assert_eq!(e.slot_ids.len() % method.group_size(), 0);
                // Leaves point inside the slot table in the method's units.
                for n in e.nodes.iter().filter(|n| n.is_leaf()) {
                    let groups = (n.count as usize).div_ceil(method.group_size());
                    let end = (n.left_or_first as usize + groups) * method.group_size();
                    assert!(end <= e.slot_ids.len());
                }
            }
        }
    }

    #[test]
    fn quads_pad_only_the_last_group_of_a_leaf() {
        let m = mesh();
        let bvh = Bvh::build(&m, &BuildOptions::new(4));
        let e = Method::QuadMt.encode(&m, &bvh);
        let leaves: Vec<_> = e.nodes.iter().filter(|n| n.is_leaf()).collect();
        assert_eq!(e.slot_ids.len(), 4 * leaves.len());
        let real: usize = leaves.iter().map(|n| n.count as usize).sum();
        assert_eq!(e.padding_slots(), 4 * leaves.len() - real);
    }

    #[test]
    fn sizes_add_up() {
        let m = mesh();
        let bvh = Bvh::build(&m, &BuildOptions::new(1));
        let mt = Method::Mt.encode(&m, &bvh);
        let nodes = bvh.nodes.len() * 32;
        assert_eq!(mt.gpu_bytes(), nodes + 97 * 4 + m.positions.len() * 16 + 97 * 16);
        let unit = Method::Unit.encode(&m, &bvh);
        assert_eq!(unit.gpu_bytes(), nodes + 97 * 4 + 97 * 48);
        assert_eq!(Method::BaldwinWeber.encode(&m, &bvh).gpu_bytes(), nodes + 97 * 4 + 97 * 48);
        assert_eq!(Method::F64.encode(&m, &bvh).gpu_bytes(), mt.gpu_bytes());
    }
}
