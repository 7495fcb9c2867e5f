//! LP_NUM_THREADS scaling on lavapipe. lavapipe reads `LP_NUM_THREADS` when the instance is
//! created, so each thread count is a worker ([`crate::services::worker`]: this executable run
//! again with `LP_NUM_THREADS` set) asked for a bench of the same ray files; bench validates
//! every result before it reports a speed, and the worker answers with its measurements.

use std::path::Path;

use crate::commands::bench::{self, BenchOptions};
use crate::encoding::Method;
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::services::worker::protocol::BenchThreads;
use crate::services::worker::{self, Launch, Message, Request};

pub use crate::services::worker::protocol::ThreadMeasurement;

/// Thread counts 1, 2, ... up to the host's cores.
pub fn default_counts() -> Vec<usize> {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    (1..=cores).collect()
}

/// What each thread count's bench runs.
pub struct BenchRun<'a> {
    pub exe: &'a Path,
    pub scene: &'a Path,
    /// Holds `<scene stem>.{primary,diffuse,random}.rays`.
    pub rays_dir: &'a Path,
    pub methods: &'a [Method],
    pub leaf_size: u32,
    pub layout: crate::encoding::Layout,
    pub repeat: usize,
    /// `--device` index of the device the profile runs on.
    pub device_index: usize,
}

/// Runs the bench in a worker with `LP_NUM_THREADS=threads` and returns its rows.
pub fn bench_with_threads(run: &BenchRun, threads: usize) -> Result<Vec<ThreadMeasurement>> {
    let request = Request::BenchThreads(BenchThreads {
        threads,
        scene: run.scene.to_owned(),
        rays_dir: run.rays_dir.to_owned(),
        methods: run.methods.to_vec(),
        leaf_size: run.leaf_size,
        layout: run.layout,
        repeat: run.repeat,
    });
    let launch = Launch::new(run.exe).env("LP_NUM_THREADS", threads.to_string()).device(run.device_index);
    let who = format!("LP_NUM_THREADS={threads}");
    match worker::call(&launch, &who, &request)?.message {
        Message::Measured { measurements } => Ok(measurements),
        other => Err(worker::unexpected(&who, "measured", &other)),
    }
}

/// The worker's side of [`bench_with_threads`]: the bench `trilab bench --scenes S --rays-dir D
/// --methods M --leaf-size N --layouts L --repeat R` runs (the driver's peers as its `auto`
/// runs them: not on a CPU device), after checking that the driver loaded here read the
/// `LP_NUM_THREADS` the parent set.
pub fn measure(ctx: &Context, r: &BenchThreads) -> Result<Vec<ThreadMeasurement>> {
    let cpu = ctx.capabilities().is_cpu();
    let o = BenchOptions {
        scenes: vec![r.scene.clone()],
        axes: crate::matrix::KernelAxes { methods: r.methods.clone(), layouts: vec![r.layout], ..Default::default() },
        build: crate::bvh::BuildOptions::new(r.leaf_size),
        repeat: r.repeat,
        rays_dir: Some(r.rays_dir.clone()),
        ray_query: !cpu,
        ray_tracing_pipeline: !cpu,
        ..Default::default()
    };
    let report = bench::run(ctx, &o, |m| eprintln!("  {m}"))?;
    let seen = report.provenance.lp_num_threads.as_deref().and_then(|s| s.parse::<usize>().ok());
    if seen != Some(r.threads) {
        return Err(Error::Usage(format!("the bench reports LP_NUM_THREADS {seen:?}, wanted {}", r.threads)));
    }
    Ok(report
        .rows
        .iter()
        .map(|row| ThreadMeasurement {
            threads: r.threads,
            method: row.method.to_string(),
            ray_set: row.ray_set.to_string(),
            rays: row.rays,
            kernel_ms: row.kernel_ms,
            mrays_per_s: row.mrays_per_s,
            agreement: row.agreement,
        })
        .collect())
}
