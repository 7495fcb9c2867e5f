//! Large scenes: memory placements equal the encoded buffers, a scene that does not fit fails before
//! anything is allocated, the address path (`*_address` kernels) equals the texel path and the f64
//! reference, the placement picks the address path by itself when a buffer exceeds one binding,
//! and a million-triangle scene casts correctly through it.

mod common;

use trilab::agreement::{compare_any, compare_closest};
use trilab::bvh::{BuildOptions, Bvh};
use trilab::encoding::{AccessPath, DeviceLimits, Method, Placement, Raycast, SceneAccess};
use trilab::error::Error;
use trilab::gpu::{ContextOptions, RaycastOptions};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::{differing_hits, random_rays};
use trilab::reference::Reference;
use trilab::scene::Mesh;

const OPTS: RaycastOptions = RaycastOptions { warmup: 0, repeat: 1, batch_rays: 1 << 20 };

/// A k x k height field of 2 k^2 triangles with shared vertices (a bumpy sheet: rays from
/// random directions hit it about half the time).
fn sheet(k: u32) -> Mesh {
    let mut pos = Vec::with_capacity(((k + 1) * (k + 1)) as usize);
    for j in 0..=k {
        for i in 0..=k {
            let (x, y) = (i as f32 / k as f32, j as f32 / k as f32);
            let z = 0.05 * ((x * 37.0).sin() * (y * 23.0).cos()) + 0.02 * ((i * 7 + j * 13) % 5) as f32 / k as f32;
            pos.push([x, y, z]);
        }
    }
    let mut tris = Vec::with_capacity((2 * k * k) as usize);
    let v = |i: u32, j: u32| j * (k + 1) + i;
    for j in 0..k {
        for i in 0..k {
            tris.push([v(i, j), v(i + 1, j), v(i + 1, j + 1)]);
            tris.push([v(i, j), v(i + 1, j + 1), v(i, j + 1)]);
        }
    }
    Mesh::from_triangles(pos, tris)
}

#[test]
fn placements_equal_the_encoded_buffer_sizes_on_the_bunny() {
    let mesh = common::bunny();
    for leaf in [1, 4, 7] {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        for m in Method::ALL {
            let placement = Placement::for_bvh(m, &mesh, &bvh);
            let enc = m.encode(&mesh, &bvh);
            let want: Vec<(&str, u32, u64)> =
                enc.buffers().iter().map(|b| (b.name, b.binding, b.bytes.len() as u64)).collect();
            let got: Vec<(&str, u32, u64)> = placement.buffers.iter().map(|b| (b.name, b.binding, b.bytes)).collect();
            assert_eq!(got, want, "{m} leaf {leaf}");
            assert_eq!(placement.bytes(), enc.gpu_bytes() as u64, "{m} leaf {leaf}");
            assert_eq!(Placement::of_encoded(&enc).buffers, placement.buffers, "{m} leaf {leaf}");
        }
    }
}

#[test]
fn a_scene_that_does_not_fit_fails_before_upload_and_one_that_fits_uploads() {
    common::with_gpu(120, |ctx| {
        let mesh = common::bunny();
        let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
        let bvh = &host.bvh;
        let real = ctx.limits().unwrap();
        for m in [Method::Mt, Method::QuadUnit] {
            let placement = Placement::for_bvh(m, &mesh, bvh);
            // Fits as the device is.
            let path = placement.choose("bunny", SceneAccess::Auto, &real).unwrap();
            assert_eq!(path, AccessPath::Texel);
            let gpu = host.upload(ctx, &SceneRequest::new(m)).unwrap();
            assert_eq!(gpu.access, path);
            assert_eq!(gpu.bytes as u64, placement.gpu_bytes());
            // A device with less memory than the scene: the error names everything.
            let small = DeviceLimits { budget_bytes: Some(placement.gpu_bytes() / 2), ..real };
            let e = placement.choose("bunny", SceneAccess::Auto, &small).unwrap_err();
            assert!(matches!(e, Error::SceneTooLarge(_)), "{e}");
            let msg = e.to_string();
            for want in ["bunny", m.name(), "all scene buffers", &placement.gpu_bytes().to_string(), "budget", "try"] {
                assert!(msg.contains(want), "`{want}` missing from: {msg}");
            }
            // Buffers beyond one texel binding, with no address path: storage buffers; beyond one
            // storage binding too: names the buffer and the limit.
            let tight = DeviceLimits { max_texel_buffer_elements: 1000, buffer_device_address: false, ..real };
            assert_eq!(host.place_for(m, None, &SceneRequest::new(m), &tight).unwrap().access, AccessPath::Storage);
            let tight = DeviceLimits { max_storage_buffer_range: 16000, ..tight };
            let msg = host.place_for(m, None, &SceneRequest::new(m), &tight).err().expect("does not fit").to_string();
            assert!(msg.contains("maxStorageBufferRange") && msg.contains("16000"), "{msg}");
            // Forced texel path over the limit suggests the address path.
            let tight = DeviceLimits { max_texel_buffer_elements: 1000, ..real };
            let msg = placement.choose("bunny", SceneAccess::Texel, &tight).unwrap_err().to_string();
            assert!(msg.contains("--scene-access address"), "{msg}");
        }
    });
}

#[test]
fn address_variants_equal_the_texel_variants_and_the_reference_on_the_bunny() {
    let failures = common::with_gpu(300, |ctx| {
        assert!(ctx.enabled().buffer_device_address, "lavapipe has bufferDeviceAddress");
        let mesh = common::bunny();
        let rays = random_rays(&mesh.bounds(), 20_000, 77);
        let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
        let reference = host.reference().trace_all(&rays, false);
        let mut failures = vec![];
        for m in Method::ALL {
            let texel = host.upload(ctx, &SceneRequest::new(m).access(SceneAccess::Texel)).unwrap();
            let address = host.upload(ctx, &SceneRequest::new(m).access(SceneAccess::Address)).unwrap();
            assert_eq!(texel.access, AccessPath::Texel);
            assert_eq!(address.access, AccessPath::Address);
            let mut hits = vec![];
            for kind in [Raycast::Closest, Raycast::Any] {
                for scene in [&texel, &address] {
                    hits.push(scene.cast(ctx, kind, &rays, &OPTS).unwrap().hits);
                }
            }
            // Same arithmetic, only the loads differ: bitwise-equal hits.
            for (a, b, what) in [(0, 1, "closest"), (2, 3, "any")] {
                let d = differing_hits(&hits[a], &hits[b]);
                if d != 0 {
                    failures.push(format!("{m} {what}: {d} rays differ between texel and address paths"));
                }
            }
            let agreement = compare_closest(&mesh, &rays, &hits[1], &reference);
            if !agreement.passes(0.9999) {
                failures.push(format!("{m} closest_address vs reference: {}", agreement.summary()));
            }
            let any = compare_any(&mesh, &rays, &hits[1], &hits[3]);
            if !any.passes() {
                failures.push(format!("{m} any_address: {any:?}"));
            }
        }
        failures
    });
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn a_million_triangles_through_the_automatically_chosen_address_path_match_the_reference() {
    let mesh = sheet(708); // 1,002,528 triangles
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let rays = random_rays(&mesh.bounds(), 20_000, 5);
    let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
    let hits_ref = reference.iter().filter(|h| h.is_hit()).count();
    assert!(hits_ref > 2_000, "the rays should hit the sheet ({hits_ref})");
    // A device whose texel buffers hold 2^20 texels: MT's 1M triangle slots do not fit one.
    let options =
        ContextOptions { test_limits: Some("max_texel_buffer_elements=1048576".into()), ..Default::default() };
    let (agreement, any, path) = common::with_gpu_options(300, options, move |ctx| {
        let host = HostScene::with_bvh("sheet 1M", &mesh, bvh);
        let gpu = host.upload(ctx, &SceneRequest::new(Method::Mt)).unwrap();
        let c = gpu.cast(ctx, Raycast::Closest, &rays, &OPTS).unwrap().hits;
        let a = gpu.cast(ctx, Raycast::Any, &rays, &OPTS).unwrap().hits;
        (compare_closest(&mesh, &rays, &c, &reference), compare_any(&mesh, &rays, &c, &a), gpu.access)
    });
    assert_eq!(path, AccessPath::Address);
    assert!(agreement.passes(0.9999), "{}", agreement.summary());
    assert!(any.passes(), "{any:?}");
}

/// `trilab scale --placement-only` names each layout's node bytes per triangle: the binary tree's
/// exactly, every wide layout's a bound that holds the node buffer really built from the bunny's
/// tree.
#[test]
fn placement_only_prices_every_layouts_nodes() {
    use trilab::encoding::Layout;
    use trilab::named::Named;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("scale");
    let o = common::cli::trilab(
        &["scale", "--scenes", "bunny", "--placement-only", "--methods", "mt", "--out", out.to_str().unwrap()],
        300,
    );
    common::cli::ok(&o);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("scale.json")).unwrap()).unwrap();
    let rows = json["layouts"].as_array().unwrap();
    assert_eq!(rows.len(), Layout::ALL.len());
    let mesh = common::bunny();
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let bytes = |l: Layout| {
        let r = rows.iter().find(|r| r["layout"] == l.name()).unwrap_or_else(|| panic!("no row for {l}"));
        let b = r["node_bytes"].as_u64().unwrap();
        let per_tri = r["node_bytes_per_triangle"].as_f64().unwrap();
        assert!((per_tri - b as f64 / mesh.triangle_count() as f64).abs() < 1e-9, "{l}");
        b
    };
    assert_eq!(bytes(Layout::Bvh2), bvh.nodes.len() as u64 * 32);
    for &l in Layout::ALL.iter().filter(|&&l| l != Layout::Bvh2) {
        let built = l.nodes(&bvh.nodes, &bvh.options).unwrap().expect("a wide layout builds its nodes");
        assert!(built.bytes.len() as u64 <= bytes(l), "{l}: built {} > placed {}", built.bytes.len(), bytes(l));
    }
    let md = std::fs::read_to_string(out.join("scale.md")).unwrap();
    assert!(md.contains("## Node bytes per layout") && md.contains("| bunny | 69451 | bvh8 |"), "{md}");
}
