//! The driver's ray tracing pipeline (VK_KHR_ray_tracing_pipeline through its own BLAS/TLAS) as a
//! peer of our kernels, beside ray query: its hits are checked against the same f64 reference,
//! on the bunny and on a tiny mesh whose answer is known exactly, through the library and the
//! CLI (`raycast --peer ray-tracing-pipeline`, `bench --ray-tracing-pipeline on`); its stages bind
//! what the host provides; without the feature every entry point is a clean "unsupported" error.

mod common;

use std::time::Duration;

use ash::vk;
use trilab::agreement::{compare_any, compare_closest, edge_ulps, AMBIGUITY_ULPS};
use trilab::bvh::{BuildOptions, Bvh};
use trilab::error::Error;
use trilab::gpu::rtpipeline::{self, raycast_rtp};
use trilab::gpu::{AccelStructure, Context, ContextOptions, Peer, PeerTracer, RaycastOptions, Validation};
use trilab::kernels::{find, find_rt, RT_SHADERS};
use trilab::rays::{primary_rays, random_rays, Camera, Hit, Ray};
use trilab::reference::{brute_force, Reference};
use trilab::scene::Mesh;
use trilab::shared::{BINDING_HITS, BINDING_RAYS, BINDING_SLOT_IDS, BINDING_TLAS};
use trilab::spirv::reflect::{buffer_layouts, reflect_stage};

const OPTS: RaycastOptions = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 1 << 20 };

/// Fewest rays that must agree with the reference. Measured on lavapipe (Mesa 25.0.7): every ray
/// agrees on these sets (0 disagreements, 0 invalid), as with ray query.
const MIN_AGREEMENT: f64 = 0.999;

fn bunny_rays(mesh: &Mesh) -> Vec<(&'static str, Vec<Ray>)> {
    vec![
        ("primary", primary_rays(&Camera::framing(&mesh.bounds()), 160, 120)),
        ("random", random_rays(&mesh.bounds(), 10_000, 2024)),
    ]
}

#[test]
fn closest_hit_ray_tracing_pipeline_agrees_with_the_f64_reference_on_the_bunny() {
    let lines = common::with_gpu(600, |ctx| {
        assert!(
            ctx.enabled().ray_tracing_pipeline,
            "lavapipe (Mesa 25) has VK_KHR_ray_tracing_pipeline; the context must enable it"
        );
        let mesh = common::bunny();
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        let pipeline = rtpipeline::pipeline(ctx, false).unwrap();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let reference = Reference::new(&mesh, &bvh);
        let mut lines = vec![];
        for (set, rays) in bunny_rays(&mesh) {
            let res = raycast_rtp(ctx, &pipeline, &accel, &rays, &OPTS).unwrap();
            assert_eq!(res.hits.len(), rays.len());
            assert!(res.timed_on_gpu(), "lavapipe has timestamps: the launches are timed on the GPU");
            let refs = reference.trace_all(&rays, false);
            let a = compare_closest(&mesh, &rays, &res.hits, &refs);
            lines.push(format!("{set}: {} ({:.1} ms)", a.summary(), res.time_ms().unwrap().median));
            // The barycentrics too (the closest-hit stage's hit attributes), where the ids agree.
            let off: Vec<(usize, &Hit)> = res
                .hits
                .iter()
                .zip(&refs)
                .enumerate()
                .filter(|(_, (h, r))| {
                    h.is_hit() && h.id == r.id && ((h.u as f64 - r.u).abs() > 1e-3 || (h.v as f64 - r.v).abs() > 1e-3)
                })
                .map(|(i, (h, _))| (i, h))
                .collect();
            assert!(off.is_empty(), "{set}: barycentrics differ from the reference: {:?}", &off[..off.len().min(5)]);
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
fn any_hit_ray_tracing_pipeline_agrees_with_the_reference_occlusion() {
    let lines = common::with_gpu(600, |ctx| {
        let mesh = common::bunny();
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        let closest = PeerTracer::new(ctx, Peer::RayTracingPipeline, false).unwrap();
        let any = PeerTracer::new(ctx, Peer::RayTracingPipeline, true).unwrap();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let reference = Reference::new(&mesh, &bvh);
        let mut lines = vec![];
        for (set, rays) in bunny_rays(&mesh) {
            let c = closest.cast(ctx, &accel, &rays, &OPTS).unwrap().hits;
            let a = any.cast(ctx, &accel, &rays, &OPTS).unwrap().hits;
            let occluded: Vec<Hit> = reference.trace_all(&rays, true).iter().map(|h| h.to_hit()).collect();
            let vs_ref = compare_any(&mesh, &rays, &occluded, &a);
            assert!(vs_ref.bogus.is_empty(), "{set}: bogus any-hits {:?}", &vs_ref.bogus[..vs_ref.bogus.len().min(5)]);
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
            let vs_closest = compare_any(&mesh, &rays, &c, &a);
            assert!(vs_closest.passes(), "{set}: any-hit vs closest-hit: {vs_closest:?}");
            let occluded_count = a.iter().filter(|h| h.is_hit()).count();
            assert!(occluded_count > rays.len() / 5, "{set}: the rays should often be occluded");
            lines.push(format!("{set}: {} rays, {occluded_count} occluded", rays.len()));
        }
        lines
    });
    for l in lines {
        println!("{l}");
    }
}

#[test]
fn a_ray_at_a_known_triangle_returns_its_obj_id_and_barycentrics() {
    let (mesh, rays, res) = common::with_gpu(120, |ctx| {
        let mesh = common::tiny_accel_mesh();
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        assert_eq!(accel.stats.triangles, 2);
        let pipeline = rtpipeline::pipeline(ctx, false).unwrap();
        let point = |id: usize, u: f32, v: f32| {
            let [a, b, c] = mesh.vertices(id);
            (a * (1.0 - u - v) + b * u + c * v).to_array()
        };
        let toward = |p: [f32; 3], from: [f32; 3]| Ray::new(from, [p[0] - from[0], p[1] - from[1], p[2] - from[2]]);
        let rays = vec![
            toward(point(3, 0.2, 0.3), [2.5, 0.5, -1.0]),
            toward(point(1, 0.25, 0.5), [0.1, 0.1, 0.0]),
            toward(point(3, 0.6, 0.1), [3.0, 3.0, 0.5]),
            // Misses: beside everything, an interval ending before triangle 3, an empty interval.
            Ray::new([10.0, 10.0, 0.0], [0.0, 0.0, 1.0]),
            Ray { tmax: 0.5, ..toward(point(3, 0.2, 0.3), [2.5, 0.5, -1.0]) },
            Ray { tmin: 2.0, tmax: 1.0, ..toward(point(1, 0.25, 0.5), [0.1, 0.1, 0.0]) },
            // Invalid for Vulkan, so never traced: a zero, a NaN and an infinite direction, a NaN
            // tmax. A negative tmin is traced from 0 (triangle 1 ahead).
            Ray::new([0.1, 0.1, 0.0], [0.0, 0.0, 0.0]),
            Ray::new([0.1, 0.1, 0.0], [f32::NAN, 0.0, 1.0]),
            Ray::new([0.1, 0.1, 0.0], [0.0, f32::INFINITY, 1.0]),
            Ray { tmax: f32::NAN, ..Ray::new([0.1, 0.1, 0.0], [0.0, 0.0, 1.0]) },
            Ray { tmin: -5.0, ..toward(point(1, 0.25, 0.5), [0.1, 0.1, 0.0]) },
        ];
        // The same through many batches of 256: hits do not depend on batching.
        let mut many = rays.clone();
        many.extend(rays.iter().cycle().take(600).copied());
        let res = raycast_rtp(ctx, &pipeline, &accel, &rays, &OPTS).unwrap().hits;
        let batched = raycast_rtp(ctx, &pipeline, &accel, &many, &RaycastOptions { batch_rays: 256, ..OPTS }).unwrap();
        assert_eq!(batched.batches, many.len().div_ceil(256));
        for (i, h) in batched.hits.iter().enumerate() {
            assert_eq!(*h, res[i % rays.len()], "ray {i} through batches of 256");
        }
        (mesh, rays, res)
    });
    for (i, (ray, h)) in rays.iter().zip(&res).enumerate().take(6) {
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
    assert!(res[3..10].iter().all(|h| *h == Hit::MISS), "{:?}", &res[3..10]);
    assert_eq!(res[10].id, 1, "a negative tmin is traced from 0");
    assert!((res[10].u - 0.25).abs() < 1e-5 && (res[10].v - 0.5).abs() < 1e-5, "{:?}", res[10]);
}

#[test]
fn a_scene_of_only_zero_area_triangles_is_never_hit() {
    let hits = common::with_gpu(120, |ctx| {
        let mesh = Mesh::from_triangles(vec![[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], vec![[0, 1, 2], [0, 0, 1]]);
        let accel = AccelStructure::build(ctx, &mesh).unwrap();
        assert_eq!(accel.stats.triangles, 0);
        let pipeline = rtpipeline::pipeline(ctx, false).unwrap();
        let rays = vec![Ray::new([0.5, 0.0, -1.0], [0.0, 0.0, 1.0]), Ray::new([0.5, 1.0, 0.0], [0.0, -1.0, 0.0])];
        raycast_rtp(ctx, &pipeline, &accel, &rays, &OPTS).unwrap().hits
    });
    assert!(hits.iter().all(|h| *h == Hit::MISS), "{hits:?}");
}

/// The device's properties as `trilab devices` and the pipeline read them, and the pipeline's
/// launch limit: a batch never exceeds the device's launch size.
#[test]
fn the_device_reports_the_pipeline_properties_the_sbt_needs() {
    let props = common::with_gpu(60, |ctx| ctx.info().ray_tracing_pipeline);
    let p = props.expect("lavapipe (Mesa 25) reports VkPhysicalDeviceRayTracingPipelinePropertiesKHR");
    assert!(p.shader_group_handle_size > 0 && p.shader_group_handle_alignment.is_power_of_two(), "{p:?}");
    assert!(p.shader_group_base_alignment.is_power_of_two() && p.max_ray_recursion_depth >= 1, "{p:?}");
    assert!(p.max_ray_dispatch_invocation_count >= 1 << 20, "{p:?}");
    let l = rtpipeline::SbtLayout::new(&p).unwrap();
    assert_eq!(l.stride % p.shader_group_handle_alignment as u64, 0);
    assert_eq!(l.region % p.shader_group_base_alignment as u64, 0);
    assert!(l.stride >= p.shader_group_handle_size as u64);
}

/// Without the feature (the context option off, as on a device without it): every entry point
/// of the peer is `Error::Unsupported` naming it, ray query still runs over the structure, and
/// with both off the structure itself is refused. No validation message.
#[test]
fn without_the_ray_tracing_pipeline_every_entry_point_is_an_unsupported_error() {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let options = |ray_query: bool| ContextOptions {
            validation: Validation::Required,
            ray_query,
            ray_tracing_pipeline: false,
            ..Default::default()
        };
        let ctx = Context::new(&options(true)).expect("a Vulkan device and the validation layer");
        assert!(!ctx.enabled().ray_tracing_pipeline && ctx.enabled().ray_query);
        let caps = ctx.capabilities();
        assert!(caps.peer(Peer::RayTracingPipeline).is_err() && caps.peer(Peer::RayQuery).is_ok());
        let log = ctx.validation_log();
        let pipeline = rtpipeline::pipeline(&ctx, false).err();
        let tracer = PeerTracer::new(&ctx, Peer::RayTracingPipeline, true).err();
        // Ray query still traces the same structure.
        let accel = AccelStructure::build(&ctx, &common::tiny_accel_mesh()).unwrap();
        let rq = PeerTracer::new(&ctx, Peer::RayQuery, false).unwrap();
        let hits = rq.cast(&ctx, &accel, &[Ray::new([0.1, 0.1, 0.0], [0.0, 0.0, 1.0])], &OPTS).unwrap().hits;
        drop((rq, accel, ctx));
        let ctx = Context::new(&options(false)).expect("a Vulkan device and the validation layer");
        let neither = AccelStructure::build(&ctx, &common::tiny_accel_mesh()).err();
        let log2 = ctx.validation_log();
        drop(ctx);
        let messages = [log.messages(), log2.messages()].concat();
        let _ = tx.send((pipeline, tracer, hits, neither, messages));
    });
    let (pipeline, tracer, hits, neither, messages) =
        rx.recv_timeout(Duration::from_secs(60)).expect("the unsupported path must return, not hang or panic");
    for e in [pipeline, tracer] {
        match e {
            Some(Error::Unsupported(m)) => assert!(m.starts_with("ray tracing pipeline: unsupported on "), "{m}"),
            other => panic!("expected Error::Unsupported, got {other:?}"),
        }
    }
    assert_eq!(hits[0].id, 1, "ray query over the structure: {hits:?}");
    match neither {
        Some(Error::Unsupported(m)) => {
            assert!(m.starts_with("ray query and ray tracing pipeline: unsupported on "), "{m}")
        }
        other => panic!("expected Error::Unsupported without either feature, got {other:?}"),
    }
    assert!(messages.is_empty(), "{messages:?}");
}

/// The stages bind what `raycast_rtp` provides: ray generation the rays, hits and TLAS with
/// `Push { uint ray_count; }`, closest hit the primitive -> OBJ id table, miss nothing; with
/// rayquery.comp's (and so raycast.comp's) Ray and Hit layouts.
#[test]
fn the_stages_bind_the_rays_hits_tlas_and_id_table() {
    assert_eq!(RT_SHADERS.len(), 4, "{:?}", RT_SHADERS.iter().map(|s| s.name).collect::<Vec<_>>());
    let ty = |s: &trilab::kernels::RtShaderSource| {
        let (sets, push) = reflect_stage(s.name, &s.words()).unwrap();
        assert!(sets.keys().all(|&k| k == 0), "{}: set 0 only", s.name);
        let set: Vec<(u32, vk::DescriptorType)> = sets.get(&0).into_iter().flatten().map(|(&b, d)| (b, d.ty)).collect();
        (set, push)
    };
    let rq = find("rayquery", trilab::kernels::NO_INTERSECTOR, "closest").unwrap();
    let rq_layouts = buffer_layouts(&rq.words()).unwrap();
    for variant in ["closest", "any"] {
        let raygen = find_rt("raygen", "rgen", variant).unwrap();
        assert_eq!(
            ty(raygen),
            (
                vec![
                    (BINDING_RAYS, vk::DescriptorType::STORAGE_BUFFER),
                    (BINDING_HITS, vk::DescriptorType::STORAGE_BUFFER),
                    (BINDING_TLAS, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR),
                ],
                Some((0, 4))
            ),
            "{}",
            raygen.name
        );
        let layouts = buffer_layouts(&raygen.words()).unwrap();
        for b in [BINDING_RAYS, BINDING_HITS, u32::MAX] {
            assert_eq!(layouts.get(&b), rq_layouts.get(&b), "{}: binding {b} as rayquery.comp", raygen.name);
        }
    }
    let closest = find_rt("closest", "rchit", "main").unwrap();
    assert_eq!(ty(closest), (vec![(BINDING_SLOT_IDS, vk::DescriptorType::STORAGE_TEXEL_BUFFER)], None));
    let miss = find_rt("miss", "rmiss", "main").unwrap();
    assert_eq!(ty(miss), (vec![], None));
    // Every stage declares the RayTracingKHR capability (the context checks it is enabled).
    for s in RT_SHADERS {
        let needs = trilab::spirv::required_features(&s.words()).unwrap();
        assert!(needs.iter().any(|r| r.feature == trilab::spirv::Feature::RayTracingPipeline), "{}: {needs:?}", s.name);
    }
}

/// `trilab raycast --peer ray-tracing-pipeline` (closest and any hit) writes hits the f64
/// reference agrees with, and `trilab devices` shows the feature.
#[test]
fn cli_raycast_with_the_ray_tracing_pipeline_peer_agrees_with_the_reference() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let scene = common::root().join("scenes/bunny.obj").to_string_lossy().into_owned();
    let o = common::cli::trilab(&["rays", "random", "--scene", &scene, "--out", &p("r.rays"), "--count", "3000"], 120);
    common::cli::ok(&o);
    let mesh = common::bunny();
    let rays = trilab::rays::read_rays(std::path::Path::new(&p("r.rays"))).unwrap();
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let reference = Reference::new(&mesh, &bvh);
    let (rays_file, hits_file) = (p("r.rays"), p("h.hits"));
    for any in [false, true] {
        let mut args = vec!["raycast", "--scene", &scene, "--rays", &rays_file, "--out", &hits_file];
        args.extend(["--peer", "ray-tracing-pipeline", "--repeat", "1", "--batch-rays", "1024", "--json"]);
        if any {
            args.push("--any-hit");
        }
        let o = common::cli::trilab(&args, 300);
        common::cli::ok(&o);
        let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(report["peer"], "ray-tracing-pipeline", "{report}");
        // At most 1024 rays a batch; fewer where one probe run says a batch of 1024 would take
        // too long (`gpu::raycast::batch_for_with`: at least 256; a loaded host gets more).
        let batches = report["batches"].as_u64().unwrap();
        assert!((3..=12).contains(&batches), "3000 rays in batches of 256..=1024: {report}");
        let hits = trilab::rays::read_hits(std::path::Path::new(&hits_file)).unwrap();
        assert_eq!(hits.len(), rays.len());
        if any {
            let occluded: Vec<Hit> = reference.trace_all(&rays, true).iter().map(|h| h.to_hit()).collect();
            let c = compare_any(&mesh, &rays, &occluded, &hits);
            assert!(c.bogus.is_empty(), "{c:?}");
            let far_from_edges =
                c.status_mismatch.iter().filter(|&&i| edge_ulps(&mesh, &rays[i], occluded[i].id) > AMBIGUITY_ULPS);
            assert_eq!(far_from_edges.count(), 0, "{c:?}");
        } else {
            let a = compare_closest(&mesh, &rays, &hits, &reference.trace_all(&rays, false));
            assert!(a.invalid.is_empty() && a.fraction() >= MIN_AGREEMENT, "{}", a.summary());
        }
    }
    let o = common::cli::trilab(&["devices"], 60);
    let out = String::from_utf8_lossy(&o.stdout).into_owned() + &common::cli::ok(&o);
    assert!(out.contains("ray tracing pipeline:     yes ("), "{out}");
}

/// `trilab bench --ray-tracing-pipeline on` adds its row, validated against the reference; the
/// default (`auto`) leaves it out on lavapipe, a CPU device, with a note.
#[test]
fn cli_bench_reports_a_validated_ray_tracing_pipeline_row() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| {
        std::fs::create_dir_all(dir.path().join(n)).unwrap();
        dir.path().join(n).to_string_lossy().into_owned()
    };
    let small = [
        "bench",
        "--scenes",
        "bunny",
        "--methods",
        "mt",
        "--width",
        "24",
        "--height",
        "18",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "500",
        "--repeat",
        "1",
        "--ray-query",
        "off",
    ];
    let o = common::cli::trilab(&[&small[..], &["--ray-tracing-pipeline", "on", "--out", &p("on")]].concat(), 600);
    common::cli::ok(&o);
    let bench: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("on/bench.json")).unwrap()).unwrap();
    let rows = bench["rows"].as_array().unwrap();
    let peer: Vec<&serde_json::Value> = rows.iter().filter(|r| r["method"] == "ray-tracing-pipeline").collect();
    assert_eq!(peer.len(), 3, "one row per ray set: {rows:?}");
    for r in &peer {
        assert!(r["agreement"].as_f64().unwrap() >= MIN_AGREEMENT && r["invalid"] == 0, "{r}");
        assert!(r["mrays_per_s"].as_f64().unwrap() > 0.0 && r["leaf_size"].is_null(), "{r}");
    }
    assert!(rows.iter().all(|r| r["method"] != "ray-query"), "--ray-query off: {rows:?}");
    let notes = bench["driver_notes"].as_array().unwrap();
    assert_eq!(notes.len(), 1, "{notes:?}");
    assert!(notes[0].as_str().unwrap().starts_with("ray query: not run"), "{notes:?}");
    assert_eq!(bench["accel"].as_array().unwrap().len(), 1, "the driver's structure is built once per scene");
    let plan = std::fs::read_to_string(dir.path().join("on/rows.jsonl")).unwrap();
    assert!(plan.contains("\"peer\":\"ray-tracing-pipeline\""), "{plan}");

    let o = common::cli::trilab(&[&small[..], &["--out", &p("auto")]].concat(), 600);
    common::cli::ok(&o);
    let bench: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("auto/bench.json")).unwrap()).unwrap();
    let rows = bench["rows"].as_array().unwrap();
    assert!(rows.iter().all(|r| r["method"] != "ray-tracing-pipeline"), "auto on a CPU device: {rows:?}");
    let notes: Vec<&str> = bench["driver_notes"].as_array().unwrap().iter().filter_map(|n| n.as_str()).collect();
    assert!(
        notes.contains(&"ray tracing pipeline: not run (--ray-tracing-pipeline off, or auto on a CPU device)"),
        "{notes:?}"
    );
}
