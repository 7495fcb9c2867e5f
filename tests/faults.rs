//! GPU faults (lavapipe never loses its device, so they are injected, see `gpu::markers`): a
//! lost device or out-of-memory gives an error naming the dispatch it happened in and the last
//! one completed; a render that fails part-way keeps the last whole pass, bitwise what a clean
//! render of that many samples gives; the CLI exits non-zero with the message and no panic,
//! having written what it had.

mod common;

use common::cli::s;

use std::process::{Command, Output};

use ash::vk;
use common::{bunny, with_gpu};
use trilab::bvh::BuildOptions;
use trilab::encoding::{Method, Raycast};
use trilab::error::Error;
use trilab::gpu::{Context, Fault, FaultKind, RaycastOptions};
use trilab::pipeline::{DeviceScene, HostScene, SceneRequest};
use trilab::render::{self, KernelChoice, RenderFailure, RenderResult, RenderSettings, RenderTarget};

/// The GpuFault inside `e`.
fn fault_of(e: &Error) -> (Option<vk::Result>, String, String) {
    match e {
        Error::GpuFault { result, during, markers, .. } => (*result, during.clone(), markers.clone()),
        other => panic!("expected a GPU fault, got {other:?}"),
    }
}

/// The GpuFault inside a failed render (as is, or as a partial render's source).
fn render_fault_of(e: &RenderFailure) -> (Option<vk::Result>, String, String) {
    match e {
        RenderFailure::Error(e) => fault_of(e),
        RenderFailure::Partial(p) => fault_of(&p.source),
    }
}

fn unit_setup(ctx: &Context) -> (DeviceScene, Vec<trilab::rays::Ray>) {
    let mesh = bunny();
    let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
    let scene = host.upload(ctx, &SceneRequest::new(Method::Unit)).unwrap();
    let rays = trilab::rays::random_rays(&mesh.bounds(), 1000, 3);
    (scene, rays)
}

/// Four batches of 256 rays; the device is lost at the third batch's submit.
#[test]
fn raycast_device_loss_names_the_batch_and_the_last_completed() {
    with_gpu(120, |ctx| {
        let (scene, rays) = unit_setup(ctx);
        let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 256 };
        assert!(ctx.markers_active(), "lavapipe has host-visible memory for the breadcrumbs");
        ctx.inject_fault(Some(Fault { kind: FaultKind::DeviceLost, at: 3 }));
        let e = scene.cast(ctx, Raycast::Closest, &rays, &opts).unwrap_err();
        let (result, during, markers) = fault_of(&e);
        assert_eq!(result, Some(vk::Result::ERROR_DEVICE_LOST));
        assert_eq!(during, "raycast.unit.closest batch 3/4 (rays 512..768)");
        assert!(markers.contains("last completed: raycast.unit.closest batch 2/4 (rays 256..512)"), "{markers}");
        assert!(markers.contains("last dispatch begun: raycast.unit.closest batch 2/4"), "{markers}");
        let text = e.to_string();
        assert!(text.starts_with("device lost (VK_ERROR_DEVICE_LOST) during raycast.unit.closest batch 3/4"), "{text}");
        // Lost stays lost: the next submit fails too, as on a real device.
        ctx.inject_fault(None);
        let again = scene.cast(ctx, Raycast::Closest, &rays, &opts).unwrap_err();
        assert_eq!(fault_of(&again).0, Some(vk::Result::ERROR_DEVICE_LOST));
    });
}

/// Out of memory at a submit (not sticky) and at an allocation: both name the last dispatch.
#[test]
fn out_of_memory_names_the_last_dispatch() {
    with_gpu(120, |ctx| {
        let (scene, rays) = unit_setup(ctx);
        let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 256 };
        ctx.inject_fault(Some(Fault { kind: FaultKind::SubmitOutOfMemory, at: 2 }));
        let e = scene.cast(ctx, Raycast::Closest, &rays, &opts).unwrap_err();
        let (result, during, markers) = fault_of(&e);
        assert_eq!(result, Some(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY));
        assert_eq!(during, "raycast.unit.closest batch 2/4 (rays 256..512)");
        assert!(markers.contains("last completed: raycast.unit.closest batch 1/4 (rays 0..256)"), "{markers}");
        assert!(e.to_string().starts_with("out of device memory"), "{e}");

        // Not sticky: the same cast now runs, and completes every batch.
        ctx.inject_fault(None);
        let ok = scene.cast(ctx, Raycast::Closest, &rays, &opts).unwrap();
        assert_eq!(ok.hits.len(), rays.len());

        // The next allocation (the ray buffer of the next cast) fails.
        ctx.inject_fault(Some(Fault { kind: FaultKind::AllocationOutOfMemory, at: 1 }));
        let e = scene.cast(ctx, Raycast::Closest, &rays, &opts).unwrap_err();
        let (result, during, markers) = fault_of(&e);
        assert_eq!(result, None);
        assert_eq!(during, "allocating `rays`");
        assert!(markers.contains("last completed: raycast.unit.closest batch 4/4 (rays 768..1000)"), "{markers}");
        assert!(e.to_string().starts_with("out of GPU memory"), "{e}");
        ctx.inject_fault(None);
    });
}

fn small(mesh: &trilab::scene::Mesh, spp: u32) -> RenderSettings {
    let mut s = RenderSettings::paper(mesh);
    (s.width, s.height, s.spp, s.max_depth, s.submit_ms) = (32, 24, spp, 6, 20.0);
    s
}

fn render_on(ctx: &Context, s: &RenderSettings) -> Result<RenderResult, RenderFailure> {
    let mesh = bunny();
    let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
    let target =
        RenderTarget::new(ctx, &host, Method::Mt.into(), KernelChoice::Specialised, s.pixels(), false).unwrap();
    render::render(ctx, &target, s, &mut |_| true)
}

fn bits(accum: &[[f32; 4]]) -> Vec<u32> {
    accum.iter().flatten().map(|c| c.to_bits()).collect()
}

/// A 32x24 image is one dispatch per pass on an idle host: the device is lost in pass 4, and the render hands
/// back passes 1-3, bit for bit a clean render of that many samples.
#[test]
fn render_device_loss_keeps_the_last_whole_pass() {
    let s = small(&bunny(), 400);
    let s1 = s.clone();
    let partial = with_gpu(300, move |ctx| {
        ctx.inject_fault(Some(Fault { kind: FaultKind::DeviceLost, at: 4 }));
        let e = render_on(ctx, &s1).unwrap_err();
        let (result, during, markers) = render_fault_of(&e);
        assert_eq!(result, Some(vk::Result::ERROR_DEVICE_LOST));
        // The fourth dispatch is lost; its pass is the fourth unless a loaded host made
        // `submit_ms` split a pass (see cli_render_writes_what_it_had_when_the_device_is_lost).
        assert!(during.starts_with("pathtrace.mt.") && during.contains(" dispatch 4 (samples "), "{during}");
        assert!(markers.contains("last completed: pathtrace.mt.") && markers.contains(" dispatch 3 "), "{markers}");
        match e {
            RenderFailure::Partial(p) => *p.result,
            other => panic!("expected a partial render: {other:?}"),
        }
    });
    assert!((1..400).contains(&partial.spp), "spp {}", partial.spp);
    assert_eq!(partial.submits, 3);
    assert!(partial.failed.as_deref().is_some_and(|f| f.contains("device lost")), "{:?}", partial.failed);
    assert_eq!(partial.accum.len(), 32 * 24);
    let clean = with_gpu(300, move |ctx| render_on(ctx, &RenderSettings { spp: partial.spp, ..s }).unwrap());
    assert_eq!(clean.spp, partial.spp);
    assert!(bits(&partial.accum) == bits(&clean.accum), "partial render differs from a clean one of {} spp", clean.spp);
}

fn trilab_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_trilab"));
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    // Bounded by the kernel sizes used (seconds); the harness' own timeout catches a hang.
    c.output().unwrap()
}

fn expect_failure(o: &Output, needles: &[&str]) -> String {
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "should fail: {e}");
    assert!(!e.contains("panicked"), "panicked: {e}");
    for n in needles {
        assert!(e.contains(n), "stderr lacks `{n}`: {e}");
    }
    e
}

#[test]
fn cli_raycast_reports_the_lost_batch_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let rays = dir.path().join("r.rays");
    let o = trilab_env(&["rays", "random", "--scene", &scene, "--out", &s(&rays), "--count", "1000"], &[]);
    assert!(o.status.success());
    let hits = dir.path().join("h.hits");
    let args = ["raycast", "--scene", &scene, "--rays", &s(&rays), "--out", &s(&hits), "--batch-rays", "256"];
    let o = trilab_env(
        &[&args[..], &["--repeat", "1", "--validation"]].concat(),
        &[("TRILAB_INJECT_FAULT", "device-lost@2")],
    );
    expect_failure(
        &o,
        &[
            "device lost (VK_ERROR_DEVICE_LOST) during raycast.mt.closest batch 2/4 (rays 256..512)",
            "last completed: raycast.mt.closest batch 1/4 (rays 0..256)",
        ],
    );
    assert!(!hits.exists(), "no hit file from a failed cast");
    let o = trilab_env(&args, &[("TRILAB_INJECT_FAULT", "lost@2")]);
    expect_failure(&o, &["TRILAB_INJECT_FAULT", "device-lost@N"]);
}

/// Device lost in pass 3 of a CLI render: non-zero exit naming the dispatch, and the EXR, PNG
/// and JSON of the passes before it, the EXR byte for byte a clean render of that many spp.
#[test]
fn cli_render_writes_what_it_had_when_the_device_is_lost() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let out = dir.path().join("lost.exr");
    let base = ["render", "--scene", &scene, "--width", "32", "--height", "24", "--max-depth", "6", "--quiet"];
    let o = trilab_env(
        &[&base[..], &["--spp", "400", "--submit-ms", "20", "--validation", "--out", &s(&out)]].concat(),
        &[("TRILAB_INJECT_FAULT", "device-lost@3")],
    );
    // The third dispatch is lost. Which pass it belongs to depends on the host: `--submit-ms`
    // sizes dispatches by time, and a loaded host splits a pass in two (the soak of issue 40 saw
    // "pass 2 dispatch 3 (samples 1..2, pixels 554..768)" after one whole pass), so only the
    // dispatch is named here, and at least one whole pass is kept.
    let e =
        expect_failure(&o, &["device lost", "pathtrace.mt.", " dispatch 3 (samples ", "last completed: pathtrace.mt."]);
    assert!(e.contains("wrote the"), "{e}");
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("lost.json")).unwrap()).unwrap();
    assert!(j["failed"].as_str().unwrap().contains("device lost"), "{j}");
    assert_eq!(j["interrupted"], false);
    let spp = j["spp_done"].as_u64().unwrap();
    assert!((1..400).contains(&spp), "{j}");
    assert!(dir.path().join("lost.png").exists());
    let clean = dir.path().join("clean.exr");
    let o = trilab_env(&[&base[..], &["--spp", &spp.to_string(), "--out", &s(&clean)]].concat(), &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        std::fs::read(&out).unwrap() == std::fs::read(&clean).unwrap(),
        "EXR differs from a clean {spp} spp render"
    );
}

/// `--checkpoint-secs`: a render killed outright (SIGKILL, no chance to clean up) leaves the
/// last checkpoint.
#[test]
fn a_killed_render_leaves_its_last_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("long.exr");
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_trilab"))
        .args(["render", "--scene", &scene, "--width", "48", "--height", "32", "--spp", "100000", "--quiet"])
        .args(["--submit-ms", "50", "--checkpoint-secs", "0.5", "--out", &s(&out)])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let json = dir.path().join("long.json");
    let start = std::time::Instant::now();
    while !json.exists() && start.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    std::thread::sleep(std::time::Duration::from_millis(1500));
    child.kill().unwrap();
    child.wait().unwrap();
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert_eq!(j["checkpoint"], true, "{j}");
    assert!(j["spp_done"].as_u64().unwrap() > 0, "{j}");
    assert!(std::fs::read(&out).unwrap().len() > 1000);
    assert!(dir.path().join("long.png").exists());
    // Atomic writes: no temporary file left beside the outputs... except one being written
    // at the moment of the kill (tempfile names start with `.trilab-`).
    let stray = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .count();
    assert_eq!(stray, 3, "exactly long.exr, long.png and long.json");
}

/// Outputs never land on an input: the OBJ, an MTL it reads, the ray file, a bench scene. The
/// input is unchanged and nothing is written.
#[test]
fn outputs_over_inputs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("bunny.obj");
    let mtl = dir.path().join("bunny.mtl");
    std::fs::copy(common::root().join("scenes/bunny.obj"), &obj).unwrap();
    std::fs::copy(common::root().join("scenes/bunny.mtl"), &mtl).unwrap();
    let rays = dir.path().join("r.rays");
    let o = trilab_env(&["rays", "random", "--scene", &s(&obj), "--out", &s(&rays), "--count", "100"], &[]);
    assert!(o.status.success());
    let before: Vec<Vec<u8>> = [&obj, &mtl, &rays].iter().map(|p| std::fs::read(p).unwrap()).collect();
    let refusals: [Vec<String>; 6] = [
        vec!["rays".into(), "random".into(), "--scene".into(), s(&obj), "--out".into(), s(&mtl)],
        vec!["rays".into(), "primary".into(), "--scene".into(), s(&obj), "--out".into(), s(&obj)],
        vec!["raycast".into(), "--scene".into(), s(&obj), "--rays".into(), s(&rays), "--out".into(), s(&rays)],
        vec!["raycast".into(), "--scene".into(), s(&obj), "--rays".into(), s(&rays), "--out".into(), s(&mtl)],
        vec!["bench-render".into(), "--scenes".into(), s(&obj), "--json-out".into(), s(&obj)],
        vec!["bench".into(), "--scenes".into(), s(&obj), "--md-out".into(), s(&dir.path().join(".").join("bunny.obj"))],
    ];
    for args in &refusals {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        expect_failure(&trilab_env(&args, &[]), &["refusing to overwrite an input"]);
    }
    let after: Vec<Vec<u8>> = [&obj, &mtl, &rays].iter().map(|p| std::fs::read(p).unwrap()).collect();
    assert!(before == after, "an input changed");
    let names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    // The inputs and r.rays.json, the sidecar `trilab rays` wrote beside r.rays.
    assert_eq!(names.len(), 4, "nothing else written: {names:?}");
}
