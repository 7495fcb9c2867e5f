//! Wide BVHs on the CPU (`trilab::bvh::wide`, issue 15 groundwork): the 4- and 8-wide trees
//! collapsed from the binary SAH tree keep its invariants and find, for every ray, exactly the
//! f64 reference's closest hit (same triangle id, t, u and v; the reference walks the binary
//! tree), on the bundled bunny and on synthetic scenes, with random, primary and diffuse rays.
//! Any-hit queries agree on hit or miss and return a real hit. A corrupted child box is caught
//! by the invariant check and loses hits, so these checks can fail.
//!
//! `wide_trees_cost_less_and_visit_fewer_nodes` prints the numbers for the note (SAH costs,
//! bytes, nodes visited per ray); run it with `--nocapture` to see them.

use std::path::Path;

use trilab::bvh::{BuildOptions, Bvh, Collapse, WideBvh, WideSteps};
use trilab::encoding::Method;
use trilab::rays::{diffuse_rays, primary_rays, random_rays, Camera, Ray};
use trilab::reference::{intersect, Ray64, RefHit, Reference};
use trilab::scene::{load_obj, Mesh};
use trilab::traversal::ray_steps;

fn bunny() -> Mesh {
    load_obj(Path::new("bunny")).expect("the bundled bunny loads by name")
}

/// Random, primary (the benchmarks' peer camera, 96 x 72) and diffuse (four bounces off each primary hit) rays.
fn ray_sets(mesh: &Mesh, bvh: &Bvh, random: usize) -> Vec<(&'static str, Vec<Ray>)> {
    let b = mesh.bounds();
    let primary = primary_rays(&Camera::peer(&b).unwrap(), 96, 72);
    let hits: Vec<_> = Reference::new(mesh, bvh).trace_all(&primary, false).iter().map(RefHit::to_hit).collect();
    let diffuse = diffuse_rays(mesh, &primary, &hits, 4, 3);
    vec![("random", random_rays(&b, random, 7)), ("primary", primary), ("diffuse", diffuse)]
}

/// The wide tree's hit with the reference's triangle test.
fn trace<const N: usize>(mesh: &Mesh, w: &WideBvh<N>, r: &Ray, any: bool) -> (RefHit, WideSteps) {
    let r64 = Ray64::from(r);
    let (h, s) = w.trace(r, any, |id, tmax| intersect(&Ray64 { tmax, ..r64 }, mesh.vertices_f64(id as usize)));
    (RefHit { t: h.t, id: h.id, u: h.u, v: h.v }, s)
}

/// Rays whose wide closest hit differs from the reference's; panics on a wrong any-hit.
/// The traversal's stack never outgrows [`WideBvh::stack_bound`].
fn disagreements<const N: usize>(mesh: &Mesh, w: &WideBvh<N>, rays: &[Ray], reference: &[RefHit]) -> usize {
    let mut differ = 0;
    let bound = w.stack_bound() as u32;
    for (r, want) in rays.iter().zip(reference) {
        let (got, steps) = trace(mesh, w, r, false);
        differ += (got != *want) as usize;
        assert!(steps.stack_peak <= bound, "N {N}: stack {} > bound {bound}", steps.stack_peak);
        let (any, _) = trace(mesh, w, r, true);
        if any.is_hit() {
            // A real hit of that triangle at that distance.
            let again = intersect(&Ray64::from(r), mesh.vertices_f64(any.id as usize));
            assert_eq!(again.map(|h| h.0), Some(any.t), "N {N}: any-hit {any:?} is not a hit, ray {r:?}");
        }
        assert_eq!(any.is_hit(), want.is_hit(), "N {N}: any-hit disagrees on hit/miss, ray {r:?}");
    }
    differ
}

/// Every width and collapse: valid, and every ray's closest hit equals the reference's.
fn check_scene(name: &str, mesh: &Mesh, leaves: &[u32], random: usize) {
    for &leaf in leaves {
        let bvh = Bvh::build(mesh, &BuildOptions::new(leaf));
        let sets = ray_sets(mesh, &bvh, random);
        for how in [Collapse::Sah, Collapse::Greedy] {
            let w4 = WideBvh::<4>::collapse_with(&bvh, how);
            let w8 = WideBvh::<8>::collapse_with(&bvh, how);
            w4.validate(&bvh, mesh).unwrap_or_else(|e| panic!("{name} leaf {leaf} {how:?} N 4: {e}"));
            w8.validate(&bvh, mesh).unwrap_or_else(|e| panic!("{name} leaf {leaf} {how:?} N 8: {e}"));
            for (set, rays) in &sets {
                let reference = Reference::new(mesh, &bvh).trace_all(rays, false);
                let hits = reference.iter().filter(|h| h.is_hit()).count();
                assert!(hits * 20 >= rays.len(), "{name} {set}: too few hits to test ({hits} of {})", rays.len());
                assert_eq!(disagreements(mesh, &w4, rays, &reference), 0, "{name} leaf {leaf} {how:?} N 4 {set}");
                assert_eq!(disagreements(mesh, &w8, rays, &reference), 0, "{name} leaf {leaf} {how:?} N 8 {set}");
            }
        }
    }
}

#[test]
fn bunny_wide_hits_equal_the_reference() {
    check_scene("bunny", &bunny(), &[1, 4, 8, 16], 5000);
}

#[test]
fn synthetic_wide_hits_equal_the_reference() {
    for spec in ["synth:soup:20k:3", "synth:spheres:12k", "synth:terrain:20k"] {
        let mesh = load_obj(Path::new(spec)).unwrap();
        check_scene(spec, &mesh, &[4], 3000);
    }
}

#[test]
fn a_corrupted_child_box_is_caught_and_loses_hits() {
    let mesh = bunny();
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let good = WideBvh::<8>::collapse(&bvh);
    good.validate(&bvh, &mesh).unwrap();
    let rays = random_rays(&mesh.bounds(), 4000, 11);
    let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
    assert_eq!(disagreements(&mesh, &good, &rays, &reference), 0);
    // Shrink the root's largest inner child box to its lower half along x.
    let root = &good.nodes[0];
    let slot = (0..root.children())
        .filter(|&s| !root.is_leaf(s))
        .max_by(|&a, &b| root.child_box(a).area().total_cmp(&root.child_box(b).area()))
        .unwrap();
    let mut bad = good.clone();
    let n = &mut bad.nodes[0];
    n.max_x[slot] = 0.5 * (n.min_x[slot] + n.max_x[slot]);
    let e = bad.validate(&bvh, &mesh).expect_err("a shrunk child box must be caught");
    assert!(e.contains("not inside the node's box"), "{e}");
    let lost = (0..rays.len()).filter(|&i| trace(&mesh, &bad, &rays[i], false).0 != reference[i]).count();
    assert!(lost > 0, "the shrunk box should hide some closest hits");
}

/// A wide kernel gets its nodes by collapsing an encoding's binary nodes (leaves in the
/// encoding's units, e.g. quads): the same tree, each leaf child's first slot mapped as the
/// encoding maps that binary leaf.
#[test]
fn collapsing_an_encodings_nodes_keeps_its_leaf_units() {
    let mesh = bunny();
    for leaf in [3, 4, 8] {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        let plain = WideBvh::<8>::collapse(&bvh);
        for method in Method::ALL {
            let e = method.encode(&mesh, &bvh);
            assert_eq!(e.nodes.len(), bvh.nodes.len(), "{method}: encodings keep the node order");
            let map: std::collections::HashMap<u32, u32> = bvh
                .nodes
                .iter()
                .zip(&e.nodes)
                .filter(|(b, _)| b.is_leaf())
                .map(|(b, enc)| (b.left_or_first, enc.left_or_first))
                .collect();
            let wide = WideBvh::<8>::collapse_nodes(&e.nodes, &bvh.options, Collapse::Sah);
            assert_eq!(wide.len(), plain.nodes.len(), "{method} leaf {leaf}");
            let mut leaves = 0;
            for (a, b) in plain.nodes.iter().zip(&wide) {
                assert_eq!(bytemuck::bytes_of(&a.min_x), bytemuck::bytes_of(&b.min_x));
                assert_eq!(bytemuck::bytes_of(&a.max_z), bytemuck::bytes_of(&b.max_z));
                assert_eq!(a.count, b.count, "{method} leaf {leaf}");
                for s in 0..8 {
                    let want = if a.is_leaf(s) { map[&a.child[s]] } else { a.child[s] };
                    assert_eq!(b.child[s], want, "{method} leaf {leaf}");
                    leaves += a.is_leaf(s) as usize;
                }
            }
            assert_eq!(leaves, map.len());
        }
    }
}

/// Mean per ray.
fn mean(steps: &[WideSteps], f: impl Fn(&WideSteps) -> u32) -> f64 {
    steps.iter().map(|s| f(s) as f64).sum::<f64>() / steps.len().max(1) as f64
}

#[test]
fn wide_trees_cost_less_and_visit_fewer_nodes() {
    let mesh = bunny();
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let o = &bvh.options;
    let tris = bvh.triangle_count() as f64;
    let binary = bvh.stats();
    eprintln!(
        "bunny leaf 4, {} triangles: binary 32-byte nodes {} ({:.1} B/tri), SAH {:.3}",
        tris,
        binary.nodes,
        binary.node_bytes as f64 / tris,
        binary.sah_cost
    );
    let w2 = WideBvh::<2>::collapse(&bvh);
    assert!((w2.sah_cost(o) - binary.sah_cost).abs() <= 1e-9 * binary.sah_cost, "N = 2 is the binary tree");
    let trees4 = [Collapse::Sah, Collapse::Greedy].map(|h| WideBvh::<4>::collapse_with(&bvh, h));
    let trees8 = [Collapse::Sah, Collapse::Greedy].map(|h| WideBvh::<8>::collapse_with(&bvh, h));
    for (how, s) in [("sah", w2.stats(o))]
        .into_iter()
        .chain(trees4.iter().zip(["sah", "greedy"]).map(|(w, h)| (h, w.stats(o))))
        .chain(trees8.iter().zip(["sah", "greedy"]).map(|(w, h)| (h, w.stats(o))))
    {
        eprintln!(
            "N {} {how:>6}: nodes {:>6} ({:>5.1} B/tri, {} B/node), mean children {:.2}, depth {:>2}, SAH {:.3} (per box {:.3}), collapse {:.1} ms, stack bound {}",
            s.width,
            s.nodes,
            s.node_bytes_per_triangle,
            s.node_bytes / s.nodes,
            s.mean_children,
            s.depth,
            s.sah_cost,
            s.sah_cost_per_box,
            s.collapse_ms,
            s.stack_bound
        );
        assert!(s.sah_cost <= binary.sah_cost * (1.0 + 1e-12));
    }
    assert!(trees8[0].sah_cost(o) < trees4[0].sah_cost(o) && trees4[0].sah_cost(o) < binary.sah_cost);
    for (set, rays) in ray_sets(&mesh, &bvh, 20000) {
        let kernel = ray_steps(&mesh, &bvh, &rays);
        let per = |f: &dyn Fn(&WideSteps) -> u32, w: &[WideSteps]| mean(w, f);
        let s2: Vec<_> = rays.iter().map(|r| trace(&mesh, &w2, r, false).1).collect();
        let s4: Vec<_> = rays.iter().map(|r| trace(&mesh, &trees4[0], r, false).1).collect();
        let s8: Vec<_> = rays.iter().map(|r| trace(&mesh, &trees8[0], r, false).1).collect();
        let g8: Vec<_> = rays.iter().map(|r| trace(&mesh, &trees8[1], r, false).1).collect();
        eprintln!(
            "{set:>7}: kernel mirror (bvh2 while-if, f32 boxes) inner {:.1} + leaves {:.1} iterations, {:.1} triangles per ray",
            kernel.iter().map(|s| s.inner as f64).sum::<f64>() / rays.len() as f64,
            kernel.iter().map(|s| s.leaves as f64).sum::<f64>() / rays.len() as f64,
            kernel.iter().map(|s| s.triangles as f64).sum::<f64>() / rays.len() as f64,
        );
        for (name, s) in [("bvh2", &s2), ("bvh4", &s4), ("bvh8", &s8), ("bvh8 greedy", &g8)] {
            eprintln!(
                "{set:>7} {name:>11}: nodes {:>5.2}, boxes {:>6.2}, leaves {:>5.2}, triangles {:>5.2} per ray; stack peak {}",
                per(&|x| x.nodes, s),
                per(&|x| x.boxes, s),
                per(&|x| x.leaves, s),
                per(&|x| x.triangles, s),
                s.iter().map(|x| x.stack_peak).max().unwrap_or(0)
            );
        }
        // Fewer node visits is the point of a wide tree (not a bound worth more than that).
        assert!(per(&|x| x.nodes, &s8) < per(&|x| x.nodes, &s4) && per(&|x| x.nodes, &s4) < per(&|x| x.nodes, &s2));
    }
}
