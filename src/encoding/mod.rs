//! Intersectors and their GPU layouts: each method's encoding of the same BVH.
//!
//! An intersector is one unit: `glsl/intersect/<glsl>.glsl` holds its primitive test (the leaf
//! loop, hit update and any-hit exit are `glsl/leaf.glsl`'s), and `src/encoding/<name>.rs`
//! holds everything the host knows about it in one [`Intersector`]: names and title, its layout
//! types, encoder and memory placement, and the host layout of its primitive struct (checked
//! against the SPIR-V by `tests/reflection.rs`). What the GLSL states itself (triangles per primitive,
//! conservative traversal) is read from it by build.rs ([`crate::kernels::facts`]). The registry
//! below lists the intersectors, one line each; [`Method`] is generated from it, and everything
//! that lists methods (the CLI's values, plots, claims, reflection tests, `trilab spirv`,
//! `trilab methods` and the README's list) reads it.
//!
//! Every encoding also uploads the nodes (32 B each) and a slot -> OBJ triangle id table (4 B
//! per slot), so hits report OBJ ids whatever order the BVH stores triangles in; [`placement`]
//! sizes all of it from counts alone.
//!
//! Adding an intersector: `glsl/intersect/<glsl>.glsl`, `src/encoding/<name>.rs` with its
//! `INTERSECTOR`, and one line in `registry!` below; then `trilab spirv --out spirv` and
//! `trilab methods --markdown` refresh the generated files.

pub mod variants;
pub mod layout;
pub mod placement;

pub use layout::{Layout, LayoutNodes, LayoutSpec, NodeFootprint};
pub use placement::{AccessPath, BufferPlacement, DeviceLimits, Placement, SceneAccess, SceneCounts};
pub use variants::{
    support as traversal_support, BsdfSet, PathtraceKey, Raycast, RaycastKey, Traversal, COOP_SUBGROUP_OPERATIONS,
    PACKET_SUBGROUP_OPERATIONS,
};

use crate::bvh::{Bvh, BvhNode, PAD_SLOT};
use crate::named::Named;
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_NODES, BINDING_SLOT_IDS, MISS_ID};

/// Everything the host knows about one intersector (`src/encoding/<name>.rs`'s `INTERSECTOR`).
#[derive(Clone, Copy, Debug)]
pub struct Intersector {
    /// Command-line name (`--method`), also in files and tables.
    pub name: &'static str,
    /// `glsl/intersect/<glsl>.glsl`; its kernels are `<kernel>.<glsl>.<variant>`.
    pub glsl: &'static str,
    /// Column title in tables and plots (the paper's, for its four).
    pub title: &'static str,
    /// One line: the test and where it comes from.
    pub about: &'static str,
    /// One of Shumskiy & Parshin's four: what `trilab study` compares by default.
    pub in_paper: bool,
    /// Encodes a mesh's triangles in the BVH's slot order ([`Encoding`]).
    pub encode: fn(&Mesh, &Bvh) -> Encoding,
    /// The buffers `encode` writes beyond the nodes and slot ids, from counts alone (so a scene
    /// can be refused before anything is encoded); a test holds the two equal.
    pub placement: fn(&SceneCounts) -> Vec<BufferPlacement>,
    /// The binding of the buffer of `PRIM_STRUCT`s (what `load_prim` reads).
    pub prim_binding: u32,
    /// `PRIM_STRUCT`'s host twin: size and member offsets (`tests/reflection.rs` checks them
    /// against the SPIR-V of the layout probe).
    pub prim_struct: HostStruct,
}

/// A `#[repr(C)]` struct as the host writes it: its size and its members' offsets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HostStruct {
    pub size: usize,
    pub offsets: &'static [usize],
}

/// One line per intersector: `Variant => module`. Generates the modules, [`Method`] and its
/// lookup of each method's [`Intersector`].
macro_rules! registry {
    ($($variant:ident => $module:ident),+ $(,)?) => {
        $(mod $module;)+

        /// A ray-triangle intersection method (and with it, a GPU data layout): one per line of
        /// the registry, in its order.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Method {
            $($variant),+
        }

        impl Method {
            /// Every method, in registry order.
            pub const ALL: [Method; [$(stringify!($variant)),+].len()] = [$(Method::$variant),+];

            /// Everything the host knows about this method's intersector.
            pub fn intersector(self) -> &'static Intersector {
                match self {
                    $(Method::$variant => &$module::INTERSECTOR),+
                }
            }

            /// The method named `name`, at compile time (for constants: an unknown name does
            /// not compile).
            const fn named(name: &str) -> Method {
                $(
                    if crate::named::same(name, $module::INTERSECTOR.name) {
                        return Method::$variant;
                    }
                )+
                panic!("crate::defaults::METHOD names no method")
            }
        }
    };
}

registry! {
    Mt => mt,
    Unit => unit,
    QuadMt => quad_mt,
    QuadUnit => quad_unit,
    Watertight => watertight,
    BaldwinWeber => baldwin_weber,
    F64 => mt_f64,
    Pluecker => pluecker,
}

pub use baldwin_weber::{bw_transform, BwTriangle, BW_NEVER_HIT, BW_PAD};
pub use mt::MtTriangle;
pub use quad_mt::QuadMt;
pub use quad_unit::QuadUnit;
pub use unit::{unit_transform, UnitTriangle};

impl Method {
    /// The method taken when none is asked for: [`crate::defaults::METHOD`].
    pub const DEFAULT: Method = Method::named(crate::defaults::METHOD);

    /// The paper's four (Shumskiy & Parshin): what `trilab study` compares by default.
    pub fn paper() -> Vec<Method> {
        Method::ALL.into_iter().filter(|m| m.intersector().in_paper).collect()
    }

    /// Command-line name.
    pub fn name(self) -> &'static str {
        self.intersector().name
    }

    /// Name of the intersector file `glsl/intersect/<name>.glsl` (and of its kernels).
    pub fn glsl_name(self) -> &'static str {
        self.intersector().glsl
    }

    /// The column title.
    pub fn title(self) -> &'static str {
        self.intersector().title
    }

    /// What the GLSL states about this intersector (build.rs reads it from the file).
    fn facts(self) -> &'static crate::kernels::IntersectorFacts {
        crate::kernels::facts(self.glsl_name())
            .unwrap_or_else(|| panic!("glsl/intersect/{}.glsl was not compiled", self.glsl_name()))
    }

    /// Triangles tested together (the intersector's `PRIM_TRIANGLES`).
    pub fn group_size(self) -> usize {
        self.facts().prim_triangles as usize
    }

    /// Whether the kernels traverse with the conservative box test (the intersector defines
    /// `CONSERVATIVE_TRAVERSAL`, `glsl/box.glsl`).
    pub fn conservative_traversal(self) -> bool {
        self.facts().conservative_traversal
    }

    /// `mesh` on `bvh` in this method's layout.
    pub fn encode(self, mesh: &Mesh, bvh: &Bvh) -> EncodedScene {
        let e = (self.intersector().encode)(mesh, bvh);
        EncodedScene {
            method: self,
            leaf_size: bvh.options.max_leaf_size,
            nodes: e.nodes,
            slot_ids: e.slot_ids,
            prims: e.prims,
            unrepresentable: e.unrepresentable,
        }
    }
}

impl Named for Method {
    const ALL: &'static [Method] = &Method::ALL;

    fn name(self) -> &'static str {
        self.intersector().name
    }

    fn help(self) -> &'static str {
        self.intersector().about
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Method {
    type Err = String;

    fn from_str(s: &str) -> Result<Method, String> {
        Method::parse_named("method", s)
    }
}

impl serde::Serialize for Method {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Method {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Method, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
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

/// What an intersector's encoder makes of a BVH (see [`EncodedScene`] for the fields).
#[derive(Clone, Debug)]
pub struct Encoding {
    pub nodes: Vec<BvhNode>,
    pub slot_ids: Vec<u32>,
    pub prims: Vec<SceneBuffer>,
    pub unrepresentable: Vec<u32>,
}

/// Most nodes and most triangle slots the kernels address: traversal packs a node's
/// `left_or_first` into a packed entry's first (`crate::shared::leaf_entry`, 27 bits).
pub const MAX_NODE_INDEX: usize = crate::shared::LEAF_ENTRY_FIRST_LIMIT as usize;

/// A scene in one method's GPU layout.
#[derive(Clone, Debug)]
pub struct EncodedScene {
    pub method: Method,
    pub leaf_size: u32,
    /// The BVH with leaf `left_or_first` in this encoding's units.
    pub nodes: Vec<BvhNode>,
    /// Slot -> OBJ triangle id (`MISS_ID` for padding slots).
    pub slot_ids: Vec<u32>,
    /// Method-specific buffers (bound at `BINDING_PRIMS`, and `BINDING_INDICES` for MT's
    /// layout). Every struct in them is a whole number of 16-byte texels.
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

    /// The buffer of the method's primitive structs (`PRIM_STRUCT` in its intersector) and the
    /// struct's size.
    pub fn prim_structs(&self) -> (&SceneBuffer, usize) {
        let i = self.method.intersector();
        let buffer = self.prims.iter().find(|b| b.binding == i.prim_binding);
        (buffer.expect("every encoding has its primitive buffer"), i.prim_struct.size)
    }

    /// Checks what the kernels assume about the data: traversal packs a node's `left_or_first`
    /// and `count` into one entry (`crate::shared::leaf_entry`: 27 and 5 bits).
    pub fn check_limits(&self) -> Result<(), String> {
        if self.nodes.len() > MAX_NODE_INDEX || self.slot_ids.len() > MAX_NODE_INDEX {
            return Err(format!(
                "{} nodes and {} triangle slots: the kernels address at most {MAX_NODE_INDEX} of each",
                self.nodes.len(),
                self.slot_ids.len()
            ));
        }
        let most = crate::shared::LEAF_ENTRY_MAX_COUNT;
        if let Some(n) = self.nodes.iter().find(|n| n.count > most) {
            return Err(format!("a leaf holds {} triangles; the kernels allow at most {most}", n.count));
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
    fn the_registry_and_the_glsl_agree() {
        let glsl: Vec<&str> = Method::ALL.iter().map(|m| m.glsl_name()).collect();
        for f in crate::kernels::intersectors() {
            assert!(glsl.contains(&f), "glsl/intersect/{f}.glsl has no line in the registry");
        }
        for m in Method::ALL {
            assert!(crate::kernels::facts(m.glsl_name()).is_some(), "{m}: no glsl/intersect/{}.glsl", m.glsl_name());
            assert_eq!(m.name().parse::<Method>(), Ok(m));
            assert_eq!(serde_json::to_string(&m).unwrap(), format!("\"{}\"", m.name()));
            // build.rs names kernel variants after the method's command-line name, which it
            // derives from the file stem: the two must stay in step.
            assert_eq!(m.name(), m.glsl_name().replace('_', "-"), "{m}: name and GLSL stem");
            let k = m.raycast_kernel(Raycast::Closest, AccessPath::Texel);
            assert_eq!(k.name, format!("raycast.{}.closest", m.name()), "{m}: the kernel's name");
        }
        let mut names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Method::ALL.len(), "method names are unique");
        assert_eq!(Method::paper(), [Method::Mt, Method::Unit, Method::QuadMt, Method::QuadUnit]);
        assert!("quad_mt".parse::<Method>().is_err(), "the command line takes the method's name");
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
                // The primitive buffer holds whole structs of the declared size.
                let (prims, size) = e.prim_structs();
                assert_eq!(prims.bytes.len() % size, 0, "{method}");
                assert_eq!(size % 16, 0, "{method}: structs are whole texels");
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
