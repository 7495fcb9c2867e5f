//! `trilab bvh`: the BVH of a scene at each leaf size, binned and full-sweep SAH: nodes, depth,
//! leaf sizes, SAH cost, end-point overlap, build time and speed, and each method's GPU scene
//! size (from its memory plan).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::ser::{Serialize, SerializeStruct, Serializer};

use crate::bvh::{BuildOptions, Builder, BvhStats, LeafPolicy, PAPER_LEAF_SIZES};
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
    pub sah_group: u32,
    pub leaf_policy: LeafPolicy,
    pub rows: Vec<BvhRow>,
    /// What loading the scene warned about (a missing MTL, ignored normals): the CLI prints them.
    pub warnings: Vec<String>,
}

impl Serialize for BvhReport {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_seq(&self.rows)
    }
}

/// Builds `scene`'s BVH at each of `leaf_sizes` (the paper's when empty) with both builders.
pub fn run(scene: &Path, leaf_sizes: &[u32], leaf_policy: LeafPolicy, sah_group: u32) -> Result<BvhReport> {
    let mesh = load_obj(scene)?;
    let leaf_sizes = if leaf_sizes.is_empty() { &PAPER_LEAF_SIZES[..] } else { leaf_sizes };
    let mut rows = vec![];
    for &leaf in leaf_sizes {
        for builder in [Builder::default(), Builder::Sweep] {
            let options = BuildOptions { builder, leaf_policy, sah_group, ..BuildOptions::new(leaf) };
            let host = HostScene::build(crate::scene::scene_name(scene), &mesh, &options)?;
            let counts = host.counts();
            let gpu_scene_bytes =
                Method::ALL.iter().map(|&m| (m.name().to_owned(), MemoryPlan::of(m, &counts).bytes())).collect();
            rows.push(BvhRow { stats: host.bvh.stats_with_epo(&mesh), gpu_scene_bytes });
        }
    }
    Ok(BvhReport {
        scene: scene.to_owned(),
        triangles: mesh.triangle_count(),
        vertices: mesh.positions.len(),
        sah_group,
        leaf_policy,
        rows,
        warnings: mesh.warnings.clone(),
    })
}

impl Report for BvhReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let s = format!(
            "{}: {} triangles, {} vertices; SAH with {} triangle(s) per test, leaf policy {}\n",
            self.scene.display(),
            self.triangles,
            self.vertices,
            self.sah_group,
            self.leaf_policy
        );
        // Scene sizes of the paper's four (the others share MT's data or Woop's size).
        let paper = Method::paper();
        let mut headers: Vec<String> = [
            "leaf",
            "builder",
            "nodes",
            "depth",
            "SAH cost",
            "EPO",
            "EPO ms",
            "quad padding",
            "build ms",
            "threads",
            "Mtris/s",
            "leaf sizes (count:leaves)",
        ]
        .map(String::from)
        .to_vec();
        headers.extend(paper.iter().map(|m| format!("MB {m}")));
        let mut t = Table::new(headers);
        for r in &self.rows {
            let st = &r.stats;
            let hist: Vec<String> =
                st.leaf_histogram.iter().enumerate().filter(|(_, &n)| n > 0).map(|(k, n)| format!("{k}:{n}")).collect();
            let mut cells = vec![
                st.max_leaf_size.to_string(),
                st.builder.clone(),
                st.nodes.to_string(),
                st.depth.to_string(),
                format!("{:.2}", st.sah_cost),
                st.epo.map_or("-".into(), |e| format!("{e:.3}")),
                st.epo_ms.map_or("-".into(), |t| format!("{t:.0}")),
                st.quad_padding.to_string(),
                format!("{:.1}", st.build_ms),
                st.build_threads.to_string(),
                format!("{:.2}", st.mtris_per_s),
                hist.join(" "),
            ];
            cells.extend(paper.iter().map(|m| format!("{:.2}", r.gpu_scene_bytes[m.name()] as f64 / 1e6)));
            t.row(cells);
        }
        s + &t.to_text()
    }
}
