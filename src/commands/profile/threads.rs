//! LP_NUM_THREADS scaling on lavapipe. lavapipe reads `LP_NUM_THREADS` when the instance is
//! created, so each thread count runs `trilab bench` (this executable) as a subprocess on the
//! same ray files, with a JSON report; bench validates every result before it reports a speed.

use std::path::Path;
use std::process::Command;

use serde::Serialize;

use crate::encoding::Method;
use crate::error::{Error, Result};
use crate::report::Summary;

/// Thread counts 1, 2, ... up to the host's cores.
pub fn default_counts() -> Vec<usize> {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    (1..=cores).collect()
}

/// One (threads, method, ray set) measurement from a bench subprocess.
#[derive(Clone, Debug, Serialize)]
pub struct ThreadMeasurement {
    pub threads: usize,
    pub method: String,
    pub ray_set: String,
    pub rays: usize,
    pub kernel_ms: Summary,
    pub mrays_per_s: f64,
    pub agreement: f64,
}

/// Arguments of one bench subprocess.
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

/// Runs bench with `LP_NUM_THREADS=threads` and returns its rows.
pub fn bench_with_threads(run: &BenchRun, threads: usize) -> Result<Vec<ThreadMeasurement>> {
    let json = run.rays_dir.join(format!("bench-threads-{threads}.json"));
    let methods: Vec<String> = run.methods.iter().map(|m| m.to_string()).collect();
    let output = crate::children::output(
        Command::new(run.exe)
            .env("LP_NUM_THREADS", threads.to_string())
            .arg("bench")
            .arg("--scenes")
            .arg(run.scene)
            .arg("--rays-dir")
            .arg(run.rays_dir)
            .arg("--methods")
            .arg(methods.join(","))
            .arg("--leaf-size")
            .arg(run.leaf_size.to_string())
            .arg("--layouts")
            .arg(run.layout.to_string())
            .arg("--repeat")
            .arg(run.repeat.to_string())
            .arg("--device")
            .arg(run.device_index.to_string())
            .arg("--json-out")
            .arg(&json),
    )
    .map_err(|e| Error::io(run.exe, e))?;
    if !output.status.success() {
        return Err(Error::Usage(format!(
            "LP_NUM_THREADS={threads}: `{} bench` failed ({}): {}",
            run.exe.display(),
            output.status,
            String::from_utf8_lossy(&output.stderr).trim()
        )));
    }
    let text = std::fs::read_to_string(&json).map_err(|e| Error::io(&json, e))?;
    let report: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::Usage(format!("{}: {e}", json.display())))?;
    let seen = report["lp_num_threads"].as_str().and_then(|s| s.parse::<usize>().ok());
    if seen != Some(threads) {
        return Err(Error::Usage(format!("bench subprocess reports LP_NUM_THREADS {seen:?}, wanted {threads}")));
    }
    let bad = || Error::Usage(format!("{}: unexpected bench report layout", json.display()));
    let rows = report["rows"].as_array().ok_or_else(bad)?;
    rows.iter()
        .map(|r| {
            let f = |k: &str| r[k].as_f64().ok_or_else(bad);
            let ms = &r["kernel_ms"];
            let m = |k: &str| ms[k].as_f64().ok_or_else(bad);
            Ok(ThreadMeasurement {
                threads,
                method: r["method"].as_str().ok_or_else(bad)?.to_owned(),
                ray_set: r["ray_set"].as_str().ok_or_else(bad)?.to_owned(),
                rays: r["rays"].as_u64().ok_or_else(bad)? as usize,
                kernel_ms: Summary {
                    median: m("median")?,
                    min: m("min")?,
                    max: m("max")?,
                    runs: ms["runs"].as_u64().ok_or_else(bad)? as usize,
                },
                mrays_per_s: f("mrays_per_s")?,
                agreement: f("agreement")?,
            })
        })
        .collect()
}
