//! What trilab and the trilab it runs again ([`super`]) say to each other: typed requests
//! ([`Request`]) on the child's stdin and typed answers ([`Message`]) on its stdout, one JSON
//! object a line. Both ends are built from these types, so nothing either reads back is untyped.
//!
//! Two ways in, one vocabulary: `trilab __worker` answers one-shot requests (a bench under
//! another `LP_NUM_THREADS`, kernels dispatched under `GALLIVM_DEBUG=asm`, a side's driver
//! statistics), and `trilab __ab-worker WORKLOAD --hits-dir DIR`, the name every build since
//! protocol 1 answers to, loads an `ab` side's workload, says [`Message::Ready`] and then times
//! its cells on request. The protocol's version ([`PROTOCOL`]) is what a side's `ready` says,
//! so a build can be timed against an older one (`ab --a-bin OLD`): a worker older than
//! [`PROTOCOL_TYPED`] reads the words `round`, `cell N` and `quit` instead of JSON
//! ([`Request::line`]), and has no `__worker`.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::encoding::{Layout, Method, SceneAccess, Traversal};
use crate::report::{Status, Summary};
use crate::rows::Row;

/// The version of the protocol. A worker of another build answers with its own
/// ([`Message::Ready`]); the parent takes every version up to its own, so a build can be timed
/// against an older one (`ab --a-bin`). Version 1 (no `protocol` field) had no traversal axis
/// (its cells are all while-if) and timed whole rounds only; version 2 adds `cell N`, so the
/// parent can run the two sides' runs of one cell back to back; version 3 reads typed requests
/// (JSON lines) and has `trilab __worker`, which gives an `ab` side's driver statistics.
pub const PROTOCOL: u32 = 3;

/// The first protocol with the `cell N` command (one cell timed at a time).
pub const PROTOCOL_CELL: u32 = 2;

/// The first protocol whose worker reads [`Request`]s as JSON and answers one-shot requests
/// (`trilab __worker`).
pub const PROTOCOL_TYPED: u32 = 3;

/// The hidden command that answers one-shot requests read from its stdin.
pub const COMMAND: &str = "__worker";

/// The hidden command that serves an `ab` side (the same command by its older name, which
/// every build since protocol 1 answers to).
pub const SESSION_COMMAND: &str = "__ab-worker";

/// What the parent asks of a worker, one a line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "request", rename_all = "kebab-case")]
pub enum Request {
    /// An `ab` side: time every cell once ([`Message::Round`]).
    Round,
    /// An `ab` side: time cell `index` once (protocol 2; [`Message::Round`] of one cell).
    Cell { index: usize },
    /// The end: the worker exits.
    Quit,
    /// `profile`'s LP_NUM_THREADS section: a bench of ray files under the `LP_NUM_THREADS` the
    /// parent set ([`Message::Measured`]).
    BenchThreads(BenchThreads),
    /// The driver statistics' child, run with `GALLIVM_DEBUG=asm`: dispatch each named kernel
    /// once between marker lines on stderr, where gallivm prints its machine code
    /// ([`Message::Dispatched`]).
    DispatchKernels { kernels: Vec<String> },
    /// An `ab` side's driver statistics of these kernels, in that side's environment
    /// ([`Message::DriverStats`]).
    DriverStats(DriverStatsRequest),
    /// `trilab repro`'s capture: the repro in `dir` dispatched once by a worker whose context is
    /// that repro's (`__worker --repro DIR`, under GFXReconstruct's layer), its hits written to
    /// `hits` ([`Message::ReproDispatched`]).
    ReproDispatch { dir: PathBuf, hits: PathBuf },
    /// `ab --repro`: a repro of one cell made by a side's worker, with its build and in its
    /// environment ([`Message::ReproMade`]).
    MakeRepro(ReproSpec),
    /// A GPU target's worker (`driver-stats --targets`): compile each named kernel once and give
    /// what the driver made of it ([`Message::Compiled`]). Nothing is dispatched, so a device
    /// that only compiles (RADV's null device) answers it.
    CompileKernels(CompileRequest),
}

/// Which kernels a [`Request::CompileKernels`] compiles, and at which subgroup size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompileRequest {
    /// Registry names (`raycast.mt.closest`).
    pub kernels: Vec<String>,
    /// The pipeline's `requiredSubgroupSize` (`None`: the driver's choice).
    #[serde(default)]
    pub subgroup_size: Option<u32>,
}

/// What a [`Request::CompileKernels`] compiled: the worker's device and driver, and each kernel's
/// statistics or why it could not be compiled there.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompiledKernels {
    pub device: String,
    /// The driver as a label (`radv, Mesa 25.0.7`).
    pub driver: String,
    /// The driver's `driverInfo` (`Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)`): which build compiled.
    pub driver_info: String,
    pub mesa_version: Option<String>,
    pub kernels: Vec<CompiledKernel>,
}

/// One kernel a target's worker compiled, or refused.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompiledKernel {
    pub name: String,
    /// The subgroup size the driver compiled it at (its executable's).
    pub subgroup_size: u32,
    pub statistics: Vec<crate::gpu::executable::CompilerStatistic>,
    /// Why it was not compiled (a feature the device lacks); then no statistics.
    pub refused: Option<String>,
}

/// The cell a [`Request::MakeRepro`] makes a repro of (what `trilab repro` is given), and where.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReproSpec {
    pub scene: PathBuf,
    pub rays: PathBuf,
    pub method: Method,
    pub layout: Layout,
    pub traversal: Traversal,
    pub access: SceneAccess,
    pub build: crate::bvh::BuildOptions,
    pub out: PathBuf,
}

impl Request {
    /// The line that asks a worker speaking `protocol` for this; `None` when it has no such
    /// request (a worker older than [`PROTOCOL_TYPED`] reads only `round`, `cell N` and `quit`).
    pub fn line(&self, protocol: u32) -> Option<String> {
        if protocol >= PROTOCOL_TYPED {
            return Some(serde_json::to_string(self).expect("requests serialise"));
        }
        match self {
            Request::Round => Some("round".into()),
            Request::Cell { index } => Some(format!("cell {index}")),
            Request::Quit => Some("quit".into()),
            _ => None,
        }
    }

    /// Reads a line a parent wrote: a JSON request, or the words of protocols 1 and 2 (`round`,
    /// `cell N`, `quit`; an empty line is `quit`). The error names the line.
    pub fn parse(line: &str) -> std::result::Result<Request, String> {
        let line = line.trim();
        if line.starts_with('{') {
            return serde_json::from_str(line).map_err(|e| format!("`{line}` is not a request ({e})"));
        }
        match line {
            "round" => Ok(Request::Round),
            "quit" | "" => Ok(Request::Quit),
            _ => match line.strip_prefix("cell ").map(|i| i.trim().parse::<usize>()) {
                Some(Ok(index)) => Ok(Request::Cell { index }),
                _ => Err(format!("unknown command `{line}`")),
            },
        }
    }
}

/// A bench of one scene's ray files, each method on one layout, for one `LP_NUM_THREADS`
/// value: what `trilab bench --scenes S --rays-dir D --methods M --leaf-size N --layouts L
/// --repeat R` measures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchThreads {
    /// The `LP_NUM_THREADS` the parent set in the worker's environment: the worker checks that
    /// the driver it loaded read it.
    pub threads: usize,
    pub scene: PathBuf,
    /// Holds `<scene stem>.{primary,diffuse,random}.rays`.
    pub rays_dir: PathBuf,
    pub methods: Vec<Method>,
    pub leaf_size: u32,
    pub layout: Layout,
    pub repeat: usize,
}

/// One (threads, method, ray set) measurement of a [`BenchThreads`] request.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThreadMeasurement {
    pub threads: usize,
    pub method: String,
    pub ray_set: String,
    pub rays: usize,
    pub kernel_ms: Summary,
    pub mrays_per_s: f64,
    pub agreement: f64,
}

/// Which kernel variants' driver statistics an `ab` side gives: `trilab driver-stats
/// --kernels --variants --methods --layouts`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DriverStatsRequest {
    pub kernels: Vec<String>,
    pub variants: Vec<String>,
    pub methods: Vec<Method>,
    pub layouts: Vec<Layout>,
}

/// What an `ab` cell runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CellKind {
    /// The closest-hit ray-casting kernel over a ray set.
    Raycast,
    /// The path tracer's kernel rendering the scene's image.
    Pathtrace,
}

/// One `ab` cell, as the worker names it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CellInfo {
    pub kind: CellKind,
    pub scene: String,
    /// The ray set; `pathtrace` for a path-trace cell.
    pub set: String,
    pub method: String,
    pub layout: String,
    /// The traversal (`while-if` for a path-trace cell, and from a version 1 worker).
    #[serde(default = "while_if")]
    pub traversal: String,
    /// Rays cast; a path-trace cell's samples (pixels x samples per pixel).
    pub rays: usize,
    /// The kernel that ran (`raycast.mt.closest`), for the driver statistics.
    pub kernel: String,
    /// Its cell in each side's rows, made by the worker where the values are typed: bench's,
    /// or for a path-trace cell bench-render's.
    pub coordinates: crate::rows::Cell,
}

/// `while-if`, the traversal of every cell of a version 1 worker.
pub fn while_if() -> String {
    Traversal::WhileIf.to_string()
}

impl CellInfo {
    /// `bunny primary mt bvh2` (and the traversal when it is not while-if).
    pub fn label(&self) -> String {
        let mut s = format!("{} {} {} {}", self.scene, self.set, self.method, self.layout);
        if self.traversal != while_if() {
            s = format!("{s} {}", self.traversal);
        }
        s
    }

    /// What names a cell on both sides, whichever build each side runs: its kind, scene, set,
    /// method, layout and traversal (not its kernel's name, nor its rows' coordinates, which a
    /// build may spell differently).
    pub fn key(&self) -> CellKey {
        CellKey {
            kind: self.kind,
            scene: self.scene.clone(),
            set: self.set.clone(),
            method: self.method.clone(),
            layout: self.layout.clone(),
            traversal: self.traversal.clone(),
        }
    }

    /// The kernel a cell times, as `ab` groups cells: its kind, method, layout and traversal
    /// (`raycast mt bvh2`, `pathtrace mt bvh2`).
    pub fn kernel_label(&self) -> String {
        let kind = match self.kind {
            CellKind::Raycast => "raycast",
            CellKind::Pathtrace => "pathtrace",
        };
        let mut s = format!("{kind} {} {}", self.method, self.layout);
        if self.traversal != while_if() {
            s = format!("{s} {}", self.traversal);
        }
        s
    }
}

/// A cell's identity across builds ([`CellInfo::key`]).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct CellKey {
    pub kind: CellKind,
    pub scene: String,
    pub set: String,
    pub method: String,
    pub layout: String,
    pub traversal: String,
}

/// A round's result for one cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CellRound {
    /// Kernel time, ms; `None` when the round did not validate (then it does not count).
    pub ms: Option<f64>,
    pub agree: usize,
    pub unexplained: usize,
    pub invalid: usize,
}

/// What a worker prints, one JSON object a line.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "message", rename_all = "kebab-case")]
pub enum Message {
    /// An `ab` side is loaded. `provenance` is the worker's `Provenance` as its build wrote it
    /// (carried into `ab.json` as it is; [`ProvenanceFields`] reads it).
    Ready {
        /// [`PROTOCOL`]; absent (1) from the first version.
        #[serde(default = "first_protocol")]
        protocol: u32,
        provenance: serde_json::Value,
        cells: Vec<CellInfo>,
        pipeline_ms: f64,
        /// Per cell, its compute-shader invocations when asked for and measured.
        invocations: Vec<Option<u64>>,
        /// Why there are no invocations counts, when they were asked for and are none.
        invocations_note: Option<String>,
    },
    /// An `ab` round: every cell's, or one cell's.
    Round { cells: Vec<CellRound> },
    /// A [`BenchThreads`] request's measurements.
    Measured { measurements: Vec<ThreadMeasurement> },
    /// A [`Request::DispatchKernels`] request ran its kernels (their machine code is on stderr).
    Dispatched { kernels: usize },
    /// A [`DriverStatsRequest`]'s statistics: whether the driver has them, how they were
    /// obtained or why there are none, and the `driver-stats` rows.
    DriverStats { status: Status, note: String, rows: Vec<Row> },
    /// A [`Request::ReproDispatch`] ran: `rays` hits were written.
    ReproDispatched { rays: usize },
    /// A [`Request::MakeRepro`]'s repro was made: its one-line summary.
    ReproMade { summary: String },
    /// A [`Request::CompileKernels`]'s kernels.
    Compiled(CompiledKernels),
    /// The request failed; the worker ends.
    Failed { error: String },
}

fn first_protocol() -> u32 {
    1
}

impl Message {
    /// Its kind, for an error that expected another.
    pub fn kind(&self) -> &'static str {
        match self {
            Message::Ready { .. } => "ready",
            Message::Round { .. } => "round",
            Message::Measured { .. } => "measured",
            Message::Dispatched { .. } => "dispatched",
            Message::DriverStats { .. } => "driver-stats",
            Message::ReproDispatched { .. } => "repro-dispatched",
            Message::ReproMade { .. } => "repro-made",
            Message::Compiled(_) => "compiled",
            Message::Failed { .. } => "failed",
        }
    }
}

/// The fields of a worker's provenance that `ab` reads (its driver, device, commit, date,
/// settings and host), from the provenance its build wrote; a field that build did not write
/// is empty.
#[derive(Clone, Debug, Default)]
pub struct ProvenanceFields {
    pub device: Option<String>,
    pub driver: Option<String>,
    pub commit: Option<String>,
    pub date: Option<String>,
    pub settings: std::collections::BTreeMap<String, String>,
    pub host: Option<crate::host::Host>,
}

impl ProvenanceFields {
    /// Reads `provenance`; what does not read as these fields is left empty (it is another
    /// build's, and only shown).
    pub fn of(provenance: &serde_json::Value) -> ProvenanceFields {
        let field = |k: &str| provenance.get(k).cloned().unwrap_or_default();
        ProvenanceFields {
            device: serde_json::from_value(field("device")).ok().flatten(),
            driver: serde_json::from_value(field("driver")).ok().flatten(),
            commit: serde_json::from_value(field("commit")).ok().flatten(),
            date: serde_json::from_value(field("date")).ok().flatten(),
            settings: serde_json::from_value(field("settings")).unwrap_or_default(),
            host: serde_json::from_value(field("host")).ok().flatten(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_read_back_as_json_and_as_the_words_of_older_protocols() {
        let bench = Request::BenchThreads(BenchThreads {
            threads: 3,
            scene: "scenes/bunny.obj".into(),
            rays_dir: "/tmp/rays".into(),
            methods: vec![Method::Mt, Method::QuadUnit],
            leaf_size: 4,
            layout: Layout::Bvh4,
            repeat: 2,
        });
        for r in [Request::Round, Request::Cell { index: 7 }, Request::Quit, bench.clone()] {
            let line = r.line(PROTOCOL).unwrap();
            assert!(line.starts_with('{') && !line.contains('\n'), "{line}");
            assert_eq!(Request::parse(&line).unwrap(), r, "{line}");
        }
        let line = bench.line(PROTOCOL).unwrap();
        assert!(line.contains(r#""methods":["mt","quad-unit"]"#) && line.contains(r#""layout":"bvh4""#), "{line}");
        // A worker of protocol 2 reads words, and has no typed requests.
        assert_eq!(Request::Cell { index: 7 }.line(2).as_deref(), Some("cell 7"));
        assert_eq!(Request::Round.line(1).as_deref(), Some("round"));
        assert_eq!(bench.line(2), None);
        for (words, r) in [
            ("round", Request::Round),
            ("cell 12", Request::Cell { index: 12 }),
            ("quit", Request::Quit),
            ("", Request::Quit),
        ] {
            assert_eq!(Request::parse(words).unwrap(), r);
        }
        assert!(Request::parse("cell x").unwrap_err().contains("unknown command `cell x`"));
        assert!(Request::parse(r#"{"request":"nope"}"#).unwrap_err().contains("is not a request"));
        let bad = line.replace("quad-unit", "quad-nope");
        assert!(Request::parse(&bad).unwrap_err().contains("quad-nope"), "{bad}");
    }

    #[test]
    fn a_version_1_ready_and_another_builds_provenance_read() {
        let ready = r#"{"message":"ready","provenance":{"device":"llvmpipe","driver":"Mesa 25.0.7","settings":{"subgroup_size":"8"},"new_field":1},
            "cells":[],"pipeline_ms":1.5,"invocations":[],"invocations_note":null}"#;
        let Message::Ready { protocol, provenance, .. } = serde_json::from_str(ready).unwrap() else { panic!() };
        assert_eq!(protocol, 1);
        let p = ProvenanceFields::of(&provenance);
        assert_eq!((p.device.as_deref(), p.driver.as_deref(), p.commit), (Some("llvmpipe"), Some("Mesa 25.0.7"), None));
        assert_eq!(p.settings.get("subgroup_size").map(String::as_str), Some("8"));
        // A field of another shape is left empty, not an error.
        let p = ProvenanceFields::of(&serde_json::json!({"device": 3, "settings": "x"}));
        assert!(p.device.is_none() && p.settings.is_empty());
    }
}
