//! GPU targets: every kernel compiled for real GPUs on a machine without one, through Mesa's
//! RADV on its null device (`RADV_FORCE_FAMILY=<chip>`), the way Mesa's shader-db and
//! fossil-db compare compilers without hardware.
//!
//! A target is a chip ([`Chip`]) x a compiler (ACO, RADV's own, or LLVM's AMDGPU backend under
//! `RADV_DEBUG=llvm`) x a subgroup size (64, or 32 on RDNA, set through the pipeline's
//! `requiredSubgroupSize`, not a driver variable) x a Mesa build (the installed one, Debian 12's
//! own unpacked by `scripts/stock-mesa.sh`, or any RADV ICD file). A driver reads its
//! environment once, when it loads, so each target runs in a worker of its own
//! ([`crate::services::worker`]) with the environment that makes the target, and answers one
//! [`Request::CompileKernels`]: each kernel compiled once, with its statistics
//! ([`super::statistic`]) or the reason it cannot be compiled there. A worker that dies (a chip
//! this Mesa build does not know aborts in RADV) fails its target, named, and the others go on.
//!
//! Which targets a run compiles for (the `--targets` items, their defaults, their crossing) is
//! the experiment matrix's: `src/matrix/targets.rs`.

use std::ffi::OsString;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::gpu::amd::Chip;
use crate::services::worker::protocol::{CompileRequest, CompiledKernels};
use crate::services::worker::{self, Launch, Message, Request};

/// The compiler RADV uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compiler {
    /// ACO, RADV's own compiler (the default).
    Aco,
    /// LLVM's AMDGPU backend (`RADV_DEBUG=llvm`).
    Llvm,
}

impl Compiler {
    pub const ALL: [Compiler; 2] = [Compiler::Aco, Compiler::Llvm];

    /// The compiler a RADV device compiles with: its name says `(LLVM x.y.z)` under
    /// `RADV_DEBUG=llvm`.
    pub fn of_device_name(device: &str) -> Compiler {
        if device.contains("(LLVM ") {
            Compiler::Llvm
        } else {
            Compiler::Aco
        }
    }
}

impl fmt::Display for Compiler {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Compiler::Aco => "aco",
            Compiler::Llvm => "llvm",
        })
    }
}

impl FromStr for Compiler {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Compiler, String> {
        match s.to_ascii_lowercase().as_str() {
            "aco" => Ok(Compiler::Aco),
            "llvm" => Ok(Compiler::Llvm),
            _ => Err(format!("no compiler `{s}` (aco or llvm)")),
        }
    }
}

/// Which Mesa's RADV compiles.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum MesaBuild {
    /// The system's (`mesa-vulkan-drivers`; 25.0.7 from bookworm-backports where
    /// `install-deps.sh` installed it).
    Installed,
    /// Debian 12's own (22.3.6), unpacked beside it by `scripts/stock-mesa.sh`.
    Stock,
    /// A RADV ICD file (a Mesa build of one's own).
    Icd(PathBuf),
}

impl fmt::Display for MesaBuild {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MesaBuild::Installed => f.write_str("installed"),
            MesaBuild::Stock => f.write_str("stock"),
            MesaBuild::Icd(p) => write!(f, "{}", p.display()),
        }
    }
}

impl FromStr for MesaBuild {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<MesaBuild, String> {
        match s {
            "installed" => Ok(MesaBuild::Installed),
            "stock" => Ok(MesaBuild::Stock),
            p if p.ends_with(".json") => Ok(MesaBuild::Icd(PathBuf::from(p))),
            _ => Err(format!("no Mesa build `{s}` (installed, stock, or a RADV ICD file, *.json)")),
        }
    }
}

/// The folders the Vulkan loader reads ICD files from, where a distribution installs them.
const ICD_DIRS: &[&str] = &["/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d"];

impl MesaBuild {
    /// The ICD file that loads this build's RADV, and the variables it needs beside
    /// `VK_DRIVER_FILES` (an unpacked build's `LD_LIBRARY_PATH`); an error naming what is missing
    /// and how to get it.
    pub fn icd(&self) -> Result<(PathBuf, Vec<(String, String)>)> {
        match self {
            MesaBuild::Installed => {
                for dir in ICD_DIRS {
                    let Ok(entries) = std::fs::read_dir(dir) else { continue };
                    let mut found: Vec<PathBuf> = entries
                        .filter_map(|e| e.ok().map(|e| e.path()))
                        .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("radeon_icd")))
                        .collect();
                    found.sort();
                    if let Some(p) = found.into_iter().next() {
                        return Ok((p, vec![]));
                    }
                }
                Err(Error::Unsupported(format!(
                    "no RADV installed: no radeon_icd*.json in {} (Debian's mesa-vulkan-drivers ships it; \
                     scripts/install-deps.sh installs it)",
                    ICD_DIRS.join(", ")
                )))
            }
            MesaBuild::Stock => {
                let dir = std::env::var_os("TRILAB_STOCK_MESA")
                    .map(PathBuf::from)
                    .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/trilab/stock-mesa")))
                    .unwrap_or_default();
                let icd = dir.join("radv_icd.json");
                if !icd.is_file() {
                    return Err(Error::Unsupported(format!(
                        "{}: no such file: Debian 12's own Mesa is not unpacked with its RADV (run \
                         scripts/stock-mesa.sh)",
                        icd.display()
                    )));
                }
                let env = std::fs::read_to_string(dir.join("env")).unwrap_or_default();
                let extra = env
                    .lines()
                    .filter_map(|l| l.split_once('='))
                    .filter(|(k, _)| *k == "LD_LIBRARY_PATH")
                    .map(|(k, v)| (k.to_owned(), v.to_owned()))
                    .collect();
                Ok((icd, extra))
            }
            MesaBuild::Icd(p) => {
                if p.is_file() {
                    Ok((p.clone(), vec![]))
                } else {
                    Err(Error::bad_input(p, None, "no such ICD file"))
                }
            }
        }
    }
}

/// One target: a chip, a compiler, a subgroup size and a Mesa build.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct GpuTarget {
    pub chip: Chip,
    pub compiler: Compiler,
    /// The subgroup size every kernel is compiled at (64, or 32 on RDNA).
    pub wave: u32,
    pub mesa: MesaBuild,
}

impl fmt::Display for GpuTarget {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}@{}", self.chip, self.compiler, self.wave, self.mesa)
    }
}

impl GpuTarget {
    /// The worker that compiles for this target: this executable with the environment that
    /// makes the target (the RADV ICD, the chip, the compiler, no shader cache, none of the
    /// driver's own switches that would change the code).
    pub fn launch(&self, exe: &Path, validation: bool, timeout: Duration) -> Result<Launch> {
        let (icd, extra) = self.mesa.icd()?;
        let mut l = Launch::new(exe).validation(validation);
        l.timeout = Some(timeout);
        l.unset = ["VK_ICD_FILENAMES", "VK_ADD_DRIVER_FILES", "RADV_DEBUG", "RADV_PERFTEST", "ACO_DEBUG", "AMD_DEBUG"]
            .map(String::from)
            .to_vec();
        let mut l = l
            .env("VK_DRIVER_FILES", icd.as_os_str())
            .env("RADV_FORCE_FAMILY", self.chip.name)
            .env("MESA_SHADER_CACHE_DISABLE", "true");
        if self.compiler == Compiler::Llvm {
            l = l.env("RADV_DEBUG", "llvm");
        }
        for (k, v) in extra {
            l = l.env(OsString::from(k), OsString::from(v));
        }
        Ok(l)
    }

    /// Compiles `kernels` (registry names) on this target in its worker: what the driver made of
    /// each, or why it could not. The worker's device must be RADV's null device for this chip
    /// and compiler, or the target fails naming what it got.
    pub fn compile(
        &self,
        exe: &Path,
        kernels: &[String],
        validation: bool,
        timeout: Duration,
    ) -> Result<CompiledKernels> {
        let launch = self.launch(exe, validation, timeout)?;
        let who = format!("the worker of target {self}");
        let request =
            Request::CompileKernels(CompileRequest { kernels: kernels.to_vec(), subgroup_size: Some(self.wave) });
        let answered = worker::call(&launch, &who, &request).map_err(|e| self.explain(e))?;
        let stderr = answered.stderr;
        let got = match answered.message {
            Message::Compiled(c) => c,
            other => return Err(worker::unexpected(&who, "compiled", &other)),
        };
        let chip = Chip::of_device_name(&got.device);
        let compiler = Compiler::of_device_name(&got.device);
        if chip != Some(self.chip) || compiler != self.compiler {
            return Err(Error::Unsupported(format!(
                "target {self}: the worker's device is `{}` ({}), not RADV's null device for {} with {}{}",
                got.device,
                got.driver,
                self.chip,
                self.compiler,
                if stderr.trim().is_empty() { String::new() } else { format!(" (its stderr: {})", stderr.trim()) }
            )));
        }
        Ok(got)
    }

    /// A worker's failure, with what it means where that is known: RADV aborts on a chip its
    /// Mesa build does not know ("radv: Unknown family"), and on a chip the LLVM it was built
    /// with has no backend for (Mesa 25.0.7 on LLVM 15 and gfx1201: "LLVM doesn't support
    /// gfx1201, bailing out").
    fn explain(&self, e: Error) -> Error {
        let text = e.to_string();
        if text.contains("Unknown family") {
            return Error::Unsupported(format!(
                "target {self}: this Mesa build's RADV does not know the chip {} (it printed \"Unknown family\" and \
                 aborted)",
                self.chip
            ));
        }
        if text.contains("LLVM doesn't support") {
            return Error::Unsupported(format!(
                "target {self}: the LLVM this Mesa build's RADV uses has no backend for {} (it printed \"LLVM doesn't \
                 support {}, bailing out\" and aborted); ACO compiles for it",
                self.chip, self.chip
            ));
        }
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mesa_build_is_installed_stock_or_an_icd_file() {
        assert!("nope".parse::<MesaBuild>().unwrap_err().contains("installed, stock"));
        assert_eq!("x/radv.json".parse::<MesaBuild>().unwrap(), MesaBuild::Icd("x/radv.json".into()));
        assert_eq!("stock".parse::<MesaBuild>().unwrap(), MesaBuild::Stock);
    }

    #[test]
    fn the_compiler_is_read_from_the_device_name() {
        assert_eq!(Compiler::of_device_name("Null hardware (RADV NAVI31 (LLVM 15.0.6))"), Compiler::Llvm);
        assert_eq!(Compiler::of_device_name("Null hardware (RADV NAVI31)"), Compiler::Aco);
    }
}
