//! Validation, synchronization validation included: proof that it is active (a deliberately
//! missing barrier is reported as a SYNC-HAZARD), and every kernel family running clean under
//! it (`common::with_gpu` fails on any message).

mod common;

use ash::vk;
use trilab::encoding::Raycast;
use trilab::gpu::{Context, ContextOptions, Resource, Validation};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::shared::{BINDING_HITS, BINDING_RAYS, BINDING_RNG_PROBE_OUT};

/// Two dispatches in one command buffer: the rng probe writes a buffer, then a raycast kernel
/// reads it as its rays. Without a barrier between them synchronization validation must report
/// a read-after-write hazard; with one, nothing.
fn write_then_read(with_barrier: bool) -> Vec<String> {
    let ctx = Context::new(&ContextOptions { validation: Validation::Required, ..Default::default() }).unwrap();
    assert!(ctx.sync_validation_enabled(), "the validation layer offers VK_EXT_validation_features");
    let log = ctx.validation_log();
    {
        let writer = ctx.create_kernel(trilab::render::rng::probe_kernel()).unwrap();
        let mesh = common::bunny();
        let host = HostScene::build("bunny", &mesh, &trilab::bvh::BuildOptions::new(4)).unwrap();
        let scene = host.upload(&ctx, &SceneRequest::new(trilab::encoding::Method::Mt)).unwrap();
        let reader = scene.kernel(&ctx, Raycast::Closest).unwrap();
        const N: u32 = 64;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let gpu = gpu_allocator::MemoryLocation::GpuOnly;
        let shared = ctx.create_buffer("written then read", N as u64 * 32, usage, gpu).unwrap();
        let hits = ctx.create_buffer("hits", N as u64 * 16, usage, gpu).unwrap();
        let mut reader_res: Vec<(u32, Resource)> = scene.resources().collect();
        reader_res.push((BINDING_RAYS, Resource::whole(&shared)));
        reader_res.push((BINDING_HITS, Resource::whole(&hits)));
        let writer_res = [(BINDING_RNG_PROBE_OUT, Resource::whole(&shared))];
        let push_w: Vec<u8> = [1u32, N].iter().flat_map(|x| x.to_le_bytes()).collect();
        ctx.dispatch_chain(
            &[
                (&writer, &writer_res, &push_w, N / 64),
                (&reader, &reader_res, &N.to_le_bytes(), N.div_ceil(reader.layout.local_size.0)),
            ],
            with_barrier,
        )
        .unwrap();
    }
    drop(ctx);
    log.messages()
}

#[test]
fn a_missing_barrier_is_reported_as_a_sync_hazard() {
    let messages = write_then_read(false);
    assert!(
        messages.iter().any(|m| m.contains("SYNC-HAZARD-READ-AFTER-WRITE")),
        "synchronization validation did not see the missing barrier: {messages:#?}"
    );
    let clean = write_then_read(true);
    assert!(clean.is_empty(), "with the barrier: {clean:#?}");
}

/// Every kernel family under validation with synchronization validation on, through the paths
/// the commands use: raycast (every method x closest, any, stats, clock, through texel buffers,
/// storage buffers and buffer device addresses), pathtrace (every
/// method x every BSDF variant and the all-BSDF kernel), ray query. `with_gpu` fails on any
/// message, teardown included. (The probe kernels run under `with_gpu` in tests/probe.rs,
/// tests/bsdf_probe.rs and tests/render.rs.)
#[test]
fn every_kernel_family_runs_clean_under_synchronization_validation() {
    use trilab::bvh::BuildOptions;
    use trilab::encoding::SceneAccess;
    use trilab::gpu::RaycastOptions;
    use trilab::render::{self, KernelChoice, RenderSettings, RenderTarget};
    use trilab::scene::{BsdfKind, GpuMaterial, Material};
    common::with_gpu(900, |ctx| {
        assert!(ctx.sync_validation_enabled());
        let mesh = common::bunny();
        let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
        let rays = trilab::rays::random_rays(&mesh.bounds(), 600, 2);
        // Two batches, so consecutive submits share the output buffers.
        let opts = RaycastOptions { warmup: 1, repeat: 1, batch_rays: 512 };
        for m in trilab::conditioning::available_methods(&ctx.capabilities()) {
            // Every ray-casting variant, through texel buffers, storage buffers (devices without
            // 64-bit integers) and (scenes beyond one binding's range) buffer device addresses.
            let mut paths = vec![SceneAccess::Texel, SceneAccess::Storage];
            if ctx.enabled().buffer_device_address {
                paths.push(SceneAccess::Address);
            }
            for access in paths {
                let scene = host.upload(ctx, &SceneRequest::new(m).access(access)).unwrap();
                for kind in [Raycast::Closest, Raycast::Any] {
                    assert_eq!(scene.cast(ctx, kind, &rays, &opts).unwrap().hits.len(), rays.len());
                }
                let once = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
                let stats = scene.cast(ctx, Raycast::Stats, &rays, &once).unwrap();
                assert_eq!(stats.traversal.unwrap().len(), rays.len());
                if ctx.enabled().shader_clock && access != SceneAccess::Storage {
                    let k = scene.kernel(ctx, Raycast::Clock).unwrap();
                    let stats = ctx.enabled().pipeline_statistics_query;
                    let d = trilab::commands::profile::dispatch_once(ctx, &k, &scene, &rays, stats).unwrap();
                    assert_eq!(d.cycles.unwrap().len(), rays.len());
                }
            }
            // Each single-BSDF kernel on the bunny made of that BSDF, and the all-BSDF one.
            let mut kinds: Vec<Option<BsdfKind>> = BsdfKind::ALL.into_iter().map(Some).collect();
            kinds.push(None);
            for kind in kinds {
                let mut mesh = mesh.clone();
                if let Some(kind) = kind {
                    mesh.materials = vec![Material { name: "m".into(), kind, gpu: GpuMaterial::new(kind) }];
                    mesh.material_ids.iter_mut().for_each(|i| *i = 0);
                }
                let choice = if kind.is_some() { KernelChoice::Specialised } else { KernelChoice::General };
                let mut s = RenderSettings::paper(&mesh);
                (s.width, s.height, s.spp, s.max_depth, s.submit_ms) = (8, 6, 3, 4, 20.0);
                let host = HostScene::with_bvh("bunny", &mesh, host.bvh.clone());
                let target = RenderTarget::new(ctx, &host, m.into(), choice, s.pixels(), false).unwrap();
                let r = render::render(ctx, &target, &s, &mut |_| true).unwrap();
                assert_eq!(r.spp, 3, "{}", r.kernel);
            }
        }
        if ctx.enabled().ray_query {
            let accel = trilab::gpu::AccelStructure::build(ctx, &mesh).unwrap();
            for any in [false, true] {
                let k = trilab::gpu::rayquery::kernel(ctx, any).unwrap();
                let r = trilab::gpu::raycast_rq(ctx, &k, &accel, &rays[..64], &RaycastOptions::default()).unwrap();
                assert_eq!(r.hits.len(), 64);
            }
        }
        if ctx.enabled().ray_tracing_pipeline {
            let accel = trilab::gpu::AccelStructure::build(ctx, &mesh).unwrap();
            for any in [false, true] {
                let p = trilab::gpu::rtpipeline::pipeline(ctx, any).unwrap();
                let r = trilab::gpu::raycast_rtp(ctx, &p, &accel, &rays[..64], &RaycastOptions::default()).unwrap();
                assert_eq!(r.hits.len(), 64);
            }
        }
    });
}

/// Every GPU command through the CLI with validation required (TRILAB_VALIDATION=1): a
/// message fails the command (main exits non-zero), so success means zero messages.
#[test]
fn every_gpu_command_runs_clean_under_validation() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::root().join("scenes/bunny.obj").to_string_lossy().into_owned();
    let p = |n: &str| dir.path().join(n).to_string_lossy().into_owned();
    let run = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_trilab"))
            .args(args)
            .env("TRILAB_VALIDATION", "1")
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success() && !err.contains("validation:"), "trilab {args:?}: {err}");
    };
    run(&["rays", "random", "--scene", &scene, "--out", &p("r.rays"), "--count", "2000"]);
    for extra in [
        &["--method", "quad-unit"][..],
        &["--any-hit"],
        &["--peer", "ray-query", "--batch-rays", "256"],
        &["--peer", "ray-tracing-pipeline", "--batch-rays", "256"],
    ] {
        let base = ["raycast", "--scene", &scene, "--rays", &p("r.rays"), "--out", &p("h.hits"), "--repeat", "1"];
        run(&[&base[..], extra].concat());
    }
    run(&["steps", "--scene", &scene, "--rays", &p("r.rays"), "--gpu", "--methods", "mt,unit"]);
    run(&[
        "render",
        "--scene",
        &scene,
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "2",
        "--quiet",
        "--out",
        &p("i.exr"),
    ]);
    run(&["bench", "--scenes", &scene, "--methods", "mt", "--repeat", "1", "--width", "32", "--height", "24"]
        .iter()
        .chain(&["--diffuse-per-hit", "1", "--random-rays", "2000", "--ray-query", "off"])
        .copied()
        .collect::<Vec<_>>());
    run(&["bench-render", "--scenes", &scene, "--methods", "unit", "--width", "16", "--height", "12", "--spp", "2"]
        .iter()
        .chain(&["--repeat", "1"])
        .copied()
        .collect::<Vec<_>>());
    run(&["profile", "--scene", &scene, "--methods", "mt", "--width", "32", "--height", "24", "--random-rays", "2000"]
        .iter()
        .chain(&["--repeat", "1", "--workgroup-sizes", "64", "--no-threads", "--out", &p("profile")])
        .copied()
        .collect::<Vec<_>>());
    // The smoke presets: seconds each.
    run(&["study", "--preset", "smoke", "--scenes", &scene, "--out", &p("study")]);
    run(&["accuracy", "--preset", "smoke", "--out", &p("accuracy")]);
}
