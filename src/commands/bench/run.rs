//! Running a bench: the peers checked first, then per scene its kernels uploaded, and per ray
//! set one interleaved measurement of every kernel and peer program, each validated against the
//! f64 reference before its speed becomes a row.

use std::collections::hash_map::{Entry, HashMap};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use super::plan::BenchOptions;
use super::report::{rate, row, BenchReport, Tracer};
use crate::agreement::compare_closest;
use crate::encoding::{Raycast, Traversal};
use crate::error::{Error, Result};
use crate::gpu::{AccelStats, AccelStructure, Context, Kernel, Peer, PeerTracer, RaycastOptions, TraversalSummary};
use crate::matrix::{KernelCell, KernelLabel};
use crate::pipeline::{DeviceScene, HostScene};
use crate::rays::order::RayOrder;
use crate::rays::{self, Ray};
use crate::reference::RefHit;
use crate::scene::{load_obj, Mesh};
use crate::services::efficiency;
use crate::services::peer_report::{PeerComparison, TrilabBest};
use crate::services::peers::{self, EmbreeApi, PeerKind, PeerProgram, PeerResult, PeerRound, PeerSet};
use crate::services::provenance::Provenance;
use crate::services::rayset::{ray_sets, RaySet};
use crate::services::roofline::RooflineReport;
use crate::services::validate::{interleaved_with, mrays_summary, Job, RoundJob};
use crate::timeline;

/// The driver's peers get batches of about this long per submit.
const PEER_SUBMIT_MS: f64 = 500.0;

/// The options with what the device cannot run left out (`matrix::KernelAxes::for_device`),
/// a note each.
pub fn for_device(ctx: &Context, o: &BenchOptions, notes: &mut Vec<String>) -> Result<BenchOptions> {
    Ok(BenchOptions { axes: o.axes.for_device(&ctx.capabilities(), notes)?, ..o.clone() })
}

pub fn run(ctx: &Context, o: &BenchOptions, mut progress: impl FnMut(&str)) -> Result<BenchReport> {
    o.sizes.check_memory()?;
    let mut device_notes = vec![];
    let o = &for_device(ctx, o, &mut device_notes)?;
    for note in &device_notes {
        progress(note);
    }
    let mut report = BenchReport {
        provenance: Provenance::of(ctx),
        leaf_size: o.build.max_leaf_size,
        recipe: o.recipe(),
        repeat: o.repeat,
        rows: vec![],
        peers: vec![],
        accel: vec![],
        driver_notes: vec![],
        notes: device_notes,
        shard: o.shard,
        plan: vec![],
    };
    o.check_shard()?;
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let checking = timeline::span("peer", "peers: check the programs");
    let programs = peer_programs(o, tmp.path(), &mut report, &mut progress)?;
    drop(checking);
    let driver = driver_tracers(ctx, o, &mut report, &mut progress)?;
    let peer_names: Vec<String> = programs.iter().map(|p| p.kind.to_string()).collect();
    let driver_peers: Vec<Peer> = driver.iter().map(PeerTracer::peer).collect();
    report.plan = super::plan_cells(o, &driver_peers, &peer_names);
    for note in o.axes.notes() {
        progress(&note);
        report.notes.push(note);
    }
    for (scene_index, scene_path) in o.scenes.iter().enumerate() {
        if !o.split().runs(scene_index, 0) {
            continue;
        }
        let name = crate::scene::scene_name(scene_path);
        let _scene_span = timeline::span_with("scene", || format!("scene {name}"));
        let _scene_label = timeline::labels(|| vec![("scene", name.clone().into())]);
        let mesh = load_obj(scene_path)?;
        // The peers read the scene as we loaded it (same triangles, same ids, any scene spec).
        let scene_obj = tmp.path().join(format!("scene{scene_index}.obj"));
        if !programs.is_empty() {
            peers::write_obj(&mesh, &scene_obj)?;
        }
        progress(&format!("{name}: {} triangles; making ray sets", mesh.triangle_count()));
        let t = Instant::now();
        let host = HostScene::build(&name, &mesh, &o.build)?;
        let reference = host.reference();
        let making = timeline::span("rays", "ray sets");
        let mut sets = ray_sets(&mesh, &name, &reference, &o.sizes, o.rays_dir.as_deref())?;
        drop(making);
        // An empty set has no speed: it is skipped with a note, and the other sets still run.
        sets.retain(|(set, rays)| {
            if rays.is_empty() {
                let note = format!("{name} {set}: skipped, no rays ({})", o.sizes.why_empty(*set));
                progress(&note);
                report.notes.push(note);
            }
            !rays.is_empty()
        });
        progress(&format!("{name}: ray sets ready in {:.1} s", t.elapsed().as_secs_f64()));
        let uploading = timeline::span("upload", "upload every kernel's scene");
        let scenes = upload_kernels(ctx, o, &host, &name, &mut report, &mut progress)?;
        drop(uploading);
        let accel = match driver.is_empty() {
            false => {
                let _span = timeline::span("peer", "driver acceleration structure");
                let a = AccelStructure::build(ctx, &mesh)?;
                progress(&accel_line(&name, &a.stats));
                report.accel.push((name.clone(), a.stats));
                Some(a)
            }
            true => None,
        };
        let compiling = timeline::span("pipeline", "pipelines");
        let kernels = scenes.iter().map(|s| s.kernel(ctx, Raycast::Closest)).collect::<Result<Vec<_>>>()?;
        drop(compiling);
        // The roofline at every scene's bytes on its access path, before any timing.
        let roofline = match &o.roofline {
            Some(ro) => {
                let _span = timeline::span("roofline", "traversal roofline");
                Some(efficiency::scene_roofline(ctx, &scenes, ro, &mut progress)?)
            }
            None => None,
        };
        // Every set's reference before any timing: the f64 traversal fills every core (and
        // rayon's threads linger), which would slow whichever kernel ran next.
        let referencing = timeline::span("reference", "f64 reference of every set");
        let ref_hits: Vec<Vec<RefHit>> = sets.iter().map(|(_, rays)| reference.trace_all(rays, false)).collect();
        drop(referencing);
        for ((set, rays), ref_hits) in sets.iter().zip(&ref_hits) {
            let set = *set;
            let _set_span = timeline::span_with("set", || format!("{name} {set}")).with("rays", rays.len());
            let _set_label = timeline::labels(|| vec![("set", set.to_string().into())]);
            // The peer programs run in the same rounds, each once a round beside every kernel.
            let rays_file = tmp.path().join(format!("scene{scene_index}.{set}.rays"));
            if !programs.is_empty() {
                rays::write_rays(&rays_file, rays)?;
            }
            let peer_set = PeerSet { scene_obj: &scene_obj, rays_file: &rays_file, mesh: &mesh, rays, ref_hits };
            let on = SetUnderTest { name: &name, mesh: &mesh, set, rays, ref_hits };
            let kernels = Kernels { scenes: &scenes, kernels: &kernels, roofline: roofline.as_ref() };
            let (best, results) =
                kernel_rows(ctx, o, &on, &kernels, &programs, &peer_set, tmp.path(), &mut report, &mut progress)?;
            if let Some(accel) = &accel {
                let _span = timeline::span("peer", "driver peers");
                driver_rows(ctx, o, &on, &driver, accel, &mut report, &mut progress)?;
            }
            if !programs.is_empty() {
                compare_with_peers(&on, best, results, &mut report, &mut progress);
            }
        }
    }
    Ok(report)
}

/// The peer programs asked for, checked first: a missing program, a garbage line or no OpenCL is
/// found before any work; those that pass a probe on a small scene.
fn peer_programs(
    o: &BenchOptions,
    tmp: &Path,
    report: &mut BenchReport,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<PeerProgram>> {
    if o.embree.is_none() && !o.embree_apis.is_empty() {
        return Err(Error::Usage("--embree-apis: Embree's calls need the Embree peer (--embree FILE)".into()));
    }
    if let Some(p) = &o.embree {
        peers::check_program("--embree", p)?;
    }
    if let Some(p) = &o.tinybvh {
        peers::check_program("--tinybvh", p)?;
    }
    let programs = peers::programs(o.embree.as_deref(), &o.embree_apis, o.tinybvh.as_deref(), &o.tinybvh_layouts);
    if !programs.is_empty() {
        progress(&format!("checking {} peer(s) on a small scene", programs.len()));
    }
    let mut peer_notes = vec![];
    let programs = peers::probe(&programs, tmp, &mut peer_notes)?;
    for note in peer_notes {
        progress(&note);
        report.notes.push(note);
    }
    Ok(programs)
}

/// The driver's peers: each traced where asked for and the device has it, else a note.
fn driver_tracers(
    ctx: &Context,
    o: &BenchOptions,
    report: &mut BenchReport,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<PeerTracer>> {
    let mut driver: Vec<PeerTracer> = vec![];
    for &peer in <Peer as crate::named::Named>::ALL {
        let note = if !o.wants(peer) {
            format!("{}: not run (--{peer} off, or auto on a CPU device)", peer.feature())
        } else if let Err(u) = ctx.capabilities().peer(peer) {
            let note = u.to_string();
            progress(&note);
            note
        } else {
            driver.push(PeerTracer::new(ctx, peer, false)?);
            continue;
        };
        report.driver_notes.push(note);
    }
    Ok(driver)
}

/// Every kernel the options ask for, uploaded for this scene. Each method's plan picks its access
/// path before encoding (and fails clearly if the scene cannot fit); its kernels read the scene
/// through that path. Each node order is one more scene of every kernel. A kernel the device
/// cannot run on this scene (a traversal without a kernel on the path the scene needs here) is
/// left out with its reason; the others run.
fn upload_kernels(
    ctx: &Context,
    o: &BenchOptions,
    host: &HostScene,
    name: &str,
    report: &mut BenchReport,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<DeviceScene>> {
    let mut scenes: Vec<DeviceScene> = vec![];
    for req in o.axes.kernels().iter().map(KernelCell::request) {
        match host.upload(ctx, &req) {
            Ok(s) => scenes.push(s),
            Err(Error::Unsupported(why)) => {
                let note = format!("{name}: {why}; left out");
                if !report.notes.contains(&note) {
                    progress(&note);
                    report.notes.push(note);
                }
            }
            Err(e) => return Err(e),
        }
    }
    if scenes.is_empty() {
        return Err(Error::Unsupported(format!(
            "{name}: none of the kernels asked for can run on this scene here: {}",
            report.notes.join("; ")
        )));
    }
    Ok(scenes)
}

/// One scene's ray set under measurement, with its reference hits.
struct SetUnderTest<'a> {
    name: &'a str,
    mesh: &'a Mesh,
    set: RaySet,
    rays: &'a [Ray],
    ref_hits: &'a [RefHit],
}

/// The scene's kernels: each uploaded scene with its closest-hit kernel, and the roofline at
/// their bytes when asked for.
struct Kernels<'a> {
    scenes: &'a [DeviceScene],
    kernels: &'a [Arc<Kernel>],
    roofline: Option<&'a RooflineReport>,
}

/// One interleaved measurement of every kernel (in every ray order) and peer program on a set:
/// a row per kernel, with its efficiency against the roofline when asked for. Returns the best
/// kernel's median Mrays/s and the peers' results.
#[allow(clippy::too_many_arguments)]
fn kernel_rows(
    ctx: &Context,
    o: &BenchOptions,
    on: &SetUnderTest,
    k: &Kernels,
    programs: &[PeerProgram],
    peer_set: &PeerSet,
    tmp: &Path,
    report: &mut BenchReport,
    progress: &mut impl FnMut(&str),
) -> Result<(f64, Vec<PeerResult>)> {
    let SetUnderTest { name, mesh, set, rays, ref_hits } = *on;
    let mut best: f64 = 0.0;
    let label = |scene: &DeviceScene, order: RayOrder| KernelLabel {
        method: scene.method,
        layout: Some(scene.layout),
        traversal: scene.traversal,
        node_order: scene.node_order,
        order,
        access: scene.access,
    };
    let jobs: Vec<Job> = k
        .scenes
        .iter()
        .zip(k.kernels)
        .flat_map(|(scene, kernel)| o.axes.orders().into_iter().map(move |order| (scene, kernel, order)))
        .map(|(scene, kernel, order)| Job { scene, kernel, rays, ref_hits, order })
        .collect();
    let mut peer_rounds: Vec<PeerRound> = (programs.iter().enumerate())
        .map(|(i, p)| PeerRound::new(p, peer_set, tmp.join(format!("peer{i}.hits"))))
        .collect();
    let mut others: Vec<&mut dyn RoundJob> = peer_rounds.iter_mut().map(|p| p as &mut dyn RoundJob).collect();
    let rounds = timeline::span("rounds", "interleaved rounds").with("kernels", jobs.len()).with("peers", others.len());
    let measured = interleaved_with(ctx, mesh, &jobs, &mut others, o.warmup, o.repeat, o.batch_rays).map_err(
        |(i, e)| match jobs.get(i) {
            Some(j) => Error::Usage(format!("{name} {set} {}: {e}", label(j.scene, j.order))),
            None => Error::Usage(format!("{name} {set}: {e}")),
        },
    )?;
    drop(rounds);
    drop(others);
    let results: Vec<PeerResult> = peer_rounds.into_iter().map(PeerRound::finish).collect();
    // Each kernel's traversal counts on this set, cast once whatever its nodes' order (the walk
    // does not depend on it: tests/node_orders_gpu.rs), on the first scene of that kernel; once
    // per ray order where its lanes walk together (packets: which rays share a subgroup
    // changes the walk), else once however many orders it ran in.
    let mut counts: HashMap<(usize, usize), Option<Vec<crate::gpu::TraversalCounts>>> = HashMap::new();
    // The order each ray order dispatched the rays in, sorted once for every kernel's
    // lanes busy (which rays share a subgroup).
    let orders = o.axes.orders();
    let mut dispatched: Vec<Option<Option<Vec<u32>>>> = vec![None; orders.len()];
    for (job, m) in jobs.iter().zip(measured) {
        let (scene, order) = (job.scene, job.order);
        let (ms, agreement) = (m.kernel_ms, m.agreement);
        let mr = mrays_summary(rays.len(), ms);
        progress(&format!(
            "{name} {set} {}: {:.2} Mrays/s ({:.1} ms), {}",
            label(scene, order),
            mr.median,
            ms.median,
            agreement.summary()
        ));
        best = best.max(mr.median);
        let tracer = Tracer::Method(scene.method);
        let bytes = (scene.bytes, Some(scene.access));
        let mut r = row(name, mesh, set, rays, tracer, Some(o), bytes, ms, &agreement);
        r.layout = Some(scene.layout);
        r.traversal = Some(scene.traversal);
        r.node_order = Some(scene.node_order);
        r.order = Some(order);
        r.reorder_ms = (order != RayOrder::Given).then_some(m.reorder_ms);
        // The roofline's figures, and the hybrid's switch rate, come from the stats kernel.
        let switches = scene.traversal == Traversal::Hybrid;
        if k.roofline.is_some() || switches {
            let kernel = |s: &DeviceScene| (s.method, s.layout, s.traversal, s.access);
            let i =
                k.scenes.iter().position(|s| kernel(s) == kernel(scene)).expect("a job's scene is one of the scenes");
            // The lanes a subgroup's rays keep busy depend on which rays share it: the
            // order the kernel got them in (the sort is deterministic).
            let oi = orders.iter().position(|&x| x == order).expect("a job's order is one of the orders");
            let d = dispatched[oi].get_or_insert_with(|| order.permutation(rays));
            let together = scene.traversal.walks_together();
            let c = match counts.entry((i, if together { oi } else { 0 })) {
                Entry::Occupied(e) => e.into_mut(),
                Entry::Vacant(e) => {
                    let _span = timeline::span("counts", "traversal counts (stats kernel)");
                    let cast_in = if together { d.as_deref() } else { None };
                    e.insert(efficiency::fetch_counts(ctx, &k.scenes[i], rays, cast_in, o.batch_rays)?)
                }
            };
            if let Some(roof) = k.roofline {
                let lanes = ctx.info().subgroup_size;
                r.roofline = c.as_deref().and_then(|c| efficiency::efficiency(scene, roof, mr, c, lanes, d.as_deref()));
            }
            if switches {
                r.switched = c.as_deref().and_then(|c| TraversalSummary::of(c).switched);
            }
        }
        report.rows.push(r);
    }
    Ok((best, results))
}

/// Every driver peer over the scene's one structure (built whenever there is a peer). The
/// driver's answer may differ on edge rays: report the agreement, refuse only impossible values
/// (NaN, ids out of range, t outside the interval).
fn driver_rows(
    ctx: &Context,
    o: &BenchOptions,
    on: &SetUnderTest,
    driver: &[PeerTracer],
    accel: &AccelStructure,
    report: &mut BenchReport,
    progress: &mut impl FnMut(&str),
) -> Result<()> {
    let SetUnderTest { name, mesh, set, rays, ref_hits } = *on;
    for tracer in driver {
        let peer = tracer.peer();
        let batch = tracer.batch_for(ctx, accel, rays, PEER_SUBMIT_MS, o.batch_rays)?;
        let opts = RaycastOptions { warmup: o.warmup, repeat: o.repeat, batch_rays: batch };
        let res = tracer.cast(ctx, accel, rays, &opts)?;
        let agreement = compare_closest(mesh, rays, &res.hits, ref_hits);
        let ms = res.time_ms()?;
        progress(&format!(
            "{name} {set} {peer}: {} Mrays/s ({:.1} ms, {} rays per submit), {}",
            rate(crate::services::validate::mrays_per_s(rays.len(), ms.median)),
            ms.median,
            batch,
            agreement.summary()
        ));
        if !agreement.invalid.is_empty() {
            return Err(Error::Usage(format!(
                "{name} {set} {peer}: {} invalid results, e.g. ray {}: {}; not reporting a speed",
                agreement.invalid.len(),
                agreement.invalid[0].0,
                agreement.invalid[0].1
            )));
        }
        let bytes = (accel.stats.blas_bytes + accel.stats.tlas_bytes) as usize;
        report.rows.push(row(name, mesh, set, rays, Tracer::Peer(peer), None, (bytes, None), ms, &agreement));
    }
    Ok(())
}

/// The peer programs' results on a set beside trilab's fastest row of it: each row learns
/// Embree's rtcIntersect1 rate, and the report one comparison.
fn compare_with_peers(
    on: &SetUnderTest,
    best: f64,
    results: Vec<PeerResult>,
    report: &mut BenchReport,
    progress: &mut impl FnMut(&str),
) {
    let SetUnderTest { name, set, rays, .. } = *on;
    for r in &results {
        progress(&format!("{name} {set} {}", r.progress(best)));
    }
    if let Some(e) = results.iter().find(|r| r.peer == PeerKind::Embree(EmbreeApi::Ray1)).and_then(|r| r.mrays_per_s())
    {
        for r in report.rows.iter_mut().filter(|r| r.scene == name && r.ray_set == set) {
            r.embree_mrays_per_s = Some(e);
        }
    }
    let mine = report.rows.iter().filter(|r| r.scene == name && r.ray_set == set);
    let best = TrilabBest::fastest(mine.filter_map(|r| match r.method {
        Tracer::Method(m) => Some((r.label(m), r.layout, r.mrays_per_s)),
        Tracer::Peer(_) => None, // the driver's ray tracing is not ours
    }));
    report.peers.push(PeerComparison::new(name, set, rays.len(), best, results));
}

/// The progress line of the driver's acceleration structure.
fn accel_line(name: &str, s: &AccelStats) -> String {
    format!(
        "{name}: driver BLAS {} B + TLAS {} B, built in {}",
        s.blas_bytes,
        s.tlas_bytes,
        s.blas_build_ms
            .zip(s.tlas_build_ms)
            .map_or_else(|| format!("{:.1} ms (wall)", s.wall_ms), |(b, t)| format!("{b:.2} + {t:.2} ms (GPU)"))
    )
}
