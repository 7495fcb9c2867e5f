//! The cwbvh layout on the GPU (`glsl/layout/cwbvh.glsl`, Ylitie et al.'s compressed 8-wide
//! nodes; host side `bvh::cwbvh`), validation on:
//! - for every intersector, on the bunny's primary, diffuse and random rays, the cwbvh kernel's
//!   closest hits equal the binary kernel's ray for ray (but for ties: two triangles at exactly
//!   the same t, where the kernel keeps the later one it visits, and cwbvh's visiting order is
//!   the octant's, not bvh2's near to far; at most 1 ray in 1000) and pass the f64 agreement
//!   rule; its
//!   any-hit answers agree with the binary kernel's on occlusion;
//! - `watertight` on cwbvh does not leak: rays from inside closed meshes (the accuracy harness's
//!   generators and aims: vertices, shared edges, random directions), placed at scales 1e-6 .. 1e6
//!   and moved as far as 1e7 from the origin, where the quantized grids' steps come down to a few
//!   ulps, all hit, closest and any-hit, as on bvh2. Möller–Trumbore's leaks on the same rays are
//!   counted beside them (the rays can find a leak).

mod common;

use glam::{DVec3, Vec3};
use trilab::bvh::{BuildOptions, Bvh};
use trilab::commands::accuracy::closed::{
    icosphere, perturbed_sphere, subdivided_cube, winding_number, ClosedMesh, Placement,
};
use trilab::commands::accuracy::probes::{leak_rays, LeakKind};
use trilab::commands::accuracy::rng::Rng;
use trilab::encoding::{Layout, Method, Raycast};
use trilab::named::Named;
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::Ray;
use trilab::services::rayset::{ray_sets, RaySetSizes};
use trilab::services::validate::validate_hits;

const SIZES: RaySetSizes = RaySetSizes { width: 96, height: 72, diffuse_per_hit: 2, random_rays: 20_000, seed: 5 };

#[test]
fn cwbvh_hits_equal_bvh2_for_every_intersector() {
    let lines = common::with_gpu(1500, |ctx| {
        let mesh = common::bunny();
        let mut lines = vec![];
        let mut total_ties = 0;
        for (leaf, methods) in [(4, Method::ALL.to_vec()), (1, vec![Method::Mt, Method::Watertight, Method::QuadUnit])]
        {
            let host = HostScene::build("bunny", &mesh, &BuildOptions::new(leaf)).unwrap();
            let reference = host.reference();
            let sets = ray_sets(&mesh, "bunny", &reference, &SIZES, None).unwrap();
            for &method in &methods {
                let bvh2 = host.upload(ctx, &SceneRequest::new(method)).unwrap();
                let cw = host.upload(ctx, &SceneRequest::new(method).layout(Layout::Cwbvh)).unwrap();
                assert_eq!(cw.layout, Layout::Cwbvh);
                assert!(cw.kernel_source(Raycast::Closest).unwrap().name.ends_with(".closest_cwbvh"));
                for (set, rays) in &sets {
                    let ref_hits = reference.trace_all(rays, false);
                    let hits = ref_hits.iter().filter(|h| h.is_hit()).count();
                    assert!(hits * 20 >= rays.len(), "{set}: too few hits to test ({hits} of {})", rays.len());
                    let h2 = bvh2.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
                    let hc = cw.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
                    let agreement = validate_hits(&mesh, rays, &hc, &ref_hits)
                        .unwrap_or_else(|e| panic!("leaf {leaf} {method} {set} cwbvh: {e}"));
                    // Equal ray for ray, except ties: two triangles at exactly the same t (a
                    // shared edge or vertex), of which the leaf loop keeps the later one visited
                    // (leaf.glsl), and cwbvh visits in octant order, not near to far.
                    let differ: Vec<usize> = (0..rays.len()).filter(|&i| h2[i] != hc[i]).collect();
                    let (ties, other): (Vec<usize>, Vec<usize>) =
                        differ.iter().partition(|&&i| h2[i].t.to_bits() == hc[i].t.to_bits() && h2[i].is_hit());
                    assert!(
                        other.is_empty(),
                        "leaf {leaf} {method} {set}: {} of {} rays differ between bvh2 and cwbvh, e.g. ray {:?}: {:?} vs {:?}",
                        other.len(),
                        rays.len(),
                        other.first().map(|&i| rays[i]),
                        other.first().map(|&i| h2[i]),
                        other.first().map(|&i| hc[i])
                    );
                    assert!(ties.len() * 1000 <= rays.len(), "leaf {leaf} {method} {set}: {} ties", ties.len());
                    total_ties += ties.len();
                    // Occlusion: the any-hit kernels agree with each other (and so with the
                    // binary kernel's closest hits, up to the agreement rule's allowance).
                    let a2 = bvh2.cast(ctx, Raycast::Any, rays, &common::ONCE).unwrap().hits;
                    let ac = cw.cast(ctx, Raycast::Any, rays, &common::ONCE).unwrap().hits;
                    let occl = (0..rays.len()).filter(|&i| a2[i].is_hit() != ac[i].is_hit()).count();
                    assert!(occl <= rays.len() / 10_000, "leaf {leaf} {method} {set}: {occl} rays' occlusion differs");
                    let vs_closest = (0..rays.len()).filter(|&i| ac[i].is_hit() != hc[i].is_hit()).count();
                    assert!(
                        vs_closest <= rays.len() / 10_000,
                        "leaf {leaf} {method} {set}: any vs closest {vs_closest}"
                    );
                    lines.push(format!("leaf {leaf} {method:>13} {set:>7}: cwbvh {}", agreement.summary()));
                }
            }
        }
        lines.push(format!("hits at an equal t resolved to another triangle than bvh2's: {total_ties} rays"));
        lines
    });
    println!("{}", lines.join("\n"));
}

/// Rays from `origin` (inside `mesh`): the harness's three aims, `n` each.
fn leak_set(mesh: &trilab::scene::Mesh, origin: Vec3, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Rng::new(seed);
    LeakKind::ALL.iter().flat_map(|&k| leak_rays(mesh, &[origin], k, n, &mut rng)).collect()
}

#[test]
fn watertight_on_cwbvh_does_not_leak() {
    let (leaks, mt_leaks, rays) = common::with_gpu(1500, |ctx| {
        let shapes: Vec<ClosedMesh> = vec![icosphere(3), subdivided_cube(8), perturbed_sphere(16, 32, 0.05, 11)];
        let (mut leaks, mut mt_leaks, mut total) = (vec![], 0usize, 0usize);
        for shape in &shapes {
            for scale in [1e-6, 1.0, 1e6] {
                for shift in [0.0, 1e3, 1e7] {
                    let offset = DVec3::new(1.0, 0.61, -0.37) * shift;
                    let mesh = shape.to_mesh(Placement { scale, translate: offset });
                    let origin = (shape.centre * scale + offset).as_vec3();
                    // Still closed around the f32 origin after rounding (else skipped).
                    let w = winding_number(&mesh, origin.as_dvec3());
                    if !mesh.degenerate_ids().is_empty() || (w.abs() - 1.0).abs() > 1e-6 {
                        continue;
                    }
                    let rays = leak_set(&mesh, origin, 1500, (scale.log10() as i64 * 31 + shift as i64) as u64 ^ 7);
                    for leaf in [1, 4] {
                        let host = HostScene::with_bvh("leak", &mesh, Bvh::build(&mesh, &BuildOptions::new(leaf)));
                        for method in [Method::Watertight, Method::Mt] {
                            for layout in [Layout::Cwbvh, Layout::Bvh2] {
                                let scene = host.upload(ctx, &SceneRequest::new(method).layout(layout)).unwrap();
                                for kind in [Raycast::Closest, Raycast::Any] {
                                    let hits = scene.cast(ctx, kind, &rays, &common::ONCE).unwrap().hits;
                                    let missed = hits.iter().filter(|h| !h.is_hit()).count();
                                    if method == Method::Mt {
                                        mt_leaks += missed;
                                    } else if missed > 0 {
                                        leaks.push(format!(
                                            "{} scale {scale:e} shift {shift:e} leaf {leaf} {layout} {}: {missed} of {} rays leak",
                                            shape.name,
                                            kind.name(),
                                            rays.len()
                                        ));
                                    }
                                }
                            }
                        }
                    }
                    total += rays.len();
                }
            }
        }
        (leaks, mt_leaks, total)
    });
    println!("{rays} leak rays per configuration set; mt (bvh2 + cwbvh, closest + any) leaked {mt_leaks}");
    assert!(rays > 50_000, "{rays}");
    assert!(leaks.is_empty(), "watertight leaks:\n{}", leaks.join("\n"));
}
