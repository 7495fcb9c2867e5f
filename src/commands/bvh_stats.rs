//! `trilab bvh`: the BVH of a scene at each leaf size, binned and full-sweep SAH: nodes, depth,
//! leaf sizes, SAH cost, end-point overlap, build time and speed, and each method's GPU scene
//! size (from its memory placement); with `--layouts` or `--node-orders`, per node layout of the
//! binned tree its bytes per triangle (nodes, and nodes + each method's leaf bytes) and per node
//! order the locality of a descent (`bvh::order::Locality`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::ser::{Serialize, SerializeStruct, Serializer};

use crate::bvh::{BuildOptions, Builder, Bvh, BvhStats, Locality, NodeOrder, PAPER_LEAF_SIZES};
use crate::encoding::{Layout, Method, Placement, SceneCounts};
use crate::error::Error;
use crate::error::Result;
use crate::pipeline::HostScene;
use crate::report::{Report, Table};
use crate::scene::load_obj;
use crate::shared::BINDING_NODES;

/// One build: its statistics and each method's GPU scene bytes.
#[derive(Clone, Debug)]
pub struct BvhRow {
    pub stats: BvhStats,
    pub gpu_scene_bytes: BTreeMap<String, u64>,
}

impl Serialize for BvhRow {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("BvhRow", 2)?;
        st.serialize_field("stats", &self.stats)?;
        st.serialize_field("gpu_scene_bytes", &self.gpu_scene_bytes)?;
        st.end()
    }
}

/// One node layout of a binned tree: its node buffer's size and, per node order, its locality.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LayoutBytes {
    pub leaf: u32,
    pub layout: Layout,
    pub nodes: usize,
    /// The node buffer's bytes (cwbvh's leaf table included) over the triangles in the tree.
    pub node_bytes_per_triangle: f64,
    /// Per method, the node buffer plus the method's leaf bytes (primitives and slot ids, from
    /// its memory placement), over the triangles: what the kernels read per triangle. Every method's
    /// encoding has the same tree (a Quad encoding renumbers leaf starts only), so the node
    /// buffer is the same for each.
    pub bytes_per_triangle: BTreeMap<String, f64>,
    /// Per node order, how close the nodes a descent reads lie.
    pub locality: Vec<(NodeOrder, Locality)>,
}

/// Each method's leaf bytes (every buffer but the nodes) per triangle at `counts`.
pub fn leaf_bytes_per_triangle(counts: &SceneCounts) -> BTreeMap<String, f64> {
    let tris = counts.triangles.max(1) as f64;
    Method::ALL
        .iter()
        .map(|&m| {
            let placement = Placement::of(m, counts);
            let leaf: u64 = placement.buffers.iter().filter(|b| b.binding != BINDING_NODES).map(|b| b.bytes).sum();
            (m.name().to_owned(), leaf as f64 / tris)
        })
        .collect()
}

/// `layouts` of `bvh` (leaf size `leaf`), each with the locality of every one of `orders`.
pub fn layout_bytes(
    bvh: &Bvh,
    counts: &SceneCounts,
    layouts: &[Layout],
    orders: &[NodeOrder],
) -> Result<Vec<LayoutBytes>> {
    let tris = counts.triangles.max(1) as f64;
    let leaf = leaf_bytes_per_triangle(counts);
    let mut out = vec![];
    for &layout in layouts {
        let mut locality = vec![];
        let mut built = None;
        for &order in orders {
            let f = layout
                .footprint(&bvh.nodes, &bvh.options, order)
                .map_err(|e| Error::Usage(format!("{layout} nodes in {order} order: {e}")))?;
            built.get_or_insert(f);
            locality.push((order, f.locality));
        }
        // Nodes and bytes are the same in every order (only the locality differs).
        let Some(f) = built else { continue };
        let node = f.bytes as f64 / tris;
        out.push(LayoutBytes {
            leaf: bvh.options.max_leaf_size,
            layout,
            nodes: f.nodes,
            node_bytes_per_triangle: node,
            bytes_per_triangle: leaf.iter().map(|(m, l)| (m.clone(), node + l)).collect(),
            locality,
        });
    }
    Ok(out)
}

/// Every build (serialised as the list of rows, or with layouts as `{builds, layouts,
/// leaf_bytes_per_triangle}`).
#[derive(Clone, Debug)]
pub struct BvhReport {
    pub scene: PathBuf,
    pub triangles: usize,
    pub vertices: usize,
    /// The tree's shape every build shares (its leaf policy and SAH group; each row has its own
    /// leaf size and builder).
    pub shape: BuildOptions,
    pub rows: Vec<BvhRow>,
    /// `--layouts`, `--node-orders`: each layout of each leaf size's binned tree.
    pub layouts: Vec<LayoutBytes>,
    /// Each method's leaf bytes per triangle per leaf size, beside `layouts`.
    pub leaf_bytes: Vec<(u32, BTreeMap<String, f64>)>,
    /// What loading the scene warned about (a missing MTL, ignored normals) and the builds whose
    /// EPO was not computed (past its work limit): the CLI prints them.
    pub warnings: Vec<String>,
}

impl Serialize for BvhReport {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        if self.layouts.is_empty() {
            return s.collect_seq(&self.rows);
        }
        let mut st = s.serialize_struct("BvhReport", 3)?;
        st.serialize_field("builds", &self.rows)?;
        st.serialize_field("layouts", &self.layouts)?;
        let leaf: BTreeMap<String, &BTreeMap<String, f64>> =
            self.leaf_bytes.iter().map(|(l, b)| (l.to_string(), b)).collect();
        st.serialize_field("leaf_bytes_per_triangle", &leaf)?;
        st.end()
    }
}

/// Builds `scene`'s BVH at each of `leaf_sizes` (the paper's when empty) with both builders, each
/// tree shaped as `shape` says (its leaf size and builder are replaced).
pub fn run(scene: &Path, leaf_sizes: &[u32], shape: BuildOptions) -> Result<BvhReport> {
    run_with_layouts(scene, leaf_sizes, shape, &[], &[])
}

/// [`run`], and each of `layouts` of every binned tree with the locality of each of `orders`
/// (none when both are empty; either empty: every layout, or every order).
pub fn run_with_layouts(
    scene: &Path,
    leaf_sizes: &[u32],
    shape: BuildOptions,
    layouts: &[Layout],
    orders: &[NodeOrder],
) -> Result<BvhReport> {
    use crate::named::Named;
    let wanted = !layouts.is_empty() || !orders.is_empty();
    let layouts = if layouts.is_empty() { Layout::ALL } else { layouts };
    let orders = if orders.is_empty() { NodeOrder::ALL } else { orders };
    let (mut layout_rows, mut leaf_bytes) = (vec![], vec![]);
    let mesh = load_obj(scene)?;
    let leaf_sizes = if leaf_sizes.is_empty() { &PAPER_LEAF_SIZES[..] } else { leaf_sizes };
    let mut rows = vec![];
    let mut warnings = mesh.warnings.clone();
    for &leaf in leaf_sizes {
        for builder in [Builder::default(), Builder::Sweep] {
            let options = BuildOptions { builder, max_leaf_size: leaf, ..shape };
            let host = HostScene::build(crate::scene::scene_name(scene), &mesh, &options)?;
            let counts = host.counts();
            let gpu_scene_bytes =
                Method::ALL.iter().map(|&m| (m.name().to_owned(), Placement::of(m, &counts).bytes())).collect();
            let stats = host.bvh.stats_with_epo(&mesh);
            if stats.epo.is_none() {
                warnings.push(format!("leaf {leaf}, {}: {}", stats.builder, crate::bvh::epo::not_computed(&host.bvh)));
            }
            if wanted && builder == Builder::default() {
                layout_rows.extend(layout_bytes(&host.bvh, &counts, layouts, orders)?);
                leaf_bytes.push((leaf, leaf_bytes_per_triangle(&counts)));
            }
            rows.push(BvhRow { stats, gpu_scene_bytes });
        }
    }
    Ok(BvhReport {
        scene: scene.to_owned(),
        triangles: mesh.triangle_count(),
        vertices: mesh.positions.len(),
        shape,
        rows,
        layouts: layout_rows,
        leaf_bytes,
        warnings,
    })
}

impl Report for BvhReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let s = format!(
            "{}: {} triangles, {} vertices\nSAH with {} triangle(s) per test, leaf policy {}\n",
            self.scene.display(),
            self.triangles,
            self.vertices,
            self.shape.sah_group,
            self.shape.leaf_policy
        );
        // Two tables that each fit 100 columns: the tree, then the build and the GPU scene sizes
        // of the paper's four (the others share MT's data or Woop's size). The leaf-size
        // histogram and every method's size are in --json.
        let mut tree = Table::new([
            "leaf",
            "builder",
            "nodes",
            "leaves",
            "tris/leaf",
            "depth",
            "SAH cost",
            "EPO",
            "EPO ms",
            "quad pad",
        ]);
        let paper = Method::paper();
        let mut build_headers: Vec<String> =
            ["leaf", "builder", "threads", "build ms", "Mtris/s"].map(String::from).to_vec();
        build_headers.extend(paper.iter().map(|m| format!("MB {m}")));
        let mut build = Table::new(build_headers);
        for r in &self.rows {
            let st = &r.stats;
            let in_leaves: usize = st.leaf_histogram.iter().enumerate().map(|(k, n)| k * n).sum();
            tree.row([
                st.max_leaf_size.to_string(),
                st.builder.clone(),
                st.nodes.to_string(),
                st.leaves.to_string(),
                if st.leaves == 0 { "-".into() } else { format!("{:.2}", in_leaves as f64 / st.leaves as f64) },
                st.depth.to_string(),
                format!("{:.2}", st.sah_cost),
                st.epo.map_or("-".into(), |e| format!("{e:.3}")),
                st.epo_ms.map_or("-".into(), |t| format!("{t:.0}")),
                st.quad_padding.to_string(),
            ]);
            let mut cells = vec![
                st.max_leaf_size.to_string(),
                st.builder.clone(),
                st.build_threads.to_string(),
                format!("{:.1}", st.build_ms),
                format!("{:.2}", st.mtris_per_s),
            ];
            cells.extend(paper.iter().map(|m| format!("{:.2}", r.gpu_scene_bytes[m.name()] as f64 / 1e6)));
            build.row(cells);
        }
        let mut out = format!("{s}\n{}\n{}", tree.to_text(), build.to_text());
        if !self.layouts.is_empty() {
            out += &format!("\n{}\n{}", self.bytes_table().to_text(), self.locality_table().to_text());
        }
        out
    }
}

impl BvhReport {
    /// Bytes per triangle of each layout of the binned trees: the node buffer, and the node
    /// buffer plus each of the paper's methods' leaf bytes (a `leaves` row per leaf size gives
    /// the leaf bytes alone; every method in --json).
    pub fn bytes_table(&self) -> Table {
        let paper = Method::paper();
        let mut header: Vec<String> = ["leaf", "layout", "nodes", "node B/tri"].map(String::from).to_vec();
        header.extend(paper.iter().map(|m| format!("B/tri {m}")));
        let mut t = Table::new(header);
        for (leaf, bytes) in &self.leaf_bytes {
            let mut cells = vec![leaf.to_string(), "leaves".into(), "-".into(), "-".into()];
            cells.extend(paper.iter().map(|m| format!("{:.1}", bytes[m.name()])));
            t.row(cells);
            for l in self.layouts.iter().filter(|l| l.leaf == *leaf) {
                let mut cells = vec![
                    leaf.to_string(),
                    l.layout.to_string(),
                    l.nodes.to_string(),
                    format!("{:.1}", l.node_bytes_per_triangle),
                ];
                cells.extend(paper.iter().map(|m| format!("{:.1}", l.bytes_per_triangle[m.name()])));
                t.row(cells);
            }
        }
        t
    }

    /// Per layout and node order, the new 64-byte lines and 4 KiB pages a step from a node to
    /// a child reads (weighted by the child's surface area; `bvh::order::Locality`).
    pub fn locality_table(&self) -> Table {
        let mut t = Table::new(["leaf", "layout", "node order", "new lines/step", "new pages/step"]);
        for l in &self.layouts {
            for (order, loc) in &l.locality {
                t.row([
                    l.leaf.to_string(),
                    l.layout.to_string(),
                    order.to_string(),
                    format!("{:.3}", loc.lines_per_step),
                    format!("{:.3}", loc.pages_per_step),
                ]);
            }
        }
        t
    }
}
