//! No speed without a correct answer: every harness checks a cast's hits against the CPU f64
//! reference before its time counts (as tinybvh's speed test validates before it reports).

use crate::agreement::{compare_closest, Agreement};
use crate::encoding::Raycast;
use crate::error::{Error, Result};
use crate::gpu::{Context, Kernel, RaycastOptions};
use crate::pipeline::DeviceScene;
use crate::rays::order::{self, RayOrder};
use crate::rays::{Hit, Ray};
use crate::reference::RefHit;
use crate::report::Summary;
use crate::scene::Mesh;

/// Fewest rays that must agree with the f64 reference before a speed is reported.
pub const MIN_AGREEMENT: f64 = 0.9999;

/// Compares GPU hits with the f64 reference; an error (never a reported speed) when fewer than
/// 99.99 % agree (the share of disagreements rounded up to whole rays), any disagreement is
/// unexplained (not an edge, vertex or tie case) or any hit is invalid.
pub fn validate_hits(mesh: &Mesh, rays: &[Ray], hits: &[Hit], ref_hits: &[RefHit]) -> Result<Agreement> {
    let agreement = compare_closest(mesh, rays, hits, ref_hits);
    if !agreement.passes(MIN_AGREEMENT) {
        return Err(Error::Usage(format!(
            "results disagree with the f64 reference ({}); not reporting a speed",
            agreement.summary()
        )));
    }
    Ok(agreement)
}

/// Mrays/s from a kernel-time summary: the median run's rate, and min/max from the slowest and
/// fastest runs.
pub fn mrays_summary(rays: usize, ms: Summary) -> Summary {
    let mr = |ms: f64| mrays_per_s(rays, ms);
    Summary { median: mr(ms.median), min: mr(ms.max), max: mr(ms.min), runs: ms.runs }
}

/// Millions of rays a second: `rays` cast in `ms` milliseconds (the one formula every report
/// uses).
pub fn mrays_per_s(rays: usize, ms: f64) -> f64 {
    rays as f64 / (ms * 1e-3) / 1e6
}

/// One validated ray-casting measurement.
#[derive(Clone, Debug)]
pub struct RayMeasure {
    /// GPU kernel time per run (or host wall time where the queue has no timestamps), ms.
    pub kernel_ms: Summary,
    /// Mrays/s at the median, slowest and fastest run (so `min` comes from `kernel_ms.max`).
    pub mrays_per_s: Summary,
    pub agreement: Agreement,
    pub hits: Vec<Hit>,
}

/// Casts `rays` for the closest hit over `scene` (`opts.warmup` untimed runs, then `opts.repeat`
/// timed ones) and validates the hits against the f64 reference before the time counts: fewer
/// than 99.99 % agreeing rays, an unexplained disagreement or an invalid hit is an error, never a
/// reported speed.
pub fn measure_rays(
    ctx: &Context,
    scene: &DeviceScene,
    mesh: &Mesh,
    rays: &[Ray],
    ref_hits: &[RefHit],
    opts: &RaycastOptions,
) -> Result<RayMeasure> {
    let res = scene.cast(ctx, Raycast::Closest, rays, opts)?;
    let agreement = validate_hits(mesh, rays, &res.hits, ref_hits)?;
    let ms = res.time_ms()?;
    let mrays_per_s = mrays_summary(rays.len(), ms);
    Ok(RayMeasure { kernel_ms: ms, mrays_per_s, agreement, hits: res.hits })
}

/// One kernel on one ray set, for [`interleaved`].
pub struct Job<'a> {
    pub scene: &'a DeviceScene,
    pub kernel: &'a Kernel,
    pub rays: &'a [Ray],
    pub ref_hits: &'a [RefHit],
    /// The order the rays are dispatched in; the time to reorder them and to put the hits back
    /// is part of the job's time.
    pub order: RayOrder,
}

/// One job's validated timings from [`interleaved`].
#[derive(Clone, Debug)]
pub struct Interleaved {
    /// Kernel time per timed round (GPU timestamps, or host wall time without them), ms, with
    /// the host's time to reorder the rays and put the hits back when the job reorders.
    pub kernel_ms: Summary,
    /// The host's reordering time per timed round, ms (0 for [`RayOrder::Given`]).
    pub reorder_ms: Summary,
    /// The last timed round's agreement with the reference and hits.
    pub agreement: Agreement,
    pub hits: Vec<Hit>,
    /// Dispatches per round.
    pub batches: usize,
}

/// Times every job with their rounds interleaved: `warmup` untimed rounds of every job, then
/// `repeat` timed rounds, each running every job once, the job that opens a round rotating, so
/// that a burst of other work on the host lands on all jobs alike rather than on the few timed
/// while it lasted (on a busy 2-core lavapipe host, back-to-back rounds let one kernel's cells
/// read 1.4-1.7x slow together). Every round's hits are validated against the f64 reference
/// before its time counts. An error names the job (its index).
pub fn interleaved(
    ctx: &Context,
    mesh: &Mesh,
    jobs: &[Job],
    warmup: usize,
    repeat: usize,
    batch_rays: usize,
) -> std::result::Result<Vec<Interleaved>, (usize, Error)> {
    let once = RaycastOptions { warmup: 0, repeat: 1, batch_rays };
    let mut times: Vec<Vec<f64>> = vec![vec![]; jobs.len()];
    let mut reorder: Vec<Vec<f64>> = vec![vec![]; jobs.len()];
    let mut last: Vec<Option<(Agreement, Vec<Hit>, usize)>> = vec![None; jobs.len()];
    for round in 0..warmup + repeat.max(1) {
        for k in 0..jobs.len() {
            let i = (k + round) % jobs.len();
            let j = &jobs[i];
            let t = std::time::Instant::now();
            let order = j.order.permutation(j.rays);
            let permuted = order.as_ref().map(|o| order::permute(o, j.rays));
            let mut host_ms = t.elapsed().as_secs_f64() * 1e3;
            let mut res =
                j.scene.cast_with(ctx, j.kernel, permuted.as_deref().unwrap_or(j.rays), &once).map_err(|e| (i, e))?;
            if let Some(o) = &order {
                let t = std::time::Instant::now();
                res.hits = order::unpermute(o, &res.hits);
                host_ms += t.elapsed().as_secs_f64() * 1e3;
            }
            let agreement = validate_hits(mesh, j.rays, &res.hits, j.ref_hits).map_err(|e| (i, e))?;
            if round >= warmup {
                times[i].push(res.time_ms().map_err(|e| (i, e))?.median + host_ms);
                reorder[i].push(host_ms);
                last[i] = Some((agreement, res.hits, res.batches));
            }
        }
    }
    Ok(times
        .iter()
        .zip(&reorder)
        .zip(last)
        .map(|((t, r), l)| {
            let (agreement, hits, batches) = l.expect("at least one timed round");
            let of = |v: &[f64]| Summary::of(v).expect("at least one timed round");
            Interleaved { kernel_ms: of(t), reorder_ms: of(r), agreement, hits, batches }
        })
        .collect())
}
