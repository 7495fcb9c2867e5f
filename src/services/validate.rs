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

/// Work timed once in every round beside the kernels of [`interleaved_with`] (a peer program
/// on the same rays): it validates its own answer and keeps its own times.
pub trait RoundJob {
    /// Runs once; `timed` is false in the warm-up rounds, whose time does not count.
    fn run_once(&mut self, timed: bool) -> Result<()>;
}

/// The rounds every interleaved measurement runs: `warmup` untimed rounds, then `repeat` (at
/// least 1) timed ones, each running every job once, the job that opens a round rotating. An
/// error names the job (its index).
pub fn rounds(jobs: &mut [&mut dyn RoundJob], warmup: usize, repeat: usize) -> std::result::Result<(), (usize, Error)> {
    for round in 0..warmup + repeat.max(1) {
        // The trace's round: a span on the host, and labels on every dispatch in it.
        let warm_up = round < warmup;
        let _span = crate::timeline::span_with("round", || match warm_up {
            true => format!("round {} (warm-up)", round + 1),
            false => format!("round {}", round + 1),
        });
        let _labels = crate::timeline::labels(|| vec![("round", (round + 1).into()), ("warm_up", warm_up.into())]);
        for k in 0..jobs.len() {
            let i = (k + round) % jobs.len();
            jobs[i].run_once(round >= warmup).map_err(|e| (i, e))?;
        }
    }
    Ok(())
}

/// One kernel job as a [`RoundJob`]: each run casts its rays once (reordered and put back where
/// its order says), validates the hits and, in a timed round, keeps the time.
pub struct KernelRound<'a> {
    ctx: &'a Context,
    mesh: &'a Mesh,
    job: &'a Job<'a>,
    once: RaycastOptions,
    times: Vec<f64>,
    reorder: Vec<f64>,
    last: Option<(Agreement, Vec<Hit>, usize)>,
}

impl<'a> KernelRound<'a> {
    pub fn new(ctx: &'a Context, mesh: &'a Mesh, job: &'a Job<'a>, batch_rays: usize) -> KernelRound<'a> {
        let once = RaycastOptions { warmup: 0, repeat: 1, batch_rays };
        KernelRound { ctx, mesh, job, once, times: vec![], reorder: vec![], last: None }
    }

    /// Its timed rounds' figures; `None` before any timed round.
    pub fn finish(self) -> Option<Interleaved> {
        let (agreement, hits, batches) = self.last?;
        let of = |v: &[f64]| Summary::of(v);
        Some(Interleaved { kernel_ms: of(&self.times)?, reorder_ms: of(&self.reorder)?, agreement, hits, batches })
    }
}

impl RoundJob for KernelRound<'_> {
    fn run_once(&mut self, timed: bool) -> Result<()> {
        let j = self.job;
        let _span = crate::timeline::span_with("cast", || {
            let s = j.scene;
            format!("cast {} {} {} {} ({} order)", s.method, s.layout, s.traversal, s.access.name(), j.order)
        })
        .with("rays", j.rays.len());
        let t = std::time::Instant::now();
        let order = j.order.permutation(j.rays);
        let permuted = order.as_ref().map(|o| order::permute(o, j.rays));
        let mut host_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut res = j.scene.cast_with(self.ctx, j.kernel, permuted.as_deref().unwrap_or(j.rays), &self.once)?;
        if let Some(o) = &order {
            let t = std::time::Instant::now();
            res.hits = order::unpermute(o, &res.hits);
            host_ms += t.elapsed().as_secs_f64() * 1e3;
        }
        let validate = crate::timeline::span("validate", "validate against the f64 reference");
        let agreement = validate_hits(self.mesh, j.rays, &res.hits, j.ref_hits)?;
        drop(validate);
        if timed {
            self.times.push(res.time_ms()?.median + host_ms);
            self.reorder.push(host_ms);
            self.last = Some((agreement, res.hits, res.batches));
        }
        Ok(())
    }
}

/// Times every job with their rounds interleaved ([`rounds`]): `warmup` untimed rounds of every
/// job, then `repeat` timed rounds, each running every job once, the job that opens a round
/// rotating, so that a burst of other work on the host lands on all jobs alike rather than on
/// the few timed while it lasted (on a busy 2-core lavapipe host, back-to-back rounds let one
/// kernel's cells read 1.4-1.7x slow together). Every round's hits are validated against the
/// f64 reference before its time counts. An error names the job (its index).
pub fn interleaved(
    ctx: &Context,
    mesh: &Mesh,
    jobs: &[Job],
    warmup: usize,
    repeat: usize,
    batch_rays: usize,
) -> std::result::Result<Vec<Interleaved>, (usize, Error)> {
    interleaved_with(ctx, mesh, jobs, &mut [], warmup, repeat, batch_rays)
}

/// [`interleaved`] with `others` (the peer programs) run once in every round too, warm-up rounds
/// included, rotating with the kernels: the kernels are jobs `0..jobs.len()`, `others[k]` job
/// `jobs.len() + k` (the index an error names). The others keep their own figures.
pub fn interleaved_with(
    ctx: &Context,
    mesh: &Mesh,
    jobs: &[Job],
    others: &mut [&mut dyn RoundJob],
    warmup: usize,
    repeat: usize,
    batch_rays: usize,
) -> std::result::Result<Vec<Interleaved>, (usize, Error)> {
    let mut kernels: Vec<KernelRound> = jobs.iter().map(|j| KernelRound::new(ctx, mesh, j, batch_rays)).collect();
    let mut all: Vec<&mut dyn RoundJob> = vec![];
    for k in kernels.iter_mut() {
        all.push(k);
    }
    for o in others.iter_mut() {
        all.push(&mut **o);
    }
    rounds(&mut all, warmup, repeat)?;
    drop(all);
    Ok(kernels.into_iter().map(|k| k.finish().expect("at least one timed round")).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A job that logs (its index, timed) on every run and fails on its `fail_at`-th run.
    struct Logged<'a> {
        id: usize,
        log: &'a std::cell::RefCell<Vec<(usize, bool)>>,
        fail_at: Option<usize>,
    }

    impl RoundJob for Logged<'_> {
        fn run_once(&mut self, timed: bool) -> Result<()> {
            let mut log = self.log.borrow_mut();
            if self.fail_at == Some(log.iter().filter(|e| e.0 == self.id).count()) {
                return Err(Error::Usage(format!("job {} failed", self.id)));
            }
            log.push((self.id, timed));
            Ok(())
        }
    }

    #[test]
    fn every_round_runs_every_job_once_the_opener_rotating() {
        let log = std::cell::RefCell::new(vec![]);
        let mut jobs: Vec<Logged> = (0..3).map(|id| Logged { id, log: &log, fail_at: None }).collect();
        let mut all: Vec<&mut dyn RoundJob> = jobs.iter_mut().map(|j| j as &mut dyn RoundJob).collect();
        rounds(&mut all, 1, 2).unwrap();
        let want =
            [(0, false), (1, false), (2, false), (1, true), (2, true), (0, true), (2, true), (0, true), (1, true)];
        assert_eq!(log.borrow().as_slice(), want);
        // An error names the job and ends the rounds there.
        log.borrow_mut().clear();
        let mut jobs: Vec<Logged> =
            (0..2).map(|id| Logged { id, log: &log, fail_at: (id == 1).then_some(1) }).collect();
        let mut all: Vec<&mut dyn RoundJob> = jobs.iter_mut().map(|j| j as &mut dyn RoundJob).collect();
        let (i, e) = rounds(&mut all, 0, 3).unwrap_err();
        assert_eq!((i, e.to_string().contains("job 1 failed")), (1, true));
        assert_eq!(log.borrow().as_slice(), [(0, true), (1, true)]);
    }
}
