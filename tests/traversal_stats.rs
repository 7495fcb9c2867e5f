//! The GPU traversal counters (`raycast.<method>.stats`, `glsl/counts.glsl`) against the CPU
//! mirror of the kernel loop (`trilab::traversal::ray_steps`), on the bunny with primary and
//! random rays, for every method.
//!
//! Tolerance: the mirror walks the same f32 slab tests in the same order but tests triangles in
//! f64, so its closest t (which shortens the ray and culls boxes) can differ from the kernel's
//! f32 t on rays within a few ULPs of an edge or a box face. At most 0.1 % of rays may have any
//! counter differ, and the mean nodes visited and triangles tested per ray must agree within
//! 0.5 %. The stats variant must return exactly the closest variant's hits. Observed on
//! lavapipe: at most 1 ray of 40,000 (random) or 43,200 (primary) differs, in any method.

mod common;

use trilab::bvh::{BuildOptions, Bvh};
use trilab::encoding::Method;
use trilab::encoding::Raycast;
use trilab::gpu::{RaycastOptions, TraversalCounts, TraversalSummary};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::{primary_rays, random_rays, Camera, Ray};
use trilab::scene::Mesh;
use trilab::traversal::{ray_steps, ray_steps_with, RaySteps};

/// Most rays whose counts may differ from the mirror's, as a fraction.
const MAX_DIFFERING: f64 = 0.001;
/// Largest relative difference of the mean counters.
const MEAN_TOLERANCE: f64 = 0.005;

/// How GPU counts compare with the mirror's; `Err` says why they do not agree.
fn check(method: Method, gpu: &[TraversalCounts], cpu: &[RaySteps]) -> Result<String, String> {
    assert_eq!(gpu.len(), cpu.len());
    let differing: Vec<usize> = (0..gpu.len())
        .filter(|&i| (gpu[i].inner, gpu[i].leaves, gpu[i].triangles) != (cpu[i].inner, cpu[i].leaves, cpu[i].triangles))
        .collect();
    let n = gpu.len() as f64;
    let mean = |f: &dyn Fn(usize) -> u32| (0..gpu.len()).map(|i| f(i) as f64).sum::<f64>() / n;
    let (gpu_nodes, cpu_nodes) = (mean(&|i| gpu[i].nodes()), mean(&|i| cpu[i].iterations()));
    let (gpu_tris, cpu_tris) = (mean(&|i| gpu[i].triangles), mean(&|i| cpu[i].triangles));
    let line = format!(
        "{method:>9}: {} of {} rays differ; nodes/ray GPU {gpu_nodes:.3} CPU {cpu_nodes:.3}, \
         triangles/ray GPU {gpu_tris:.3} CPU {cpu_tris:.3}",
        differing.len(),
        gpu.len()
    );
    let rel = |a: f64, b: f64| (a - b).abs() / b.max(1e-12);
    if differing.len() as f64 > MAX_DIFFERING * n
        || rel(gpu_nodes, cpu_nodes) > MEAN_TOLERANCE
        || rel(gpu_tris, cpu_tris) > MEAN_TOLERANCE
    {
        let first: Vec<_> = differing.iter().take(3).map(|&i| (i, gpu[i], cpu[i])).collect();
        return Err(format!("{line}; first differing (ray, GPU, CPU): {first:?}"));
    }
    // Slots: whole primitives, padding included.
    let group = method.group_size() as u32;
    for (i, c) in gpu.iter().enumerate() {
        let ok = if group == 1 {
            c.slots == c.triangles
        } else {
            c.slots % group == 0 && c.slots >= c.triangles && c.slots - c.triangles <= (group - 1) * c.leaves
        };
        if !ok {
            return Err(format!(
                "{method}: ray {i}: slots {} for {} triangles in {} leaves",
                c.slots, c.triangles, c.leaves
            ));
        }
    }
    Ok(line)
}

fn same_bits(a: &[trilab::rays::Hit], b: &[trilab::rays::Hit]) -> usize {
    a.iter().zip(b).filter(|(x, y)| bytemuck::bytes_of(*x) != bytemuck::bytes_of(*y)).count()
}

#[test]
fn gpu_counts_match_the_cpu_mirror_on_the_bunny() {
    let (lines, failures) = common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let camera = Camera::framing(&mesh.bounds());
        let ray_sets: [(&str, Vec<Ray>); 2] =
            [("primary", primary_rays(&camera, 240, 180)), ("random", random_rays(&mesh.bounds(), 40_000, 77))];
        let mut lines = vec![];
        let mut failures = vec![];
        // Leaf size 7: leaves of 5-7 triangles, so the Quad methods test padding slots.
        for leaf in [4, 7] {
            let host = HostScene::build("bunny", &mesh, &BuildOptions::new(leaf)).unwrap();
            for (kind, rays) in &ray_sets {
                let cpu = ray_steps(&mesh, &host.bvh, rays);
                let cpu_conservative = ray_steps_with(&mesh, &host.bvh, rays, true);
                for method in Method::ALL {
                    let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
                    let opts = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
                    let stats = scene.cast(ctx, Raycast::Stats, rays, &opts).unwrap();
                    let (hits, counts) = (stats.hits, stats.traversal.expect("the stats kernel writes counters"));
                    let closest = scene.cast(ctx, Raycast::Closest, rays, &opts).unwrap();
                    assert!(closest.traversal.is_none(), "the closest variant writes no counters");
                    let hits_differing = same_bits(&hits, &closest.hits);
                    if hits_differing > 0 {
                        failures
                            .push(format!("{method} leaf {leaf} {kind}: {hits_differing} hits differ from closest"));
                    }
                    let summary = TraversalSummary::of(&counts);
                    // Not vacuous: the rays do real work.
                    assert!(
                        summary.nodes.mean > 3.0 && summary.triangles.mean > 1.0 && summary.nodes.max > 20,
                        "{summary:?}"
                    );
                    let mirror = if method.conservative_traversal() { &cpu_conservative } else { &cpu };
                    match check(method, &counts, mirror) {
                        Ok(l) => lines.push(format!("leaf {leaf} {kind:>7} {l}; max nodes {}", summary.nodes.max)),
                        Err(e) => failures.push(format!("leaf {leaf} {kind}: {e}")),
                    }
                }
            }
        }
        (lines, failures)
    });
    for l in &lines {
        println!("{l}");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The comparison itself detects wrong counts: GPU counts for a leaf-4 tree are rejected
/// against the mirror of a leaf-8 tree, and a single counter off by one on 1 % of rays fails.
#[test]
fn the_check_rejects_counts_of_another_tree() {
    let counts = common::with_gpu(300, |ctx| {
        let mesh = common::bunny();
        let rays = random_rays(&mesh.bounds(), 5_000, 3);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let (_, counts) = common::cast_stats(ctx, Method::Mt, &mesh, &bvh, &rays);
        (mesh, rays, bvh, counts)
    });
    let (mesh, rays, bvh, gpu) = counts;
    let cpu = ray_steps(&mesh, &bvh, &rays);
    check(Method::Mt, &gpu, &cpu).expect("same tree agrees");
    let other = ray_steps(&mesh, &Bvh::build(&mesh, &BuildOptions::new(8)), &rays);
    assert!(check(Method::Mt, &gpu, &other).is_err());
    let mut off = gpu.clone();
    for c in off.iter_mut().step_by(100) {
        c.inner += 1;
    }
    assert!(check(Method::Mt, &off, &cpu).is_err());
}

/// Exact counts on a hand-built tree: a root over two leaves of two triangles each.
#[test]
fn hand_counted_tree() {
    let mut pos = vec![];
    let mut tris = vec![];
    for (x, z) in [(0.0f32, 0.0f32), (100.0, 10.0)] {
        let b = pos.len() as u32;
        pos.extend([[x, 0.0, z], [x + 1.0, 0.0, z], [x + 1.0, 1.0, z], [x, 1.0, z]]);
        tris.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
    }
    let mesh = Mesh::from_triangles(pos, tris);
    let bvh = Bvh::build(&mesh, &BuildOptions::new(2));
    assert_eq!(bvh.nodes.len(), 3);
    // The first ray hits the first square; the second misses the root box.
    let rays = [Ray::new([0.3, 0.2, -1.0], [0.0, 0.0, 1.0]), Ray::new([50.0, 50.0, -1.0], [0.0, 0.0, 1.0])];
    let out = common::with_gpu(300, move |ctx| {
        Method::ALL.iter().map(|&m| (m, common::cast_stats(ctx, m, &mesh, &bvh, &rays))).collect::<Vec<_>>()
    });
    for (m, (hits, counts)) in out {
        assert!(hits[0].is_hit() && !hits[1].is_hit(), "{m}");
        // Root (inner), then the near leaf with 2 triangles; the far leaf is never entered. Boxes:
        // the root's, then both children's.
        let slots = if m.group_size() == 4 { 4 } else { 2 };
        assert_eq!(counts[0], TraversalCounts { inner: 1, leaves: 1, triangles: 2, slots, boxes: 3, alone: 0 }, "{m}");
        // Only the root box is tested, and missed.
        assert_eq!(counts[1], TraversalCounts { boxes: 1, ..Default::default() }, "{m}");
    }
}
