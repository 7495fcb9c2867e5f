//! Same inputs and seed twice => bitwise-identical outputs on the same device: the ray files
//! of every generator, the hits of every method (closest and any), the render's EXR, PNG and
//! JSON (timing fields aside), and the BVH (nodes and prim ids) and every encoder's bytes.
//! The CLI where a run is cheap, the library otherwise.

mod common;

use std::path::Path;
use std::process::Command;

use common::{bunny, with_gpu};
use trilab::bvh::{BuildOptions, Builder, Bvh, LeafPolicy};
use trilab::encoding::Method;
use trilab::encoding::Raycast;
use trilab::gpu::RaycastOptions;
use trilab::pipeline::{HostScene, SceneRequest};

fn trilab(args: &[String]) {
    let o = Command::new(env!("CARGO_BIN_EXE_trilab")).args(args).output().unwrap();
    assert!(o.status.success(), "trilab {args:?}: {}", String::from_utf8_lossy(&o.stderr));
}

fn s(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

fn args(a: &[&str]) -> Vec<String> {
    a.iter().map(|x| x.to_string()).collect()
}

#[test]
fn every_ray_generator_writes_the_same_file_twice() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let gens: [&[&str]; 3] = [
        &["primary", "--width", "40", "--height", "30"],
        &["diffuse", "--width", "20", "--height", "15", "--per-hit", "2", "--seed", "11"],
        &["random", "--count", "3000", "--seed", "11"],
    ];
    for g in gens {
        let files: Vec<Vec<u8>> = (0..2)
            .map(|i| {
                let out = dir.path().join(format!("{}-{i}.rays", g[0]));
                trilab(&[args(&["rays"]), args(g), args(&["--scene", &scene, "--out", &s(&out)])].concat());
                std::fs::read(&out).unwrap()
            })
            .collect();
        assert!(files[0].len() > 1000, "{}: {} bytes", g[0], files[0].len());
        assert!(files[0] == files[1], "rays {}: two runs differ", g[0]);
    }
    // A different seed gives different rays (the comparison can fail).
    let other = dir.path().join("other.rays");
    trilab(&args(&["rays", "random", "--count", "3000", "--seed", "12", "--scene", &scene, "--out", &s(&other)]));
    assert!(std::fs::read(&other).unwrap() != std::fs::read(dir.path().join("random-0.rays")).unwrap());
}

#[test]
fn every_method_casts_the_same_hits_twice() {
    with_gpu(600, |ctx| {
        let mesh = bunny();
        let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
        let rays = trilab::rays::random_rays(&mesh.bounds(), 4000, 5);
        let opts = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 1024 };
        for m in trilab::conditioning::available_methods(&ctx.capabilities()) {
            let scene = host.upload(ctx, &SceneRequest::new(m)).unwrap();
            for kind in [Raycast::Closest, Raycast::Any] {
                let k = scene.kernel(ctx, kind).unwrap();
                let a = scene.cast_with(ctx, &k, &rays, &opts).unwrap().hits;
                let b = scene.cast_with(ctx, &k, &rays, &opts).unwrap().hits;
                assert!(a.iter().filter(|h| h.is_hit()).count() > 100, "{}: too few hits to mean anything", k.name);
                assert!(
                    bytemuck::cast_slice::<_, u8>(&a) == bytemuck::cast_slice::<_, u8>(&b),
                    "{}: hits differ",
                    k.name
                );
            }
        }
    });
}

#[test]
fn render_writes_the_same_exr_png_and_json_twice() {
    let dir = tempfile::tempdir().unwrap();
    let scene = s(&common::root().join("scenes/bunny.obj"));
    let outs: Vec<_> = (0..2)
        .map(|i| {
            let out = dir.path().join(format!("r{i}.exr"));
            trilab(&args(&[
                "render",
                "--scene",
                &scene,
                "--width",
                "40",
                "--height",
                "30",
                "--spp",
                "6",
                "--seed",
                "9",
                "--method",
                "unit",
                "--quiet",
                "--out",
                &s(&out),
            ]));
            let json: serde_json::Value =
                serde_json::from_slice(&std::fs::read(dir.path().join(format!("r{i}.json"))).unwrap()).unwrap();
            (std::fs::read(&out).unwrap(), std::fs::read(dir.path().join(format!("r{i}.png"))).unwrap(), json)
        })
        .collect();
    assert!(outs[0].0 == outs[1].0, "EXR differs");
    assert!(outs[0].1 == outs[1].1, "PNG differs");
    // Timing, and what timing decides (how the passes were cut into submits), may differ.
    let strip = |mut j: serde_json::Value| {
        for k in ["gpu_ms", "wall_ms", "build_ms", "samples_per_second", "mrays_per_second", "submits"] {
            assert!(j.as_object_mut().unwrap().remove(k).is_some(), "JSON lacks {k}");
        }
        j
    };
    let (a, b) = (strip(outs[0].2.clone()), strip(outs[1].2.clone()));
    assert_eq!(a, b);
    assert_eq!(a["spp_done"], 6);
}

#[test]
fn bvh_and_every_encoding_are_the_same_bytes_twice() {
    let mesh = bunny();
    for builder in [Builder::Binned { bins: 32 }, Builder::Sweep] {
        for leaf_policy in [LeafPolicy::Fill, LeafPolicy::Sah] {
            for sah_group in [1, 4] {
                let o = BuildOptions { builder, leaf_policy, sah_group, ..BuildOptions::new(4) };
                let (a, b) = (Bvh::build(&mesh, &o), Bvh::build(&mesh, &o));
                let what = format!("{builder:?} {leaf_policy} sah_group {sah_group}");
                assert!(
                    bytemuck::cast_slice::<_, u8>(&a.nodes) == bytemuck::cast_slice::<_, u8>(&b.nodes),
                    "{what}: nodes"
                );
                assert_eq!(a.prim_ids, b.prim_ids, "{what}: prim ids");
                for m in Method::ALL {
                    let (ea, eb) = (m.encode(&mesh, &a), m.encode(&mesh, &b));
                    for (x, y) in ea.buffers().iter().zip(eb.buffers()) {
                        assert!(x.bytes == y.bytes, "{what}: {m} buffer `{}` differs", x.name);
                    }
                }
            }
        }
    }
}
