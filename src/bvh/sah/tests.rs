//! The builder's tests: every leaf size, builder and leaf policy gives a valid tree; the depth
//! bound holds on a pathological scene; degenerate triangles are left out; and the parallel build
//! equals the serial one bit for bit.

use super::*;
use crate::bvh::testing::grid;

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
    let sweep = Bvh::build(&mesh, &BuildOptions { builder: Builder::Sweep, ..BuildOptions::new(4) }).stats().sah_cost;
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
            _ => pos.extend([[c[0] + z, c[1], c[2]], [c[0] + e, c[1] + z, c[2]], [c[0], c[1] + e, c[2] + e * next()]]),
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
    let grains = [Grain::DEFAULT, Grain { serial_below: 2, chunk: 7 }];
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
                                let par = pool.install(|| build_grain(mesh, &o, g));
                                assert_eq!(par.build_threads, *threads);
                                assert!(
                                    serial.same_tree(&par),
                                    "{name} leaf {leaf} {leaf_policy} g{sah_group} {builder} threads {threads} {g:?}"
                                );
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
    let par = pool.install(|| build_grain(&mesh, &o, Grain { serial_below: 64, chunk: 16 }));
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
            let g = Grain { serial_below: 0, chunk: 1 };
            assert!(Bvh::build_serial(&mesh, &o).same_tree(&build_grain(&mesh, &o, g)));
        }
    }
}
