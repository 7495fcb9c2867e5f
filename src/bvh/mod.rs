//! Bounding volume hierarchy: top-down SAH build into the paper's 32-byte nodes.
//!
//! - `Aabb` (from `scene`): boxes.
//! - `BvhNode`: the 32-byte node shared with the kernels.
//! - `builder`: binned and full-sweep SAH construction with a depth bound.
//! - [`wide`]: the binary tree collapsed into 4- and 8-wide nodes (child boxes in the parent),
//!   their SAH cost and a CPU traversal (issue 15 groundwork).
//! - [`cwbvh`]: the 8-wide tree compressed into Ylitie et al.'s 80-byte nodes (quantized
//!   child boxes, octant-ordered slots) and its hit-mask traversal on the CPU.
//! - [`order`]: the tree's node order in memory (as built, depth first, breadth first, treelets),
//!   applied to any layout's node array by renaming child indices (issue 27).
//! - `BvhStats`: nodes, depth, leaf-size histogram, SAH cost, build time, and (with the mesh)
//!   end-point overlap ([`epo`]).

pub mod builder;
pub mod cwbvh;
pub mod epo;
mod node;
pub mod order;
pub mod wide;

pub use crate::scene::Aabb;
pub use builder::{BuildOptions, Builder, LeafPolicy, MAX_DEPTH, MAX_LEAF_SIZE, PAPER_LEAF_SIZES};
pub use cwbvh::{CwBvh, CwNode, CwStats, SlotOrder};
pub use node::BvhNode;
pub use order::{Locality, NodeOrder, NodeTree};
pub use wide::{Bvh4, Bvh4Node, Bvh8, Bvh8Node, Collapse, Wide2Node, WideBvh, WideHit, WideNode, WideStats, WideSteps};

use crate::scene::Mesh;

/// Marks a padding slot in [`Bvh::prim_ids`]: a degenerate triangle that can never be hit.
pub const PAD_SLOT: u32 = u32::MAX;

/// A built hierarchy over one mesh. Leaves index `prim_ids` (`left_or_first`, `count`); the
/// encodings turn that into their own storage order.
#[derive(Clone, Debug)]
pub struct Bvh {
    /// Root at 0; the children of an inner node are adjacent.
    pub nodes: Vec<BvhNode>,
    /// Leaf slot -> triangle id, in leaf order ([`PAD_SLOT`] for padding).
    pub prim_ids: Vec<u32>,
    pub options: BuildOptions,
    pub build_seconds: f64,
    /// Threads the build ran on (rayon's pool; 1 for [`Bvh::build_serial`]).
    pub build_threads: usize,
    /// Zero-area triangles left out of the hierarchy (never hit).
    pub degenerate_excluded: usize,
}

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
    /// Builds a BVH over the mesh's non-degenerate triangles, in parallel on rayon's current
    /// thread pool (run it inside `ThreadPool::install` to choose the thread count). The tree
    /// is bitwise identical to [`Bvh::build_serial`]'s whatever the pool.
    pub fn build(mesh: &Mesh, options: &BuildOptions) -> Bvh {
        builder::build(mesh, options)
    }

    /// The same tree built by one single-threaded loop (the reference for the parallel build).
    pub fn build_serial(mesh: &Mesh, options: &BuildOptions) -> Bvh {
        builder::build_serial(mesh, options)
    }

    /// The same tree bit for bit: nodes (as bytes, so -0.0 and +0.0 differ), slot order and
    /// the degenerate triangles left out. Build settings and timings are not compared.
    pub fn same_tree(&self, other: &Bvh) -> bool {
        bytemuck::cast_slice::<_, u8>(&self.nodes) == bytemuck::cast_slice::<_, u8>(&other.nodes)
            && self.prim_ids == other.prim_ids
            && self.degenerate_excluded == other.degenerate_excluded
    }

    /// Triangles in the hierarchy (degenerate ones excluded, padding not counted).
    pub fn triangle_count(&self) -> usize {
        self.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count()
    }

    /// Calls `f(node_index, depth)` for every node, depth first.
    pub fn visit(&self, mut f: impl FnMut(usize, u32)) {
        let mut stack = vec![(0usize, 0u32)];
        while let Some((i, d)) = stack.pop() {
            f(i, d);
            let n = &self.nodes[i];
            if !n.is_leaf() {
                let l = n.left_or_first as usize;
                stack.push((l + 1, d + 1));
                stack.push((l, d + 1));
            }
        }
    }

    /// The SAH cost of this tree priced with `o`'s costs and `sah_group` (so trees built
    /// with different options can be compared on one scale).
    pub fn sah_cost(&self, o: &BuildOptions) -> f64 {
        let root_area = self.nodes[0].aabb().area().max(f64::MIN_POSITIVE);
        let mut cost = 0.0;
        self.visit(|i, _| {
            let n = &self.nodes[i];
            let rel = n.aabb().area() / root_area;
            cost += if n.is_leaf() {
                o.cost_intersect as f64 * o.tests(n.count as usize) * rel
            } else {
                o.cost_traversal as f64 * rel
            };
        });
        cost
    }

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

    /// Checks the structural invariants every consumer relies on; returns the first violation.
    pub fn validate(&self, mesh: &Mesh) -> Result<(), String> {
        let mut seen = vec![false; self.prim_ids.len()];
        let mut err = None;
        self.visit(|i, d| {
            if err.is_some() {
                return;
            }
            let n = &self.nodes[i];
            if d > MAX_DEPTH {
                err = Some(format!("node {i} at depth {d} > {MAX_DEPTH}"));
            } else if n.is_leaf() {
                if n.count > self.options.max_leaf_size {
                    err = Some(format!("leaf {i} holds {} > {}", n.count, self.options.max_leaf_size));
                }
                for s in n.left_or_first..n.left_or_first + n.count {
                    let Some(flag) = seen.get_mut(s as usize) else {
                        err = Some(format!("leaf {i} slot {s} out of range"));
                        return;
                    };
                    if std::mem::replace(flag, true) {
                        err = Some(format!("slot {s} in two leaves"));
                    }
                    let id = self.prim_ids[s as usize];
                    if id != PAD_SLOT && !n.aabb().contains(&Aabb::from_points(&mesh.vertices(id as usize))) {
                        err = Some(format!("leaf {i} box does not contain triangle {id}"));
                    }
                }
            } else {
                let l = n.left_or_first as usize;
                if l + 1 >= self.nodes.len() || l <= i {
                    err = Some(format!("node {i} has bad children {l}"));
                } else if !n.aabb().contains(&self.nodes[l].aabb()) || !n.aabb().contains(&self.nodes[l + 1].aabb()) {
                    err = Some(format!("node {i} box does not contain its children"));
                }
            }
        });
        if let Some(e) = err {
            return Err(e);
        }
        if let Some(s) = seen.iter().position(|&x| !x) {
            return Err(format!("slot {s} in no leaf"));
        }
        let mut ids: Vec<u32> = self.prim_ids.iter().copied().filter(|&p| p != PAD_SLOT).collect();
        ids.sort_unstable();
        let expected: Vec<u32> =
            (0..mesh.triangle_count() as u32).filter(|&i| !mesh.is_degenerate(i as usize)).collect();
        if ids != expected {
            return Err("leaves do not hold exactly the non-degenerate triangles".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A jittered grid of small triangles (deterministic), for builder tests (and `wide`'s).
    pub(super) fn grid(n: usize) -> Mesh {
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for i in 0..n {
            let x = (i % 37) as f32 + 0.13 * ((i * 7919) % 11) as f32;
            let y = (i / 37) as f32;
            let z = 0.3 * ((i * 104729) % 13) as f32;
            let b = pos.len() as u32;
            pos.extend([[x, y, z], [x + 0.5, y, z + 0.1], [x, y + 0.5, z - 0.1]]);
            tris.push([b, b + 1, b + 2]);
        }
        Mesh::from_triangles(pos, tris)
    }

    #[test]
    fn every_leaf_size_and_builder_gives_a_valid_tree() {
        let mesh = grid(2000);
        for leaf in [1, 2, 3, 4, 8, 16] {
            for builder in [Builder::Binned { bins: 32 }, Builder::Sweep] {
                let bvh = Bvh::build(&mesh, &BuildOptions { builder, ..BuildOptions::new(leaf) });
                bvh.validate(&mesh).unwrap_or_else(|e| panic!("leaf {leaf} {builder}: {e}"));
                let s = bvh.stats();
                assert_eq!(s.leaf_histogram.iter().enumerate().map(|(k, n)| k * n).sum::<usize>(), 2000);
                assert_eq!(s.nodes, s.inner_nodes + s.leaves);
                assert_eq!(s.leaves, s.inner_nodes + 1);
            }
        }
    }

    #[test]
    fn fill_policy_fills_leaves_and_sah_policy_only_caps_them() {
        let mesh = grid(2000);
        for leaf in [2, 4, 8, 16] {
            let fill = Bvh::build(&mesh, &BuildOptions::new(leaf));
            // Fill: no inner node holds <= leaf triangles (it would have been a leaf).
            let mut under = vec![0usize; fill.nodes.len()];
            for i in (0..fill.nodes.len()).rev() {
                let n = &fill.nodes[i];
                under[i] = if n.is_leaf() {
                    n.count as usize
                } else {
                    under[n.left_or_first as usize] + under[n.left_or_first as usize + 1]
                };
                assert!(n.is_leaf() || under[i] > leaf as usize, "leaf {leaf}: inner node {i} holds only {}", under[i]);
            }
            let sah = Bvh::build(&mesh, &BuildOptions { leaf_policy: LeafPolicy::Sah, ..BuildOptions::new(leaf) });
            sah.validate(&mesh).unwrap();
            assert!(sah.stats().leaves >= fill.stats().leaves, "SAH termination never makes fewer leaves");
        }
    }

    #[test]
    fn quad_aware_sah_prices_leaves_in_quads() {
        let mesh = grid(3000);
        for leaf in [4, 8, 16] {
            for leaf_policy in [LeafPolicy::Fill, LeafPolicy::Sah] {
                let plain = Bvh::build(&mesh, &BuildOptions { leaf_policy, ..BuildOptions::new(leaf) });
                let o4 = BuildOptions { leaf_policy, sah_group: 4, ..BuildOptions::new(leaf) };
                let quad = Bvh::build(&mesh, &o4);
                quad.validate(&mesh).unwrap();
                let (p, q) = (plain.stats(), quad.stats());
                eprintln!(
                    "leaf {leaf} {leaf_policy}: quad-priced SAH {:.2} -> {:.2}, padding {} -> {}",
                    plain.sah_cost(&o4),
                    q.sah_cost,
                    p.quad_padding,
                    q.quad_padding
                );
                assert_eq!(q.sah_group, 4);
                assert!((q.sah_cost - quad.sah_cost(&o4)).abs() < 1e-9);
                // Greedy top-down builds are not optimal, but pricing what the kernel pays
                // must not make the tree worse by that price.
                assert!(q.sah_cost <= plain.sah_cost(&o4) * 1.01, "leaf {leaf} {leaf_policy}");
            }
        }
        // ceil(n / 4) tests per leaf.
        let o = BuildOptions { sah_group: 4, ..BuildOptions::new(8) };
        assert_eq!([1, 4, 5, 8].map(|n| o.tests(n)), [1.0, 1.0, 2.0, 2.0]);
        assert_eq!(BuildOptions::new(8).tests(5), 5.0);
    }

    #[test]
    fn sweep_is_never_much_worse_than_binned() {
        // The full sweep prices a superset of the binned candidates at each node, so its
        // greedy tree should not cost much more (greedy choices can differ, so allow 2%).
        let mesh = grid(3000);
        let binned = Bvh::build(&mesh, &BuildOptions::new(4)).stats().sah_cost;
        let sweep =
            Bvh::build(&mesh, &BuildOptions { builder: Builder::Sweep, ..BuildOptions::new(4) }).stats().sah_cost;
        assert!(sweep <= binned * 1.02, "sweep {sweep} binned {binned}");
    }

    /// Triangles over f32's whole exponent range: eight per halving of scale, from 1 down to
    /// 2^-250 (the smallest flush to zero and become degenerate). Binned SAH splits off about
    /// five halvings per level, so unguarded it would go about 50 levels deeper than allowed.
    fn exponent_range_scene() -> Mesh {
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for k in 0..2000 {
            let x = (0.5f64).powi(k / 8) as f32 * (1.0 + (k % 8) as f32 * 0.05);
            let b = pos.len() as u32;
            pos.extend([[x, 0.0, 0.0], [x, 0.1 * x, 0.0], [x, 0.0, 0.1 * x]]);
            tris.push([b, b + 1, b + 2]);
        }
        Mesh::from_triangles(pos, tris)
    }

    #[test]
    fn depth_is_bounded_on_a_pathological_scene() {
        let mesh = exponent_range_scene();
        for leaf in [1, 4, 16] {
            for builder in [Builder::Binned { bins: 32 }, Builder::Sweep] {
                let bvh = Bvh::build(&mesh, &BuildOptions { builder, ..BuildOptions::new(leaf) });
                bvh.validate(&mesh).unwrap();
                let depth = bvh.stats().depth;
                assert!(depth <= MAX_DEPTH, "leaf {leaf} {builder}: depth {depth}");
                if leaf == 1 && matches!(builder, Builder::Binned { .. }) {
                    // The fallback split is what held it: the tree reaches the limit exactly.
                    assert_eq!(depth, MAX_DEPTH, "binned leaf 1 should hit the depth limit");
                }
            }
        }
    }

    #[test]
    fn identical_centroids_still_split() {
        let n = 100;
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for i in 0..n {
            let s = 1.0 + i as f32;
            let b = pos.len() as u32;
            pos.extend([[-s, -s, 0.0], [2.0 * s, -s, 0.0], [-s, 2.0 * s, 0.0]]);
            tris.push([b, b + 1, b + 2]);
        }
        let mesh = Mesh::from_triangles(pos, tris);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        bvh.validate(&mesh).unwrap();
        assert!(bvh.stats().leaf_histogram.iter().skip(5).all(|&c| c == 0));
    }

    #[test]
    fn degenerate_triangles_are_left_out() {
        let mesh = Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            vec![[0, 1, 2], [0, 1, 3], [3, 3, 3]],
        );
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        assert_eq!(bvh.degenerate_excluded, 2);
        assert_eq!(bvh.prim_ids, vec![1]);
        bvh.validate(&mesh).unwrap();
    }

    #[test]
    fn all_degenerate_scene_gets_one_padding_leaf() {
        let mesh = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], vec![[0, 1, 1]]);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        assert_eq!(bvh.prim_ids, vec![PAD_SLOT]);
        assert_eq!(bvh.nodes.len(), 1);
        assert!(bvh.nodes[0].is_leaf());
    }

    /// A deterministic triangle soup that exercises the build's corner cases: clustered and
    /// spread triangles, exact duplicates (identical centroids), coordinates of +0.0 and -0.0
    /// (node boxes must not depend on which zero a reduction meets first), and degenerate
    /// triangles, which are left out.
    fn soup(n: usize, seed: u64) -> Mesh {
        let mut s = seed;
        let mut next = move || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 33) as f32) / (1u64 << 31) as f32
        };
        let mut pos = Vec::new();
        let mut tris = Vec::new();
        for i in 0..n {
            let b = pos.len() as u32;
            let c = match i % 5 {
                0 => [next() * 100.0, next() * 100.0, next() * 100.0],
                1 => [50.0 + next(), 50.0 + next(), 50.0 + next()],
                2 => [0.0, if i % 2 == 0 { -0.0 } else { 0.0 }, next() * 10.0],
                _ => [next() * 100.0, next() * 3.0, 0.0],
            };
            let e = 0.05 + next();
            let z = if i % 3 == 0 { -0.0 } else { 0.0 };
            match i % 23 {
                // Degenerate: collinear.
                7 => pos.extend([c, [c[0] + e, c[1], c[2]], [c[0] + 2.0 * e, c[1], c[2]]]),
                // Duplicate of the previous triangle.
                11 if i > 0 => {
                    let p = tris.last().copied().unwrap_or([0, 0, 0]);
                    tris.push(p);
                    continue;
                }
                _ => pos.extend([
                    [c[0] + z, c[1], c[2]],
                    [c[0] + e, c[1] + z, c[2]],
                    [c[0], c[1] + e, c[2] + e * next()],
                ]),
            }
            tris.push([b, b + 1, b + 2]);
        }
        Mesh::from_triangles(pos, tris)
    }

    /// The parallel build equals the serial one bit for bit: every leaf size, both leaf
    /// policies, classic and quad-priced SAH, on pools of 1 and 4 threads, with the default
    /// grain and with a tiny one that sends every node through the parallel scans and joins.
    #[test]
    fn parallel_build_is_bitwise_identical_to_serial() {
        let pools: Vec<_> = [1, 4].map(|t| (t, rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap())).into();
        let grains = [builder::Grain::DEFAULT, builder::Grain { serial_below: 2, chunk: 7 }];
        let scenes = [("soup", soup(3000, 1)), ("grid", grid(2500)), ("exponent range", exponent_range_scene())];
        let mut checked = 0;
        for (name, mesh) in &scenes {
            for leaf in 1..=MAX_LEAF_SIZE {
                for leaf_policy in [LeafPolicy::Fill, LeafPolicy::Sah] {
                    for sah_group in [1, 4] {
                        let mut builders = vec![Builder::Binned { bins: 32 }, Builder::Binned { bins: 5 }];
                        if [1, 4, 16].contains(&leaf) {
                            builders.push(Builder::Sweep);
                        }
                        for builder in builders {
                            let o = BuildOptions { builder, leaf_policy, sah_group, ..BuildOptions::new(leaf) };
                            let serial = Bvh::build_serial(mesh, &o);
                            serial.validate(mesh).unwrap();
                            for (threads, pool) in &pools {
                                for g in grains {
                                    let par = pool.install(|| builder::build_grain(mesh, &o, g));
                                    assert_eq!(par.build_threads, *threads);
                                    assert!(serial.same_tree(&par), "{name} leaf {leaf} {leaf_policy} g{sah_group} {builder} threads {threads} {g:?}");
                                    checked += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 1000);
    }

    /// A scene large enough that the default grain scans its top nodes in many chunks, and
    /// the depth-limit fallback (leaf 1 on the exponent-range scene) reached through the
    /// parallel driver: both still match the serial build.
    #[test]
    fn parallel_build_matches_serial_on_a_larger_scene() {
        let mesh = soup(120_000, 7);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
        for (leaf, leaf_policy) in [(4, LeafPolicy::Fill), (1, LeafPolicy::Sah), (16, LeafPolicy::Sah)] {
            let o = BuildOptions { leaf_policy, ..BuildOptions::new(leaf) };
            let serial = Bvh::build_serial(&mesh, &o);
            serial.validate(&mesh).unwrap();
            let par = pool.install(|| Bvh::build(&mesh, &o));
            assert!(serial.same_tree(&par), "leaf {leaf} {leaf_policy}");
        }
        let mesh = exponent_range_scene();
        let o = BuildOptions::new(1);
        let par = pool.install(|| builder::build_grain(&mesh, &o, builder::Grain { serial_below: 64, chunk: 16 }));
        assert_eq!(par.stats().depth, MAX_DEPTH, "the fallback split held the depth");
        assert!(Bvh::build_serial(&mesh, &o).same_tree(&par));
    }

    /// Degenerate-only and single-triangle scenes go through the same parallel entry point.
    #[test]
    fn parallel_build_handles_tiny_scenes() {
        let all_degenerate = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], vec![[0, 1, 1]]);
        let one = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]]);
        for mesh in [all_degenerate, one, soup(40, 3)] {
            for leaf in [1, 4] {
                let o = BuildOptions::new(leaf);
                let g = builder::Grain { serial_below: 0, chunk: 1 };
                assert!(Bvh::build_serial(&mesh, &o).same_tree(&builder::build_grain(&mesh, &o, g)));
            }
        }
    }
}
