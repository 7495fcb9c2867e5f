//! The driver's ray tracing (VK_KHR_ray_query through its own BLAS/TLAS) as a peer of our
//! kernels: its hits are checked against the same f64 reference, on the bunny and on a tiny mesh
//! whose answer is known exactly; without ray query every entry point is a clean error.

mod common;

use std::time::Duration;

use trilab::agreement::{compare_any, compare_closest, edge_ulps, AMBIGUITY_ULPS};
use trilab::bvh::{BuildOptions, Bvh};
use trilab::error::Error;
use trilab::gpu::rayquery::{self, raycast_rq};
use trilab::gpu::{AccelStructure, Context, ContextOptions, RaycastOptions, Validation};
use trilab::rays::{primary_rays, random_rays, Camera, Hit, Ray};
use trilab::reference::{brute_force, Reference};
use trilab::scene::Mesh;

const OPTS: RaycastOptions = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 1 << 20 };

/// Fewest rays that must agree with the reference. Measured on lavapipe (Mesa 25.0.7): every
/// ray agrees, on these sets and on 120,000 primary (400x300) and 100,000 random rays (seed 2024):
/// 0 disagreements, 0 invalid. The sets are small because lavapipe's ray query is slow (some
/// 0.3 ms per random ray on 2 cores).
const MIN_AGREEMENT: f64 = 0.999;

fn bunny_rays(mesh: &Mesh) -> Vec<(&'static str, Vec<Ray>)> {
    vec![
        ("primary", primary_rays(&Camera::framing(&mesh.bounds()), 160, 120)),
        ("random", random_rays(&mesh.bounds(), 10_000, 2024)),
    ]
}

#[test]
fn closest_hit_ray_query_agrees_with_the_f64_reference_on_the_bunny() {
    let lines = common::with_gpu(600, |ctx| {
        assert!(ctx.enabled().ray_query, "lavapipe (Mesa 25) has VK_KHR_ray_query; the context must enable it");
        let mesh = common::bunny();
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        let s = accel.stats;
        assert_eq!(s.triangles, mesh.triangle_count() - mesh.degenerate_ids().len());
        assert!(s.blas_bytes > 0 && s.tlas_bytes > 0);
        let mut lines = vec![format!("{s:?}")];
        let kernel = rayquery::kernel(ctx, false).unwrap();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let reference = Reference::new(&mesh, &bvh);
        for (set, rays) in bunny_rays(&mesh) {
            let res = raycast_rq(ctx, &kernel, &accel, &rays, &OPTS).unwrap();
            let a = compare_closest(&mesh, &rays, &res.hits, &reference.trace_all(&rays, false));
            lines.push(format!("{set}: {} ({:.1} ms)", a.summary(), res.time_ms().unwrap().median));
            assert!(a.invalid.is_empty(), "{set}: invalid results {:?}", &a.invalid[..a.invalid.len().min(5)]);
            assert!(a.fraction() >= MIN_AGREEMENT, "{set}: {}", a.summary());
            assert!(a.reference_hits > rays.len() / 5, "{set}: the rays should hit the bunny often");
        }
        lines
    });
    for l in lines {
        println!("{l}");
    }
}

#[test]
fn any_hit_ray_query_agrees_with_the_reference_occlusion() {
    let lines = common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        let closest = rayquery::kernel(ctx, false).unwrap();
        let any = rayquery::kernel(ctx, true).unwrap();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let reference = Reference::new(&mesh, &bvh);
        let mut lines = vec![];
        for (set, rays) in bunny_rays(&mesh) {
            let c = raycast_rq(ctx, &closest, &accel, &rays, &OPTS).unwrap().hits;
            let a = raycast_rq(ctx, &any, &accel, &rays, &OPTS).unwrap().hits;
            // The reference's occlusion answer; any hit it reports must be genuine.
            let occluded: Vec<Hit> = reference.trace_all(&rays, true).iter().map(|h| h.to_hit()).collect();
            let vs_ref = compare_any(&mesh, &rays, &occluded, &a);
            assert!(vs_ref.bogus.is_empty(), "{set}: bogus any-hits {:?}", &vs_ref.bogus[..vs_ref.bogus.len().min(5)]);
            // Occluded or not differs only for rays grazing an edge of the triangle concerned.
            let unexplained: Vec<_> = vs_ref
                .status_mismatch
                .iter()
                .filter(|&&i| {
                    let id = if a[i].is_hit() { a[i].id } else { occluded[i].id };
                    edge_ulps(&mesh, &rays[i], id) > AMBIGUITY_ULPS
                })
                .collect();
            assert!(
                unexplained.is_empty(),
                "{set}: occlusion differs from the reference away from edges: {unexplained:?}"
            );
            // The driver's own closest and any-hit queries run the same triangle tests.
            let vs_closest = compare_any(&mesh, &rays, &c, &a);
            assert!(vs_closest.passes(), "{set}: any-hit vs closest-hit: {vs_closest:?}");
            lines.push(format!(
                "{set}: {} rays, {} occluded, {} differ from the reference (all at edges)",
                rays.len(),
                a.iter().filter(|h| h.is_hit()).count(),
                vs_ref.status_mismatch.len()
            ));
        }
        lines
    });
    for l in lines {
        println!("{l}");
    }
}

#[test]
fn a_ray_at_a_known_triangle_returns_its_obj_id_and_barycentrics() {
    let hits = common::with_gpu(120, |ctx| {
        let mesh = common::tiny_accel_mesh();
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        assert_eq!(accel.stats.triangles, 2);
        let kernel = rayquery::kernel(ctx, false).unwrap();
        let point = |id: usize, u: f32, v: f32| {
            let [a, b, c] = mesh.vertices(id);
            (a * (1.0 - u - v) + b * u + c * v).to_array()
        };
        let toward = |p: [f32; 3], from: [f32; 3]| Ray::new(from, [p[0] - from[0], p[1] - from[1], p[2] - from[2]]);
        let mut rays = vec![
            toward(point(3, 0.2, 0.3), [2.5, 0.5, -1.0]),
            toward(point(1, 0.25, 0.5), [0.1, 0.1, 0.0]),
            toward(point(3, 0.6, 0.1), [3.0, 3.0, 0.5]),
            // Misses: beside everything, an interval ending before triangle 3, an empty interval.
            Ray::new([10.0, 10.0, 0.0], [0.0, 0.0, 1.0]),
            Ray { tmax: 0.5, ..toward(point(3, 0.2, 0.3), [2.5, 0.5, -1.0]) },
            Ray { tmin: 2.0, tmax: 1.0, ..toward(point(1, 0.25, 0.5), [0.1, 0.1, 0.0]) },
        ];
        // The same through many batches of 256: hits do not depend on batching.
        let mut many = rays.clone();
        many.extend(rays.iter().cycle().take(600).copied());
        let res = raycast_rq(ctx, &kernel, &accel, &rays, &OPTS).unwrap().hits;
        let batched =
            raycast_rq(ctx, &kernel, &accel, &many, &RaycastOptions { batch_rays: 256, ..OPTS }).unwrap().hits;
        for (i, h) in batched.iter().enumerate() {
            assert_eq!(h.id, res[i % rays.len()].id, "ray {i} through batches of 256");
        }
        rays.truncate(6);
        (mesh, rays, res)
    });
    let (mesh, rays, res) = hits;
    for (i, (ray, h)) in rays.iter().zip(&res).enumerate() {
        let r = brute_force(&mesh, ray);
        assert_eq!(h.id, r.id, "ray {i}: OBJ id {} against the reference's {}", h.id, r.id);
        if r.is_hit() {
            assert!((h.u as f64 - r.u).abs() <= 1e-5 && (h.v as f64 - r.v).abs() <= 1e-5, "ray {i}: {h:?} vs {r:?}");
            assert!((h.t as f64 - r.t).abs() <= 1e-5 * r.t, "ray {i}: t {} vs {}", h.t, r.t);
        } else {
            assert_eq!(*h, Hit::MISS, "ray {i}");
        }
    }
    assert_eq!([res[0].id, res[1].id, res[2].id], [3, 1, 3]);
    assert!(!res[3].is_hit() && !res[4].is_hit() && !res[5].is_hit());
}

#[test]
fn a_scene_of_only_zero_area_triangles_is_never_hit() {
    let hits = common::with_gpu(120, |ctx| {
        let mesh = Mesh::from_triangles(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], vec![[0, 1, 2], [0, 0, 1]]);
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        assert_eq!(accel.stats.triangles, 0);
        let kernel = rayquery::kernel(ctx, false).unwrap();
        let rays = vec![Ray::new([0.5, 0.0, -1.0], [0.0, 0.0, 1.0]), Ray::new([0.5, 1.0, 0.0], [0.0, -1.0, 0.0])];
        raycast_rq(ctx, &kernel, &accel, &rays, &OPTS).unwrap().hits
    });
    assert!(hits.iter().all(|h| *h == Hit::MISS), "{hits:?}");
}

#[test]
fn without_ray_query_every_entry_point_is_an_error_not_a_panic() {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let ctx =
            Context::new(&ContextOptions { validation: Validation::Required, ray_query: false, ..Default::default() })
                .expect("a Vulkan device and the validation layer");
        assert!(!ctx.enabled().ray_query);
        let log = ctx.validation_log();
        // The structure itself is refused only without the ray tracing pipeline too
        // (tests/rtpipeline.rs); the ray-query kernel is refused here.
        let kernel = rayquery::kernel(&ctx, false).err();
        let message = kernel.as_ref().map(|e| e.to_string());
        let unsupported = matches!(kernel, Some(Error::Unsupported(_)));
        drop(ctx);
        let _ = tx.send((message, unsupported, log.messages()));
    });
    let (message, unsupported, messages) =
        rx.recv_timeout(Duration::from_secs(60)).expect("the unsupported path must return, not hang or panic");
    let message = message.expect("rayquery::kernel must fail without ray query");
    assert!(message.starts_with("ray query: unsupported on "), "{message}");
    assert!(unsupported, "rayquery::kernel must return Error::Unsupported");
    assert!(messages.is_empty(), "{messages:?}");
}
