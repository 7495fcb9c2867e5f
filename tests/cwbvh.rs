//! The compressed wide BVH on the CPU (`trilab::bvh::cwbvh`, issue 15): Ylitie et al.'s 80-byte
//! nodes built from the bunny's trees keep every invariant, every quantized child box contains
//! its true box in the kernel's f32 arithmetic (every child, every plane, every leaf size), and
//! the hit-mask traversal of the quantized tree finds exactly the f64 reference's closest hit
//! (which walks the binary tree) on random, primary, diffuse and grazing rays, with any-hit
//! agreeing on hit or miss, the stack within `stack_bound`. Boxes shrunk by four grid steps are
//! caught and loses hits, so these checks can fail.
//!
//! `cwbvh_memory_and_cost_beside_the_wide_trees` prints bytes per triangle, SAH costs and work
//! per ray for the study; run it with `--nocapture`.

use std::path::Path;

use glam::Vec3;
use trilab::bvh::cwbvh::{check_contains, CW_WIDTH};
use trilab::bvh::{BuildOptions, Bvh, BvhNode, CwBvh, SlotOrder, WideBvh, WideSteps};
use trilab::rays::{diffuse_rays, primary_rays, random_rays, Camera, Ray};
use trilab::reference::{intersect, Ray64, RefHit, Reference};
use trilab::scene::{load_obj, Mesh};

fn bunny() -> Mesh {
    load_obj(Path::new("bunny")).expect("the bundled bunny loads by name")
}

/// Deterministic uniform numbers in [0, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 40) as f32) / (1u64 << 24) as f32
    }
}

/// Rays that touch boxes on their planes: (a) axis-parallel rays through triangle vertices
/// (a vertex is on its leaf's box planes), (b) rays lying in a binary node's min or max plane,
/// moving inside it, (c) rays at 1e-3..1e-7 rad to an axis plane through a vertex.
fn grazing_rays(mesh: &Mesh, bvh: &Bvh, n: usize) -> Vec<Ray> {
    let b = mesh.bounds();
    let span = (b.max - b.min).max_element() * 2.0;
    let mut rng = Lcg(17);
    let mut rays = Vec::with_capacity(n);
    let axis = |k: usize| Vec3::from_array(std::array::from_fn(|j| (j == k) as u8 as f32));
    while rays.len() < n {
        let v = mesh.vertices((rng.next() * mesh.triangle_count() as f32) as usize % mesh.triangle_count())
            [(rng.next() * 3.0) as usize % 3];
        let k = (rng.next() * 3.0) as usize % 3;
        let sign = if rng.next() < 0.5 { -1.0 } else { 1.0 };
        match rays.len() % 3 {
            0 => {
                let d = axis(k) * sign;
                rays.push(Ray::new((v - d * span).to_array(), d.to_array()));
            }
            1 => {
                let node: &BvhNode = &bvh.nodes[(rng.next() * bvh.nodes.len() as f32) as usize % bvh.nodes.len()];
                let nb = node.aabb();
                let plane = if rng.next() < 0.5 { nb.min[k] } else { nb.max[k] };
                let (a, c) = ((k + 1) % 3, (k + 2) % 3);
                let mut o = nb.center() - (axis(a) * (rng.next() - 0.5) + axis(c) * (rng.next() - 0.5)) * span;
                o[k] = plane;
                let mut target = nb.center();
                target[k] = plane;
                let d = target - o;
                if d.length() > 0.0 {
                    rays.push(Ray::new(o.to_array(), d.to_array()));
                }
            }
            _ => {
                let angle = 10f32.powi(-3 - (rng.next() * 5.0) as i32);
                let (a, c) = ((k + 1) % 3, (k + 2) % 3);
                let d = axis(a) * sign + axis(c) * (rng.next() - 0.5) + axis(k) * angle;
                rays.push(Ray::new((v - d * span).to_array(), d.to_array()));
            }
        }
    }
    rays
}

/// Random, primary (the peer camera, 96 x 72), diffuse (four bounces per primary hit) and
/// grazing rays.
fn ray_sets(mesh: &Mesh, bvh: &Bvh, random: usize) -> Vec<(&'static str, Vec<Ray>)> {
    let b = mesh.bounds();
    let primary = primary_rays(&Camera::peer(&b).unwrap(), 96, 72);
    let hits: Vec<_> = Reference::new(mesh, bvh).trace_all(&primary, false).iter().map(RefHit::to_hit).collect();
    let diffuse = diffuse_rays(mesh, &primary, &hits, 4, 3);
    vec![
        ("random", random_rays(&b, random, 7)),
        ("primary", primary),
        ("diffuse", diffuse),
        ("grazing", grazing_rays(mesh, bvh, random)),
    ]
}

fn trace(mesh: &Mesh, cw: &CwBvh, r: &Ray, any: bool) -> (RefHit, WideSteps) {
    let r64 = Ray64::from(r);
    let (h, s) = cw.trace(r, any, |id, tmax| intersect(&Ray64 { tmax, ..r64 }, mesh.vertices_f64(id as usize)));
    (RefHit { t: h.t, id: h.id, u: h.u, v: h.v }, s)
}

/// Rays whose closest hit differs from the reference's; panics on a wrong any-hit or a stack
/// beyond the bound.
fn disagreements(mesh: &Mesh, cw: &CwBvh, rays: &[Ray], reference: &[RefHit]) -> usize {
    let bound = cw.stack_bound() as u32;
    let mut differ = 0;
    for (r, want) in rays.iter().zip(reference) {
        let (got, steps) = trace(mesh, cw, r, false);
        differ += (got != *want) as usize;
        assert!(steps.stack_peak <= bound, "stack {} > bound {bound}", steps.stack_peak);
        let (any, _) = trace(mesh, cw, r, true);
        if any.is_hit() {
            let again = intersect(&Ray64::from(r), mesh.vertices_f64(any.id as usize));
            assert_eq!(again.map(|h| h.0), Some(any.t), "any-hit {any:?} is not a hit, ray {r:?}");
        }
        assert_eq!(any.is_hit(), want.is_hit(), "any-hit disagrees on hit/miss, ray {r:?}");
    }
    differ
}

/// Per node, the smallest leaf unit under it: identifies a subtree (leaves are disjoint), so a
/// compressed node can be paired with the wide node it came from.
fn first_units(children: impl Fn(usize) -> Vec<(bool, u32)>, len: usize) -> Vec<u32> {
    let mut min = vec![u32::MAX; len];
    // Children come after their parents in both layouts.
    for i in (0..len).rev() {
        min[i] =
            children(i).iter().map(|&(inner, x)| if inner { min[x as usize] } else { x }).min().unwrap_or(u32::MAX);
    }
    min
}

/// Every decoded plane of every child contains the collapsed tree's f32 child box (the binary
/// node's box), checked plane by plane in the kernel's arithmetic ([`check_contains`]). Returns
/// the planes checked.
fn check_every_plane(cw: &CwBvh, w8: &WideBvh<8>) -> usize {
    let cw_kids = |i: usize| -> Vec<(bool, u32)> {
        let n = &cw.nodes[i];
        (0..CW_WIDTH)
            .filter(|&s| n.is_present(s))
            .map(|s| {
                if n.is_inner(s) {
                    (true, n.inner_child(s))
                } else {
                    (false, cw.leaf(n, (n.meta[s] & 31) as u32) >> 5)
                }
            })
            .collect()
    };
    let w_kids = |i: usize| -> Vec<(bool, u32)> {
        let n = &w8.nodes[i];
        (0..n.children()).map(|s| (!n.is_leaf(s), n.child[s])).collect()
    };
    let (cmin, wmin) = (first_units(cw_kids, cw.nodes.len()), first_units(w_kids, w8.nodes.len()));
    let key = |inner: bool, x: u32, mins: &[u32]| if inner { mins[x as usize] } else { x };
    let mut planes = 0;
    let mut stack = vec![(0usize, 0usize)];
    while let Some((ci, wi)) = stack.pop() {
        let (c, w) = (&cw.nodes[ci], &w8.nodes[wi]);
        let slots: Vec<usize> = (0..CW_WIDTH).filter(|&s| c.is_present(s)).collect();
        assert_eq!(slots.len(), w.children(), "node {ci}");
        for ws in 0..w.children() {
            let wkey = key(!w.is_leaf(ws), w.child[ws], &wmin);
            let ckeys = cw_kids(ci);
            let at = ckeys.iter().position(|&(inner, x)| inner != w.is_leaf(ws) && key(inner, x, &cmin) == wkey);
            let cs = slots[at.unwrap_or_else(|| panic!("node {ci}: wide slot {ws} has no compressed slot"))];
            let truth = w.child_box(ws);
            if !truth.is_empty() {
                check_contains(&c.grid(), c.planes(cs), &truth).unwrap_or_else(|e| panic!("node {ci} slot {cs}: {e}"));
            }
            planes += 6;
            if c.is_inner(cs) {
                stack.push((c.inner_child(cs) as usize, w.child[ws] as usize));
            }
        }
    }
    planes
}

#[test]
fn every_quantized_plane_of_the_bunny_is_conservative() {
    let mesh = bunny();
    let mut planes = 0;
    for leaf in [1, 2, 4, 8, 16] {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        let w8 = WideBvh::<8>::collapse(&bvh);
        for order in [SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] {
            let cw = CwBvh::build_with(&bvh, order).unwrap();
            cw.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("leaf {leaf} {order:?}: {e}"));
            planes += check_every_plane(&cw, &w8);
        }
    }
    assert!(planes > 1_000_000, "{planes}");
}

#[test]
fn bunny_cwbvh_hits_equal_the_reference() {
    let mesh = bunny();
    for leaf in [1, 4, 8, 16] {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        let sets = ray_sets(&mesh, &bvh, 5000);
        let orders: &[SlotOrder] =
            if leaf == 4 { &[SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] } else { &[SlotOrder::Greedy] };
        for &order in orders {
            let cw = CwBvh::build_with(&bvh, order).unwrap();
            cw.validate(&bvh, &mesh).unwrap();
            for (set, rays) in &sets {
                let reference = Reference::new(&mesh, &bvh).trace_all(rays, false);
                let hits = reference.iter().filter(|h| h.is_hit()).count();
                assert!(hits * 20 >= rays.len(), "{set}: too few hits to test ({hits} of {})", rays.len());
                assert_eq!(disagreements(&mesh, &cw, rays, &reference), 0, "leaf {leaf} {order:?} {set}");
            }
        }
    }
}

#[test]
fn synthetic_cwbvh_hits_equal_the_reference() {
    for spec in ["synth:soup:20k:3", "synth:terrain:20k"] {
        let mesh = load_obj(Path::new(spec)).unwrap();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &mesh).unwrap();
        for (set, rays) in ray_sets(&mesh, &bvh, 3000) {
            let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
            assert_eq!(disagreements(&mesh, &cw, &rays, &reference), 0, "{spec} {set}");
        }
    }
}

/// The bunny (about 0.15 across) far from the origin (at 1e3, where f32's ulp is 6e-5, and at
/// -3e5 scaled by 1e4), tiny (1e-6) and huge (1e30): grids whose steps are near f32's ulp, and
/// exponents far from 127.
#[test]
fn a_far_tiny_or_huge_bunny_keeps_its_hits() {
    let base = bunny();
    for (scale, offset) in [(1.0f32, 1e3f32), (1e4, -3e5), (1e-6, 0.0), (1e30, 0.0)] {
        let pos: Vec<[f32; 3]> = base.positions.iter().map(|p| p.map(|c| c * scale + offset)).collect();
        let mesh = Mesh::from_triangles(pos, base.triangles.clone());
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("scale {scale} offset {offset}: {e}"));
        let w8 = WideBvh::<8>::collapse(&bvh);
        check_every_plane(&cw, &w8);
        let rays = random_rays(&mesh.bounds(), 3000, 5);
        let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
        assert!(reference.iter().filter(|h| h.is_hit()).count() > 100);
        assert_eq!(disagreements(&mesh, &cw, &rays, &reference), 0, "scale {scale} offset {offset}");
    }
}

#[test]
fn boxes_shrunk_by_four_steps_are_caught_and_lose_hits() {
    let mesh = bunny();
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let good = CwBvh::build(&bvh).unwrap();
    let rays = random_rays(&mesh.bounds(), 4000, 11);
    let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
    assert_eq!(disagreements(&mesh, &good, &rays, &reference), 0);
    // Every child of the root loses four grid steps on every plane.
    let mut bad = good.clone();
    let n = &mut bad.nodes[0];
    let present: Vec<usize> = (0..CW_WIDTH).filter(|&s| n.is_present(s)).collect();
    for s in present {
        for q in [&mut n.q_lo_x, &mut n.q_lo_y, &mut n.q_lo_z] {
            q[s] = q[s].saturating_add(4);
        }
        for q in [&mut n.q_hi_x, &mut n.q_hi_y, &mut n.q_hi_z] {
            q[s] = q[s].saturating_sub(4);
        }
    }
    let e = bad.validate(&bvh, &mesh).expect_err("a shrunk box must be caught");
    assert!(e.contains("decoded"), "{e}");
    let lost = (0..rays.len()).filter(|&i| trace(&mesh, &bad, &rays[i], false).0 != reference[i]).count();
    assert!(lost > 0, "boxes shrunk by four steps should hide some closest hits");
}

/// Mean per ray.
fn mean(steps: &[WideSteps], f: impl Fn(&WideSteps) -> u32) -> f64 {
    steps.iter().map(|s| f(s) as f64).sum::<f64>() / steps.len().max(1) as f64
}

#[test]
fn cwbvh_memory_and_cost_beside_the_wide_trees() {
    let mesh = bunny();
    for leaf in [1, 4, 8, 16] {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        let o = &bvh.options;
        let tris = bvh.triangle_count() as f64;
        let binary = bvh.stats();
        let w4 = WideBvh::<4>::collapse(&bvh);
        let w8 = WideBvh::<8>::collapse(&bvh);
        let (s4, s8) = (w4.stats(o), w8.stats(o));
        let cws: Vec<_> =
            [SlotOrder::Greedy, SlotOrder::Exact].iter().map(|&h| CwBvh::build_with(&bvh, h).unwrap()).collect();
        let cs = cws[0].stats(o);
        eprintln!(
            "bunny leaf {leaf:>2}, {tris} triangles: node bytes per triangle bvh2 {:.1} (32 B x {}), bvh4 {:.1} (128 B x {}), bvh8 {:.1} (256 B x {}), cwbvh {:.1} (80 B x {} + leaf table 4 B x {}); cwbvh / bvh8 {:.2}",
            binary.node_bytes as f64 / tris,
            binary.nodes,
            s4.node_bytes_per_triangle,
            s4.nodes,
            s8.node_bytes_per_triangle,
            s8.nodes,
            cs.bytes_per_triangle,
            cs.nodes,
            cs.leaves,
            cs.bytes_per_triangle / s8.node_bytes_per_triangle
        );
        eprintln!(
            "  SAH: bvh2 {:.3}, bvh4 {:.3}, bvh8 {:.3}, cwbvh (decoded boxes) {:.3} (+{:.2}%); stack bound bvh8 {} cwbvh {}; build {:.1} ms (exact slots {:.1} ms)",
            binary.sah_cost,
            s4.sah_cost,
            s8.sah_cost,
            cs.sah_cost,
            100.0 * (cs.sah_cost / s8.sah_cost - 1.0),
            s8.stack_bound,
            cs.stack_bound,
            cs.build_ms,
            cws[1].build_seconds * 1e3,
        );
        // What the format is for: a fraction of the uncompressed 8-wide tree's memory, at the
        // price of boxes a little larger than the true ones (never smaller).
        assert_eq!((cs.nodes, cs.leaves), (s8.nodes, s8.leaves));
        assert!(cs.bytes_per_triangle < 0.4 * s8.node_bytes_per_triangle);
        assert!(cs.sah_cost >= s8.sah_cost * (1.0 - 1e-12), "quantized boxes contain the true ones");
        assert!(
            cs.sah_cost < s8.sah_cost * 1.25,
            "8-bit planes should cost little: {} vs {}",
            cs.sah_cost,
            s8.sah_cost
        );
        if leaf != 4 {
            continue;
        }
        for (set, rays) in ray_sets(&mesh, &bvh, 20000) {
            let wide = |w: &WideBvh<8>| -> Vec<WideSteps> {
                let t = |r: &Ray, id: u32, tmax| {
                    intersect(&Ray64 { tmax, ..Ray64::from(r) }, mesh.vertices_f64(id as usize))
                };
                rays.iter().map(|r| w.trace(r, false, |id, tmax| t(r, id, tmax)).1).collect()
            };
            let s8: Vec<_> = wide(&w8);
            let mut rows = vec![("bvh8", s8)];
            for (cw, name) in cws.iter().zip(["cwbvh greedy", "cwbvh exact"]) {
                rows.push((name, rays.iter().map(|r| trace(&mesh, cw, r, false).1).collect()));
            }
            let plain = CwBvh::build_with(&bvh, SlotOrder::Plain).unwrap();
            rows.push(("cwbvh plain", rays.iter().map(|r| trace(&mesh, &plain, r, false).1).collect()));
            for (name, s) in &rows {
                eprintln!(
                    "  {set:>7} {name:>12}: nodes {:>5.2}, boxes {:>6.2}, leaves {:>5.2}, triangles {:>5.2} per ray; stack peak {}",
                    mean(s, |x| x.nodes),
                    mean(s, |x| x.boxes),
                    mean(s, |x| x.leaves),
                    mean(s, |x| x.triangles),
                    s.iter().map(|x| x.stack_peak).max().unwrap_or(0)
                );
            }
        }
    }
}

/// Adversarial boxes through the public quantizer: every child of a parent grid, after
/// [`trilab::bvh::cwbvh::quantize_axis`], decodes (both ways) to planes around it.
#[test]
fn adversarial_children_decode_around_their_boxes() {
    use trilab::bvh::cwbvh::{axis_grid, decode_plane, quantize_axis};
    let cases: Vec<Vec<(f32, f32)>> = vec![
        // Magnitudes far apart: p = -2^66, a child just below 0 (f64's lo - p rounds to 2^66).
        vec![(-(2f32.powi(66)), -1.0), (-1e-20, 1e-20), (3.0, 2f32.powi(60))],
        vec![(-1e20, -1e19), (-1e-30, -1e-30), (1e-30, 1e-30), (5e19, 1e20)],
        // Huge and at the top of f32.
        vec![(-3e38, -1e38), (1e38, 3.4e38)],
        vec![(1e20, 1e20), (1e20, 1.0000001e20)],
        // Tiny boxes, subnormals, zero extent, negative zero.
        vec![(1e-40, 2e-40), (-1e-42, 1e-42), (0.0, 0.0)],
        vec![(-0.0, 0.0), (0.0, 1e-45)],
        vec![(-1.5 * f32::MIN_POSITIVE, -0.5 * f32::MIN_POSITIVE), (f32::MIN_POSITIVE, f32::MIN_POSITIVE)],
        // Flat boxes far out.
        vec![(-7.25e9, -7.25e9), (-7.25e9, -7.2499994e9)],
        vec![(123.456, 123.456)],
    ];
    let mut rng = Lcg(3);
    let mut fuzz = vec![];
    for _ in 0..3000 {
        let centre = (rng.next() - 0.5) * 10f32.powi((rng.next() * 76.0) as i32 - 38);
        let size = 10f32.powi((rng.next() * 80.0) as i32 - 45);
        let kids: Vec<(f32, f32)> = (0..1 + (rng.next() * 8.0) as usize)
            .map(|_| {
                let a = centre + (rng.next() - 0.5) * size;
                let b = if rng.next() < 0.2 { a } else { centre + (rng.next() - 0.5) * size };
                (a.min(b), a.max(b))
            })
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect();
        if !kids.is_empty() {
            fuzz.push(kids);
        }
    }
    let mut checked = 0;
    for kids in cases.iter().chain(&fuzz) {
        let lo = kids.iter().map(|k| k.0).fold(f32::INFINITY, f32::min);
        let hi = kids.iter().map(|k| k.1).fold(f32::NEG_INFINITY, f32::max);
        let (p, e) = axis_grid(lo, hi).unwrap_or_else(|| panic!("{kids:?}: no grid"));
        assert!(!p.is_subnormal() && p <= lo && (1..=254).contains(&e));
        for &(a, b) in kids {
            let (ql, qh) = quantize_axis(p, e, a, b).unwrap_or_else(|| panic!("{a} {b} on grid {p} {e}"));
            for d in decode_plane(p, e, ql) {
                assert!(d <= a, "{kids:?}: min {a} decodes to {d} (q {ql}, p {p}, e {e})");
            }
            for d in decode_plane(p, e, qh) {
                assert!(d >= b, "{kids:?}: max {b} decodes to {d} (q {qh}, p {p}, e {e})");
            }
            checked += 1;
        }
    }
    assert!(checked > 10_000, "{checked}");
    // The first case needs the correction: the unchecked floor puts its lo on 0 > -1e-20.
    let (p, e) = axis_grid(-(2f32.powi(66)), 2f32.powi(60)).unwrap();
    assert_eq!((p, e), (-(2f32.powi(66)), 127 + 59));
    let (ql, _) = quantize_axis(p, e, -1e-20, 1e-20).unwrap();
    assert_eq!(ql, 127, "one below the unchecked floor (128, which decodes to 0)");
    assert_eq!(decode_plane(p, e, 128)[0], 0.0);
    // The same through the builder: a mesh whose triangles are the first case's boxes on every
    // axis (plus a triangle spanning the parent), one triangle per leaf.
    let mut pos = vec![];
    let mut tris = vec![];
    for (a, b) in [(-(2f32.powi(66)), -1.0), (-1e-20, 1e-20), (3.0, 2f32.powi(60)), (-1e-30, 1e-30)] {
        let n = pos.len() as u32;
        pos.extend([[a, a, b], [b, a, a], [a, b, b]]);
        tris.push([n, n + 1, n + 2]);
    }
    let mesh = Mesh::from_triangles(pos, tris);
    let bvh = Bvh::build(&mesh, &BuildOptions::new(1));
    let cw = CwBvh::build(&bvh).unwrap();
    cw.validate(&bvh, &mesh).unwrap();
    let rays: Vec<Ray> = (0..200)
        .map(|i| {
            let t = i as f32 / 200.0;
            Ray::new([-1e-20 * t, 1e-20 * (1.0 - t), -(2f32.powi(70))], [1e-22 * (t - 0.5), 0.0, 1.0])
        })
        .collect();
    let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
    assert!(reference.iter().any(|h| h.id == 1), "the rays hit the triangle near 0");
    assert_eq!(disagreements(&mesh, &cw, &rays, &reference), 0);
}
