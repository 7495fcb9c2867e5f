//! Where and when a measurement ran, carried by every harness's report.

use serde::Serialize;

use crate::gpu::Context;
use crate::scene::SceneSource;

/// Where and when a measurement ran: device, driver, commit, date and host, carried by every
/// report (and by every row of the study and the accuracy tables), so results from many runs and
/// devices can be set side by side.
#[derive(Clone, Debug, Serialize)]
pub struct Provenance {
    pub device: String,
    pub driver: String,
    pub mesa_version: Option<String>,
    pub commit: String,
    pub date: String,
    /// The host CPU: model, logical CPUs, load average when the report was made.
    pub host: crate::host::Host,
    pub lp_num_threads: Option<String>,
    pub timed_on_gpu: bool,
    /// The driver settings in the environment that change what is measured
    /// ([`SETTINGS`]), name to value.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub settings: std::collections::BTreeMap<String, String>,
    /// Where each scene named so far came from (a path as given, or a name found in
    /// `--scene-dir`, `TRILAB_SCENES`, beside the executable, built in, or the source tree).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub scenes: Vec<SceneSource>,
    /// The GLSL compiler that made the kernels' SPIR-V ([`crate::kernels::SPIRV_COMPILER`]).
    pub spirv_compiler: &'static str,
    /// The package an unpacked driver came from, where the loader was given one ICD file
    /// (`VK_DRIVER_FILES`) with a `version` file beside it, as `scripts/stock-mesa.sh` and
    /// `scripts/swiftshader.sh` write: SwiftShader reports no driver version of its own, and the
    /// Chromium release that ships it is what names its build.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub driver_package: Option<String>,
    /// On lavapipe: the CPU features its JIT compiled for ([`crate::gpu::LavapipeCpu`]): the
    /// host's, less what `GALLIUM_OVERRIDE_CPU_CAPS` removed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compiles_for: Option<crate::gpu::LavapipeCpu>,
}

impl Provenance {
    pub fn of(ctx: &Context) -> Provenance {
        Provenance::of_device(ctx.info())
    }

    /// Where a measurement on the device `info` describes runs, now, on this host.
    pub fn of_device(info: &crate::gpu::DeviceInfo) -> Provenance {
        Provenance {
            device: info.name.clone(),
            driver: info.driver_label(),
            mesa_version: info.mesa_version.clone(),
            commit: commit(),
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            host: crate::host::Host::current(),
            lp_num_threads: std::env::var("LP_NUM_THREADS").ok(),
            timed_on_gpu: info.timestamp_valid_bits > 0,
            settings: SETTINGS
                .iter()
                .filter_map(|&k| std::env::var(k).ok().map(|v| (k.to_owned(), v)))
                .chain([("subgroup_size".to_owned(), info.subgroup_size.to_string())])
                .collect(),
            scenes: crate::scene::find::resolved_scenes(),
            spirv_compiler: crate::kernels::SPIRV_COMPILER,
            driver_package: driver_package(),
            compiles_for: info.compiles_for.clone(),
        }
    }
}

impl Provenance {
    /// Where a run that opened no device itself ran (its workers each had one: `driver-stats
    /// --targets`), now, on this host: `device` and `driver` say what those were.
    pub fn without_device(device: &str, driver: &str) -> Provenance {
        Provenance {
            device: device.into(),
            driver: driver.into(),
            mesa_version: None,
            commit: commit(),
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            host: crate::host::Host::current(),
            lp_num_threads: None,
            timed_on_gpu: false,
            settings: Default::default(),
            scenes: vec![],
            spirv_compiler: crate::kernels::SPIRV_COMPILER,
            driver_package: None,
            compiles_for: None,
        }
    }
}

/// The `version` file beside the one ICD file `VK_DRIVER_FILES` names, if there is exactly one and
/// it has such a file (see [`Provenance::driver_package`]).
fn driver_package() -> Option<String> {
    let files = std::env::var_os("VK_DRIVER_FILES")?;
    let mut paths = std::env::split_paths(&files);
    let icd = paths.next()?;
    if paths.next().is_some() {
        return None;
    }
    let version = std::fs::read_to_string(icd.parent()?.join("version")).ok()?;
    Some(version.trim().to_owned()).filter(|v| !v.is_empty() && v.len() < 200)
}

/// Environment variables of the drivers that change what a run measures: a row records them so
/// that `compare` and `merge` can tell two runs of one device apart.
pub const SETTINGS: &[&str] = &[
    "LP_NATIVE_VECTOR_WIDTH",
    // What lavapipe compiles for (gpu::lavapipe_cpu): `avx` makes an AVX-512 host's code a Zen 3's.
    "GALLIUM_OVERRIDE_CPU_CAPS",
    "LP_NUM_THREADS",
    "LP_PERF",
    "GALLIVM_PERF",
    "MESA_SHADER_CACHE_DISABLE",
    // RADV's and ACO's switches change the code its compiler makes (RADV_DEBUG=llvm: another
    // compiler; RADV_PERFTEST=cswave32: another subgroup size).
    "RADV_DEBUG",
    "RADV_PERFTEST",
    "ACO_DEBUG",
];

impl Provenance {
    /// Where a result row was measured ([`crate::rows::Source`]).
    pub fn source(&self) -> crate::rows::Source {
        crate::rows::Source {
            device: self.device.clone(),
            driver: self.driver.clone(),
            commit: self.commit.clone(),
            date: self.date.clone(),
            settings: self.settings.clone(),
            host: Some(self.host.clone()),
        }
    }
}

/// The commit trilab was built from, as the working directory says: `TRILAB_COMMIT` if set (a copy without `.git`, such as the
/// GPU machine's), else `git rev-parse` in the working directory, "-dirty" when tracked files
/// differ from it; "unknown" without either.
pub fn commit() -> String {
    if let Ok(c) = std::env::var("TRILAB_COMMIT") {
        return c;
    }
    let git = |args: &[&str]| {
        std::process::Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
    };
    match git(&["rev-parse", "--short=12", "HEAD"]) {
        Some(c) => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
            if dirty {
                format!("{c}-dirty")
            } else {
                c
            }
        }
        None => "unknown".into(),
    }
}
