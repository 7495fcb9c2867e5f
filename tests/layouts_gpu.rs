//! Every node layout on the GPU (issue 15): the `*_<layout>` variants of raycast.comp
//! (glsl/layout/<layout>.glsl) over the node buffers the pipeline binds with
//! `SceneRequest::layout`. With validation on, on the bunny and a synthetic soup, with the
//! harness's primary, diffuse and random ray sets, for every method (every kernel is compiled for
//! every intersector: the leaves keep the encoding's units):
//! - closest hits pass the crate's agreement rule against the CPU f64 reference and equal the
//!   binary kernel's hits ray for ray;
//! - any-hit (occlusion) answers equal the reference's (a ray is occluded iff it has a closest
//!   hit) up to the agreement rule's allowance, and the stats kernel's hits equal the closest
//!   kernel's, its counters plausible for the layout's width;
//! - the address path (`*_address`) returns the texel path's hits.
//!
//! `layout_speed_on_the_bunny` (ignored; run it with `--ignored --nocapture`) prints a speed
//! figure: mt on the bunny's three sets, every layout measured side by side, interleaved, GPU
//! timestamps, after a warm-up.

mod common;

use std::path::Path;

use trilab::bvh::BuildOptions;
use trilab::commands::bench::BenchOptions;
use trilab::encoding::{AccessPath, Layout, Method, Raycast, SceneAccess};
use trilab::error::Error;
use trilab::gpu::RaycastOptions;
use trilab::named::Named;
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::report::Summary;
use trilab::scene::{load_obj, Mesh};
use trilab::services::rayset::{ray_sets, RaySetSizes};
use trilab::services::validate::{mrays_summary, validate_hits};

/// Test-sized sets: a 120 x 90 image, two diffuse bounces per hit, 30,000 random rays.
const SIZES: RaySetSizes = RaySetSizes { width: 120, height: 90, diffuse_per_hit: 2, random_rays: 30_000, seed: 7 };

fn check_scene(ctx: &trilab::gpu::Context, name: &str, mesh: &Mesh, leaf: u32, methods: &[Method]) -> Vec<String> {
    let host = HostScene::build(name, mesh, &BuildOptions::new(leaf)).unwrap();
    let reference = host.reference();
    let sets = ray_sets(mesh, name, &reference, &SIZES, None).unwrap();
    let mut lines = vec![];
    for &method in methods {
        let bvh2 = host.upload(ctx, &SceneRequest::new(method)).unwrap();
        let binary: Vec<_> =
            sets.iter().map(|(_, rays)| bvh2.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits).collect();
        for &layout in &Layout::ALL[1..] {
            let wide = host.upload(ctx, &SceneRequest::new(method).layout(layout)).unwrap();
            assert_eq!(wide.layout, layout);
            let suffix = format!(".closest_{layout}");
            assert!(wide.kernel_source(Raycast::Closest).unwrap().name.ends_with(&suffix));
            for ((set, rays), h2) in sets.iter().zip(&binary) {
                assert!(!rays.is_empty(), "{name} {set}: no rays");
                let ref_hits = reference.trace_all(rays, false);
                let hits = ref_hits.iter().filter(|h| h.is_hit()).count();
                assert!(hits * 20 >= rays.len(), "{name} {set}: too few hits to test ({hits} of {})", rays.len());
                let hw = wide.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
                let agreement = validate_hits(mesh, rays, &hw, &ref_hits)
                    .unwrap_or_else(|e| panic!("{name} leaf {leaf} {method} {set} {layout}: {e}"));
                let differ: Vec<usize> = (0..rays.len()).filter(|&i| h2[i] != hw[i]).collect();
                assert!(
                    differ.is_empty(),
                    "{name} leaf {leaf} {method} {set}: {} of {} rays differ between bvh2 and {layout}, e.g. ray {}: {:?} vs {:?}",
                    differ.len(),
                    rays.len(),
                    differ[0],
                    h2[differ[0]],
                    hw[differ[0]]
                );
                lines.push(format!("{name} leaf {leaf} {method:>13} {set:>7}: {layout} {}", agreement.summary()));
            }
        }
    }
    lines
}

/// Any-hit, stats and the address path of every wide layout, for every method, on the bunny's
/// diffuse set (the one with the most rays near surfaces).
fn check_kinds(ctx: &trilab::gpu::Context, mesh: &Mesh) -> Vec<String> {
    let host = HostScene::build("bunny", mesh, &BuildOptions::new(4)).unwrap();
    let reference = host.reference();
    let sets = ray_sets(mesh, "bunny", &reference, &SIZES, None).unwrap();
    let rays = &sets.iter().find(|(s, _)| s.to_string() == "diffuse").unwrap().1;
    let ref_hits = reference.trace_all(rays, false);
    let mut lines = vec![];
    for method in Method::ALL {
        let stats2 = host
            .upload(ctx, &SceneRequest::new(method))
            .unwrap()
            .cast(ctx, Raycast::Stats, rays, &common::ONCE)
            .unwrap();
        let mean = |c: &[trilab::gpu::TraversalCounts], f: fn(&trilab::gpu::TraversalCounts) -> u32| {
            c.iter().map(|x| f(x) as f64).sum::<f64>() / c.len() as f64
        };
        let c2 = stats2.traversal.unwrap();
        for &layout in &Layout::ALL[1..] {
            let scene = host.upload(ctx, &SceneRequest::new(method).layout(layout)).unwrap();
            let closest = scene.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
            // Occlusion: as many disagreements with the reference as the closest kernel has.
            let any = scene.cast(ctx, Raycast::Any, rays, &common::ONCE).unwrap().hits;
            let wrong_any = any.iter().zip(&ref_hits).filter(|(a, r)| a.is_hit() != r.is_hit()).count();
            let wrong_closest = closest.iter().zip(&ref_hits).filter(|(a, r)| a.is_hit() != r.is_hit()).count();
            assert!(
                wrong_any <= wrong_closest + rays.len() / 10_000,
                "{method} {layout}: any-hit answers {wrong_any} rays wrongly, closest {wrong_closest}"
            );
            // Stats: the same hits, and work that a wider node must show.
            let stats = scene.cast(ctx, Raycast::Stats, rays, &common::ONCE).unwrap();
            assert!(
                stats.hits == closest,
                "{method} {layout}: the stats kernel's hits differ from the closest kernel's"
            );
            let c = stats.traversal.unwrap();
            let width = layout.spec().width as f64;
            let (inner, boxes, tris) = (mean(&c, |x| x.inner), mean(&c, |x| x.boxes), mean(&c, |x| x.triangles));
            assert!(
                inner > 0.0 && inner < mean(&c2, |x| x.inner),
                "{method} {layout}: {inner} nodes per ray, bvh2 {}",
                mean(&c2, |x| x.inner)
            );
            assert!(boxes <= inner * width && boxes >= inner, "{method} {layout}: {boxes} boxes for {inner} nodes");
            assert!(
                c.iter().all(|x| x.boxes <= x.inner * layout.spec().width),
                "{method} {layout}: a ray tested more boxes than slots"
            );
            assert!(tris > 0.0, "{method} {layout}: no triangles tested");
            // The address path reads the same nodes.
            let bda = host.upload(ctx, &SceneRequest::new(method).layout(layout).access(SceneAccess::Address)).unwrap();
            assert_eq!(bda.access, AccessPath::Address);
            assert!(bda.kernel_source(Raycast::Closest).unwrap().name.ends_with(&format!(".closest_address_{layout}")));
            let hb = bda.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
            assert!(hb == closest, "{method} {layout}: the address path's hits differ from the texel path's");
            // So does the storage path (issue 38), every kind it has.
            let sb = host.upload(ctx, &SceneRequest::new(method).layout(layout).access(SceneAccess::Storage)).unwrap();
            assert_eq!(sb.access, AccessPath::Storage);
            assert!(sb.kernel_source(Raycast::Closest).unwrap().name.ends_with(&format!(".closest_storage_{layout}")));
            assert!(sb.kernel_source(Raycast::Clock).is_err(), "{method} {layout}: the storage path has no clock");
            let hs = sb.cast(ctx, Raycast::Closest, rays, &common::ONCE).unwrap().hits;
            assert!(hs == closest, "{method} {layout}: the storage path's hits differ from the texel path's");
            let any_storage = sb.cast(ctx, Raycast::Any, rays, &common::ONCE).unwrap().hits;
            assert!(any_storage == any, "{method} {layout}: the storage path's any-hit answers differ");
            let stats_storage = sb.cast(ctx, Raycast::Stats, rays, &common::ONCE).unwrap();
            assert!(
                stats_storage.hits == closest && stats_storage.traversal.as_deref() == Some(&c[..]),
                "{method} {layout}"
            );
            lines.push(format!(
                "{method:>13} {layout}: nodes/ray {inner:.1} (bvh2 {:.1}), boxes/ray {boxes:.1} (bvh2 {:.1}), triangles/ray {tris:.1} (bvh2 {:.1})",
                mean(&c2, |x| x.inner),
                mean(&c2, |x| x.boxes),
                mean(&c2, |x| x.triangles)
            ));
        }
    }
    lines
}

#[test]
fn every_layout_agrees_with_the_reference_and_the_binary_kernel() {
    let lines = common::with_gpu(1200, |ctx| {
        let bunny = common::bunny();
        let soup = load_obj(Path::new("synth:soup:20000:3")).unwrap();
        let mut lines = check_scene(ctx, "bunny", &bunny, 4, &Method::ALL);
        lines.extend(check_scene(ctx, "bunny", &bunny, 1, &[Method::Mt, Method::QuadMt, Method::Watertight]));
        lines.extend(check_scene(ctx, "soup", &soup, 8, &[Method::Mt, Method::QuadUnit, Method::Watertight]));
        lines
    });
    println!("{}", lines.join("\n"));
}

#[test]
fn every_layout_has_any_hit_stats_and_the_address_path() {
    let lines = common::with_gpu(900, |ctx| check_kinds(ctx, &common::bunny()));
    println!("{}", lines.join("\n"));
}

#[test]
fn a_layout_scene_refuses_kernels_of_another_layout() {
    common::with_gpu(300, |ctx| {
        let bunny = common::bunny();
        let host = HostScene::build("bunny", &bunny, &BuildOptions::new(4)).unwrap();
        let rays = trilab::rays::random_rays(&bunny.bounds(), 100, 1);
        let scene = host.upload(ctx, &SceneRequest::new(Method::Mt).layout(Layout::Bvh4)).unwrap();
        // The binary kernels cannot read the wide nodes, nor the bvh8 kernel bvh4's.
        for other in [Layout::Bvh2, Layout::Bvh8] {
            let k = ctx.kernel(Method::Mt.layout_kernel(Raycast::Closest, AccessPath::Texel, other).unwrap()).unwrap();
            match scene.cast_with(ctx, &k, &rays, &common::ONCE) {
                Err(Error::Usage(m)) => assert!(m.contains("bvh4"), "{m}"),
                Err(e) => panic!("expected a usage error, got {e}"),
                Ok(_) => panic!("a bvh4 scene ran a {other} kernel"),
            }
        }
    });
}

/// Rounds of the speed figure: each round casts every set with both layouts, one after the other.
const ROUNDS: usize = 7;

#[test]
#[ignore = "a measurement, not a test: run with --ignored --nocapture"]
fn layout_speed_on_the_bunny() {
    let out = common::with_gpu(3000, |ctx| {
        let bunny = common::bunny();
        let o = BenchOptions::default();
        let host = HostScene::build("bunny", &bunny, &o.build).unwrap();
        let reference = host.reference();
        let sets = ray_sets(&bunny, "bunny", &reference, &o.sizes, None).unwrap();
        let layouts = Layout::ALL;
        let scenes: Vec<_> =
            layouts.iter().map(|&l| host.upload(ctx, &SceneRequest::new(Method::Mt).layout(l)).unwrap()).collect();
        let mut out = vec![format!(
            "{} | leaf {} | mt | {} rounds, interleaved, 1 warm-up each | Mrays/s median (min-max), GPU timestamps",
            ctx.info().name,
            o.build.max_leaf_size,
            ROUNDS
        )];
        for (set, rays) in &sets {
            let ref_hits = reference.trace_all(rays, false);
            let mut ms = vec![vec![]; layouts.len()];
            let warm = RaycastOptions { warmup: 1, repeat: 1, batch_rays: o.batch_rays };
            let once = RaycastOptions { warmup: 0, ..warm.clone() };
            for round in 0..ROUNDS {
                for (i, scene) in scenes.iter().enumerate() {
                    let r = scene.cast(ctx, Raycast::Closest, rays, if round == 0 { &warm } else { &once }).unwrap();
                    assert!(r.timed_on_gpu(), "no GPU timestamps on this device");
                    validate_hits(&bunny, rays, &r.hits, &ref_hits).unwrap();
                    ms[i].extend(r.kernel_ms);
                }
            }
            let rate: Vec<Summary> = ms.iter().map(|m| mrays_summary(rays.len(), Summary::of(m).unwrap())).collect();
            let cells: Vec<String> = layouts
                .iter()
                .zip(&rate)
                .map(|(l, r)| {
                    format!("{l} {:.2} ({:.2}-{:.2}) x{:.2}", r.median, r.min, r.max, r.median / rate[0].median)
                })
                .collect();
            out.push(format!("{set:>7} ({:>7} rays): {}", rays.len(), cells.join(", ")));
        }
        out
    });
    println!("{}", out.join("\n"));
}

/// `raycast --layout` goes through the same pipeline from the command line: every layout's hit
/// file is byte-identical to `--layout bvh2`'s, it passes the f64 check, the report names the
/// layout, and any-hit runs on a wide layout.
#[test]
fn raycast_takes_the_layout_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = |f: &str| dir.path().join(f).to_string_lossy().into_owned();
    let made = common::cli::trilab(
        &["rays", "random", "--scene", "bunny", "--random-rays", "20000", "--out", &p("r.rays")],
        120,
    );
    assert!(made.status.success(), "{}", String::from_utf8_lossy(&made.stderr));
    let mut reports = vec![];
    for layout in ["bvh2", "bvh4", "bvh8"] {
        let o = common::cli::trilab(
            &[
                "raycast",
                "--scene",
                "bunny",
                "--rays",
                &p("r.rays"),
                "--out",
                &p(&format!("{layout}.hits")),
                "--method",
                "watertight",
                "--layout",
                layout,
                "--reference",
                "--repeat",
                "1",
                "--json",
            ],
            300,
        );
        assert!(o.status.success(), "{layout}: {}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["layout"], layout);
        assert_eq!(v["validation"]["passes"], true, "{v}");
        reports.push(v);
    }
    let a = std::fs::read(p("bvh2.hits")).unwrap();
    assert_eq!(a.len(), 20000 * 16);
    for layout in ["bvh4", "bvh8"] {
        let b = std::fs::read(p(&format!("{layout}.hits"))).unwrap();
        assert!(a == b, "{layout}'s hit file differs from bvh2's");
    }
    let o = common::cli::trilab(
        &[
            "raycast",
            "--scene",
            "bunny",
            "--rays",
            &p("r.rays"),
            "--out",
            &p("any.hits"),
            "--layout",
            "bvh8",
            "--any-hit",
            "--json",
        ],
        120,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["layout"], "bvh8");
    // Occluded exactly where the closest-hit file has a hit (t > 0 is the first 4 bytes).
    let any = std::fs::read(p("any.hits")).unwrap();
    let is_hit = |f: &[u8], i: usize| u32::from_le_bytes(f[16 * i + 4..16 * i + 8].try_into().unwrap()) != u32::MAX;
    let differ = (0..20000).filter(|&i| is_hit(&a, i) != is_hit(&any, i)).count();
    assert!(differ <= 2, "{differ} rays: bvh8 any-hit disagrees with bvh2 closest hits on occlusion");
}

/// `bench --layouts bvh2,bvh4,bvh8` times every method on both layouts in one run, each row
/// validated against the f64 reference and naming its layout.
#[test]
fn bench_times_each_method_on_each_layout() {
    let o = common::cli::trilab(
        &[
            "bench",
            "--methods",
            "mt,quad-unit",
            "--layouts",
            "bvh2,bvh4,bvh8",
            "--width",
            "48",
            "--height",
            "36",
            "--diffuse-per-hit",
            "1",
            "--random-rays",
            "3000",
            "--repeat",
            "1",
            "--json",
        ],
        300,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    for set in ["primary", "diffuse", "random"] {
        for method in ["mt", "quad-unit"] {
            for layout in ["bvh2", "bvh4", "bvh8"] {
                let n = rows
                    .iter()
                    .filter(|r| r["ray_set"] == set && r["method"] == method && r["layout"] == layout)
                    .inspect(|r| assert!(r["agreement"].as_f64().unwrap() >= 0.9999 && r["invalid"] == 0, "{r}"))
                    .count();
                assert_eq!(n, 1, "{set} {method} {layout}: {v}");
            }
        }
    }
}

/// The path tracer on every layout: the same closest hits and occlusion answers give the same
/// image, bit for bit (its random numbers depend on pixel, sample and dimension only). The
/// bunny has one BSDF: bvh2 takes its single-BSDF variant, the wide layouts their `all_<layout>`
/// kernel narrowed by the specialisation constant.
#[test]
fn the_path_tracer_renders_the_same_image_on_every_layout() {
    use trilab::render::{self, KernelChoice, RenderSettings, RenderTarget};
    let images = common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
        let mut s = RenderSettings::paper(&mesh);
        (s.width, s.height, s.spp, s.submit_ms) = (40, 30, 4, 50.0);
        Layout::ALL
            .iter()
            .map(|&layout| {
                let request = SceneRequest::new(Method::Watertight).layout(layout);
                let target =
                    RenderTarget::new(ctx, &host, request, KernelChoice::Specialised, s.pixels(), false).unwrap();
                assert_eq!(target.device.layout, layout);
                let r = render::render(ctx, &target, &s, &mut |_| true).unwrap();
                assert_eq!((r.spp, r.dropped_samples), (4, 0), "{layout}");
                (layout, r.kernel, r.image())
            })
            .collect::<Vec<_>>()
    });
    let (_, _, base) = &images[0];
    assert!(base.iter().flatten().any(|&c| c > 0.0), "a black image proves nothing");
    for (layout, kernel, img) in &images[1..] {
        assert!(kernel.ends_with(&format!("_{layout}")), "{layout}: kernel {kernel}");
        let differ = base.iter().zip(img).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{layout}: {differ} pixels differ from bvh2's image");
    }
}

/// `profile --layout` profiles the layout's kernels (its shader-clock and sweeps run the
/// `*_<layout>` variants, each validated against the f64 reference) and says so in profile.md.
#[test]
fn profile_takes_the_layout() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("prof");
    let o = common::cli::trilab(
        &[
            "profile",
            "--scene",
            "bunny",
            "--layout",
            "bvh4",
            "--methods",
            "mt",
            "--random-rays",
            "5000",
            "--width",
            "32",
            "--height",
            "24",
            "--repeat",
            "1",
            "--workgroup-sizes",
            "64",
            "--threads",
            "1",
            "--out",
            out.to_str().unwrap(),
        ],
        600,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(out.join("profile.md")).unwrap();
    assert!(md.contains("layout `bvh4`"), "{md}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("profile.json")).unwrap()).unwrap();
    assert!(json.to_string().contains("\"layout\":\"bvh4\""), "the JSON names the layout");
}
