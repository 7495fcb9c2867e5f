//! Node layouts: how the BVH's inner nodes reach the ray-casting and path-tracing kernels
//! (issue 15's second axis beside the intersectors).
//!
//! A layout is one unit, like an intersector: `glsl/layout/<name>.glsl` holds its node format and
//! its step (`glsl/layout_interface.glsl`: the root, `layout_visit`, the stack size; the leaf loop
//! and the box test are every layout's, so every intersector runs on every layout, and every
//! traversal drives the step), `src/encoding/layout/<name>.rs`
//! holds everything the host knows about it in one [`LayoutSpec`] (names, node size, how its node
//! buffer is made from the encoding's binary nodes, the placement's bound, the kernel's stack),
//! and one line of `layouts!` below. build.rs compiles the variants a kernel lists on its
//! `// trilab:layouts` line once per file in `glsl/layout/` but the default `bvh2.glsl`
//! (`closest_bvh4`, `any_address_bvh8`, ...);
//! everything that lists layouts (the CLI's values, `bench --layouts`, the study) reads
//! [`Layout::ALL`].
//!
//! The paper's binary tree, `bvh2`, has no node format of its own: its nodes are the encoding's
//! own (`bvh::BvhNode`, 32 bytes; `types.glsl`'s `BvhNode`), uploaded as they are, and
//! `glsl/layout/bvh2.glsl`, the default layout, holds its step. Every other layout's node buffer replaces
//! them at `BINDING_NODES`; the triangles, slot ids and leaves (first unit, count) are the
//! encoding's, unchanged.

mod bvh2;
mod bvh4;
mod bvh8;
mod cwbvh;
mod qbvh4;

use crate::bvh::{Aabb, BuildOptions, BvhNode, Locality, NodeOrder, NodeTree};
use crate::named::Named;

use super::placement::SceneCounts;

/// A node buffer made for a layout.
#[derive(Clone, Debug, Default)]
pub struct LayoutNodes {
    /// The bytes bound at `BINDING_NODES` (a whole number of 16-byte texels).
    pub bytes: Vec<u8>,
    /// Nodes in it.
    pub nodes: usize,
    /// Most entries the layout's traversal stack can hold on this tree.
    pub stack_bound: usize,
    /// The tree's SAH cost, priced with the build options (node cost per node visited).
    pub sah_cost: f64,
}

/// How close the nodes a descent reads lie in a layout's built node buffer (`bytes`, `nodes`
/// nodes; `bounds`: the root's box), read back from the buffer (not made with every buffer, so
/// neither uploads nor build-bench's conversion times pay for it).
pub type NodeLocality = fn(&LayoutNodes, &Aabb) -> Result<Locality, String>;

/// Makes a layout's node buffer from the encoding's binary nodes with its nodes in the given
/// order (`bvh::order`), or says why it cannot.
pub type BuildNodes = fn(&[BvhNode], &BuildOptions, NodeOrder) -> Result<LayoutNodes, String>;

/// A layout's node buffer as `trilab bvh` reports it: its size and locality in one node order.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct NodeFootprint {
    pub nodes: usize,
    /// The bytes bound at `BINDING_NODES` (cwbvh's leaf table included).
    pub bytes: usize,
    pub locality: Locality,
}

/// Everything the host knows about one layout (`src/encoding/layout/<name>.rs`'s `LAYOUT`).
#[derive(Clone, Copy, Debug)]
pub struct LayoutSpec {
    /// Command-line name (`--layout`), also `glsl/layout/<name>.glsl` and the kernels' variant
    /// suffix (`closest_<name>`); `bvh2`, the default, has no suffix.
    pub name: &'static str,
    /// Column title in tables and plots.
    pub title: &'static str,
    /// One line: the node and the traversal, and where they come from.
    pub about: &'static str,
    /// Children per node.
    pub width: u32,
    /// Bytes per node (what the node buffer costs per node).
    pub node_bytes: usize,
    /// The node buffer's name in placements and errors.
    pub buffer: &'static str,
    /// The node buffer from the encoding's binary nodes (leaves in the encoding's units), or
    /// `None` for the binary nodes themselves; an error where the tree cannot be represented
    /// (cwbvh: a box without a grid, word indices beyond 32 bits).
    pub build: Option<BuildNodes>,
    /// The locality of a buffer `build` made (`None` with `build`: the binary nodes are read
    /// directly).
    pub locality: Option<NodeLocality>,
    /// An upper bound of the node buffer's bytes from counts alone, for the scene's placement (a
    /// test holds every built buffer within it).
    pub placement_bytes: fn(&SceneCounts) -> u64,
    /// Entries of the kernel's traversal stack: a tree that could need more is refused before
    /// anything is uploaded.
    pub stack_size: u32,
}

/// One line per layout: `Variant => module`. Generates the modules, [`Layout`] and its lookup
/// of each layout's [`LayoutSpec`]. The default is named in `crate::defaults` ([`Layout::DEFAULT`]).
macro_rules! layouts {
    ($first:ident => $first_module:ident $(, $variant:ident => $module:ident)* $(,)?) => {
        /// How the BVH's nodes are laid out for the kernels: one per line of the registry.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum Layout {
            $first,
            $($variant),*
        }

        impl Layout {
            /// Everything the host knows about this layout.
            pub fn spec(self) -> &'static LayoutSpec {
                match self {
                    Layout::$first => &$first_module::LAYOUT,
                    $(Layout::$variant => &$module::LAYOUT),*
                }
            }

            /// The layout named `name`, at compile time (for constants: an unknown name does not
            /// compile).
            const fn named(name: &str) -> Layout {
                if crate::named::same(name, $first_module::LAYOUT.name) {
                    return Layout::$first;
                }
                $(
                    if crate::named::same(name, $module::LAYOUT.name) {
                        return Layout::$variant;
                    }
                )*
                panic!("crate::defaults::LAYOUT names no layout")
            }
        }

        impl Named for Layout {
            const ALL: &'static [Layout] = &[Layout::$first, $(Layout::$variant),*];

            fn name(self) -> &'static str {
                self.spec().name
            }

            fn help(self) -> &'static str {
                self.spec().about
            }
        }
    };
}

layouts! {
    Bvh2 => bvh2,
    Bvh4 => bvh4,
    Bvh8 => bvh8,
    Cwbvh => cwbvh,
    Qbvh4 => qbvh4,
}

impl Layout {
    /// The layout taken when none is asked for: [`crate::defaults::LAYOUT`], the binary nodes.
    pub const DEFAULT: Layout = Layout::named(crate::defaults::LAYOUT);

    /// The column title.
    pub fn title(self) -> &'static str {
        self.spec().title
    }

    /// The node buffer for `binary` (the encoding's nodes), `None` for the binary layout.
    pub fn nodes(self, binary: &[BvhNode], o: &BuildOptions) -> Result<Option<LayoutNodes>, String> {
        self.nodes_in(binary, o, NodeOrder::Built)
    }

    /// The same with the nodes in `order`; `None` for the binary layout, whose nodes are the
    /// encoding's own (`NodeOrder::reorder_binary` orders them).
    pub fn nodes_in(
        self,
        binary: &[BvhNode],
        o: &BuildOptions,
        order: NodeOrder,
    ) -> Result<Option<LayoutNodes>, String> {
        self.spec().build.map(|b| b(binary, o, order)).transpose()
    }

    /// This layout's node buffer for `binary` in `order`: nodes, bytes and locality (the binary
    /// layout's from `binary` itself, reordered).
    pub fn footprint(self, binary: &[BvhNode], o: &BuildOptions, order: NodeOrder) -> Result<NodeFootprint, String> {
        if let Some(built) = self.nodes_in(binary, o, order)? {
            let read = self.spec().locality.ok_or_else(|| format!("{self}: no reader of its nodes' locality"))?;
            let locality = read(&built, &binary[0].aabb())?;
            return Ok(NodeFootprint { nodes: built.nodes, bytes: built.bytes.len(), locality });
        }
        let mut nodes = binary.to_vec();
        order.reorder_binary(&mut nodes)?;
        Ok(NodeFootprint {
            nodes: nodes.len(),
            bytes: std::mem::size_of_val(nodes.as_slice()),
            locality: NodeTree::binary(&nodes).locality(),
        })
    }
}

impl Default for Layout {
    fn default() -> Layout {
        Layout::DEFAULT
    }
}

impl std::fmt::Display for Layout {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Layout {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        Layout::parse_named("BVH layout", s)
    }
}

impl serde::Serialize for Layout {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> serde::Deserialize<'de> for Layout {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Layout, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// A wide tree's node buffer: the binary nodes collapsed with [`crate::bvh::Collapse::Sah`], in
/// `order`.
pub(super) fn wide_nodes<const N: usize>(
    binary: &[BvhNode],
    o: &BuildOptions,
    order: NodeOrder,
) -> Result<LayoutNodes, String> {
    use crate::bvh::{Collapse, WideBvh};
    let start = std::time::Instant::now();
    let mut nodes = WideBvh::<N>::collapse_nodes(binary, o, Collapse::Sah);
    order.reorder_wide(&mut nodes, &binary[0].aabb())?;
    let tree = WideBvh::<N> {
        nodes,
        bounds: binary[0].aabb(),
        prim_ids: vec![],
        max_leaf_size: o.max_leaf_size,
        collapse_seconds: start.elapsed().as_secs_f64(),
    };
    Ok(LayoutNodes {
        bytes: bytemuck::cast_slice(&tree.nodes).to_vec(),
        nodes: tree.nodes.len(),
        stack_bound: tree.stack_bound(),
        sah_cost: tree.sah_cost(o),
    })
}

/// [`NodeLocality`] of a wide tree's node buffer.
pub(super) fn wide_locality<const N: usize>(built: &LayoutNodes, bounds: &Aabb) -> Result<Locality, String> {
    use crate::bvh::WideNode;
    let size = std::mem::size_of::<WideNode<N>>();
    let nodes: Vec<WideNode<N>> = built.bytes.chunks_exact(size).map(bytemuck::pod_read_unaligned).collect();
    Ok(NodeTree::wide(&nodes, bounds)?.locality())
}

/// Inner nodes of the binary tree: a collapsed tree has at most this many nodes (each wide node
/// takes at least one binary inner node; a tree of one leaf still gets a root).
pub(super) fn inner_nodes(c: &SceneCounts) -> u64 {
    (c.nodes / 2).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{Bvh, PAD_SLOT};
    use crate::scene::Mesh;

    fn grid(n: u32) -> Mesh {
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for i in 0..n {
            let (x, y) = ((i % 23) as f32, (i / 23) as f32);
            pos.extend([[x, y, 0.1 * x], [x + 0.9, y, 0.3], [x, y + 0.9, 0.6]]);
            tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        Mesh::from_triangles(pos, tris)
    }

    /// Every layout's footprint in every order: the built buffer's nodes and bytes, and the
    /// locality read back from the buffer equal to the one of the tree it was made from.
    #[test]
    fn footprints_read_the_built_buffers() {
        use crate::bvh::qbvh4::Qbvh4;
        use crate::bvh::{CwBvh, SlotOrder, WideBvh};
        let bvh = Bvh::build(&grid(2000), &BuildOptions::new(4));
        let bounds = bvh.nodes[0].aabb();
        for &order in NodeOrder::ALL {
            for &l in Layout::ALL {
                let f = l.footprint(&bvh.nodes, &bvh.options, order).unwrap();
                let want = match l {
                    Layout::Bvh2 => {
                        let mut n = bvh.nodes.clone();
                        order.reorder_binary(&mut n).unwrap();
                        (n.len(), NodeTree::binary(&n).locality())
                    }
                    Layout::Bvh4 => {
                        let mut w = WideBvh::<4>::collapse(&bvh).nodes;
                        order.reorder_wide(&mut w, &bounds).unwrap();
                        (w.len(), NodeTree::wide(&w, &bounds).unwrap().locality())
                    }
                    Layout::Bvh8 => {
                        let mut w = WideBvh::<8>::collapse(&bvh).nodes;
                        order.reorder_wide(&mut w, &bounds).unwrap();
                        (w.len(), NodeTree::wide(&w, &bounds).unwrap().locality())
                    }
                    Layout::Cwbvh => {
                        let mut cw = CwBvh::build_with(&bvh, SlotOrder::Greedy).unwrap();
                        order.reorder_cwbvh(&mut cw).unwrap();
                        (cw.nodes.len(), NodeTree::cwbvh(&cw.nodes, &cw.bounds).locality())
                    }
                    Layout::Qbvh4 => {
                        let mut w = WideBvh::<4>::collapse(&bvh);
                        order.reorder_wide_as(&mut w.nodes, &bounds, 64).unwrap();
                        let d = Qbvh4::quantize(&w).unwrap().decoded();
                        let mut t = NodeTree::wide(&d.nodes, &bounds).unwrap();
                        t.node_bytes = 64;
                        (d.nodes.len(), t.locality())
                    }
                };
                assert_eq!((f.nodes, f.locality), want, "{l} {order}");
                let bytes = l.nodes(&bvh.nodes, &bvh.options).unwrap().map_or(bvh.nodes.len() * 32, |b| b.bytes.len());
                assert_eq!(f.bytes, bytes, "{l} {order}: the built buffer's bytes");
                assert!(f.locality.lines_per_step >= 1.0 && f.locality.pages_per_step > 0.0, "{l} {order}");
            }
        }
    }

    #[test]
    fn names_parse_and_the_binary_layout_is_the_default() {
        assert_eq!(Layout::default(), Layout::Bvh2);
        assert_eq!(Layout::DEFAULT, Layout::Bvh2);
        for &l in Layout::ALL {
            assert_eq!(l.name().parse::<Layout>(), Ok(l));
            assert!(!l.help().is_empty() && !l.title().is_empty(), "{l}");
        }
        assert!("bvh3".parse::<Layout>().unwrap_err().contains("bvh2"));
    }

    /// The placement's bound holds every built node buffer, over leaf sizes and tree shapes
    /// (one leaf, a few, thousands), and the buffer is whole texels of whole nodes.
    #[test]
    fn the_placement_bounds_every_node_buffer() {
        for n in [1, 3, 40, 2000] {
            let mesh = grid(n);
            for leaf in [1, 4, 16] {
                let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
                let counts = SceneCounts {
                    triangles: n as u64,
                    nodes: bvh.nodes.len() as u64,
                    slots: bvh.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count() as u64,
                    ..Default::default()
                };
                for &l in Layout::ALL {
                    let Some(built) = l.nodes(&bvh.nodes, &bvh.options).unwrap() else { continue };
                    let bound = (l.spec().placement_bytes)(&counts);
                    assert!(
                        built.bytes.len() as u64 <= bound,
                        "{l} n={n} leaf={leaf}: {} > {bound}",
                        built.bytes.len()
                    );
                    assert_eq!(built.bytes.len() % 16, 0, "{l}: whole texels");
                    assert!(built.nodes >= 1 && built.stack_bound <= l.spec().stack_size as usize, "{l} n={n}");
                    // Every node order gives the same tree: its bytes, nodes, stack and cost.
                    for &order in NodeOrder::ALL {
                        let o = l.nodes_in(&bvh.nodes, &bvh.options, order).unwrap().unwrap();
                        assert_eq!(
                            (o.bytes.len(), o.nodes, o.stack_bound, o.sah_cost),
                            (built.bytes.len(), built.nodes, built.stack_bound, built.sah_cost),
                            "{l} {order} n={n} leaf={leaf}"
                        );
                        if order == NodeOrder::Built {
                            assert!(o.bytes == built.bytes, "{l}: the built order is the buffer as before");
                        }
                    }
                }
            }
        }
    }
}
