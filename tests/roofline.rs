//! The traversal roofline's kernel (`glsl/roofline.comp`) against its CPU walk
//! (`gpu::roofline::reference`): every access path, at two working sets, bit for bit; and the
//! command's refusals of bad input before any device work.

mod common;

use common::cli::{run, trilab};
use trilab::gpu::roofline::{self, RooflineAccess, RooflinePush};
use trilab::named::Named;

/// Invocations: not a multiple of the workgroup size, so the last workgroup's bounds test runs.
const INVOCATIONS: u32 = 1000;

#[test]
fn every_access_path_walks_exactly_the_cpu_chain() {
    common::with_gpu(300, |ctx| {
        // 4 KiB (128 nodes, in every cache) and 1 MiB (32768 nodes).
        for (nodes, seed) in [(128usize, 3u32), (1 << 15, 11)] {
            let host = roofline::nodes(nodes, seed as u64).unwrap();
            let data = roofline::upload(ctx, "roofline test nodes", &host).unwrap();
            assert!(data.unsupported.is_empty(), "{nodes} nodes: {:?}", data.unsupported);
            let push = RooflinePush { mask: nodes as u32 - 1, steps: 64, count: INVOCATIONS, seed };
            let want = roofline::reference(&host, &push).unwrap();
            for &access in RooflineAccess::ALL {
                let t = roofline::run(ctx, &data, access, &push, 0, 1, true).unwrap();
                let got = t.checksums.unwrap();
                assert_eq!(got.len(), want.len());
                let bad: Vec<usize> = (0..want.len()).filter(|&i| got[i] != want[i]).collect();
                assert!(
                    bad.is_empty(),
                    "{access} path, {nodes} nodes: {} of {INVOCATIONS} checksums differ from the CPU walk, first at \
                     invocation {} ({:#010x}, CPU {:#010x})",
                    bad.len(),
                    bad[0],
                    got[bad[0]],
                    want[bad[0]]
                );
                assert_eq!(t.ms.len(), 1);
            }
            // The kernel reads the nodes it is given: one node's next index changed changes the
            // checksums of the walks through it (the CPU walk says which).
            let mut changed = host.clone();
            let k = (0..nodes).find(|&k| changed[k].next_miss != (k as u32 + 1) % nodes as u32).unwrap();
            changed[k].next_miss = (k as u32 + 1) % nodes as u32;
            changed[k].next_hit ^= 1;
            let want_changed = roofline::reference(&changed, &push).unwrap();
            assert_ne!(want_changed, want, "{nodes} nodes: the change should reach some walk");
            let data = roofline::upload(ctx, "roofline test nodes (changed)", &changed).unwrap();
            let got = roofline::run(ctx, &data, RooflineAccess::Texel, &push, 0, 1, true).unwrap().checksums.unwrap();
            assert_eq!(got, want_changed, "{nodes} nodes: the changed buffer's walk");
        }
    });
}

/// The library call bench and profile use: a rate per access path at any working-set size,
/// read off the rates measured at the two powers of two around it.
#[test]
fn rates_at_a_size_come_from_the_two_sizes_around_it() {
    common::with_gpu(300, |ctx| {
        let o = trilab::services::roofline::RooflineOptions {
            invocations: 8192,
            steps: 16,
            rounds: 1,
            ..Default::default()
        };
        let bytes = 48 << 10;
        let rates = trilab::services::roofline::rates_at(ctx, bytes, &o, |_| {}).unwrap();
        assert_eq!(rates.iter().map(|r| r.0).collect::<Vec<_>>(), RooflineAccess::ALL);
        let around = trilab::services::roofline::measure_at(ctx, bytes, RooflineAccess::ALL, &o, |_| {}).unwrap();
        assert_eq!(around.measured.iter().map(|m| m.cell.bytes).collect::<std::collections::BTreeSet<_>>().len(), 2);
        for (access, r) in rates {
            assert!(r > 0.0 && r.is_finite(), "{access}: {r}");
        }
    });
}

#[test]
fn a_mask_that_does_not_match_the_buffer_is_refused() {
    common::with_gpu(120, |ctx| {
        let host = roofline::nodes(64, 1).unwrap();
        let data = roofline::upload(ctx, "roofline test nodes", &host).unwrap();
        let push = RooflinePush { mask: 127, steps: 4, count: 64, seed: 1 };
        let e = roofline::run(ctx, &data, RooflineAccess::Storage, &push, 0, 1, true).unwrap_err();
        assert!(e.to_string().contains("mask 0x7f for 64 nodes"), "{e}");
    });
}

fn text(o: &std::process::Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Bad input is refused naming the option, before any device is opened: the runs name a device
/// that does not exist, and the error is about the option, not the device.
#[test]
fn bad_options_are_refused_before_any_device_work() {
    let refused = |args: &[&str], needles: &[&str]| {
        let mut a = vec!["roofline", "--device", "no-such-device-xyz"];
        a.extend_from_slice(args);
        let o = trilab(&a, 60);
        let t = text(&o);
        assert!(matches!(o.status.code(), Some(1 | 2)), "trilab {a:?}: exit {:?}:\n{t}", o.status.code());
        assert!(!t.contains("panicked") && !t.contains("no-such-device-xyz"), "trilab {a:?}:\n{t}");
        for n in needles {
            assert!(t.contains(n), "trilab {a:?} should mention `{n}`:\n{t}");
        }
    };
    refused(&["--sizes", "16K,3K"], &["--sizes", "3K", "power of two"]);
    refused(&["--sizes", "32"], &["--sizes", "at least 64 bytes"]);
    refused(&["--sizes", "1T"], &["--sizes", "unknown unit"]);
    refused(&["--sizes", "lots"], &["--sizes", "not a size"]);
    refused(&["--access", "texture"], &["--access", "texture"]);
    refused(&["--rounds", "0"], &["--rounds"]);
    refused(&["--steps", "0"], &["--steps 0"]);
    refused(&["--invocations", "0"], &["--invocations 0"]);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, "x").unwrap();
    refused(&["--out", file.to_str().unwrap()], &["--out"]);
}

#[test]
fn a_small_sweep_writes_its_rows_and_table() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("roofline");
    let o = trilab(
        &[
            "roofline",
            "--sizes",
            "4K,64K",
            "--access",
            "texel,address",
            "--invocations",
            "4096",
            "--steps",
            "16",
            "--rounds",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        240,
    );
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("texel Msteps/s") && t.contains("address Msteps/s") && !t.contains("storage Msteps/s"), "{t}");
    assert!(t.contains("4 KiB") && t.contains("64 KiB"), "{t}");
    let rows = trilab::rows::read(&out.join(trilab::rows::FILE)).unwrap();
    let mut keys: Vec<String> = rows.rows.iter().map(|r| r.key()).collect();
    keys.sort();
    assert_eq!(
        keys,
        [
            "roofline access=address bytes=4096 invocations=4096 steps=16",
            "roofline access=address bytes=65536 invocations=4096 steps=16",
            "roofline access=texel bytes=4096 invocations=4096 steps=16",
            "roofline access=texel bytes=65536 invocations=4096 steps=16",
        ]
    );
    for r in &rows.rows {
        let f = &r.figures["msteps_per_s"];
        assert!(f.min > 0.0 && f.min <= f.median && f.median <= f.max && f.runs == 2, "{}: {f:?}", r.key());
        assert_eq!(f.unit, "Msteps/s");
    }
    assert!(out.join("roofline.md").is_file() && out.join("roofline.json").is_file());
}

/// `bench --roofline`: every kernel row carries its fetches per ray and its share of the roofline
/// at its scene's size; a bench without the flag carries neither.
#[test]
fn bench_with_roofline_adds_each_kernels_share_of_it() {
    let dir = tempfile::tempdir().unwrap();
    let bench = |out: &std::path::Path, roofline: bool| {
        std::fs::create_dir_all(out).unwrap();
        let mut a = vec![
            "bench",
            "--scenes",
            "bunny",
            "--methods",
            "mt",
            "--layouts",
            "bvh2,bvh4",
            "--width",
            "16",
            "--height",
            "16",
            "--diffuse-per-hit",
            "0",
            "--random-rays",
            "500",
            "--repeat",
            "2",
            "--out",
            out.to_str().unwrap(),
        ];
        if roofline {
            a.push("--roofline");
        }
        let o = trilab(&a, 600);
        assert!(o.status.success(), "{}", text(&o));
        (text(&o), trilab::rows::read(&out.join(trilab::rows::FILE)).unwrap())
    };
    let (said, rows) = bench(&dir.path().join("with"), true);
    assert!(said.contains("of roofline %") && said.contains("checksums of"), "{said}");
    let kernels: Vec<_> = rows.rows.iter().filter(|r| r.cell.contains_key("method")).collect();
    assert_eq!(kernels.len(), 4, "mt on bvh2 and bvh4, primary and random rays");
    for r in &kernels {
        let e = &r.figures.get("roofline_efficiency").unwrap_or_else(|| panic!("{}: no roofline_efficiency", r.key()));
        assert!(e.median > 0.0 && e.min <= e.median && e.median <= e.max, "{}: {e:?}", r.key());
        // A ray that enters the tree visits the root and at least one leaf.
        assert!(r.figures["fetches_per_ray"].median >= 1.0, "{}", r.key());
    }
    // bvh4 visits fewer nodes than bvh2 on the same rays (16 vs 8 on random rays, docs/bvh.md).
    let fetches = |layout: &str, set: &str| {
        kernels
            .iter()
            .find(|r| r.cell["layout"] == layout && r.cell["set"] == set)
            .map(|r| r.figures["fetches_per_ray"].median)
            .unwrap()
    };
    assert!(fetches("bvh4", "random") < fetches("bvh2", "random"));
    let (_, rows) = bench(&dir.path().join("without"), false);
    assert!(rows.rows.iter().all(|r| !r.figures.contains_key("roofline_efficiency")));
}

/// `profile --roofline`: its timing table, profile.json and rows.jsonl carry each kernel's fetches
/// per ray and share of the roofline, as bench's do (tests/profile.rs holds the counts to the
/// stats variant's and the CPU's).
#[test]
fn profile_with_roofline_adds_each_kernels_share_of_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("profile");
    let small = "profile --scene bunny --methods mt --width 16 --height 16 --diffuse-per-hit 1 --random-rays 500 \
                 --repeat 1 --workgroup-sizes 64 --no-threads --no-driver-stats --roofline --out";
    let mut args: Vec<&str> = small.split_whitespace().collect();
    args.push(out.to_str().unwrap());
    let o = trilab(&args, 600);
    assert!(o.status.success(), "{}", text(&o));
    let md = std::fs::read_to_string(out.join("profile.md")).unwrap();
    assert!(md.contains("| fetches/ray | roofline Msteps/s | of roofline % |"), "{md}");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("profile.json")).unwrap()).unwrap();
    let timings = json["timestamps"]["rows"].as_array().unwrap();
    assert_eq!(timings.len(), 3, "mt on three ray sets");
    let rows = trilab::rows::read(&out.join(trilab::rows::FILE)).unwrap();
    for t in timings {
        let e = &t["roofline"];
        assert!(e["efficiency"].as_f64().unwrap() > 0.0 && e["roofline_msteps_per_s"].as_f64().unwrap() > 0.0, "{t}");
        let row = rows
            .rows
            .iter()
            .find(|r| r.cell.get("set").map(String::as_str) == t["ray_set"].as_str() && r.cell.len() == 6)
            .unwrap_or_else(|| panic!("no row for {t}"));
        assert_eq!(row.figures["roofline_efficiency"].median, e["efficiency"].as_f64().unwrap(), "{}", row.key());
        assert!(row.figures["fetches_per_ray"].median >= 1.0, "{}", row.key());
    }
}

/// Sizes a path cannot hold are skipped naming the limit, and the other paths still run
/// (`TRILAB_TEST_LIMITS` lowers the device's limits as the scene placement's tests do).
#[test]
fn sizes_past_a_paths_limit_are_skipped_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("roofline");
    let args = [
        "roofline",
        "--sizes",
        "16K,256K",
        "--invocations",
        "2048",
        "--steps",
        "8",
        "--rounds",
        "1",
        "--out",
        out.to_str().unwrap(),
    ];
    let limits = "max_texel_buffer_elements=4096,max_storage_buffer_range=65536";
    let (o, _) = run(&args, None, &[("TRILAB_TEST_LIMITS", limits)], 240);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(
        t.contains("skipped: 256 KiB on the texel path: 16384 texels, more than maxTexelBufferElements (4096)"),
        "{t}"
    );
    assert!(
        t.contains("skipped: 256 KiB on the storage path: 262144 bytes, more than maxStorageBufferRange (65536)"),
        "{t}"
    );
    let rows = trilab::rows::read(&out.join(trilab::rows::FILE)).unwrap();
    let mut keys: Vec<String> = rows.rows.iter().map(|r| format!("{} {}", r.cell["access"], r.cell["bytes"])).collect();
    keys.sort();
    assert_eq!(
        keys,
        ["address 16384", "address 262144", "address32 16384", "address32 262144", "storage 16384", "texel 16384"]
    );
    // Without the address path (no bufferDeviceAddress) and nothing else left: an error saying why.
    let (o, _) = run(
        &["roofline", "--sizes", "256K", "--access", "texel,address", "--out", out.to_str().unwrap()],
        None,
        &[("TRILAB_TEST_LIMITS", "max_texel_buffer_elements=4096,buffer_device_address=0")],
        120,
    );
    let t = text(&o);
    assert_eq!(o.status.code(), Some(1), "{t}");
    assert!(t.contains("nothing to measure") && t.contains("bufferDeviceAddress"), "{t}");
}

/// `bench --roofline`'s lanes busy: for every kernel row, the share of lane-steps that fetch
/// for a ray when the subgroup's rays run in lock-step, in the order the kernel got them. Held
/// to this test's own sum over the CPU mirror's counts (equal to the mt kernel's own on bvh2,
/// tests/traversal_stats.rs) grouped in the rays' dispatch order: as given, and after the
/// octant-origin sort (the sort moves rays between subgroups, so the figure must follow it).
#[test]
fn bench_lanes_busy_follows_the_rays_a_subgroup_traces_together() {
    use trilab::rays::order::RayOrder;
    let dir = tempfile::tempdir().unwrap();
    let rays_dir = dir.path().join("rays");
    std::fs::create_dir_all(&rays_dir).unwrap();
    let out = |set: &str| rays_dir.join(format!("bunny.{set}.rays")).to_str().unwrap().to_string();
    for a in [
        vec!["rays", "primary", "--scene", "bunny", "--width", "24", "--height", "16", "--out", &out("primary")],
        vec!["rays", "diffuse", "--scene", "bunny", "--width", "24", "--height", "16", "--out", &out("diffuse")],
        vec!["rays", "random", "--scene", "bunny", "--random-rays", "3001", "--out", &out("random")],
    ] {
        let o = trilab(&a, 120);
        assert!(o.status.success(), "{}", text(&o));
    }
    let bench_out = dir.path().join("bench");
    std::fs::create_dir_all(&bench_out).unwrap();
    let args = [
        "bench",
        "--scenes",
        "bunny",
        "--methods",
        "mt",
        "--rays-dir",
        rays_dir.to_str().unwrap(),
        "--orders",
        "given,octant-origin",
        "--repeat",
        "1",
        "--roofline",
        "--out",
        bench_out.to_str().unwrap(),
    ];
    let o = trilab(&args, 600);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("lanes busy %"), "{}", text(&o));
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(bench_out.join("bench.json")).unwrap()).unwrap();
    let mesh = common::bunny();
    let bvh = trilab::bvh::Bvh::build(&mesh, &trilab::bvh::BuildOptions::new(4));
    let mut checked = 0;
    let mut busy_by_order = std::collections::BTreeMap::new();
    for row in report["rows"].as_array().unwrap() {
        let set = row["ray_set"].as_str().unwrap();
        let order: RayOrder = row["order"].as_str().unwrap().parse().unwrap();
        let e = &row["roofline"];
        let lanes = e["lanes"].as_u64().unwrap() as usize;
        assert!(lanes >= 1, "{row}");
        let rays = trilab::rays::read_rays(std::path::Path::new(&out(set))).unwrap();
        let steps = trilab::traversal::ray_steps(&mesh, &bvh, &rays);
        let fetches: Vec<u64> = steps.iter().map(|s| (s.inner + s.leaves + s.triangles) as u64).collect();
        let dispatched: Vec<u64> = match order.permutation(&rays) {
            Some(p) => p.iter().map(|&i| fetches[i as usize]).collect(),
            None => fetches.clone(),
        };
        let (mut done, mut paid) = (0u64, 0u64);
        for group in dispatched.chunks(lanes) {
            done += group.iter().sum::<u64>();
            paid += lanes as u64 * group.iter().max().unwrap();
        }
        let want = done as f64 / paid as f64;
        let got = e["lanes_busy"].as_f64().unwrap_or_else(|| panic!("no lanes_busy in {row}"));
        assert!((got - want).abs() < 1e-12, "{set} {order}: lanes busy {got}, want {want}");
        assert!(want > 0.0 && want <= 1.0);
        busy_by_order.insert((set.to_string(), order.to_string()), got);
        checked += 1;
    }
    assert_eq!(checked, 6, "three sets x two orders");
    // The sort changes which rays share a subgroup, and with it the figure.
    assert_ne!(
        busy_by_order[&("random".into(), "given".into())],
        busy_by_order[&("random".into(), "octant-origin".into())]
    );
}
