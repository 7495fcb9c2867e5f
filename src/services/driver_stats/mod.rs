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
//! Where the device is not lavapipe: the statistics the driver reports through
//! `VK_KHR_pipeline_executable_properties` if it offers the extension (untested here, as in
//! `trilab profile`), else "not available on this driver" and no figures.

pub mod dispatch;
pub mod executable;
pub mod lavapipe_asm;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bvh::BuildOptions;
use crate::encoding::{Layout, Method, RaycastKey};
use crate::error::{Error, Result};
use crate::gpu::{Context, PipelineOptions, RaycastOptions, Statistic};
use crate::kernels::{KernelSource, KERNELS};
use crate::named::Named;
use crate::pipeline::{HostScene, SceneRequest};
use crate::report::Status;
use crate::rows::{cell, Figure, Row};
use crate::scene::load_obj;
use crate::services::provenance::Provenance;
use crate::services::worker::{self, Launch, Message, Request};
use lavapipe_asm::KernelAsm;

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
    /// Variants without their layout suffix (`closest`, `any`, `closest_bda`, `all`, ...).
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

/// A variant's name without its layout suffix: `closest_bda_bvh4` on bvh4 -> `closest_bda`.
pub fn base_variant(k: &KernelSource) -> &'static str {
    k.variant.strip_suffix(&format!("_{}", k.layout)).unwrap_or(k.variant)
}

impl Selection {
    /// The registry's variants it names, in the registry's order; an error naming what matched
    /// nothing.
    pub fn kernels(&self) -> Result<Vec<&'static KernelSource>> {
        let methods: Vec<String> = self.methods.iter().map(|m| m.to_string()).collect();
        let layouts: Vec<String> = self.layouts.iter().map(|l| l.to_string()).collect();
        for k in &self.kernels {
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
                self.kernels.contains(&c.kernel)
                    && self.variants.contains(&c.variant)
                    && methods.contains(&c.method)
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
    /// Other drivers: the executable statistics they report, name to value (numbers only).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub executable: BTreeMap<String, f64>,
}

impl KernelStats {
    fn of(k: &KernelSource) -> KernelStats {
        KernelStats { name: k.name.into(), cell: KernelCell::of(k), lavapipe: None, executable: BTreeMap::new() }
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
    pub kernels: Vec<KernelStats>,
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
        });
    }
    if ctx.enabled().pipeline_executable_properties {
        let mut out = vec![];
        for k in kernels {
            let kernel =
                ctx.create_kernel_with(k, &PipelineOptions { capture_statistics: true, ..Default::default() })?;
            let stats = executable::executable_statistics(ctx, &kernel)?;
            out.push(KernelStats { executable: executable_figures(&stats), ..KernelStats::of(k) });
        }
        let note = "VK_KHR_pipeline_executable_properties: the driver's own statistics per executable (untested here: \
                    lavapipe lacks the extension)";
        return Ok(DriverStatsReport { provenance, status: Status::Measured, note: note.into(), kernels: out });
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
    })
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

/// The numeric statistics of a pipeline's executables as figures named
/// `<executable index>_<statistic in snake case>` ("0_register_count"); booleans and text are
/// left out (a row's figures are numbers).
pub fn executable_figures(stats: &[executable::ExecutableStatistic]) -> BTreeMap<String, f64> {
    stats
        .iter()
        .filter_map(|st| st.value.parse::<f64>().ok().map(|v| (format!("{}_{}", st.executable, snake(&st.name)), v)))
        .collect()
}

/// `Instruction Count` -> `instruction_count`.
fn snake(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') && !out.is_empty() {
            out.push('_');
        }
    }
    out.trim_end_matches('_').to_owned()
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
    let key = RaycastKey::of(k).filter(|_| k.kernel == "raycast").ok_or_else(|| {
        Error::Usage(format!(
            "{}: driver-stats dispatches `raycast` kernels only (lavapipe compiles a shader at its first dispatch)",
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

/// One row per kernel (command [`COMMAND`]; cell kernel, variant, method, layout; every figure
/// a count).
pub fn rows(r: &DriverStatsReport) -> Vec<Row> {
    let mut source = r.provenance.source();
    // The driver compiles the SPIR-V: another GLSL compiler's modules give other machine code.
    source.settings.insert(crate::rows::SPIRV_COMPILER.into(), crate::kernels::SPIRV_COMPILER.into());
    if r.kernels.iter().any(|k| k.lavapipe.is_some()) {
        // lavapipe's machine code is LLVM's for this host's CPU: another CPU compiles other code.
        source.settings.insert(crate::rows::JIT_CPU.into(), r.provenance.host.cpu_id.clone());
    }
    r.kernels
        .iter()
        .map(|k| {
            let mut row = Row::new(COMMAND, k.cell.coordinates(), &source);
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
                ] {
                    row = row.with(name, Figure::count(v as f64, unit));
                }
            }
            for (name, v) in &k.executable {
                row = row.with(name, Figure::count(*v, "count"));
            }
            row
        })
        .collect()
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
        ]);
    }
    t
}

/// What the table's columns count.
pub const LEGEND: &str = "\nvector spills: xmm/ymm/zmm stores to fixed stack slots that are read back; vector reloads: \
     loads from them (moves and folded operands); stack stores: vector stores to slots never read back at a fixed offset \
     (local arrays' zero fill); helper calls: calls from the shader's body through a descriptor's function table \
     (llvmpipe's texel-fetch/image/size helpers); stack bytes: the largest frame. Counts are static (code size), not \
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
}

impl crate::report::Report for DriverStatsReport {
    fn to_text(&self) -> String {
        let p = &self.provenance;
        let mut out = format!(
            "# Driver statistics: {} ({})\n\n- **driver**: {}{}\n- **settings**: {}\n- **commit**: {}, {}\n- **how**: {}\n\n",
            p.device,
            p.driver,
            p.mesa_version.as_deref().map(|m| format!("Mesa {m}")).unwrap_or_else(|| p.driver.clone()),
            if self.status == Status::Measured { "" } else { " (no figures)" },
            p.settings.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>().join(", "),
            p.commit,
            p.date,
            self.note
        );
        if self.kernels.iter().any(|k| k.lavapipe.is_some()) {
            out.push_str(&table(&self.kernels).to_markdown());
            out.push_str(LEGEND);
        }
        for k in self.kernels.iter().filter(|k| !k.executable.is_empty()) {
            out.push_str(&format!("\n{}: ", k.name));
            out.push_str(&k.executable.iter().map(|(n, v)| format!("{n} {v}")).collect::<Vec<_>>().join(", "));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encoding::{SceneAccess, Traversal};

    /// What a driver with `VK_KHR_pipeline_executable_properties` reports (lavapipe does not:
    /// these are the statistics an NVIDIA driver names), as figures: numbers kept per
    /// executable, booleans left out, names in snake case.
    #[test]
    fn executable_statistics_become_figures_per_executable() {
        let st = |executable: u32, name: &str, value: &str| super::executable::ExecutableStatistic {
            executable,
            executable_name: "Compute Shader".into(),
            executable_description: String::new(),
            subgroup_size: 32,
            name: name.into(),
            description: String::new(),
            value: value.into(),
        };
        let f = executable_figures(&[
            st(0, "Register Count", "96"),
            st(0, "Spill Count", "0"),
            st(0, "Uses Shared Memory", "true"),
            st(1, "Register Count", "40"),
            st(1, "Occupancy", "0.75"),
        ]);
        let want: BTreeMap<String, f64> =
            [("0_register_count", 96.0), ("0_spill_count", 0.0), ("1_occupancy", 0.75), ("1_register_count", 40.0)]
                .into_iter()
                .map(|(k, v)| (k.to_owned(), v))
                .collect();
        assert_eq!(f, want);
    }

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
    fn the_default_selection_is_every_method_and_layout() {
        let ks = Selection::default().kernels().unwrap();
        let n = Method::ALL.len() * Layout::ALL.len();
        assert_eq!(ks.len(), 2 * n);
        assert!(ks.iter().all(|k| k.kernel == "raycast" && raycast_request(k).is_ok()));
        let k = ks.iter().find(|k| k.name == "raycast.quad-mt.any_cwbvh").unwrap();
        assert_eq!((base_variant(k), k.layout), ("any", "cwbvh"));
        let pt = kernels_named(&["pathtrace.mt.all"]);
        assert!(raycast_request(pt[0]).unwrap_err().to_string().contains("raycast` kernels only"));
        let bda = kernels_named(&["raycast.unit.closest_bda_bvh8"]);
        let r = raycast_request(bda[0]).unwrap();
        assert_eq!((r.access, r.layout, r.traversal), (SceneAccess::Address, Layout::Bvh8, Traversal::WhileIf));
        let ww = kernels_named(&["raycast.mt.any_ww"]);
        assert_eq!(raycast_request(ww[0]).unwrap().traversal, Traversal::WhileWhile);
        let bad = Selection { kernels: vec!["nope".into()], ..Selection::default() };
        assert!(bad.kernels().unwrap_err().to_string().contains("no kernel `nope`"));
        let none = Selection { variants: vec!["nope".into()], ..Selection::default() };
        assert!(none.kernels().is_err());
    }

    #[test]
    fn a_kernel_cell_is_read_back_from_the_coordinates_it_writes() {
        let k = kernels_named(&["raycast.quad-mt.closest_bda_bvh8"])[0];
        let want = [("kernel", "raycast"), ("layout", "bvh8"), ("method", "quad-mt"), ("variant", "closest_bda")];
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

    #[test]
    fn snake_case_statistic_names() {
        assert_eq!(snake("Instruction Count"), "instruction_count");
        assert_eq!(snake("SGPRs (spilled)"), "sgprs_spilled");
    }
}
