//! The qbvh4 layout on the GPU (`glsl/layout/qbvh4.glsl`: bvh4's tree with 8-bit child planes on
//! a per-node grid; host side `bvh::qbvh4`), validation on. Quantized boxes contain the true ones,
//! so a ray visits a superset of bvh4's nodes and must find the same closest hit:
//! - for every intersector and every traversal that drives qbvh4's step (while-if, the
//!   cooperative kernel, persistent threads), the closest hits equal bvh4 while-if's ray for ray
//!   and pass the f64 agreement rule, on the bunny's primary, diffuse and random rays and on a
//!   scene of extremes (boxes from 1e-9 to 1e12 wide in one tree, flat and sliver triangles, a
//!   cluster at 1e7 from the origin where a grid step is a few ulps), each ray aimed at one
//!   triangle so the small and far ones are hit too;
//! - any-hit answers agree with bvh4's on occlusion.

mod common;

use trilab::agreement::{compare_closest, Agreement};
use trilab::bvh::BuildOptions;
use trilab::encoding::{AccessPath, Layout, Method, Raycast, Traversal};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::{Hit, Ray};
use trilab::reference::RefHit;
use trilab::scene::Mesh;
use trilab::services::rayset::{ray_sets, RaySetSizes};
use trilab::services::validate::validate_hits;

const SIZES: RaySetSizes = RaySetSizes { width: 80, height: 60, diffuse_per_hit: 2, random_rays: 10_000, seed: 13 };

/// Deterministic numbers in [0, 1).
fn rng(seed: u64) -> impl FnMut() -> f32 {
    let mut s = seed;
    move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((s >> 40) as f32) / (1u64 << 24) as f32
    }
}

/// Triangles at extreme scales in one scene, and one ray aimed at each triangle's centroid from
/// three of its sizes away, from both sides.
fn extremes() -> (Mesh, Vec<Ray>) {
    let mut rnd = rng(3);
    let (mut pos, mut tris) = (vec![], vec![]);
    let mut add = |centre: [f32; 3], size: f32, kind: usize, rnd: &mut dyn FnMut() -> f32| {
        let j = |r: &mut dyn FnMut() -> f32| size * (0.5 + r());
        let c = centre;
        let v = match kind {
            // A general triangle.
            0 => [c, [c[0] + j(rnd), c[1], c[2] + 0.3 * j(rnd)], [c[0], c[1] + j(rnd), c[2] - 0.2 * j(rnd)]],
            // Flat in z (a box of zero extent on one axis).
            1 => [c, [c[0] + j(rnd), c[1], c[2]], [c[0], c[1] + j(rnd), c[2]]],
            // In the plane x = const.
            _ => [c, [c[0], c[1] + j(rnd), c[2]], [c[0], c[1], c[2] + j(rnd)]],
        };
        let i = pos.len() as u32;
        pos.extend(v);
        tris.push([i, i + 1, i + 2]);
    };
    // (centre scale, triangle size, count)
    let clusters: [([f32; 3], f32, f32, usize); 5] = [
        ([0.0; 3], 1e-9, 1e-7, 60),
        ([1.0, -2.0, 0.5], 1e-3, 1e-2, 60),
        ([0.0; 3], 1e12, 1e11, 40),
        ([1e7, -1e7, 1e7], 4.0, 64.0, 60),
        ([-5.0, 3.0, 2.0], 0.5, 10.0, 60),
    ];
    for (k, &(offset, size, spread, n)) in clusters.iter().enumerate() {
        for i in 0..n {
            let centre = std::array::from_fn(|a| offset[a] + spread * (rnd() - 0.5));
            add(centre, size, (i + k) % 3, &mut rnd);
        }
    }
    let mesh = Mesh::from_triangles(pos.clone(), tris.clone());
    let mut rays = vec![];
    for t in &tris {
        let v: Vec<[f32; 3]> = t.iter().map(|&i| pos[i as usize]).collect();
        let c: [f32; 3] = std::array::from_fn(|a| (v[0][a] + v[1][a] + v[2][a]) / 3.0);
        let size = (0..3).map(|a| (v[1][a] - v[0][a]).abs().max((v[2][a] - v[0][a]).abs())).fold(0.0, f32::max);
        for _ in 0..3 {
            let d = [rnd() - 0.5, rnd() - 0.5, rnd() - 0.5];
            let len = d.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-3);
            let d = d.map(|x| x / len);
            let o: [f32; 3] = std::array::from_fn(|a| c[a] - 3.0 * size * d[a]);
            rays.push(Ray::new(o, d));
            let o: [f32; 3] = std::array::from_fn(|a| c[a] + 3.0 * size * d[a]);
            rays.push(Ray::new(o, d.map(|x| -x)));
        }
    }
    (mesh, rays)
}

/// The f64 reference's rule: `validate_hits` on the bunny; on the extremes, where the f32
/// intersectors land within an ulp of an edge far more often than on a mesh of ordinary scale
/// (unit's affine map at 1e7 and 1e12), every disagreement explained by an edge or a tie, without
/// the rule's cap on their share.
fn check(mesh: &Mesh, rays: &[Ray], hits: &[Hit], ref_hits: &[RefHit]) -> Result<Agreement, String> {
    if mesh.triangle_count() > 1000 {
        return validate_hits(mesh, rays, hits, ref_hits).map_err(|e| e.to_string());
    }
    let a = compare_closest(mesh, rays, hits, ref_hits);
    if a.all_explained() && a.fraction() > 0.9 {
        Ok(a)
    } else {
        Err(a.summary())
    }
}

#[test]
fn qbvh4_hits_equal_bvh4_for_every_method_and_traversal() {
    let lines = common::with_gpu(1800, |ctx| {
        let bunny = common::bunny();
        let (ext, ext_rays) = extremes();
        let mut lines = vec![];
        for (name, mesh, leaf) in [("bunny", &bunny, 4), ("extremes", &ext, 4), ("extremes", &ext, 1)] {
            let host = HostScene::build(name, mesh, &BuildOptions::new(leaf)).unwrap();
            let reference = host.reference();
            let sets: Vec<(String, Vec<Ray>)> = if name == "bunny" {
                ray_sets(mesh, name, &reference, &SIZES, None)
                    .unwrap()
                    .into_iter()
                    .map(|(s, r)| (s.to_string(), r))
                    .collect()
            } else {
                vec![("aimed".to_owned(), ext_rays.clone())]
            };
            let refs: Vec<_> = sets.iter().map(|(_, rays)| reference.trace_all(rays, false)).collect();
            for ((set, rays), r) in sets.iter().zip(&refs) {
                let hits = r.iter().filter(|h| h.is_hit()).count();
                assert!(hits * 20 >= rays.len(), "{name} {set}: too few hits to test ({hits} of {})", rays.len());
            }
            for method in Method::ALL {
                let bvh4 = host.upload(ctx, &SceneRequest::new(method).layout(Layout::Bvh4)).unwrap();
                for ((set, rays), ref_hits) in sets.iter().zip(&refs) {
                    let base = bvh4.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
                    check(mesh, rays, &base, ref_hits).unwrap_or_else(|e| panic!("{name} {method} {set} bvh4: {e}"));
                    for t in [Traversal::WhileIf, Traversal::Coop, Traversal::Persistent] {
                        assert!(method.traversal_kernel(Raycast::Closest, AccessPath::Texel, Layout::Qbvh4, t).is_ok());
                        let q =
                            host.upload(ctx, &SceneRequest::new(method).layout(Layout::Qbvh4).traversal(t)).unwrap();
                        assert!(q.kernel_source(Raycast::Closest).unwrap().name.ends_with("_qbvh4"));
                        let h = q.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
                        let agreement = check(mesh, rays, &h, ref_hits)
                            .unwrap_or_else(|e| panic!("{name} leaf {leaf} {method} {set} qbvh4 {t}: {e}"));
                        let differ: Vec<usize> = (0..rays.len()).filter(|&i| base[i] != h[i]).collect();
                        assert!(
                            differ.is_empty(),
                            "{name} leaf {leaf} {method} {set} {t}: {} of {} rays differ between bvh4 while-if and qbvh4, e.g. {:?}: {:?} vs {:?}",
                            differ.len(),
                            rays.len(),
                            differ.first().map(|&i| rays[i]),
                            differ.first().map(|&i| base[i]),
                            differ.first().map(|&i| h[i])
                        );
                        lines.push(format!(
                            "{name} leaf {leaf} {method:>13} {set:>7} qbvh4 {t}: {}",
                            agreement.summary()
                        ));
                    }
                    if method == Method::F64 || method == Method::Mt {
                        let q = host.upload(ctx, &SceneRequest::new(method).layout(Layout::Qbvh4)).unwrap();
                        let a4 = bvh4.cast(ctx, Raycast::Any, rays, &common::ONCE).unwrap().hits;
                        let aq = q.cast(ctx, Raycast::Any, rays, &common::ONCE).unwrap().hits;
                        let occl = (0..rays.len()).filter(|&i| a4[i].is_hit() != aq[i].is_hit()).count();
                        assert_eq!(occl, 0, "{name} {method} {set}: occlusion differs from bvh4's on {occl} rays");
                    }
                }
            }
        }
        lines
    });
    println!("{}", lines.join("\n"));
}
