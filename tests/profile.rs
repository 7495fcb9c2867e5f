//! `trilab profile`'s measurements checked against what they must be: invocation counts against
//! the dispatch, the clock and size variants' hits against the default kernel's (and the f64
//! reference), and each feature reported unsupported exactly when the device lacks it.

mod common;

use trilab::agreement::compare_closest;
use trilab::bvh::{BuildOptions, Bvh};
use trilab::commands::profile::{self, differing_hits, dispatch_once, sweep, ProfileOptions, Status};
use trilab::encoding::{Method, Raycast};
use trilab::gpu::{Context, PipelineOptions, RaycastOptions};
use trilab::pipeline::{DeviceScene, HostScene, SceneRequest};
use trilab::rays::{primary_rays, random_rays, Camera, Ray};
use trilab::reference::Reference;
use trilab::scene::Mesh;
use trilab::services::rayset::RaySetSizes;
use trilab::shared::{SPEC_ID_WORKGROUP_SIZE, WORKGROUP_SIZE};

/// The bunny, its BVH, an uploaded scene for `method`, and `n` random rays.
fn setup(ctx: &Context, method: Method, n: usize) -> (Mesh, Bvh, DeviceScene, Vec<Ray>) {
    let mesh = common::bunny();
    let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
    let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
    let bvh = host.bvh;
    let rays = random_rays(&mesh.bounds(), n, 99);
    (mesh, bvh, scene, rays)
}

fn assert_matches_reference(mesh: &Mesh, bvh: &Bvh, rays: &[Ray], hits: &[trilab::rays::Hit], what: &str) {
    let reference = Reference::new(mesh, bvh).trace_all(rays, false);
    let a = compare_closest(mesh, rays, hits, &reference);
    assert!(a.passes(profile::MIN_AGREEMENT), "{what}: {}", a.summary());
}

#[test]
fn pipeline_statistics_count_every_invocation_dispatched() {
    common::with_gpu(300, |ctx| {
        // 777 rays: no workgroup size divides it, so the count includes the idle invocations.
        let (mesh, bvh, scene, rays) = setup(ctx, Method::Mt, 777);
        if !ctx.enabled().pipeline_statistics_query {
            assert!(!ctx.info().pipeline_statistics_query);
            assert!(dispatch_once(ctx, &scene.kernel(ctx, Raycast::Closest).unwrap(), &scene, &rays, true).is_err());
            return;
        }
        let (sizes, _) = sweep::workgroup_sizes(ctx.info(), &[32, 64, 128, 256]);
        assert!(sizes.contains(&WORKGROUP_SIZE));
        for s in sizes {
            let k = ctx
                .create_kernel_specialized(
                    scene.kernel_source(Raycast::Closest).unwrap(),
                    &[(SPEC_ID_WORKGROUP_SIZE, s)],
                )
                .unwrap();
            let d = dispatch_once(ctx, &k, &scene, &rays, true).unwrap();
            let expected = (rays.len() as u64).div_ceil(u64::from(s)) * u64::from(s);
            assert_eq!(d.dispatched_invocations(), expected, "workgroup size {s}");
            assert!(expected > rays.len() as u64);
            assert_eq!(d.compute_shader_invocations, Some(expected), "workgroup size {s}: COMPUTE_SHADER_INVOCATIONS");
            assert_matches_reference(&mesh, &bvh, &rays, &d.hits, &format!("workgroup size {s}"));
        }
    });
}

#[test]
fn clock_variant_hits_equal_closest_and_every_ray_gets_ticks() {
    common::with_gpu(300, |ctx| {
        if !ctx.enabled().shader_clock {
            assert!(!ctx.info().shader_clock.is_some_and(|(subgroup, _)| subgroup));
            return;
        }
        for method in Method::ALL {
            let (mesh, bvh, scene, mut rays) = setup(ctx, method, 2000);
            rays.extend(primary_rays(&Camera::framing(&mesh.bounds()), 64, 48));
            let closest = scene.kernel(ctx, Raycast::Closest).unwrap();
            let clock = scene.kernel(ctx, Raycast::Clock).unwrap();
            let c = dispatch_once(ctx, &closest, &scene, &rays, false).unwrap();
            let started = std::time::Instant::now();
            let k = dispatch_once(ctx, &clock, &scene, &rays, false).unwrap();
            let took = started.elapsed();
            assert!(c.cycles.is_none());
            assert_eq!(differing_hits(&c.hits, &k.hits), 0, "{method}: clock variant's hits differ from closest");
            assert_matches_reference(&mesh, &bvh, &rays, &k.hits, &format!("{method} clock"));
            let cycles = k.cycles.unwrap();
            assert_eq!(cycles.len(), rays.len());
            assert!(cycles.iter().all(|&t| t > 0), "{method}: a ray with 0 ticks");
            assert!(cycles.iter().any(|&t| t != cycles[0]), "{method}: every ray has the same tick count");
            // Issue 39: this failed once in CI ("a tick count saturated"). The kernel wrote one
            // mark for two things: a count beyond 32 bits, and a clock that read lower at the end.
            // On this host the clock does not step back (a thread moved between the two CPUs 20,000
            // times read the TSC lower 0 times), so the ray most likely saw more than 2^32 ticks:
            // its thread stopped for seconds on a loaded CI host. Now the two are
            // told apart: a step back is a driver finding and fails; a count beyond 32 bits is
            // possible only when the dispatch itself took a second or more (2^32 ticks at any
            // clock up to 4.3 GHz), and fails in a dispatch faster than that.
            let stats = trilab::commands::profile::clock::CycleStats::of(&cycles).unwrap();
            assert_eq!(stats.stepped_back, 0, "{method}: the shader clock read lower at the end of a ray");
            assert!(
                stats.saturated == 0 || took >= std::time::Duration::from_secs(1),
                "{method}: {} tick counts beyond 32 bits in a dispatch of {took:?}",
                stats.saturated
            );
        }
    });
}

#[test]
fn workgroup_size_specialisation_gives_identical_hits_at_each_size() {
    common::with_gpu(300, |ctx| {
        for method in [Method::Unit, Method::QuadMt] {
            let (mesh, bvh, scene, rays) = setup(ctx, method, 3000);
            let opts = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
            let default = scene.kernel(ctx, Raycast::Closest).unwrap();
            assert_eq!(default.layout.local_size.0, WORKGROUP_SIZE);
            let base = scene.cast_with(ctx, &default, &rays, &opts).unwrap();
            assert_matches_reference(&mesh, &bvh, &rays, &base.hits, &format!("{method} default"));
            let (sizes, _) = sweep::workgroup_sizes(ctx.info(), &[32, 64, 128, 256]);
            // Vulkan guarantees at least 128 invocations and 128 along x.
            assert!(sizes.starts_with(&[32, 64, 128]), "{sizes:?}");
            for s in sizes {
                let k = ctx
                    .create_kernel_specialized(
                        scene.kernel_source(Raycast::Closest).unwrap(),
                        &[(SPEC_ID_WORKGROUP_SIZE, s)],
                    )
                    .unwrap();
                assert_eq!(k.layout.local_size, (s, 1, 1), "reflection after specialisation");
                let r = scene.cast_with(ctx, &k, &rays, &opts).unwrap();
                assert_eq!(differing_hits(&r.hits, &base.hits), 0, "{method}: workgroup size {s}");
            }
        }
    });
}

#[test]
fn subgroup_size_sweep_runs_every_allowed_size_or_says_why_not() {
    common::with_gpu(300, |ctx| {
        let info = ctx.info();
        let en = *ctx.enabled();
        match sweep::subgroup_sizes(info, &en, WORKGROUP_SIZE) {
            Err(why) => {
                assert!(!en.subgroup_size_control || !info.required_subgroup_size_compute, "{why}");
                assert!(why.starts_with("unsupported"), "{why}");
            }
            Ok((sizes, note)) => {
                let (min, max) = info.subgroup_size_control.unwrap();
                if min == max {
                    assert!(note.starts_with(&format!("only size {min}")), "{note}");
                }
                assert!(!sizes.is_empty(), "{note}");
                assert!(sizes.iter().all(|s| s.is_power_of_two() && (min..=max).contains(s)));
                let (mesh, bvh, scene, rays) = setup(ctx, Method::QuadUnit, 3000);
                let opts = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
                let default = scene.kernel(ctx, Raycast::Closest).unwrap();
                let base = scene.cast_with(ctx, &default, &rays, &opts).unwrap();
                assert_matches_reference(&mesh, &bvh, &rays, &base.hits, "default");
                for s in sizes {
                    let k = ctx
                        .create_kernel_with(
                            scene.kernel_source(Raycast::Closest).unwrap(),
                            &PipelineOptions { required_subgroup_size: Some(s), ..Default::default() },
                        )
                        .unwrap();
                    let r = scene.cast_with(ctx, &k, &rays, &opts).unwrap();
                    assert_eq!(differing_hits(&r.hits, &base.hits), 0, "required subgroup size {s}");
                }
            }
        }
    });
}

/// The whole profile on tiny ray sets: executable properties are "unsupported" exactly when the
/// extension is absent, and every section measured where the device has the feature.
#[test]
fn profile_reports_unsupported_exactly_where_features_are_absent() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_owned();
    let report = common::with_gpu(600, move |ctx| {
        let o = ProfileOptions {
            scene: common::root().join("scenes/bunny.obj"),
            methods: vec![Method::Mt, Method::QuadUnit],
            sizes: RaySetSizes { width: 40, height: 30, diffuse_per_hit: 1, random_rays: 1000, ..Default::default() },
            warmup: 1,
            repeat: 2,
            workgroup_sizes: vec![32, 128],
            thread_counts: vec![1, 2],
            exe: Some(env!("CARGO_BIN_EXE_trilab").into()),
            ..Default::default()
        };
        let r = profile::run(ctx, &o, Some(&out), |_| {}).unwrap();
        let info = ctx.info().clone();
        let en = *ctx.enabled();
        (r, info, en, out)
    });
    let (r, info, en, out) = report;
    let has_pep = info.pipeline_executable_properties;
    assert_eq!(r.executable_properties.status == Status::Unsupported, !has_pep);
    if !has_pep {
        let note = &r.executable_properties.note;
        assert_eq!(note, "VK_KHR_pipeline_executable_properties is not enabled");
        assert!(r.executable_properties.rows.is_empty());
    }
    assert_eq!(r.pipeline_statistics.status == Status::Measured, en.pipeline_statistics_query);
    for row in &r.pipeline_statistics.rows {
        assert_eq!(row.data.compute_shader_invocations, row.data.dispatched, "{:?}", row.data);
    }
    assert_eq!(r.shader_clock.status == Status::Measured, en.shader_clock);
    if en.shader_clock {
        for m in ["mt", "quad-unit"] {
            let png = out.join(format!("heatmap-{m}.png"));
            let img = image::open(&png).unwrap();
            // The 40x30 ray image scaled up to a readable size, with a title, axes and a colour bar.
            assert!(img.width() >= 480 + 200 && img.height() >= 360 + 60, "{}x{}", img.width(), img.height());
        }
        assert!(r.shader_clock.rows.iter().all(|x| x.data.hits_differing_from_closest == 0));
        assert!(r.heat_scale.is_some());
    }
    assert_eq!(
        r.subgroup_sizes.status == Status::Measured,
        en.subgroup_size_control && info.required_subgroup_size_compute
    );
    assert!(r
        .subgroup_sizes
        .rows
        .iter()
        .chain(&r.workgroup_sizes.rows)
        .all(|x| x.data.hits_differing_from_default == 0));
    assert_eq!(r.workgroup_sizes.rows.len(), 2 * 2);
    assert_eq!(r.timestamps.rows.len(), 2 * 3);
    if trilab::gpu::DriverKind::of(&info) == trilab::gpu::DriverKind::Lavapipe {
        assert_eq!(r.lp_num_threads_scaling.status, Status::Measured);
        let threads: Vec<usize> = r.lp_num_threads_scaling.rows.iter().map(|x| x.data.threads).collect();
        assert_eq!(threads.len(), 2 * 2 * 3, "two thread counts x two methods x three ray sets");
        assert!(threads.contains(&1) && threads.contains(&2));
    } else {
        assert_eq!(r.lp_num_threads_scaling.status, Status::NotApplicable);
    }
    // Every row carries the device, driver and Mesa version.
    let json = serde_json::to_value(&r).unwrap();
    for section in ["timestamps", "pipeline_statistics", "shader_clock", "workgroup_sizes", "lp_num_threads_scaling"] {
        for row in json[section]["rows"].as_array().unwrap() {
            assert_eq!(row["device"], info.name.as_str(), "{section}");
            assert!(row["driver"].is_string() && row.get("mesa_version").is_some(), "{section}");
        }
    }
    let md = profile::markdown::render(&r, "trilab profile (test)");
    assert!(md.contains("## 7. LP_NUM_THREADS scaling"));
}

/// `profile --roofline` (issue 27 item 1): every timing row carries its kernel's fetches per ray
/// (exactly what the kernel's stats variant counts on the same rays, and within the traversal
/// mirror's tolerance of the CPU's counts, as tests/traversal_stats.rs holds them), the roofline
/// at the scene's bytes (> 0) and the efficiency those give at the row's Mrays/s (> 0; not held
/// below 1: a kernel's triangle loads are not all dependent, and this test's short probe is
/// dispatch-bound). Without the flag the JSON, the rows and the table are what they were.
#[test]
fn profile_with_roofline_gives_each_kernel_its_fetches_and_share_of_the_roofline() {
    use trilab::gpu::TraversalSummary;
    use trilab::services::rayset::ray_sets;
    use trilab::services::roofline::RooflineOptions;
    /// Largest relative difference of the mean counters from the CPU mirror's.
    const MEAN_TOLERANCE: f64 = 0.005;
    let methods = [Method::Mt, Method::QuadUnit];
    let sizes = RaySetSizes { width: 24, height: 16, diffuse_per_hit: 1, random_rays: 600, ..Default::default() };
    let (with, without, counted) = common::with_gpu(600, move |ctx| {
        let base = ProfileOptions {
            scene: common::root().join("scenes/bunny.obj"),
            methods: methods.to_vec(),
            sizes,
            warmup: 1,
            repeat: 2,
            workgroup_sizes: vec![],
            ..Default::default()
        };
        let ro = RooflineOptions { invocations: 8192, steps: 16, rounds: 2, ..Default::default() };
        let with = profile::run(ctx, &ProfileOptions { roofline: Some(ro), ..base.clone() }, None, |_| {}).unwrap();
        let without = profile::run(ctx, &base, None, |_| {}).unwrap();
        // The profile's rays (its ray sets are a function of the scene and sizes) on its tree.
        let mesh = common::bunny();
        let host = HostScene::build("bunny", &mesh, &BuildOptions::new(4)).unwrap();
        let sets = ray_sets(&mesh, "bunny", &host.reference(), &sizes, None).unwrap();
        let mut counted = vec![];
        for m in methods {
            let scene = host.upload(ctx, &SceneRequest::new(m)).unwrap();
            for (set, rays) in &sets {
                let opts = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
                let gpu =
                    TraversalSummary::of(&scene.cast(ctx, Raycast::Stats, rays, &opts).unwrap().traversal.unwrap());
                let cpu = trilab::traversal::ray_steps_with(&mesh, &host.bvh, rays, m.conservative_traversal());
                let n = cpu.len() as f64;
                let nodes = cpu.iter().map(|s| s.iterations() as f64).sum::<f64>() / n;
                let triangles = cpu.iter().map(|s| s.triangles as f64).sum::<f64>() / n;
                // Lanes busy from the mirror's fetches, in groups of the subgroup's size.
                let lanes = ctx.info().subgroup_size as usize;
                let fetches: Vec<u64> = cpu.iter().map(|s| (s.iterations() + s.triangles) as u64).collect();
                let (done, paid) = fetches
                    .chunks(lanes)
                    .fold((0, 0), |(d, p), g| (d + g.iter().sum::<u64>(), p + lanes as u64 * g.iter().max().unwrap()));
                counted.push((m, *set, gpu, nodes, triangles, (lanes as u32, done as f64 / paid as f64)));
            }
        }
        (with, without, counted)
    });
    assert_eq!(with.timestamps.rows.len(), methods.len() * 3);
    for row in &with.timestamps.rows {
        let d = &row.data;
        let what = format!("{} {}", row.method, d.ray_set);
        let e = d.roofline.unwrap_or_else(|| panic!("{what}: no roofline efficiency"));
        let (_, _, gpu, cpu_nodes, cpu_triangles, (lanes, busy)) =
            counted.iter().find(|c| c.0 == row.method && c.1 == d.ray_set).expect("counted on every set");
        assert_eq!((e.nodes_per_ray, e.triangles_per_ray), (gpu.nodes.mean, gpu.triangles.mean), "{what}");
        let rel = |a: f64, b: f64| (a - b).abs() / b.max(1e-12);
        assert!(rel(e.nodes_per_ray, *cpu_nodes) <= MEAN_TOLERANCE, "{what}: {e:?} against CPU {cpu_nodes}");
        assert!(rel(e.triangles_per_ray, *cpu_triangles) <= MEAN_TOLERANCE, "{what}: {e:?} against {cpu_triangles}");
        assert!(e.nodes_per_ray >= 1.0, "{what}: every ray visits the root");
        assert!(e.roofline_msteps_per_s > 0.0 && e.roofline_msteps_per_s.is_finite(), "{what}: {e:?}");
        let want = e.fetches_per_ray() * d.mrays_per_s / e.roofline_msteps_per_s;
        assert!(rel(e.efficiency, want) < 1e-9, "{what}: {e:?}, want {want}");
        assert!(0.0 < e.efficiency_min && e.efficiency_min <= e.efficiency, "{what}: {e:?}");
        assert!(e.efficiency <= e.efficiency_max && e.efficiency_max.is_finite(), "{what}: {e:?}");
        // The lanes the rays keep busy in lock-step, from the kernel's own counts: the mirror's
        // within the counts' tolerance.
        assert_eq!(e.lanes, *lanes, "{what}: the device's subgroup size");
        let got = e.lanes_busy.unwrap_or_else(|| panic!("{what}: no lanes busy"));
        assert!((got - busy).abs() <= 0.01 && got <= 1.0, "{what}: lanes busy {got}, the mirror's {busy}");
    }
    // The rows: the same cells, and the three figures only with the flag.
    let (rows_with, rows_without) = (profile::rows(&with), profile::rows(&without));
    let cells = |rows: &[trilab::rows::Row]| rows.iter().map(|r| r.key()).collect::<Vec<_>>();
    assert_eq!(cells(&rows_with), cells(&rows_without));
    let timing_rows = |rows: &[trilab::rows::Row]| {
        rows.iter()
            .filter(|r| r.command == "profile" && r.figures.contains_key("mrays_per_s") && r.cell.len() == 6)
            .count()
    };
    assert_eq!(timing_rows(&rows_with), methods.len() * 3);
    for r in rows_with.iter().filter(|r| r.figures.contains_key("roofline_efficiency")) {
        let t = with
            .timestamps
            .rows
            .iter()
            .find(|t| r.cell["method"] == t.method.to_string() && r.cell["set"] == t.data.ray_set.to_string())
            .unwrap();
        let e = t.data.roofline.unwrap();
        let f = &r.figures["roofline_efficiency"];
        assert_eq!((f.median, f.min, f.max), (e.efficiency, e.efficiency_min, e.efficiency_max), "{}", r.key());
        assert_eq!(r.figures["fetches_per_ray"].median, e.fetches_per_ray(), "{}", r.key());
        assert_eq!(Some(r.figures["lanes_busy"].median), e.lanes_busy, "{}", r.key());
    }
    assert_eq!(rows_with.iter().filter(|r| r.figures.contains_key("roofline_efficiency")).count(), methods.len() * 3);
    assert!(rows_without
        .iter()
        .all(|r| ["roofline_efficiency", "fetches_per_ray", "lanes_busy"].iter().all(|f| !r.figures.contains_key(*f))));
    // The JSON and the table.
    let json = serde_json::to_value(&without).unwrap();
    assert!(json["timestamps"]["rows"].as_array().unwrap().iter().all(|r| r.get("roofline").is_none()));
    let json = serde_json::to_value(&with).unwrap();
    assert!(json["timestamps"]["rows"].as_array().unwrap().iter().all(|r| r["roofline"]["efficiency"].is_f64()));
    let md = |r: &profile::ProfileReport| profile::markdown::render(r, "trilab profile (test)");
    let (md_with, md_without) = (md(&with), md(&without));
    assert!(md_with.contains("| fetches/ray | roofline Msteps/s | of roofline % |"), "{md_with}");
    assert!(!md_without.contains("roofline"), "{md_without}");
    assert!(
        md_without.contains("| method | set | rays | dispatches | kernel ms | min..max | Mrays/s | agree % |\n"),
        "{md_without}"
    );
}
