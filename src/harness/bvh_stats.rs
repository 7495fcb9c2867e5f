//! `trilab bvh`: the BVH of a scene at each leaf size, binned and full-sweep SAH: nodes, depth,
//! leaf sizes, SAH cost, end-point overlap, build time and speed, and each method's GPU scene
//! size (from its memory plan).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::ser::{Serialize, SerializeStruct, Serializer};

use crate::bvh::{BuildOptions, Builder, BvhStats, PAPER_LEAF_SIZES};
use crate::encoding::{MemoryPlan, Method};
use crate::error::Result;
use crate::pipeline::HostScene;
use crate::report::{Report, Table};
use crate::scene::load_obj;

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

/// Every build (serialised as the list of rows).
#[derive(Clone, Debug)]
pub struct BvhReport {
    pub scene: PathBuf,
    pub triangles: usize,
    pub vertices: usize,
    /// The tree's shape every build shares (its leaf policy and SAH group; each row has its own
    /// leaf size and builder).
    pub shape: BuildOptions,
    pub rows: Vec<BvhRow>,
    /// What loading the scene warned about (a missing MTL, ignored normals) and the builds whose
    /// EPO was not computed (past its work limit): the CLI prints them.
    pub warnings: Vec<String>,
}

impl Serialize for BvhReport {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq(&self.rows)
    }
}

/// Builds `scene`'s BVH at each of `leaf_sizes` (the paper's when empty) with both builders, each
/// tree shaped as `shape` says (its leaf size and builder are replaced).
pub fn run(scene: &Path, leaf_sizes: &[u32], shape: BuildOptions) -> Result<BvhReport> {
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
                Method::ALL.iter().map(|&m| (m.name().to_owned(), MemoryPlan::of(m, &counts).bytes())).collect();
            let stats = host.bvh.stats_with_epo(&mesh);
            if stats.epo.is_none() {
                warnings.push(format!("leaf {leaf}, {}: {}", stats.builder, crate::bvh::epo::not_computed(&host.bvh)));
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
        format!("{s}\n{}\n{}", tree.to_text(), build.to_text())
    }
}
