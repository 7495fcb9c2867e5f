//! Pictures a person wants to look at (issue 14, defects 10 and the camera part of 4): `render`'s
//! defaults light a white object with a sky and a sun and look at the scene from its front; the
//! Cornell box looks like the Cornell box; `rays primary` takes `render`'s `--camera` (and
//! `--camera peer` is the benchmarks' camera, bit for bit); scenes too large for f32 cameras are
//! refused naming their bounds; and the sun's next-event estimate with MIS converges to the
//! analytic radiance, as BSDF sampling alone does. CLI runs have wall-clock limits and run with
//! the validation layer required.

mod common;

use common::cli::{expect_error, ok, s};

use std::path::Path;
use std::process::Output;

use glam::DVec3;
use trilab::bvh::BuildOptions;
use trilab::encoding::Method;
use trilab::pipeline::HostScene;
use trilab::rays::{read_rays, Camera};
use trilab::render::{self, KernelChoice, RenderSettings, RenderTarget, Sky};
use trilab::scene::Mesh;

fn trilab(args: &[&str], timeout_s: u64) -> Output {
    common::cli::trilab(args, timeout_s)
}

/// A render's EXR (rgb radiance, a coverage) as rows of pixels, and its JSON sidecar.
fn render(scene: &str, out: &Path, extra: &[&str]) -> (usize, Vec<[f32; 4]>, serde_json::Value, String) {
    let o = s(out);
    let args = [&["render", "--scene", scene, "--out", &o, "--quiet", "--submit-ms", "100"][..], extra].concat();
    let err = ok(&trilab(&args, 240));
    let image = exr::prelude::read_first_rgba_layer_from_file(
        out,
        |res, _| (res.width(), vec![[0f32; 4]; res.width() * res.height()]),
        |(w, px): &mut (usize, Vec<[f32; 4]>), pos, (r, g, b, a): (f32, f32, f32, f32)| {
            px[pos.y() * *w + pos.x()] = [r, g, b, a]
        },
    )
    .unwrap();
    let (w, px) = image.layer_data.channel_data.pixels;
    let json = serde_json::from_slice(&std::fs::read(out.with_extension("json")).unwrap()).unwrap();
    (w, px, json, err)
}

fn luminance(p: &[f32; 4]) -> f64 {
    0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2])
}

fn forward(json: &serde_json::Value) -> DVec3 {
    let f = &json["camera"]["forward"];
    DVec3::new(f[0].as_f64().unwrap(), f[1].as_f64().unwrap(), f[2].as_f64().unwrap())
}

/// The white bunny under the default lighting shows its shape: a sky, a sun from the front
/// left; faces towards the sun much brighter than faces away from it (today: a uniform white
/// environment, a flat silhouette from a 3/4 view).
#[test]
fn a_white_object_at_the_defaults_is_lit_by_a_sky_and_sun_and_seen_from_the_front() {
    let dir = tempfile::tempdir().unwrap();
    let (_, px, json, _) =
        render("scenes/bunny.obj", &dir.path().join("bunny.exr"), &["--width", "64", "--height", "48", "--spp", "16"]);
    assert_eq!(json["environment"], "sky", "{json}");
    assert!(json["settings"]["sky"]["sun_radius_degrees"].as_f64().unwrap() > 0.0, "{json}");
    assert_eq!(json["camera_choice"], "front");
    assert!((forward(&json) - DVec3::NEG_Z).length() < 1e-6, "front camera looks down -z: {json}");
    // The bunny's pixels: its shading spans a wide range (lit against shaded faces).
    let mut lum: Vec<f64> = px.iter().filter(|p| p[3] > 0.99).map(luminance).collect();
    assert!(lum.len() > 300, "the bunny fills the view: {} covered pixels", lum.len());
    lum.sort_by(f64::total_cmp);
    let (p10, p90) = (lum[lum.len() / 10], lum[lum.len() * 9 / 10]);
    assert!(p90 > 2.0 * p10 && p90 - p10 > 0.2, "flat shading: 10th percentile {p10}, 90th {p90}");
    // The background is the sky above the horizon and the ground below it, not a constant.
    let bg: Vec<f64> = px.iter().filter(|p| p[3] == 0.0).map(luminance).collect();
    let (lo, hi) = bg.iter().fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(hi > 1.5 * lo, "background from {lo} to {hi}");
}

/// The Cornell box at the defaults: no environment (it has an emitter), seen through its open
/// front: the red wall on the left, the green one on the right, the light at the top.
#[test]
fn the_cornell_box_at_the_defaults_looks_like_the_cornell_box() {
    let dir = tempfile::tempdir().unwrap();
    let (w, px, json, err) = render(
        "scenes/cornell.obj",
        &dir.path().join("cornell.exr"),
        &["--width", "48", "--height", "48", "--spp", "16"],
    );
    assert!(!err.contains("black"), "a scene with emitters needs no environment: {err}");
    assert_eq!(json["environment"], "0", "{json}");
    assert!((forward(&json) - DVec3::NEG_Z).length() < 1e-6, "{json}");
    let mean = |x0: usize, x1: usize, y0: usize, y1: usize| {
        let mut m = [0.0f64; 3];
        for y in y0..y1 {
            for x in x0..x1 {
                for c in 0..3 {
                    m[c] += f64::from(px[y * w + x][c]) / ((x1 - x0) * (y1 - y0)) as f64;
                }
            }
        }
        m
    };
    let left = mean(4, 8, 16, 32);
    let right = mean(40, 44, 16, 32);
    assert!(left[0] > 2.0 * left[1] && left[0] > 2.0 * left[2], "left wall should be red: {left:?}");
    assert!(right[1] > 2.0 * right[0] && right[1] > 2.0 * right[2], "right wall should be green: {right:?}");
    // The box's opening fills the view but for a margin: the centre sees only its inside.
    assert!((4..44).all(|y| (4..44).all(|x| px[y * w + x][3] > 0.99)), "the box fills the view");
    // The light, at the top centre, is the brightest thing.
    let top = mean(20, 28, 2, 8);
    let centre = mean(20, 28, 20, 28);
    assert!(top.iter().sum::<f64>() > 1.5 * centre.iter().sum::<f64>(), "top {top:?} centre {centre:?}");
}

/// `--env 0` on a scene with no emitters warns that the image will be black; `--sun-dir`
/// without the sky is refused; the constant environment is still there.
#[test]
fn env_options_warn_and_refuse_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let (_, px, json, err) = render(
        "scenes/bunny.obj",
        &dir.path().join("black.exr"),
        &["--width", "16", "--height", "16", "--spp", "1", "--env", "0"],
    );
    assert!(err.contains("warning") && err.contains("black"), "{err}");
    assert!(px.iter().all(|p| p[0] == 0.0 && p[1] == 0.0 && p[2] == 0.0));
    assert_eq!(json["environment"], "0");
    let (_, px, json, err) = render(
        "scenes/bunny.obj",
        &dir.path().join("white.exr"),
        &["--width", "16", "--height", "16", "--spp", "1", "--env", "1"],
    );
    assert!(!err.contains("black"), "{err}");
    assert_eq!(json["environment"], "1");
    assert!(px.iter().filter(|p| p[3] == 0.0).all(|p| p[0] == 1.0), "the background is the constant environment");
    let out = s(&dir.path().join("x.exr"));
    let base = ["render", "--scene", "scenes/bunny.obj", "--out", &out, "--width", "8", "--height", "8", "--spp", "1"];
    expect_error(
        &trilab(&[&base[..], &["--env", "1", "--sun-dir", "0,1,0"]].concat(), 60),
        &["--sun-dir", "--env sky"],
    );
    expect_error(&trilab(&[&base[..], &["--env", "sunny"]].concat(), 60), &["--env", "sky"]);
    expect_error(&trilab(&[&base[..], &["--sun-dir", "0,0,0"]].concat(), 60), &["--sun-dir", "non-zero"]);
    let (_, _, json, _) = render(
        "scenes/bunny.obj",
        &dir.path().join("sun.exr"),
        &["--width", "8", "--height", "8", "--spp", "1", "--sun-dir", "1,1,0"],
    );
    assert_eq!(json["settings"]["sky"]["sun_dir"], serde_json::json!([1.0, 1.0, 0.0]));
}

/// `rays primary` places its camera as `render` does, from the same `--camera` parser:
/// `--camera peer` is the benchmarks' camera bit for bit (the SHA-256 below is of the rays the
/// pre-issue-14 binary wrote by default), and the default front camera's central ray is the
/// render's view direction.
#[test]
fn rays_primary_takes_the_render_camera() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.rays");
    let primary = |extra: &[&str]| {
        let o = s(&out);
        let args = [
            &["rays", "primary", "--scene", "scenes/bunny.obj", "--out", &o, "--width", "8", "--height", "6"][..],
            extra,
        ]
        .concat();
        ok(&trilab(&args, 60));
        std::fs::read(&out).unwrap()
    };
    use sha2::Digest;
    let sha = |b: &[u8]| sha2::Sha256::digest(b).iter().map(|x| format!("{x:02x}")).collect::<String>();
    assert_eq!(
        sha(&primary(&["--camera", "peer"])),
        "6a67fb71c3364058b2bc3e6dce9012214647719b795611caed1d3956b5477fbf",
        "--camera peer must reproduce the committed benchmarks' primary rays"
    );
    primary(&[]);
    let rays = read_rays(&out).unwrap();
    let (_, _, json, _) =
        render("scenes/bunny.obj", &dir.path().join("r.exr"), &["--width", "8", "--height", "6", "--spp", "1"]);
    let eye = &json["camera"]["eye"];
    for r in &rays {
        for (i, o) in r.origin.iter().enumerate() {
            assert_eq!(f64::from(*o), eye[i].as_f64().unwrap(), "rays start at the render's eye");
        }
    }
    // The four central rays straddle the view direction.
    let mid = [rays[2 * 8 + 3], rays[2 * 8 + 4], rays[3 * 8 + 3], rays[3 * 8 + 4]];
    let sum = mid.iter().fold(DVec3::ZERO, |a, r| a + DVec3::from_array(r.dir.map(f64::from)));
    assert!(sum.normalize().dot(forward(&json)) > 1.0 - 1e-6);
    // An explicit camera: the same numbers in both commands.
    let cam = "0.5,0.5,2.2,0.5,0.5,0,0,1,0,38";
    primary(&["--camera", cam]);
    assert!(read_rays(&out).unwrap().iter().all(|r| r.origin == [0.5, 0.5, 2.2]));
    let (_, _, json, _) = render(
        "scenes/bunny.obj",
        &dir.path().join("e.exr"),
        &["--width", "8", "--height", "6", "--spp", "1", "--camera", cam],
    );
    assert_eq!(json["camera_choice"], cam);
    for (i, v) in [0.5, 0.5, 2.2].iter().enumerate() {
        assert!((json["camera"]["eye"][i].as_f64().unwrap() - v).abs() < 1e-6, "{json}");
    }
    let o = s(&out);
    for bad in ["side", "0,0,0,0,0,0,0,1,0,45"] {
        let e = trilab(&["rays", "primary", "--scene", "scenes/bunny.obj", "--out", &o, "--camera", bad], 60);
        expect_error(&e, &["--camera", bad]);
    }
}

fn huge_scene(dir: &Path, scale: f64) -> String {
    let p = dir.join(format!("huge{scale:e}.obj"));
    let v = |x: f64, y: f64, z: f64| format!("v {:e} {:e} {:e}\n", x * scale, y * scale, z * scale);
    let obj = [v(-1.0, -1.0, -1.0), v(1.0, -1.0, -1.0), v(0.0, 1.0, 1.0), v(0.0, 0.0, -1.0)].concat()
        + "f 1 2 3\nf 1 3 4\nf 2 4 3\n";
    std::fs::write(&p, obj).unwrap();
    s(&p)
}

/// Cameras are placed in f64: a scene at 1e20 gets finite primary rays (today: infinite
/// origins, reported as success) and a scene at 1e38, whose camera f32 cannot hold, is refused
/// at generation naming its bounds (today `render` blames a `--camera` nobody gave).
#[test]
fn cameras_for_huge_scenes_are_computed_in_f64_or_refused_naming_the_bounds() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("h.rays"));
    let big = huge_scene(dir.path(), 1e20);
    for camera in ["front", "peer"] {
        ok(&trilab(
            &["rays", "primary", "--scene", &big, "--out", &out, "--width", "8", "--height", "6", "--camera", camera],
            60,
        ));
        let rays = read_rays(Path::new(&out)).unwrap();
        assert!(rays.iter().all(|r| r.problem().is_none()), "{camera}: {:?}", rays[0]);
    }
    let huge = huge_scene(dir.path(), 1e38);
    let bounds = "scene bounds [-1e38, -1e38, -1e38] .. [1e38, 1e38, 1e38]";
    let e = trilab(&["rays", "primary", "--scene", &huge, "--out", &out], 60);
    expect_error(&e, &[bounds, "beyond f32"]);
    assert!(!Path::new(&out).exists() || read_rays(Path::new(&out)).unwrap().len() == 48, "no new file");
    let exr = s(&dir.path().join("h.exr"));
    let e = expect_error(&trilab(&["render", "--scene", &huge, "--out", &exr, "--spp", "1"], 60), &[bounds]);
    assert!(!e.contains("must be finite"), "{e}");
    assert!(!dir.path().join("h.exr").exists());
}

/// The plane y = 0 (albedo 0.8, normal +y), seen from above under a sky and a sun of radius
/// 10 degrees: every path hits the plane once and leaves to the sky, so the radiance is exactly
/// `albedo / pi * (E_sky + E_sun)` with `E_sky = pi h + 2 pi / 3 (z - h)` (the gradient over the
/// upper hemisphere) and `E_sun = sun irradiance * cos(sun, +y)` (`Sky`'s docs), in f64. Next-event
/// estimation with MIS and BSDF sampling alone both converge to it (within 5 standard errors of
/// their own pixel spread), and next-event estimation with much less noise.
#[test]
fn sun_next_event_estimation_with_mis_converges_to_the_analytic_radiance() {
    let l = 10.0f32;
    let mesh =
        Mesh::from_triangles(vec![[-l, 0.0, -l], [l, 0.0, -l], [l, 0.0, l], [-l, 0.0, l]], vec![[0, 2, 1], [0, 3, 2]]);
    let sky = Sky {
        zenith: [0.1, 0.3, 0.6],
        horizon: [0.7, 0.6, 0.5],
        ground: [5.0, 5.0, 5.0], // never seen: a wrong ground would show
        sun_dir: [0.3, 1.0, 0.2],
        sun_radius_degrees: 10.0,
        sun_irradiance: [1.0, 2.0, 0.5],
    };
    let albedo = f64::from(mesh.materials[0].gpu.diffuse[0]);
    let e_sky = sky.sky_irradiance_up();
    let e_sun = sky.sun_irradiance_on(DVec3::Y);
    let expected: [f64; 3] = std::array::from_fn(|c| albedo / std::f64::consts::PI * (e_sky[c] + e_sun[c]));
    let results = common::with_gpu(240, move |ctx| {
        let host = HostScene::build("plane", &mesh, &BuildOptions::new(4)).unwrap();
        [true, false].map(|next_event| {
            let mut s = RenderSettings::paper(&mesh);
            (s.width, s.height, s.spp, s.submit_ms, s.next_event) = (64, 64, 64, 100.0, next_event);
            s.camera = Camera::look(glam::Vec3::new(0.0, 1.0, 0.0), glam::Vec3::NEG_Y, glam::Vec3::NEG_Z, 0.5);
            s.sky = Some(sky);
            let target =
                RenderTarget::new(ctx, &host, Method::Mt.into(), KernelChoice::Specialised, s.pixels(), false).unwrap();
            let r = render::render(ctx, &target, &s, &mut |_| true).unwrap();
            assert_eq!(r.dropped_samples, 0);
            (r.image(), r.shadow_rays)
        })
    });
    let mut sems = Vec::new();
    for ((image, shadow_rays), name) in results.iter().zip(["next-event estimation + MIS", "BSDF sampling only"]) {
        assert!(image.iter().all(|p| p[3] == 1.0), "{name}: every pixel sees the plane");
        assert_eq!(*shadow_rays > 0, name.starts_with("next"), "{name}: {shadow_rays} occlusion rays");
        let n = image.len() as f64;
        let mut sem_sum = 0.0;
        for c in 0..3 {
            let mean = image.iter().map(|p| f64::from(p[c])).sum::<f64>() / n;
            let var = image.iter().map(|p| (f64::from(p[c]) - mean).powi(2)).sum::<f64>() / (n - 1.0);
            let sem = (var / n).sqrt();
            let tol = 5.0 * sem + 1e-3 * expected[c];
            assert!(
                (mean - expected[c]).abs() < tol,
                "{name}, channel {c}: mean {mean}, analytic {}, tolerance {tol}",
                expected[c]
            );
            sem_sum += sem;
        }
        sems.push(sem_sum);
    }
    assert!(sems[0] * 3.0 < sems[1], "next-event estimation should be far less noisy: {sems:?}");
}
