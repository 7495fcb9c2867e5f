//! The binary tree's statistics: nodes, depth, leaf-size histogram, SAH cost, build time, and
//! (with the mesh) the end-point overlap.

use super::{Bvh, BvhNode};
use crate::bvh::epo;
use crate::scene::Mesh;

#[derive(Clone, Debug, serde::Serialize)]
pub struct BvhStats {
    pub builder: String,
    pub leaf_policy: String,
    pub max_leaf_size: u32,
    pub triangles: usize,
    pub degenerate_excluded: usize,
    pub nodes: usize,
    pub inner_nodes: usize,
    pub leaves: usize,
    /// Deepest leaf; root at depth 0.
    pub depth: u32,
    /// `leaf_histogram[k]` = number of leaves holding `k` triangles.
    pub leaf_histogram: Vec<usize>,
    /// SAH cost with the build's costs: sum over inner nodes of C_t A(n)/A(root) plus sum over
    /// leaves of C_i ceil(|n| / g) A(n)/A(root), g = the build's `sah_group` (1: classic SAH).
    pub sah_cost: f64,
    /// Triangles priced as one test by the build's SAH (4: quad-aware).
    pub sah_group: u32,
    /// Padding slots a 4-wide (Quad) encoding adds to fill partial quads.
    pub quad_padding: usize,
    pub build_ms: f64,
    /// Threads the build ran on.
    pub build_threads: usize,
    /// Build speed: triangles in the mesh (degenerate ones included, as they were read) per
    /// microsecond of build time.
    pub mtris_per_s: f64,
    pub node_bytes: usize,
    /// End-point overlap (Aila, Karras & Laine, HPG 2013; [`epo`]) with the build's node costs;
    /// `None` unless computed ([`Bvh::stats_with_epo`]; not past its work limit).
    pub epo: Option<f64>,
    /// Time computing `epo`, milliseconds.
    pub epo_ms: Option<f64>,
}

impl Bvh {
    pub fn stats(&self) -> BvhStats {
        let o = &self.options;
        let mut s = BvhStats {
            builder: o.builder.to_string(),
            leaf_policy: o.leaf_policy.to_string(),
            max_leaf_size: o.max_leaf_size,
            triangles: self.triangle_count(),
            degenerate_excluded: self.degenerate_excluded,
            nodes: self.nodes.len(),
            inner_nodes: 0,
            leaves: 0,
            depth: 0,
            leaf_histogram: vec![0; o.max_leaf_size as usize + 1],
            sah_cost: self.sah_cost(o),
            sah_group: o.sah_group,
            quad_padding: 0,
            build_ms: self.build_seconds * 1e3,
            build_threads: self.build_threads,
            mtris_per_s: (self.triangle_count() + self.degenerate_excluded) as f64
                / self.build_seconds.max(f64::MIN_POSITIVE)
                / 1e6,
            node_bytes: self.nodes.len() * std::mem::size_of::<BvhNode>(),
            epo: None,
            epo_ms: None,
        };
        self.visit(|i, d| {
            let n = &self.nodes[i];
            s.depth = s.depth.max(d);
            if n.is_leaf() {
                s.leaves += 1;
                let c = n.count as usize;
                if c >= s.leaf_histogram.len() {
                    s.leaf_histogram.resize(c + 1, 0);
                }
                s.leaf_histogram[c] += 1;
                s.quad_padding += c.div_ceil(4) * 4 - c;
            } else {
                s.inner_nodes += 1;
            }
        });
        s
    }

    /// [`Bvh::stats`] plus the end-point overlap, which needs the triangles; `epo` is `None` where
    /// it would take more than [`epo::default_work_limit`] ([`epo::not_computed`] says why), and
    /// `epo_ms` is then the time spent before giving up.
    pub fn stats_with_epo(&self, mesh: &Mesh) -> BvhStats {
        let t0 = std::time::Instant::now();
        let epo = epo::epo_within(mesh, self, epo::default_work_limit(self));
        BvhStats { epo, epo_ms: Some(t0.elapsed().as_secs_f64() * 1e3), ..self.stats() }
    }
}
