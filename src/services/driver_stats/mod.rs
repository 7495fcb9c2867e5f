//! Driver statistics: what the driver compiled each kernel to (machine instructions, vector
//! spills and reloads, calls into the texel-fetch helpers), per kernel variant, so that
//! `trilab compare` can gate a driver change on them the way shader-db gates on instruction
//! counts.
//!
//! Real drivers report such statistics through `VK_KHR_pipeline_executable_properties`
//! ([`executable`]); lavapipe (Mesa 25.0) does not offer the extension. What the packaged
//! Mesa 25.0.7 (Debian bookworm-backports, LLVM 15, a release build) does offer, tried in turn:
//!
//! - `GALLIVM_DEBUG=asm` **works and is what this module uses**: gallivm parses the flags
//!   `tgsi`, `ir`, `asm` and `perf` in release builds too (only `dumpbc` is debug-only), and for
//!   every function it JIT-compiles prints its LLVM name and the disassembly of the machine code
//!   in memory to stderr ([`lavapipe_asm`] reads it). The flag is read once, when the
//!   driver loads, so this process cannot turn it on for itself: [`collect`] runs this
//!   executable again (a worker, [`crate::services::worker`]) with `GALLIVM_DEBUG=asm` set and
//!   asks it to dispatch each kernel once, on a small scene, between marker lines on stderr
//!   ([`emit_for_parent`]): lavapipe compiles a compute shader's variant at its first dispatch,
//!   not when the pipeline is created.
//! - `MESA_SHADER_CACHE_DISABLE=true` is needed as well, and the child sets it: llvmpipe keeps
//!   the compiled object code of each variant in Mesa's disk cache
//!   (`~/.cache/mesa_shader_cache_db`, compressed entries of a database file) and, on a hit,
//!   loads it without compiling, and then prints no disassembly (checked: a second run of one
//!   kernel printed only the per-descriptor helpers). Reading those cache entries back
//!   (decompressing and `objdump`ing the object files) would give the same code with more
//!   machinery and a dependency on the cache's private format, so it is not used.
//! - `GALLIVM_DEBUG=ir` prints the LLVM IR before code generation (no spills, no final
//!   instruction count); `dumpbc` is compiled out of release builds; `GALLIVM_PERF` only changes
//!   optimisations; `LP_DEBUG` offers no machine-code dump; `NIR_DEBUG` is compiled out of the
//!   release library (`strings libvulkan_lvp.so` finds no `NIR_DEBUG`, while it finds
//!   `GALLIVM_DEBUG`); perf's JIT map (`lp_profile`, `/tmp/perf-PID.map`) exists only in
//!   `PROFILE` builds; LLVM's own options (`-print-after-all`, the assembly printer's
//!   `Spill`/`Reload` comments) cannot be passed to a built Mesa through the environment.
//!
//! Where the device is not lavapipe: the statistics the driver's compiler reports through
//! `VK_KHR_pipeline_executable_properties` ([`compile`]; RADV and NVIDIA offer it), typed
//! ([`crate::gpu::executable`]: unit, direction, or identity), else "not available on this
//! driver" and no figures. [`target`] compiles every kernel for many GPU targets at once (chip x
//! compiler x subgroup size x Mesa build) through RADV's null device, one worker per target;
//! [`report`] writes what they compiled as tables people read, with the occupancy cliffs of
//! each kernel ([`crate::gpu::amd`]).

pub mod compile;
pub mod dispatch;
pub mod lavapipe_asm;
pub mod report;
pub mod target;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bvh::BuildOptions;
use crate::encoding::{Layout, Method, RaycastKey};
use crate::error::{Error, Result};
use crate::gpu::executable::CompilerStatistic;
use crate::gpu::{Context, RaycastOptions, Statistic};
use crate::kernels::{KernelSource, KERNELS};
use crate::named::Named;
use crate::pipeline::{HostScene, SceneRequest};
use crate::report::Status;
use crate::rows::{cell, Figure, Row};
use crate::scene::load_obj;
use crate::services::provenance::Provenance;
use crate::services::worker::{self, Launch, Message, Request};
use compile::CompiledFor;
use lavapipe_asm::KernelAsm;
use target::GpuTarget;

/// The command name on every row of driver statistics, whether `trilab driver-stats` or
/// `trilab profile` wrote them: the figures depend on the kernel and the driver only, so a
/// profile's can be compared with a standalone run's.
pub const COMMAND: &str = "driver-stats";

/// The line the child writes to stderr before each kernel's pipeline: the marker, then the
/// kernel's name.
const BEGIN: &str = "@@trilab-driver-stats begin ";
/// ... and after it.
const END: &str = "@@trilab-driver-stats end ";

/// Which kernel variants to compile.
#[derive(Clone, Debug)]
pub struct Selection {
    /// Kernel files (`raycast`, `pathtrace`, `raycast_coop`, ...).
    pub kernels: Vec<String>,
    /// Variants without their layout suffix (`closest`, `any`, `closest_address`, `all`, ...).
    pub variants: Vec<String>,
    pub methods: Vec<Method>,
    pub layouts: Vec<Layout>,
}

impl Default for Selection {
    /// Every method's and layout's `raycast` closest and any-hit kernels (texel path, while-if).
    fn default() -> Self {
        Selection {
            kernels: vec!["raycast".into()],
            variants: vec!["closest".into(), "any".into()],
            methods: Method::ALL.to_vec(),
            layouts: Layout::ALL.to_vec(),
        }
    }
}

/// A variant's name without its layout suffix: `closest_address_bvh4` on bvh4 -> `closest_address`.
pub fn base_variant(k: &KernelSource) -> &'static str {
    k.variant.strip_suffix(&format!("_{}", k.layout)).unwrap_or(k.variant)
}

/// `--kernels all` / `--variants all`: every kernel file, or every variant.
pub const ALL: &str = "all";

/// `--kernels studied`: the kernels a reader studies ([`crate::encoding::variants::studied`]:
/// every method's closest- and any-hit kernels on the default layout, closest-hit on the others,
/// the ray-query peer), whatever `--variants` says.
pub const STUDIED: &str = "studied";

impl Selection {
    /// Every kernel of the registry: every kernel file, variant, method and layout (what a
    /// compiler that needs no dispatch can compile: `driver-stats --targets`).
    pub fn everything() -> Selection {
        Selection {
            kernels: vec![ALL.into()],
            variants: vec![ALL.into()],
            methods: Method::ALL.to_vec(),
            layouts: Layout::ALL.to_vec(),
        }
    }

    /// The registry's variants it names, in the registry's order; an error naming what matched
    /// nothing. A kernel that traces no rays (`none`: the probes, the roofline, the driver's
    /// ray query) has no method, and only `--kernels` and `--variants` choose it.
    pub fn kernels(&self) -> Result<Vec<&'static KernelSource>> {
        let methods: Vec<String> = self.methods.iter().map(|m| m.to_string()).collect();
        let layouts: Vec<String> = self.layouts.iter().map(|l| l.to_string()).collect();
        let all_kernels = self.kernels.iter().any(|k| k == ALL);
        let all_variants = self.variants.iter().any(|v| v == ALL);
        let studied = crate::encoding::variants::studied();
        let studied_too = self.kernels.iter().any(|k| k == STUDIED);
        for k in self.kernels.iter().filter(|k| *k != ALL && *k != STUDIED) {
            if !KERNELS.iter().any(|s| s.kernel == k) {
                let mut known: Vec<&str> = KERNELS.iter().map(|s| s.kernel).collect();
                known.dedup();
                return Err(Error::Usage(format!("--kernels: no kernel `{k}` (kernels: {})", known.join(", "))));
            }
        }
        let picked: Vec<&'static KernelSource> = KERNELS
            .iter()
            .filter(|s| {
                let c = KernelCell::of(s);
                let chosen = (all_kernels || self.kernels.contains(&c.kernel))
                    && (all_variants || self.variants.contains(&c.variant));
                (chosen || (studied_too && studied.iter().any(|k| k.id == s.id)))
                    && (s.intersector == "none" || methods.contains(&c.method))
                    && layouts.contains(&c.layout)
            })
            .collect();
        if picked.is_empty() {
            return Err(Error::Usage(format!(
                "--variants {}: no variant of {} with these methods and layouts",
                self.variants.join(","),
                self.kernels.join(",")
            )));
        }
        Ok(picked)
    }
}

/// A driver-statistics cell: one compiled kernel variant, as its row names it and as `trilab ab
/// --driver-stats` finds a cell's kernel among the rows.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct KernelCell {
    /// The kernel file (`raycast`, `pathtrace`, ...).
    pub kernel: String,
    /// The variant without its layout suffix ([`base_variant`]).
    pub variant: String,
    /// The intersector as `--methods` names it (`quad-mt`).
    pub method: String,
    pub layout: String,
}

impl KernelCell {
    /// The cell of a kernel of the registry.
    pub fn of(k: &KernelSource) -> KernelCell {
        KernelCell {
            kernel: k.kernel.into(),
            variant: base_variant(k).into(),
            method: k.intersector.replace('_', "-"),
            layout: k.layout.into(),
        }
    }

    /// The cell's coordinates, as `rows.jsonl` names them.
    pub fn coordinates(&self) -> crate::rows::Cell {
        cell([("kernel", &self.kernel), ("variant", &self.variant), ("method", &self.method), ("layout", &self.layout)])
    }
}

impl TryFrom<&crate::rows::Cell> for KernelCell {
    /// The coordinate the cell lacks, naming the cell.
    type Error = String;

    /// Reads [`KernelCell::coordinates`] back.
    fn try_from(c: &crate::rows::Cell) -> std::result::Result<KernelCell, String> {
        let get = |k: &str| {
            c.get(k).cloned().ok_or_else(|| {
                format!("{COMMAND} cell `{}` has no `{k}` coordinate", crate::rows::cell_key(COMMAND, c))
            })
        };
        Ok(KernelCell {
            kernel: get("kernel")?,
            variant: get("variant")?,
            method: get("method")?,
            layout: get("layout")?,
        })
    }
}

/// One kernel variant's statistics.
#[derive(Clone, Debug, Serialize)]
pub struct KernelStats {
    /// `<kernel>.<method>.<variant>`.
    pub name: String,
    #[serde(flatten)]
    pub cell: KernelCell,
    /// lavapipe: the counts from its machine code.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lavapipe: Option<KernelAsm>,
    /// Other drivers: the statistics their compiler reports, typed
    /// ([`crate::gpu::executable`]); in the JSON as a map of name to value (the rows carry each
    /// one's unit and direction).
    #[serde(skip_serializing_if = "Vec::is_empty", serialize_with = "statistic_values")]
    pub statistics: Vec<CompilerStatistic>,
    /// Where those statistics were compiled (chip, compiler, subgroup size).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compiled: Option<CompiledFor>,
}

/// `statistics` as `{"vgprs": 48, "hash": "0x..."}`: a run of many targets writes hundreds of
/// thousands of them.
fn statistic_values<S: serde::Serializer>(stats: &[CompilerStatistic], s: S) -> std::result::Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut m = s.serialize_map(Some(stats.len()))?;
    for st in stats {
        m.serialize_entry(&st.name, &st.value)?;
    }
    m.end()
}

impl KernelStats {
    fn of(k: &KernelSource) -> KernelStats {
        KernelStats { name: k.name.into(), cell: KernelCell::of(k), lavapipe: None, statistics: vec![], compiled: None }
    }

    /// The statistic named `name` (`vgprs`), as a number.
    pub fn statistic(&self, name: &str) -> Option<f64> {
        self.statistics.iter().find(|s| s.name == name).and_then(|s| s.number())
    }

    /// The registry's kernel of this name.
    pub fn source(&self) -> Option<&'static KernelSource> {
        KERNELS.iter().find(|k| k.name == self.name)
    }

    /// Vector reloads: moves from stack slots and other instructions reading them.
    pub fn vector_reloads(a: &KernelAsm) -> u64 {
        a.total.vector_reloads + a.total.folded_reloads
    }
}

/// `trilab driver-stats`' report (also a section of `trilab profile`).
#[derive(Clone, Debug, Serialize)]
pub struct DriverStatsReport {
    pub provenance: Provenance,
    pub status: Status,
    /// How the figures were obtained, or why there are none.
    pub note: String,
    /// This device's kernels.
    pub kernels: Vec<KernelStats>,
    /// `--targets`: each GPU target's (then `kernels` is empty).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub targets: Vec<TargetStats>,
}

/// One GPU target's compiled kernels (`driver-stats --targets`).
#[derive(Clone, Debug, Serialize)]
pub struct TargetStats {
    /// `navi31:aco:64@installed`.
    pub target: String,
    pub compiled_for: CompiledFor,
    /// Which Mesa build was asked for (`installed`, `stock`, an ICD file).
    pub mesa_build: String,
    /// The worker's device and driver, and the driver's `driverInfo` (the build that compiled).
    pub device: String,
    pub driver: String,
    pub driver_info: String,
    pub mesa_version: Option<String>,
    pub status: Status,
    /// Why the target has no kernels (its worker failed), or how they were compiled.
    pub note: String,
    pub kernels: Vec<KernelStats>,
    /// Kernels the target cannot compile, with why (a feature the chip lacks).
    pub refused: Vec<Refused>,
}

/// A kernel a target did not compile, and why.
#[derive(Clone, Debug, Serialize)]
pub struct Refused {
    pub kernel: String,
    pub why: String,
}

/// How [`collect`] runs.
#[derive(Clone, Debug)]
pub struct CollectOptions {
    /// This executable (the worker it runs under `GALLIVM_DEBUG=asm`).
    pub exe: PathBuf,
    /// `--device` for the child: the index of the context's device.
    pub device_index: usize,
    /// Run the child with the validation layer on.
    pub validation: bool,
    /// Write each kernel's dump to `<dir>/<name>.txt`.
    pub asm_dir: Option<PathBuf>,
}

/// The note of a lavapipe section.
pub const LAVAPIPE_NOTE: &str = "lavapipe's own machine code: this executable run again with GALLIVM_DEBUG=asm and \
     MESA_SHADER_CACHE_DISABLE=true dispatches each kernel once (on cornell); gallivm's disassembly of the compiled shader functions \
     (cs_variant, cs_co_variant) counted: instructions, vector spills and reloads (moves of xmm/ymm/zmm registers to \
     and from fixed stack slots), calls into the per-descriptor texel-fetch helpers";

/// The statistics of `kernels` on `ctx`'s device: lavapipe's from its machine code, another
/// driver's from the executable properties, or none with the reason.
pub fn collect(ctx: &Context, kernels: &[&'static KernelSource], o: &CollectOptions) -> Result<DriverStatsReport> {
    let provenance = Provenance::of(ctx);
    let info = ctx.info();
    if ctx.capabilities().statistic(Statistic::MachineCode).is_ok() && !kernels.is_empty() {
        // The first kernel alone first: a lavapipe that prints nothing for it reads no
        // GALLIVM_DEBUG, and is told before the other kernels are compiled.
        let mut dumps = lavapipe_dumps(&kernels[..1], o)?;
        if !printed_code(&dumps[0]) {
            return Ok(DriverStatsReport {
                provenance,
                status: Status::Unsupported,
                note: no_asm_note(&info.name, info.mesa_version.as_deref()),
                kernels: vec![],
                targets: vec![],
            });
        }
        if kernels.len() > 1 {
            dumps.extend(lavapipe_dumps(&kernels[1..], o)?);
        }
        let mut out = vec![];
        for (k, text) in kernels.iter().zip(dumps) {
            let fs = lavapipe_asm::parse(&text)
                .map_err(|e| Error::Usage(format!("{}: GALLIVM_DEBUG=asm dump: {e}", k.name)))?;
            let asm = lavapipe_asm::kernel(&fs).ok_or_else(|| {
                Error::Usage(format!(
                    "{}: lavapipe printed no compute-shader code (cs_variant) for it; was the pipeline served from a \
                     shader cache?",
                    k.name
                ))
            })?;
            if let Some(dir) = &o.asm_dir {
                crate::io::write_atomic(&dir.join(format!("{}.txt", k.name)), text.as_bytes())?;
            }
            out.push(KernelStats { lavapipe: Some(asm), ..KernelStats::of(k) });
        }
        return Ok(DriverStatsReport {
            provenance,
            status: Status::Measured,
            note: LAVAPIPE_NOTE.into(),
            kernels: out,
            targets: vec![],
        });
    }
    if ctx.enabled().pipeline_executable_properties {
        let names: Vec<String> = kernels.iter().map(|k| k.name.to_owned()).collect();
        let (out, refused) = compiled_kernels(compile::compile_kernels(ctx, &names, None)?);
        let mut note = EXECUTABLE_NOTE.to_owned();
        if !refused.is_empty() {
            let refused: Vec<String> = refused.iter().map(|r| format!("{}: {}", r.kernel, r.why)).collect();
            note.push_str(&format!("; not compiled here: {}", refused.join("; ")));
        }
        return Ok(DriverStatsReport { provenance, status: Status::Measured, note, kernels: out, targets: vec![] });
    }
    Ok(DriverStatsReport {
        provenance,
        status: Status::NotApplicable,
        note: {
            // Neither source of driver statistics (gpu::Capabilities): say why for each.
            let caps = ctx.capabilities();
            let why =
                |s: Statistic| caps.statistic(s).err().map_or_else(String::new, |u| format!("{}: {}", u.what, u.why));
            format!(
                "not available on {} ({}): {}; {}",
                info.name,
                info.driver_id,
                why(Statistic::ExecutableStatistics),
                why(Statistic::MachineCode)
            )
        },
        kernels: vec![],
        targets: vec![],
    })
}

/// The note of the compiler's own statistics.
pub const EXECUTABLE_NOTE: &str = "VK_KHR_pipeline_executable_properties: the driver's compiler's own statistics, \
     each kernel's pipeline created once with CAPTURE_STATISTICS (nothing dispatched), typed by the driver's \
     descriptions of them";

/// How [`collect_targets`] runs.
#[derive(Clone, Debug)]
pub struct TargetOptions {
    /// This executable (each target's worker).
    pub exe: PathBuf,
    pub validation: bool,
    /// The longest a target's worker may take.
    pub timeout: std::time::Duration,
    /// Targets compiled at once (each in its own worker).
    pub jobs: usize,
}

/// Every kernel of `kernels` compiled on every target, each target in its own worker, `jobs` at
/// a time: a target whose worker fails is kept with the reason (its note) and the others go on;
/// `progress` hears of each target as it ends.
pub fn collect_targets(
    targets: &[GpuTarget],
    kernels: &[&'static KernelSource],
    o: &TargetOptions,
    progress: &(dyn Fn(&TargetStats) + Sync),
) -> Vec<TargetStats> {
    let names: Vec<String> = kernels.iter().map(|k| k.name.to_owned()).collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results: std::sync::Mutex<Vec<Option<TargetStats>>> = std::sync::Mutex::new(vec![None; targets.len()]);
    std::thread::scope(|scope| {
        for _ in 0..o.jobs.clamp(1, targets.len().max(1)) {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                let Some(t) = targets.get(i) else { break };
                let stats = target_stats(t, t.compile(&o.exe, &names, o.validation, o.timeout));
                progress(&stats);
                results.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(stats);
            });
        }
    });
    results.into_inner().unwrap_or_else(|e| e.into_inner()).into_iter().flatten().collect()
}

/// The report of a `--targets` run: no device of its own (each target's worker had one).
pub fn targets_report(targets: Vec<TargetStats>) -> DriverStatsReport {
    let mut drivers: Vec<String> = targets.iter().filter(|t| !t.driver.is_empty()).map(|t| t.driver.clone()).collect();
    drivers.sort();
    drivers.dedup();
    DriverStatsReport {
        provenance: Provenance::without_device("RADV's null device (GPU targets)", &drivers.join("; ")),
        status: Status::Measured,
        note: format!(
            "{EXECUTABLE_NOTE}; each GPU target compiled by RADV's null device (RADV_FORCE_FAMILY=<chip>, RADV_DEBUG=llvm \
             for LLVM, requiredSubgroupSize for the subgroup size) in a worker of its own"
        ),
        kernels: vec![],
        targets,
    }
}

/// A compile's answer (a target worker's, or this device's) as the report's kernels and the
/// kernels refused, each compiled kernel with where it was compiled (the chip and compiler its
/// device names, the subgroup size its executable reports).
fn compiled_kernels(c: crate::services::worker::protocol::CompiledKernels) -> (Vec<KernelStats>, Vec<Refused>) {
    let (mut kernels, mut refused) = (vec![], vec![]);
    for k in c.kernels {
        let Some(src) = KERNELS.iter().find(|s| s.name == k.name) else { continue };
        match k.refused {
            Some(why) => refused.push(Refused { kernel: k.name, why }),
            None => kernels.push(KernelStats {
                statistics: k.statistics,
                compiled: Some(CompiledFor::of(&c.device, k.subgroup_size)),
                ..KernelStats::of(src)
            }),
        }
    }
    (kernels, refused)
}

/// A target's section of the report, from what its worker answered.
fn target_stats(t: &GpuTarget, got: Result<crate::services::worker::protocol::CompiledKernels>) -> TargetStats {
    let mut s = TargetStats {
        target: t.to_string(),
        compiled_for: CompiledFor { chip: Some(t.chip), compiler: Some(t.compiler), wave: t.wave },
        mesa_build: t.mesa.to_string(),
        device: String::new(),
        driver: String::new(),
        driver_info: String::new(),
        mesa_version: None,
        status: Status::Measured,
        note: EXECUTABLE_NOTE.into(),
        kernels: vec![],
        refused: vec![],
    };
    match got {
        Err(e) => {
            s.status = Status::Unsupported;
            s.note = e.to_string();
        }
        Ok(c) => {
            s.device.clone_from(&c.device);
            s.driver.clone_from(&c.driver);
            s.driver_info.clone_from(&c.driver_info);
            s.mesa_version.clone_from(&c.mesa_version);
            (s.kernels, s.refused) = compiled_kernels(c);
        }
    }
    s
}

/// Whether a kernel's part of the child's stderr holds any machine code: with GALLIVM_DEBUG read,
/// gallivm prints at least the per-descriptor helpers it compiles, even for a variant served
/// from a shader cache; a build that reads no GALLIVM_DEBUG (Debian 12's Mesa 22.3.6) prints
/// nothing between the markers. A dump that does not parse counts as code (its error is
/// reported where it is read).
pub fn printed_code(dump: &str) -> bool {
    !lavapipe_asm::parse(dump).is_ok_and(|fs| fs.is_empty())
}

/// Why a lavapipe that printed no machine code under `GALLIVM_DEBUG=asm` (not even the texel-fetch
/// helpers every kernel uses) has no driver statistics. Older gallivm read GALLIVM_DEBUG only in
/// debug builds (`#ifdef DEBUG`; `gallivm_debug` was the constant 0 otherwise), and Debian 12's
/// own release build (22.3.6) prints nothing: `strings` on its `libvulkan_lvp.so` finds no
/// `GALLIVM_DEBUG`, while 25.0.7's (bookworm-backports) has it. It offers no
/// VK_KHR_pipeline_executable_properties either. (Its disk cache does hold each variant's
/// object code, an ELF file `objdump -d` reads, but reading it needs the cache's private format.)
pub fn no_asm_note(device: &str, mesa_version: Option<&str>) -> String {
    let mesa = mesa_version.map(|v| format!("Mesa {v}")).unwrap_or_else(|| "this Mesa".into());
    format!(
        "not available on this driver: {device}, {mesa}, printed no machine code under GALLIVM_DEBUG=asm, not even its \
         texel-fetch helpers (this release build reads no GALLIVM_DEBUG; older gallivm read it in debug builds only, \
         Mesa 25.0.7 from bookworm-backports reads it), and offers no VK_KHR_pipeline_executable_properties"
    )
}

/// Runs the child (a worker, [`crate::services::worker`], with `GALLIVM_DEBUG=asm` and
/// `MESA_SHADER_CACHE_DISABLE=true`) and returns each kernel's part of its stderr, in
/// `kernels`' order.
fn lavapipe_dumps(kernels: &[&'static KernelSource], o: &CollectOptions) -> Result<Vec<String>> {
    let names: Vec<&str> = kernels.iter().map(|k| k.name).collect();
    let launch = Launch {
        whole_stderr: true,
        ..Launch::new(&o.exe)
            .env("GALLIVM_DEBUG", "asm")
            .env("MESA_SHADER_CACHE_DISABLE", "true")
            .device(o.device_index)
            .validation(o.validation)
    };
    let who = "the driver-statistics child (GALLIVM_DEBUG=asm)";
    let request = Request::DispatchKernels { kernels: names.iter().map(|&n| n.to_owned()).collect() };
    let answered = worker::call(&launch, who, &request)?;
    match answered.message {
        Message::Dispatched { .. } => split_dump(&answered.stderr, &names),
        other => Err(worker::unexpected(who, "dispatched", &other)),
    }
}

/// Each kernel's text between its begin and end markers.
pub fn split_dump(text: &str, names: &[&str]) -> Result<Vec<String>> {
    let mut parts: BTreeMap<&str, String> = BTreeMap::new();
    let mut current: Option<(&str, String)> = None;
    for line in text.lines() {
        if let Some(name) = line.strip_prefix(BEGIN) {
            current = Some((names.iter().copied().find(|n| *n == name.trim()).unwrap_or("?"), String::new()));
        } else if let Some(name) = line.strip_prefix(END) {
            match current.take() {
                Some((n, t)) if n == name.trim() => {
                    parts.insert(n, t);
                }
                _ => return Err(Error::Usage(format!("driver-stats child: unmatched end marker for {name}"))),
            }
        } else if let Some((_, t)) = &mut current {
            t.push_str(line);
            t.push('\n');
        }
    }
    names
        .iter()
        .map(|n| parts.remove(n).ok_or_else(|| Error::Usage(format!("driver-stats child: no dump for kernel {n}"))))
        .collect()
}

/// The scene the child dispatches each kernel on (small: only the compilation matters).
const CHILD_SCENE: &str = "cornell";
/// Rays per dispatch in the child.
const CHILD_RAYS: usize = 256;

/// The method, layout, access path and traversal of a `raycast` kernel variant (its key).
fn raycast_request(k: &KernelSource) -> Result<SceneRequest> {
    let key = RaycastKey::of(k).ok_or_else(|| {
        Error::Usage(format!(
            "{}: driver-stats dispatches ray-casting kernels only, `raycast*` (lavapipe compiles a shader at its \
             first dispatch)",
            k.name
        ))
    })?;
    Ok(SceneRequest::new(key.method).layout(key.layout).access(key.access.requested()).traversal(key.traversal))
}

/// The child's side (a worker's `dispatch-kernels` request, under GALLIVM_DEBUG=asm): dispatches each named
/// kernel once on a small scene between marker lines on stderr, where gallivm prints its
/// disassembly. lavapipe compiles a compute shader at its first dispatch, not when the pipeline
/// is created (checked: creating the pipeline alone printed no `cs_variant`). The hits are
/// checked against the f64 reference like any other result (any-hit kernels against the
/// closest-hit kernel's, which is checked against the reference).
pub fn emit_for_parent(ctx: &Context, names: &[String]) -> Result<()> {
    use std::io::Write;
    let kernels: Vec<&'static KernelSource> = names
        .iter()
        .map(|n| {
            KERNELS.iter().find(|k| k.name == n).ok_or_else(|| Error::Usage(format!("dispatch-kernels: no kernel {n}")))
        })
        .collect::<Result<_>>()?;
    let requests: Vec<SceneRequest> = kernels.iter().map(|k| raycast_request(k)).collect::<Result<_>>()?;
    let mesh = load_obj(Path::new(CHILD_SCENE))?;
    let host = HostScene::build(CHILD_SCENE, &mesh, &BuildOptions::new(crate::defaults::LEAF_SIZE))?;
    let rays = crate::rays::random_rays(&mesh.bounds(), CHILD_RAYS, 1);
    let reference = host.reference().trace_all(&rays, false);
    let marker =
        |line: String| writeln!(std::io::stderr().lock(), "{line}").map_err(|e| Error::io(Path::new("stderr"), e));
    for (k, request) in kernels.iter().zip(requests) {
        let scene = host.upload(ctx, &request)?;
        let kernel = ctx.create_kernel(k)?;
        // gallivm writes with stdio's unbuffered stderr, and Rust's stderr is unbuffered: the
        // markers and the dump arrive in order.
        marker(format!("{BEGIN}{}", k.name))?;
        let opts = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
        let res = scene.cast_with(ctx, &kernel, &rays, &opts)?;
        marker(format!("{END}{}", k.name))?;
        let closest = if k.variant.starts_with("any") {
            // Any-hit: it must hit exactly where the (validated) closest-hit kernel does, and
            // only real hits (`compare::compare_any`).
            let closest = scene.cast(ctx, crate::encoding::Raycast::Closest, &rays, &opts)?;
            let check = crate::agreement::compare_any(&mesh, &rays, &closest.hits, &res.hits);
            if !check.passes() {
                return Err(Error::Usage(format!("{}: any-hit disagrees with closest-hit: {check:?}", k.name)));
            }
            closest.hits
        } else {
            res.hits
        };
        crate::services::validate::validate_hits(&mesh, &rays, &closest, &reference)
            .map_err(|e| Error::Usage(format!("{}: {e}", k.name)))?;
    }
    Ok(())
}

/// One row per kernel (command [`COMMAND`]; cell kernel, variant, method, layout, and where the
/// compiler's statistics were compiled: chip, compiler, wave), for this device and for each GPU
/// target. lavapipe's figures are counts; the compiler's statistics are figures with their unit
/// and direction, their hashes identities. Every row names the driver build that compiled it
/// ([`crate::rows::DRIVER_BUILD`]), which `compare` requires to agree before it judges counts.
pub fn rows(r: &DriverStatsReport) -> Vec<Row> {
    let mut source = r.provenance.source();
    // The driver compiles the SPIR-V: another GLSL compiler's modules give other machine code.
    source.settings.insert(crate::rows::SPIRV_COMPILER.into(), crate::kernels::SPIRV_COMPILER.into());
    source.settings.insert(crate::rows::DRIVER_BUILD.into(), r.provenance.driver.clone());
    if r.kernels.iter().any(|k| k.lavapipe.is_some()) {
        // lavapipe's machine code is LLVM's for this host's CPU: another CPU compiles other code.
        source.settings.insert(crate::rows::JIT_CPU.into(), r.provenance.host.cpu_id.clone());
    }
    if r.kernels.iter().any(|k| k.compiled.is_some()) {
        // Each kernel says the subgroup size it was compiled at (its `wave`): the device's
        // default, which a driver variable may override, says nothing about it.
        source.settings.remove("subgroup_size");
    }
    let mut out: Vec<Row> = r.kernels.iter().map(|k| kernel_row(k, &source)).collect();
    for t in r.targets.iter().filter(|t| t.status == Status::Measured) {
        let mut s = crate::rows::Source {
            device: t.device.clone(),
            driver: t.driver.clone(),
            settings: Default::default(),
            host: None,
            ..r.provenance.source()
        };
        s.settings.insert(crate::rows::SPIRV_COMPILER.into(), crate::kernels::SPIRV_COMPILER.into());
        s.settings.insert(crate::rows::DRIVER_BUILD.into(), t.driver.clone());
        out.extend(t.kernels.iter().map(|k| kernel_row(k, &s)));
    }
    out
}

/// One kernel's row.
fn kernel_row(k: &KernelStats, source: &crate::rows::Source) -> Row {
    let mut cell = k.cell.coordinates();
    if let Some(c) = &k.compiled {
        cell.extend(c.coordinates().into_iter().map(|(k, v)| (k.to_owned(), v)));
    }
    let mut row = Row::new(COMMAND, cell, source);
    if let Some(a) = &k.lavapipe {
        let t = &a.total;
        for (name, v, unit) in [
            ("instructions", t.instructions, "instructions"),
            ("vector_spills", t.vector_spills, "stores"),
            ("vector_reloads", KernelStats::vector_reloads(a), "loads"),
            ("stack_stores", t.stack_stores, "stores"),
            ("mask_spills", t.mask_spills, "stores"),
            ("calls", t.calls, "calls"),
            ("helper_calls", a.helper_calls, "calls"),
            ("stack_bytes", t.stack_bytes, "bytes"),
            ("gathers", t.gathers, "loads"),
            ("lane_loads", t.lane_loads, "loads"),
            ("broadcast_loads", t.broadcast_loads, "loads"),
        ] {
            row = row.with(name, Figure::count(v as f64, unit));
        }
    }
    for st in &k.statistics {
        row = match st.figure() {
            Some(f) => row.with(&st.name, f),
            None => row.with_identity(&st.name, &st.text()),
        };
    }
    row
}

/// The table of lavapipe's figures per kernel.
pub fn table(kernels: &[KernelStats]) -> crate::report::Table {
    let mut t = crate::report::Table::new([
        "kernel",
        "variant",
        "method",
        "layout",
        "instructions",
        "vector spills",
        "vector reloads",
        "stack stores",
        "helper calls",
        "calls",
        "stack bytes",
        "gathers",
        "lane loads",
        "broadcast loads",
    ]);
    for k in kernels {
        let Some(a) = &k.lavapipe else { continue };
        let t_ = &a.total;
        let trunc = if a.truncated { " (truncated)" } else { "" };
        t.row([
            k.cell.kernel.clone(),
            k.cell.variant.clone(),
            k.cell.method.clone(),
            k.cell.layout.clone(),
            format!("{}{trunc}", t_.instructions),
            t_.vector_spills.to_string(),
            KernelStats::vector_reloads(a).to_string(),
            t_.stack_stores.to_string(),
            a.helper_calls.to_string(),
            t_.calls.to_string(),
            t_.stack_bytes.to_string(),
            t_.gathers.to_string(),
            t_.lane_loads.to_string(),
            t_.broadcast_loads.to_string(),
        ]);
    }
    t
}

/// What the table's columns count.
pub const LEGEND: &str = "\nvector spills: xmm/ymm/zmm stores to fixed stack slots that are read back; vector reloads: \
     loads from them (moves and folded operands); stack stores: vector stores to slots never read back at a fixed offset \
     (local arrays' zero fill); helper calls: calls from the shader's body through a descriptor's function table \
     (llvmpipe's texel-fetch/image/size helpers); stack bytes: the largest frame; gathers: hardware gathers \
     (vpgatherdd, ...); lane loads: one lane's element loaded from memory (vpinsrd, vinsertps: a gather written \
     out lane by lane); broadcast loads: one load into every lane (vpbroadcastd, vbroadcastss: an address the same \
     in all lanes, a GPU's scalar load); neither counts the stack or the helpers' own loads. Counts are static (code size), not \
     executed instructions.\n";

/// `driver-stats.json`, `driver-stats.md` (the text report), `rows.jsonl` (no plan).
impl crate::services::results::Results for DriverStatsReport {
    const STEM: &'static str = "driver-stats";

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        crate::report::Report::to_text(self)
    }

    fn rows(&self) -> Option<Vec<Row>> {
        Some(rows(self))
    }

    /// `driver-stats.csv`, where the compiler reported statistics: every kernel of every
    /// target.
    fn files(&self) -> Result<Vec<(&'static str, String)>> {
        if self.kernels.iter().all(|k| k.statistics.is_empty()) && self.targets.is_empty() {
            return Ok(vec![]);
        }
        Ok(vec![("driver-stats.csv", report::csv(self)?)])
    }
}

impl crate::report::Report for DriverStatsReport {
    fn to_text(&self) -> String {
        let p = &self.provenance;
        // A compiled kernel names the subgroup size it was compiled at; the device's default
        // says nothing of it.
        let compiled = self.kernels.iter().any(|k| k.compiled.is_some());
        let settings: Vec<String> = p
            .settings
            .iter()
            .filter(|(k, _)| !(compiled && *k == "subgroup_size"))
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        let mut out = format!(
            "# Driver statistics: {} ({})\n\n- **driver**: {}{}\n{}- **commit**: {}, {}\n- **how**: {}\n\n",
            p.device,
            p.driver,
            p.mesa_version.as_deref().map(|m| format!("Mesa {m}")).unwrap_or_else(|| p.driver.clone()),
            if self.status == Status::Measured { "" } else { " (no figures)" },
            if settings.is_empty() { String::new() } else { format!("- **settings**: {}\n", settings.join(", ")) },
            p.commit,
            p.date,
            self.note
        );
        if self.kernels.iter().any(|k| k.lavapipe.is_some()) {
            out.push_str(&table(&self.kernels).to_markdown());
            out.push_str(LEGEND);
        }
        let compiled: Vec<&KernelStats> = self.kernels.iter().filter(|k| !k.statistics.is_empty()).collect();
        if !compiled.is_empty() {
            let waves: std::collections::BTreeSet<String> =
                compiled.iter().filter_map(|k| k.compiled.as_ref().map(|c| c.label())).collect();
            out.push_str(&format!("Compiled for: {}\n\n", waves.into_iter().collect::<Vec<_>>().join(", ")));
            out.push_str(&report::compiled_table(&compiled).to_markdown());
            out.push_str(report::COMPILED_LEGEND);
        }
        if !self.targets.is_empty() {
            out.push_str(&targets_text(&self.targets));
        }
        out
    }
}

/// The GPU targets' part of the report: a summary row per target, then each target's table and
/// its cliffs.
fn targets_text(targets: &[TargetStats]) -> String {
    let mut out = String::from("## GPU targets\n\n");
    out.push_str(&report::targets_table(targets).to_markdown());
    out.push_str(
        "\nat one subgroup: kernels of which a SIMD holds one subgroup (RDNA's count of wave64 reads 2); on a cliff: \
         kernels one more VGPR would cost a subgroup per SIMD. driver-stats.csv lists every kernel of every target.\n",
    );
    for t in targets {
        out.push_str(&format!("\n### {}\n\n", t.target));
        if t.status != Status::Measured {
            out.push_str(&format!("Not compiled: {}\n", t.note));
            continue;
        }
        out.push_str(&format!("{} on {} ({} kernels", t.driver, t.device, t.kernels.len()));
        if !t.refused.is_empty() {
            out.push_str(&format!("; {} not compiled: ", t.refused.len()));
            let mut whys: BTreeMap<&str, usize> = BTreeMap::new();
            for r in &t.refused {
                *whys.entry(r.why.as_str()).or_default() += 1;
            }
            out.push_str(&whys.iter().map(|(w, n)| format!("{n} as {w}")).collect::<Vec<_>>().join("; "));
        }
        out.push_str(").\n\n");
        let m = report::Summary::of(&t.kernels, t.refused.len());
        if m.model_disagrees > 0 {
            out.push_str(&format!(
                "The occupancy model gives another subgroups-per-SIMD figure than the driver for {} kernels (shown as \
                 `reported (model m)`): their cliffs are not to be trusted.\n\n",
                m.model_disagrees
            ));
        }
        if !m.on_cliff.is_empty() {
            out.push_str(&format!(
                "On a cliff ({}): {}\n\n",
                m.on_cliff.len(),
                m.on_cliff.iter().take(40).cloned().collect::<Vec<_>>().join(", ")
            ));
            if m.on_cliff.len() > 40 {
                out.push_str(&format!(
                    "... and {} more (driver-stats.csv, vgprs_to_lose_one = 1)\n\n",
                    m.on_cliff.len() - 40
                ));
            }
        }
        let (listed, cut) = report::tabled(&t.kernels);
        if cut {
            out.push_str(&format!(
                "The closest-hit ray-casting kernels ({} of {}; driver-stats.csv has all):\n\n",
                listed.len(),
                t.kernels.len()
            ));
        }
        out.push_str(&report::compiled_table(&listed).to_markdown());
    }
    out.push_str(report::COMPILED_LEGEND);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::{SceneAccess, Traversal};

    #[test]
    fn the_dump_splits_at_the_markers() {
        let text = format!(
            "noise\n{BEGIN}a\nsample:\n  0:\tretq\n{END}a\nbetween\n{BEGIN}b\ncs_variant:\n  0:\tretq\n{END}b\n"
        );
        let parts = split_dump(&text, &["a", "b"]).unwrap();
        assert_eq!(parts, ["sample:\n  0:\tretq\n", "cs_variant:\n  0:\tretq\n"]);
        assert!(split_dump(&text, &["a", "b", "c"]).is_err());
        assert!(split_dump(&format!("{END}a\n"), &["a"]).is_err());
    }

    /// What Debian 12's own lavapipe (Mesa 22.3.6) printed for two kernels under GALLIVM_DEBUG=asm
    /// (tests/data/lavapipe-asm/README.md): the markers and nothing else, so the statistics are
    /// refused as unavailable, where 25.0.7's dump of the same kernel counts.
    #[test]
    fn mesa_22_3_6_prints_no_code_and_is_told_apart() {
        let text = include_str!("../../../tests/data/lavapipe-asm/mesa-22.3.6.stderr.txt");
        let names = ["raycast.mt.closest", "raycast.quad-unit.any_cwbvh"];
        let parts = split_dump(text, &names).unwrap();
        assert!(parts.iter().all(|p| !printed_code(p)), "{parts:?}");
        let mesa_25 = include_str!("../../../tests/data/lavapipe-asm/raycast.mt.closest.txt");
        assert!(printed_code(mesa_25));
        // Only the helpers (a variant served from a cache) still shows GALLIVM_DEBUG is read.
        assert!(printed_code("sample:\n  0:\tretq\n"));
        let note = no_asm_note("llvmpipe (LLVM 15.0.6, 256 bits)", Some("22.3.6"));
        assert!(note.contains("Mesa 22.3.6") && note.contains("GALLIVM_DEBUG"), "{note}");
    }

    #[test]
    fn all_is_every_kernel_and_studied_the_studied_ones() {
        assert_eq!(Selection::everything().kernels().unwrap().len(), KERNELS.len());
        let studied = Selection { kernels: vec![STUDIED.into()], methods: vec![Method::Mt], ..Selection::everything() };
        let names: Vec<&str> = studied.kernels().unwrap().iter().map(|k| k.name).collect();
        // mt: closest and any-hit on bvh2, closest-hit on the four other layouts; the ray-query
        // peer, which has no method.
        assert_eq!(names.len(), 2 + (Layout::ALL.len() - 1) + 2, "{names:?}");
        assert!(names.contains(&"raycast.mt.any") && names.contains(&"raycast.mt.closest_qbvh4"), "{names:?}");
        assert!(names.contains(&"rayquery.none.closest") && !names.contains(&"raycast.mt.any_bvh4"), "{names:?}");
        // A method filter keeps the kernels with no method (the probes, the roofline).
        let mt = Selection { methods: vec![Method::Mt], ..Selection::everything() }.kernels().unwrap();
        assert!(
            mt.iter().any(|k| k.kernel == "roofline") && mt.iter().all(|k| ["mt", "none"].contains(&k.intersector))
        );
    }

    #[test]
    fn the_default_selection_is_every_method_and_layout() {
        let ks = Selection::default().kernels().unwrap();
        let n = Method::ALL.len() * Layout::ALL.len();
        assert_eq!(ks.len(), 2 * n);
        assert!(ks.iter().all(|k| k.kernel == "raycast" && raycast_request(k).is_ok()));
        let k = ks.iter().find(|k| k.name == "raycast.quad-mt.any_cwbvh").unwrap();
        assert_eq!((base_variant(k), k.layout), ("any", "cwbvh"));
        let pt = kernels_named(&["pathtrace.mt.all"]);
        assert!(raycast_request(pt[0]).unwrap_err().to_string().contains("ray-casting kernels only"));
        let bda = kernels_named(&["raycast.unit.closest_address_bvh8"]);
        let r = raycast_request(bda[0]).unwrap();
        assert_eq!((r.access, r.layout, r.traversal), (SceneAccess::Address, Layout::Bvh8, Traversal::WhileIf));
        let ww = kernels_named(&["raycast.mt.any_while_while"]);
        assert_eq!(raycast_request(ww[0]).unwrap().traversal, Traversal::WhileWhile);
        let bad = Selection { kernels: vec!["nope".into()], ..Selection::default() };
        assert!(bad.kernels().unwrap_err().to_string().contains("no kernel `nope`"));
        let none = Selection { variants: vec!["nope".into()], ..Selection::default() };
        assert!(none.kernels().is_err());
    }

    #[test]
    fn a_kernel_cell_is_read_back_from_the_coordinates_it_writes() {
        let k = kernels_named(&["raycast.quad-mt.closest_address_bvh8"])[0];
        let want = [("kernel", "raycast"), ("layout", "bvh8"), ("method", "quad-mt"), ("variant", "closest_address")];
        let c = KernelCell::of(k).coordinates();
        assert_eq!(c.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect::<Vec<_>>(), want);
        let read = KernelCell::try_from(&crate::rows::cell(want)).unwrap();
        assert_eq!(read, KernelCell::of(k));
        assert_eq!(read.coordinates(), c);
        let no_variant = crate::rows::cell([("kernel", "raycast"), ("method", "mt"), ("layout", "bvh2")]);
        let e = KernelCell::try_from(&no_variant).unwrap_err();
        assert!(e.contains("has no `variant` coordinate"), "{e}");
        assert!(e.contains("driver-stats kernel=raycast layout=bvh2 method=mt"), "{e}");
    }

    fn kernels_named(names: &[&str]) -> Vec<&'static KernelSource> {
        names.iter().map(|n| KERNELS.iter().find(|k| k.name == *n).unwrap()).collect()
    }
}
