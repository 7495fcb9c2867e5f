//! Rays and scenes at the edges of the contract: axis-parallel rays, origins inside the mesh,
//! rays that miss the scene box, ray intervals that end before the surface or start after it,
//! unnormalised directions, degenerate triangles, a BVH at the depth limit, and batching.
//! Every GPU result is checked against the f64 reference.

mod common;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use trilab::agreement::{compare_any, compare_closest};
use trilab::bvh::{BuildOptions, Bvh, MAX_DEPTH};
use trilab::encoding::Method;
use trilab::encoding::Raycast;
use trilab::gpu::{Context, RaycastOptions};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::{Hit, Ray};
use trilab::reference::Reference;
use trilab::scene::Mesh;

/// Runs closest and any hit for each method and leaf size; returns (method, leaf, closest hits)
/// and panics with every failure against the reference.
fn check(
    ctx: &Context,
    mesh: &Mesh,
    rays: &[Ray],
    leaf_sizes: &[u32],
    batch_rays: usize,
) -> Vec<(Method, u32, Vec<Hit>)> {
    let mut out = vec![];
    let mut failures = vec![];
    for &leaf in leaf_sizes {
        let host = HostScene::build("edge case", mesh, &BuildOptions::new(leaf)).unwrap();
        host.bvh.validate(mesh).unwrap();
        let reference = host.reference().trace_all(rays, false);
        for method in Method::ALL {
            let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
            let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays };
            let c = scene.cast(ctx, Raycast::Closest, rays, &opts).unwrap();
            let a = scene.cast(ctx, Raycast::Any, rays, &opts).unwrap();
            let agreement = compare_closest(mesh, rays, &c.hits, &reference);
            // Small ray sets: every ray must agree or be explained by an edge.
            if agreement.unexplained > 0 || !agreement.invalid.is_empty() {
                failures.push(format!(
                    "{method} leaf {leaf}: {} {:?} {:?}",
                    agreement.summary(),
                    agreement.disagreements,
                    agreement.invalid
                ));
            }
            let any_check = compare_any(mesh, rays, &c.hits, &a.hits);
            if !any_check.passes() {
                failures.push(format!("{method} leaf {leaf} any-hit: {any_check:?}"));
            }
            out.push((method, leaf, c.hits));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    out
}

#[test]
fn axis_parallel_rays() {
    common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let b = mesh.bounds();
        let mut rays = vec![];
        let n = 24;
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let mut dir = [0.0f32; 3];
                dir[axis] = sign;
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                for i in 0..n {
                    for j in 0..n {
                        let mut o = b.center().to_array();
                        o[u] = b.min[u] + (b.max[u] - b.min[u]) * (i as f32 + 0.5) / n as f32;
                        o[v] = b.min[v] + (b.max[v] - b.min[v]) * (j as f32 + 0.5) / n as f32;
                        o[axis] = if sign > 0.0 { b.min[axis] - 0.1 } else { b.max[axis] + 0.1 };
                        rays.push(Ray::new(o, dir));
                        // The same ray with -0.0 in the zero components.
                        let mut nd = dir;
                        nd[u] = -0.0;
                        nd[v] = -0.0;
                        rays.push(Ray::new(o, nd));
                        // And starting inside the box (on the centre plane).
                        o[axis] = b.center()[axis];
                        rays.push(Ray::new(o, dir));
                    }
                }
            }
        }
        let results = check(ctx, &mesh, &rays, &[1, 4, 16], 1 << 20);
        let hits = results[0].2.iter().filter(|h| h.is_hit()).count();
        assert!(hits > rays.len() / 4, "axis-parallel rays should hit the bunny often ({hits}/{})", rays.len());
    });
}

#[test]
fn rays_starting_inside_the_mesh_and_box() {
    common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let b = mesh.bounds();
        let mut rng = Pcg32::seed_from_u64(5);
        let rays: Vec<Ray> = (0..20_000)
            .map(|_| {
                let o = b.min + b.extent() * Vec3::new(rng.random(), rng.random(), rng.random());
                let d = Vec3::new(rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5, rng.random::<f32>() - 0.5);
                Ray::new(o.to_array(), d.to_array())
            })
            .collect();
        check(ctx, &mesh, &rays, &[1, 4, 16], 1 << 20);
    });
}

#[test]
fn rays_missing_the_scene_box_and_empty_intervals_always_miss() {
    common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let b = mesh.bounds();
        let c = b.center();
        let far = b.extent().length() * 2.0;
        let mut rays = vec![];
        for k in 0..200 {
            let a = k as f32 * 0.1;
            let dir = Vec3::new(a.cos(), (a * 0.7).sin(), a.sin()).normalize();
            // Outside the box, pointing away from it.
            rays.push(Ray::new((c + dir * far).to_array(), dir.to_array()));
            // Passing the box by: offset sideways, parallel to a face.
            rays.push(Ray::new([b.max.x + 0.01, c.y, c.z - far], [0.0, 0.0, 1.0]));
            // Through the scene, but with tmin > tmax.
            let mut r = Ray::new((c - dir * far).to_array(), dir.to_array());
            r.tmin = 2.0 * far;
            r.tmax = far;
            rays.push(r);
        }
        for (method, leaf, hits) in check(ctx, &mesh, &rays, &[4], 1 << 20) {
            let n = hits.iter().filter(|h| h.is_hit()).count();
            assert_eq!(n, 0, "{method} leaf {leaf}: {n} hits on rays that cannot hit");
            assert!(hits.iter().all(|h| *h == Hit::MISS), "{method}: misses must be (inf, 0xFFFFFFFF, 0, 0)");
        }
    });
}

#[test]
fn ray_interval_before_and_after_the_surface() {
    common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let base = trilab::rays::random_rays(&mesh.bounds(), 4000, 99);
        let reference = Reference::new(&mesh, &bvh).trace_all(&base, false);
        let mut rays = vec![];
        for (r, h) in base.iter().zip(&reference).filter(|(_, h)| h.is_hit()).take(1000) {
            let t = h.t as f32;
            // tmax ends well before the surface: must miss.
            rays.push(Ray { tmax: 0.5 * t, ..*r });
            // tmax just past it: must hit.
            rays.push(Ray { tmax: t * 1.001, ..*r });
            // tmin past the first surface: the next one or nothing.
            rays.push(Ray { tmin: t * 1.001, ..*r });
            // Direction scaled by 3: t in units of the direction's length.
            rays.push(Ray { dir: [r.dir[0] * 3.0, r.dir[1] * 3.0, r.dir[2] * 3.0], ..*r });
        }
        for (method, _, hits) in check(ctx, &mesh, &rays, &[1, 4, 16], 1 << 20) {
            for (i, h) in hits.chunks_exact(4).enumerate() {
                assert!(!h[0].is_hit(), "{method}: hit before tmax ended (ray {i})");
                assert!(h[1].is_hit(), "{method}: missed with tmax just past the surface (ray {i})");
                assert!(h[2].t > h[1].t || !h[2].is_hit(), "{method}: tmin ignored (ray {i})");
                let rel = (h[3].t * 3.0 - h[1].t).abs() / h[1].t;
                assert!(rel < 1e-5, "{method}: t not in units of the direction length ({} vs {})", h[3].t, h[1].t);
            }
        }
    });
}

#[test]
fn degenerate_triangles_are_never_hit() {
    common::with_gpu(600, |ctx| {
        // A 20 x 20 grid of unit squares in z = 0 (two triangles each), with degenerate
        // triangles interleaved: collinear (on the grid lines) and repeated-vertex ones.
        let mut pos = vec![];
        let mut tris = vec![];
        let mut degenerate = vec![];
        for i in 0..20 {
            for j in 0..20 {
                let (x, y) = (i as f32, j as f32);
                let b = pos.len() as u32;
                pos.extend([
                    [x, y, 0.0],
                    [x + 1.0, y, 0.0],
                    [x + 1.0, y + 1.0, 0.0],
                    [x, y + 1.0, 0.0],
                    [x + 0.5, y, 0.0],
                ]);
                tris.push([b, b + 1, b + 2]);
                degenerate.push(tris.len() as u32);
                tris.push([b, b + 4, b + 1]); // collinear along the bottom edge
                tris.push([b, b + 2, b + 3]);
                degenerate.push(tris.len() as u32);
                tris.push([b + 2, b + 2, b + 3]); // repeated vertex
            }
        }
        let mesh = Mesh::from_triangles(pos, tris);
        assert_eq!(mesh.degenerate_ids(), degenerate);
        let mut rays = vec![];
        for i in 0..20 {
            for j in 0..20 {
                let (x, y) = (i as f32, j as f32);
                // Aimed at the degenerate triangles (edge midpoints, vertices) and at interiors.
                for p in [
                    [x + 0.5, y],
                    [x + 0.25, y],
                    [x + 1.0, y + 1.0],
                    [x, y + 1.0],
                    [x + 0.7, y + 0.2],
                    [x + 0.2, y + 0.7],
                ] {
                    rays.push(Ray::new([p[0], p[1], 1.0], [0.0, 0.0, -1.0]));
                    rays.push(Ray::new([p[0] + 0.3, p[1] - 0.2, -1.0], [-0.3, 0.2, 1.0]));
                }
            }
        }
        for (method, leaf, hits) in check(ctx, &mesh, &rays, &[1, 2, 3, 4, 8, 16], 1 << 20) {
            let bad = hits.iter().filter(|h| h.is_hit() && degenerate.contains(&h.id)).count();
            assert_eq!(bad, 0, "{method} leaf {leaf}: {bad} hits on degenerate triangles");
            let n = hits.iter().filter(|h| h.is_hit()).count();
            assert!(n > rays.len() / 2, "{method} leaf {leaf}: rays through the grid should hit ({n}/{})", rays.len());
        }
    });
}

#[test]
fn scene_of_only_degenerate_triangles_misses_everything() {
    common::with_gpu(300, |ctx| {
        let mesh = Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
            vec![[0, 1, 2], [0, 0, 1], [2, 2, 2]],
        );
        let rays: Vec<Ray> = (0..64)
            .map(|i| Ray::new([i as f32 / 32.0, 0.0, 1.0], [0.0, 0.0, -1.0]))
            .chain((0..64).map(|i| Ray::new([-1.0, 0.0, 0.0], [1.0, 0.0, i as f32 * 1e-3])))
            .collect();
        for (method, leaf, hits) in check(ctx, &mesh, &rays, &[1, 4], 1 << 20) {
            assert!(hits.iter().all(|h| *h == Hit::MISS), "{method} leaf {leaf}: a degenerate-only scene was hit");
        }
    });
}

#[test]
fn bvh_at_the_depth_limit_traverses_correctly() {
    common::with_gpu(600, |ctx| {
        // Triangles over f32's whole exponent range, eight per halving of scale, in the planes
        // x = s with y, z in [0, 0.1 s]: binned SAH would nest them ~110 levels deep, and the
        // depth rule stops it at exactly MAX_DEPTH (the stack size).
        let mut pos = vec![];
        let mut tris = vec![];
        for k in 0..2000 {
            let x = (0.5f64).powi(k / 8) as f32 * (1.0 + (k % 8) as f32 * 0.05);
            let b = pos.len() as u32;
            pos.extend([[x, 0.0, 0.0], [x, 0.1 * x, 0.0], [x, 0.0, 0.1 * x]]);
            tris.push([b, b + 1, b + 2]);
        }
        let mesh = Mesh::from_triangles(pos, tris);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(1));
        assert_eq!(bvh.stats().depth, MAX_DEPTH, "the scene must reach the depth limit");
        // Rays through the origin from x < 0, where every nested box meets: with
        // |y0| + |z0| > 0.1 they pass inside the boxes but beside the triangles all the way
        // down (a full-depth traversal that misses); with less they hit the first triangle
        // large enough for f32 to resolve.
        let mut rng = Pcg32::seed_from_u64(17);
        let rays: Vec<Ray> = (0..4000)
            .map(|i| {
                let spread = if i % 2 == 0 { 0.19 } else { 0.09 };
                let y0 = -spread * rng.random::<f32>();
                let z0 = -(spread - y0.abs()) * (0.2 + 0.8 * rng.random::<f32>());
                Ray::new([-1.0, y0, z0], [1.0, -y0, -z0])
            })
            .collect();
        check(ctx, &mesh, &rays, &[1, 4], 1 << 20);
    });
}

#[test]
fn batches_give_the_same_hits_as_one_dispatch() {
    common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let rays = trilab::rays::random_rays(&mesh.bounds(), 10_001, 11);
        let one = check(ctx, &mesh, &rays, &[4], 1 << 20);
        let many = check(ctx, &mesh, &rays, &[4], 256);
        for ((m, _, a), (_, _, b)) in one.iter().zip(&many) {
            assert_eq!(a, b, "{m}: batching changed the hits");
        }
    });
}
