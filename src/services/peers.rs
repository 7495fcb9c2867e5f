//! Peer programs on trilab's own ray files: Embree 3 (`embree_rays`, scripts/embree-peer.sh; its
//! single-ray call and its 8- and 16-wide packet calls) and tinybvh (`tinybvh_rays`,
//! scripts/tinybvh-peer.sh; its CPU layouts and its OpenCL kernels).
//! Each is run as a separate process on the scene (written as a plain OBJ, so its triangle ids
//! are ours) and the ray file a bench row traced, prints one `key=value` line, and writes a hit
//! file (docs/formats.md). Bench starts it once in every one of its interleaved rounds, beside
//! trilab's kernels ([`PeerRound`]), each time tracing the set once. Its hits are checked against
//! the f64 reference with the rule every trilab row passes ([`validate_hits`]) in every round
//! before its speed counts: a peer that returns wrong hits is reported as failing, never timed.
//!
//! Failures: a missing or non-executable program is an error before any work; so is a peer that
//! exits non-zero, prints no readable result line, or traces another number of rays. The one
//! exception is an OpenCL layout (`ocl-*`) whose program says it has no OpenCL (not compiled in,
//! no platform or device, a kernel that does not build): that layout is skipped, with the reason
//! as a note, and the others still run. An Embree packet width the library does not run natively
//! is an error (the program refuses it), never skipped: it was asked for. [`probe`] finds all of
//! this on a small scene first.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::named::{named_enum, Named};
use crate::rays::{self, Ray};
use crate::reference::RefHit;
use crate::report::Summary;
use crate::scene::Mesh;
use crate::services::validate::{validate_hits, RoundJob};

named_enum! {
    /// A tinybvh layout and traversal, as `tinybvh_rays trace LAYOUT` names it.
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum TinybvhLayout: "tinybvh layout" {
        /// BVH::Intersect, tinybvh's 2-wide reference layout (CPU threads).
        CpuBvh = "cpu-bvh",
        /// BVH4_CPU::Intersect, 4-wide SSE (CPU threads).
        CpuBvh4 = "cpu-bvh4",
        /// BVH8_CPU::Intersect, 8-wide AVX2, tinybvh's fastest CPU traversal (CPU threads).
        CpuBvh8 = "cpu-bvh8",
        /// OpenCL kernel batch_ailalaine (Aila & Laine 2009) on the first OpenCL device.
        OclBvh2 = "ocl-bvh2",
        /// OpenCL kernel batch_cwbvh (Ylitie et al. 2017) on the first OpenCL device.
        OclCwbvh = "ocl-cwbvh",
    }
}

impl TinybvhLayout {
    /// `bench --tinybvh`'s layouts when none are named: the fastest CPU one and both OpenCL ones.
    pub const DEFAULT: [TinybvhLayout; 3] = [TinybvhLayout::CpuBvh8, TinybvhLayout::OclBvh2, TinybvhLayout::OclCwbvh];

    /// Runs on an OpenCL device (may be skipped where there is none).
    pub fn is_opencl(self) -> bool {
        matches!(self, TinybvhLayout::OclBvh2 | TinybvhLayout::OclCwbvh)
    }
}

named_enum! {
    /// An Embree 3 call that traces the rays; `embree_rays` runs each as a mode of its own
    /// ([`EmbreeApi::mode`]).
    #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum EmbreeApi: "Embree API" {
        /// rtcIntersect1: one ray per call (`embree_rays trace`), over threads.
        Ray1 = "ray1",
        /// rtcIntersect8: packets of 8 consecutive rays of the file (`embree_rays trace8`), over
        /// threads; needs a library and CPU with native 8-wide packets.
        Packet8 = "packet8",
        /// rtcIntersect16: packets of 16 consecutive rays of the file (`embree_rays trace16`), over
        /// threads; needs native 16-wide packets (AVX-512).
        Packet16 = "packet16",
    }
}

impl EmbreeApi {
    /// `bench --embree`'s calls when none are named: the single-ray call and 8-wide packets
    /// (issue 53's targets are against those two; 16-wide only when asked for).
    pub const DEFAULT: [EmbreeApi; 2] = [EmbreeApi::Ray1, EmbreeApi::Packet8];

    /// The `embree_rays` mode that traces with it.
    pub fn mode(self) -> &'static str {
        match self {
            EmbreeApi::Ray1 => "trace",
            EmbreeApi::Packet8 => "trace8",
            EmbreeApi::Packet16 => "trace16",
        }
    }

    /// Rays per call.
    pub fn width(self) -> usize {
        match self {
            EmbreeApi::Ray1 => 1,
            EmbreeApi::Packet8 => 8,
            EmbreeApi::Packet16 => 16,
        }
    }
}

/// Which peer: one of Embree's calls, or one tinybvh layout.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PeerKind {
    Embree(EmbreeApi),
    Tinybvh(TinybvhLayout),
}

/// `embree3` (rtcIntersect1: the name it always had, so older results and plans still match),
/// `embree3 packet8`, `embree3 packet16`, `tinybvh cpu-bvh8`.
impl std::fmt::Display for PeerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PeerKind::Embree(EmbreeApi::Ray1) => f.write_str("embree3"),
            PeerKind::Embree(api) => write!(f, "embree3 {api}"),
            PeerKind::Tinybvh(l) => write!(f, "tinybvh {l}"),
        }
    }
}

/// Serialises as its name (`embree3`, `embree3 packet8`, `tinybvh cpu-bvh8`).
impl Serialize for PeerKind {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// A peer program and the layout it is asked for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PeerProgram {
    pub kind: PeerKind,
    pub program: PathBuf,
}

/// Most wall time one peer process may take before it is killed (an error, never a hang).
const PEER_TIMEOUT: Duration = Duration::from_secs(900);

/// Rays of the [`probe`].
const PROBE_RAYS: usize = 256;

impl PeerProgram {
    /// What errors call it: `tinybvh peer /x/tinybvh_rays (layout ocl-bvh2)`, `Embree peer
    /// /x/embree_rays (api packet8, rtcIntersect8)`; rtcIntersect1's is `Embree peer /x/embree_rays`.
    pub fn describe(&self) -> String {
        match self.kind {
            PeerKind::Embree(EmbreeApi::Ray1) => format!("Embree peer {}", self.program.display()),
            PeerKind::Embree(api) => {
                format!("Embree peer {} (api {api}, rtcIntersect{})", self.program.display(), api.width())
            }
            PeerKind::Tinybvh(l) => format!("tinybvh peer {} (layout {l})", self.program.display()),
        }
    }

    /// `PROGRAM trace [LAYOUT] SCENE RAYS HITS 1` (Embree's packets: `trace8`, `trace16`): one
    /// traced run per process (its `REPEAT` argument), so each of bench's rounds starts it once.
    fn command(&self, scene: &Path, rays: &Path, hits: &Path) -> Command {
        let mut c = Command::new(&self.program);
        match self.kind {
            PeerKind::Embree(api) => c.arg(api.mode()),
            PeerKind::Tinybvh(l) => c.arg("trace").arg(l.name()),
        };
        c.arg(scene).arg(rays).arg(hits).arg("1");
        c
    }

    /// Runs the peer on a ray file; its result line and the hits it wrote, or
    /// `Ok(Err(reason))` where an OpenCL layout has no OpenCL.
    fn trace(&self, scene: &Path, rays_file: &Path, hits_file: &Path, rays: usize) -> Result<Traced> {
        let out = run_with_timeout(self.command(scene, rays_file, hits_file), PEER_TIMEOUT)
            .map_err(|e| Error::Usage(format!("{}: cannot run it: {e}", self.describe())))?;
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        if !out.status.success() {
            if let PeerKind::Tinybvh(l) = self.kind {
                if let Some(reason) = l.is_opencl().then(|| no_opencl(&stderr)).flatten() {
                    return Ok(Traced::NoOpenCl(reason));
                }
            }
            // A packet width the library does not run: say which option asked for it.
            let hint = match self.kind {
                PeerKind::Embree(api) if api != EmbreeApi::Ray1 && stderr.contains("not supported") => {
                    format!(" (leave {api} out of --embree-apis)")
                }
                _ => String::new(),
            };
            return Err(Error::Usage(format!(
                "{} failed ({}): {}{hint}",
                self.describe(),
                out.status,
                tail(&format!("{stdout}{stderr}"))
            )));
        }
        let line = parse_line(&stdout).map_err(|e| Error::Usage(format!("{}: {e}", self.describe())))?;
        if let Some(n) = line.rays.filter(|&n| n != rays) {
            return Err(Error::Usage(format!("{}: traced {n} rays, the ray file holds {rays}", self.describe())));
        }
        if let (PeerKind::Tinybvh(l), Some(said)) = (self.kind, &line.layout) {
            if said != l.name() {
                return Err(Error::Usage(format!("{}: its line names layout `{said}`", self.describe())));
            }
        }
        // A packet mode's line names its call (`embree3 packet8 ...`): a program that ignored the
        // mode and traced one ray at a time must not be timed as packets.
        if let PeerKind::Embree(api) = self.kind {
            if api != EmbreeApi::Ray1 && !line.words.iter().any(|w| w == api.name()) {
                return Err(Error::Usage(format!(
                    "{}: its result line does not name `{api}` (an embree_rays without packet modes? \
                     rebuild it with scripts/embree-peer.sh): `{}`",
                    self.describe(),
                    line.words.join(" ")
                )));
            }
        }
        let hits =
            rays::read_hits(hits_file).map_err(|e| Error::Usage(format!("{}: its hit file: {e}", self.describe())))?;
        Ok(Traced::Done(line, hits))
    }
}

enum Traced {
    Done(PeerLine, Vec<rays::Hit>),
    NoOpenCl(String),
}

/// The reason an OpenCL layout could not run, when its stderr says so.
fn no_opencl(stderr: &str) -> Option<String> {
    let l = stderr.to_ascii_lowercase();
    (l.contains("opencl") || l.contains("not compiled in")).then(|| tail(stderr))
}

/// The last non-empty line of a program's output (or `(no output)`), for messages.
fn tail(text: &str) -> String {
    text.lines().rev().map(str::trim).find(|l| !l.is_empty()).unwrap_or("(no output)").to_owned()
}

/// What a peer's result line says (`key=value` words, and the other words in `words`). Embree:
/// `embree3 default threads=2 tris=.. rays=.. hits=.. build_ms=.. best_s=.. mrays_per_s=..`
/// (rtcIntersect1), `embree3 packet8 threads=2 ...` (rtcIntersect8; `packet16`: rtcIntersect16);
/// tinybvh: `layout=cpu-bvh8 scene=.. rays=.. build_ms=.. trace_ms=.. mrays_per_s=.. threads=..
/// hits=.. median_ms=.. repeats=.. builder=..`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PeerLine {
    /// Rays per second at the best of its repeats, millions (both peers' own figure).
    pub mrays_per_s: f64,
    pub rays: Option<usize>,
    pub layout: Option<String>,
    /// Median trace time over its repeats (tinybvh), ms.
    pub median_ms: Option<f64>,
    pub build_ms: Option<f64>,
    pub threads: Option<u32>,
    /// Its words without `=`, in order (`["embree3", "packet8"]`).
    pub words: Vec<String>,
}

/// Reads the one line of a peer's stdout that carries `mrays_per_s=`. An error (naming the
/// problem and quoting the output) when there is none or several, a key appears twice, or a
/// known key's value is not a number of its kind (`mrays_per_s` finite and positive).
pub fn parse_line(stdout: &str) -> std::result::Result<PeerLine, String> {
    let quoted = || {
        let t = stdout.trim();
        if t.is_empty() {
            "(no output)".to_owned()
        } else {
            format!("`{}`", t.chars().take(300).collect::<String>())
        }
    };
    let lines: Vec<&str> =
        stdout.lines().filter(|l| l.split_whitespace().any(|w| w.starts_with("mrays_per_s="))).collect();
    let line = match lines[..] {
        [l] => l,
        [] => return Err(format!("no result line (`... mrays_per_s=X ...`) in its output: {}", quoted())),
        _ => return Err(format!("{} result lines in its output, expected one: {}", lines.len(), quoted())),
    };
    let mut seen = std::collections::BTreeMap::new();
    for w in line.split_whitespace() {
        if let Some((k, v)) = w.split_once('=') {
            if seen.insert(k, v).is_some() {
                return Err(format!("`{k}=` appears twice in its result line `{line}`"));
            }
        }
    }
    fn num<T: std::str::FromStr>(
        seen: &std::collections::BTreeMap<&str, &str>,
        k: &str,
        line: &str,
    ) -> std::result::Result<Option<T>, String> {
        seen.get(k)
            .map(|v| v.parse::<T>().map_err(|_| format!("`{k}={v}` is not a number in its result line `{line}`")))
            .transpose()
    }
    let mrays_per_s: f64 = num(&seen, "mrays_per_s", line)?.expect("the line has mrays_per_s=");
    if !(mrays_per_s.is_finite() && mrays_per_s > 0.0) {
        return Err(format!("`mrays_per_s={mrays_per_s}` is not a positive rate in its result line `{line}`"));
    }
    let non_negative = |k: &str| -> std::result::Result<Option<f64>, String> {
        match num::<f64>(&seen, k, line)? {
            Some(x) if !(x.is_finite() && x >= 0.0) => {
                Err(format!("`{k}={x}` is not a duration in its result line `{line}`"))
            }
            x => Ok(x),
        }
    };
    Ok(PeerLine {
        mrays_per_s,
        rays: num(&seen, "rays", line)?,
        layout: seen.get("layout").map(|s| s.to_string()),
        median_ms: non_negative("median_ms")?,
        build_ms: non_negative("build_ms")?,
        threads: num(&seen, "threads", line)?,
        words: line.split_whitespace().filter(|w| !w.contains('=')).map(str::to_owned).collect(),
    })
}

/// How one peer did on one ray set.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "status", rename_all = "kebab-case")]
pub enum PeerOutcome {
    /// Its hits passed the f64 check in every round; its own clock, one trace per round.
    Timed {
        /// At its median round: the figure set beside trilab's medians.
        mrays_per_s: f64,
        /// At its slowest and fastest rounds (the fastest is its best).
        mrays_per_s_min: f64,
        mrays_per_s_max: f64,
        /// Its trace time per round, ms (median, min, max, rounds).
        trace_ms: Summary,
        /// Its own BVH build per run, ms (median over the rounds; not part of the trace time).
        build_ms: Option<f64>,
        threads: Option<u32>,
        /// Fraction of rays agreeing with the f64 reference (the last round's).
        agreement: f64,
    },
    /// Its hits failed the f64 check (or the hit file had the wrong size): no speed.
    WrongHits { agreement: Option<f64>, reason: String },
    /// Not run (an OpenCL layout without OpenCL): why.
    Skipped { reason: String },
}

/// One peer's result on one ray set.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PeerResult {
    pub peer: PeerKind,
    #[serde(flatten)]
    pub outcome: PeerOutcome,
}

impl PeerResult {
    /// `<peer>: 3.25 Mrays/s (median of 5 rounds, 3.10..3.40); best trilab / it = 0.52`, or why it
    /// has no speed.
    pub fn progress(&self, best_trilab: f64) -> String {
        match &self.outcome {
            PeerOutcome::Timed { mrays_per_s: m, mrays_per_s_min: lo, mrays_per_s_max: hi, trace_ms, .. } => format!(
                "{}: {m:.2} Mrays/s (median of {} rounds, {lo:.2}..{hi:.2}); best trilab / it = {:.2}",
                self.peer,
                trace_ms.runs,
                best_trilab / m
            ),
            PeerOutcome::Skipped { reason } => format!("{}: skipped: {reason}", self.peer),
            PeerOutcome::WrongHits { reason, .. } => format!("{}: failed validation, not timed: {reason}", self.peer),
        }
    }

    /// Its validated Mrays/s (median round), if it was timed.
    pub fn mrays_per_s(&self) -> Option<f64> {
        match self.outcome {
            PeerOutcome::Timed { mrays_per_s, .. } => Some(mrays_per_s),
            _ => None,
        }
    }
}

/// The peers a bench runs: the Embree program once per call in `apis` (empty:
/// [`EmbreeApi::DEFAULT`]), then the tinybvh program once per layout in `layouts` (empty:
/// [`TinybvhLayout::DEFAULT`]); each in the order given, a value named twice once.
pub fn programs(
    embree: Option<&Path>,
    apis: &[EmbreeApi],
    tinybvh: Option<&Path>,
    layouts: &[TinybvhLayout],
) -> Vec<PeerProgram> {
    fn each<T: Copy + PartialEq>(
        given: &[T],
        default: &[T],
        kind: impl Fn(T) -> PeerKind,
        p: &Path,
    ) -> Vec<PeerProgram> {
        let given = if given.is_empty() { default } else { given };
        let mut seen = vec![];
        for &x in given {
            if !seen.contains(&x) {
                seen.push(x);
            }
        }
        seen.into_iter().map(|x| PeerProgram { kind: kind(x), program: p.to_owned() }).collect()
    }
    let mut v = vec![];
    if let Some(p) = embree {
        v.extend(each(apis, &EmbreeApi::DEFAULT, PeerKind::Embree, p));
    }
    if let Some(p) = tinybvh {
        v.extend(each(layouts, &TinybvhLayout::DEFAULT, PeerKind::Tinybvh, p));
    }
    v
}

/// A peer program must be an executable file: checked before any work.
pub fn check_program(option: &str, path: &Path) -> Result<()> {
    let bad = |why: &str| Err(Error::Usage(format!("{option} {}: {why}", path.display())));
    let hint = match option {
        "--tinybvh" => "build it with scripts/tinybvh-peer.sh",
        _ => "build it with scripts/embree-peer.sh",
    };
    match std::fs::metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bad(&format!("no such file ({hint})")),
        Err(e) => bad(&e.to_string()),
        Ok(m) if !m.is_file() => bad("is not a file (the peer program is)"),
        Ok(m) => {
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                if m.permissions().mode() & 0o111 == 0 {
                    return bad("is not executable");
                }
            }
            let _ = m;
            Ok(())
        }
    }
}

/// Runs every peer once on a small synthetic scene before the long work: a program that does
/// not run, prints no readable line or writes a hit file of the wrong size is an error now, not
/// after the first scene. Returns the peers that can run; an OpenCL layout without OpenCL is
/// left out, with a note saying why.
pub fn probe(peers: &[PeerProgram], dir: &Path, notes: &mut Vec<String>) -> Result<Vec<PeerProgram>> {
    if peers.is_empty() {
        return Ok(vec![]);
    }
    let mesh = crate::scene::synthetic::load(Path::new("synth:terrain:2k"))?;
    let scene = dir.join("probe.obj");
    write_obj(&mesh, &scene)?;
    let rays = rays::random_rays(&mesh.bounds(), PROBE_RAYS, 7);
    let rays_file = dir.join("probe.rays");
    rays::write_rays(&rays_file, &rays)?;
    let mut ok = vec![];
    for p in peers {
        let hits_file = dir.join("probe.hits");
        let _ = std::fs::remove_file(&hits_file);
        match p.trace(&scene, &rays_file, &hits_file, rays.len())? {
            Traced::NoOpenCl(reason) => notes.push(format!("{}: skipped, no OpenCL: {reason}", p.kind)),
            Traced::Done(_, hits) if hits.len() != rays.len() => {
                return Err(Error::Usage(format!(
                    "{}: wrote {} hits for {} rays on a test scene",
                    p.describe(),
                    hits.len(),
                    rays.len()
                )))
            }
            Traced::Done(..) => ok.push(p.clone()),
        }
    }
    Ok(ok)
}

/// One peer program on one ray set as a job of bench's interleaved rounds
/// ([`crate::services::validate::interleaved_with`]): every run starts the program once to trace
/// the set once (its `REPEAT` 1, so its figure is that one trace, its BVH build not counted) and
/// checks its hits against the f64 reference before the round's time counts. The figures are the
/// rounds' median with the slowest and fastest (its best), as trilab's rows have them.
///
/// A program that cannot run, prints no readable line or traces another number of rays is an
/// error ([`RoundJob::run_once`]); wrong hits, or an OpenCL layout that finds no OpenCL, are its
/// outcome instead: the program is not run again, and [`PeerRound::finish`] reports why.
pub struct PeerRound<'a> {
    peer: &'a PeerProgram,
    set: &'a PeerSet<'a>,
    hits_file: PathBuf,
    /// Trace time per timed round, ms.
    ms: Vec<f64>,
    build_ms: Vec<f64>,
    threads: Option<u32>,
    agreement: Option<f64>,
    /// Why it stopped: wrong hits, or no OpenCL.
    stopped: Option<PeerOutcome>,
}

/// What every peer of one ray set reads and is checked against: the scene as [`write_obj`]
/// wrote it, the rays as written to `rays_file`, and their f64 reference hits.
pub struct PeerSet<'a> {
    pub scene_obj: &'a Path,
    pub rays_file: &'a Path,
    pub mesh: &'a Mesh,
    pub rays: &'a [Ray],
    pub ref_hits: &'a [RefHit],
}

impl<'a> PeerRound<'a> {
    /// `peer` on `set`; its hits go to `hits_file`.
    pub fn new(peer: &'a PeerProgram, set: &'a PeerSet<'a>, hits_file: PathBuf) -> PeerRound<'a> {
        PeerRound { peer, set, hits_file, ms: vec![], build_ms: vec![], threads: None, agreement: None, stopped: None }
    }

    /// How it did over the rounds.
    pub fn finish(self) -> PeerResult {
        let median = |v: &[f64]| Summary::of(v).map(|s| s.median);
        let outcome = match (self.stopped, Summary::of(&self.ms), self.agreement) {
            (Some(why), ..) => why,
            (None, Some(trace_ms), Some(agreement)) => {
                let mr = crate::services::validate::mrays_summary(self.set.rays.len(), trace_ms);
                PeerOutcome::Timed {
                    mrays_per_s: mr.median,
                    mrays_per_s_min: mr.min,
                    mrays_per_s_max: mr.max,
                    trace_ms,
                    build_ms: median(&self.build_ms),
                    threads: self.threads,
                    agreement,
                }
            }
            (None, ..) => PeerOutcome::Skipped { reason: "no timed round".into() },
        };
        PeerResult { peer: self.peer.kind, outcome }
    }
}

impl RoundJob for PeerRound<'_> {
    fn run_once(&mut self, timed: bool) -> Result<()> {
        if self.stopped.is_some() {
            return Ok(());
        }
        let _span =
            crate::timeline::span_with("peer", || format!("peer {}", self.peer.kind)).with("rays", self.set.rays.len());
        let _ = std::fs::remove_file(&self.hits_file);
        let set = self.set;
        let (rays, n) = (set.rays, set.rays.len());
        let (line, hits) = match self.peer.trace(set.scene_obj, set.rays_file, &self.hits_file, n)? {
            Traced::NoOpenCl(reason) => {
                self.stopped = Some(PeerOutcome::Skipped { reason: format!("no OpenCL: {reason}") });
                return Ok(());
            }
            Traced::Done(line, hits) => (line, hits),
        };
        if hits.len() != n {
            let reason = format!("its hit file holds {} hits for {n} rays", hits.len());
            self.stopped = Some(PeerOutcome::WrongHits { agreement: None, reason });
            return Ok(());
        }
        match validate_hits(set.mesh, rays, &hits, set.ref_hits) {
            Ok(a) if timed => {
                // The trace's own time where the program prints it (tinybvh's `median_ms`, of
                // its one run: 1 us steps), else from its rate (2 decimals: 1 % at 1 Mrays/s).
                self.ms.push(line.median_ms.filter(|&m| m > 0.0).unwrap_or(n as f64 / (line.mrays_per_s * 1e3)));
                self.build_ms.extend(line.build_ms);
                self.threads = line.threads;
                self.agreement = Some(a.fraction());
            }
            Ok(_) => {}
            Err(e) => {
                let a = crate::agreement::compare_closest(set.mesh, rays, &hits, set.ref_hits);
                self.stopped = Some(PeerOutcome::WrongHits { agreement: Some(a.fraction()), reason: e.to_string() });
            }
        }
        Ok(())
    }
}

/// Writes `mesh` as a plain OBJ (`v x y z`, then one `f a b c` per triangle in id order), so a
/// peer reads exactly our triangles with our ids, whatever the scene was (a bundled name, a
/// `synth:` spec, `.obj.gz`). f32 values print in their shortest exact form.
pub fn write_obj(mesh: &Mesh, path: &Path) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let mut go = || -> std::io::Result<()> {
        for p in &mesh.positions {
            writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
        }
        for t in &mesh.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        w.flush()
    };
    go().map_err(|e| Error::io(path, e))
}

/// Runs `cmd` with stdin closed and both pipes drained, killing it past `limit`.
fn run_with_timeout(mut cmd: Command, limit: Duration) -> std::io::Result<std::process::Output> {
    cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut running = crate::children::spawn(&mut cmd)?;
    let child = running.child();
    let drain = |mut pipe: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            let _ = pipe.read_to_end(&mut buf);
            buf
        })
    };
    let stdout = drain(Box::new(child.stdout.take().expect("piped stdout")));
    let stderr = drain(Box::new(child.stderr.take().expect("piped stderr")));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait()? {
            break status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(std::io::Error::new(
                std::io::ErrorKind::TimedOut,
                format!("did not finish within {} s; killed", limit.as_secs()),
            ));
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let join = |h: std::thread::JoinHandle<Vec<u8>>| h.join().unwrap_or_default();
    Ok(std::process::Output { status, stdout: join(stdout), stderr: join(stderr) })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TINYBVH: &str = "layout=cpu-bvh8 scene=bunny rays=480000 build_ms=172.8 trace_ms=14.423 \
        mrays_per_s=33.28 threads=2 hits=122306 median_ms=14.585 repeats=5 builder=BuildHQ\n";
    const EMBREE: &str = "embree3 default threads=2 tris=69451 rays=480000 hits=122306 build_ms=85.1 \
        best_s=0.0192 mrays_per_s=25.00\n";

    #[test]
    fn reads_tinybvh_and_embree_lines() {
        let t = parse_line(TINYBVH).unwrap();
        assert_eq!(t.mrays_per_s, 33.28);
        assert_eq!(t.rays, Some(480_000));
        assert_eq!(t.layout.as_deref(), Some("cpu-bvh8"));
        assert_eq!(t.median_ms, Some(14.585));
        assert_eq!(t.build_ms, Some(172.8));
        assert_eq!(t.threads, Some(2));
        let e = parse_line(&format!("some banner\n{EMBREE}\n")).unwrap();
        assert_eq!(
            (e.mrays_per_s, e.rays, e.layout, e.median_ms, e.threads),
            (25.0, Some(480_000), None, None, Some(2))
        );
        assert_eq!(e.words, ["embree3", "default"]);
    }

    #[test]
    fn reads_embrees_packet_lines() {
        let p = parse_line(
            "embree3 packet8 threads=2 tris=69451 rays=480003 hits=122306 build_ms=85.1 best_s=0.0200 \
             mrays_per_s=24.00\n",
        )
        .unwrap();
        assert_eq!((p.mrays_per_s, p.rays, p.threads, p.build_ms), (24.0, Some(480_003), Some(2), Some(85.1)));
        assert_eq!(p.words, ["embree3", "packet8"]);
        let p = parse_line("embree3 packet16 robust threads=16 rays=7 mrays_per_s=1.50\n").unwrap();
        assert_eq!((p.mrays_per_s, p.rays, p.threads), (1.5, Some(7), Some(16)));
        assert_eq!(p.words, ["embree3", "packet16", "robust"]);
    }

    #[test]
    fn embree_apis_name_their_mode_width_and_peer() {
        assert_eq!(EmbreeApi::ALL.iter().map(|a| a.name()).collect::<Vec<_>>(), ["ray1", "packet8", "packet16"]);
        assert_eq!(EmbreeApi::DEFAULT, [EmbreeApi::Ray1, EmbreeApi::Packet8]);
        assert_eq!("PACKET16".parse::<EmbreeApi>(), Ok(EmbreeApi::Packet16));
        assert!("packet4".parse::<EmbreeApi>().unwrap_err().contains("ray1, packet8, packet16"));
        let names: Vec<String> = EmbreeApi::ALL.iter().map(|&a| PeerKind::Embree(a).to_string()).collect();
        assert_eq!(names, ["embree3", "embree3 packet8", "embree3 packet16"], "ray1 keeps the old name");
        let json = serde_json::to_string(&PeerKind::Embree(EmbreeApi::Packet8)).unwrap();
        assert_eq!(json, "\"embree3 packet8\"");
        let p = PeerProgram { kind: PeerKind::Embree(EmbreeApi::Packet16), program: "/x/embree_rays".into() };
        assert_eq!(p.describe(), "Embree peer /x/embree_rays (api packet16, rtcIntersect16)");
        let p = PeerProgram { kind: PeerKind::Embree(EmbreeApi::Ray1), program: "/x/embree_rays".into() };
        assert_eq!(p.describe(), "Embree peer /x/embree_rays");
    }

    /// The arguments a peer is started with, after the program.
    fn args(kind: PeerKind) -> Vec<String> {
        let p = PeerProgram { kind, program: "/x/peer".into() };
        let c = p.command(Path::new("s.obj"), Path::new("r.rays"), Path::new("h.hits"));
        assert_eq!(c.get_program(), "/x/peer");
        c.get_args().map(|a| a.to_string_lossy().into_owned()).collect()
    }

    #[test]
    fn each_api_and_layout_is_started_with_its_mode() {
        let tail = ["s.obj", "r.rays", "h.hits", "1"];
        for (kind, head) in [
            (PeerKind::Embree(EmbreeApi::Ray1), vec!["trace"]),
            (PeerKind::Embree(EmbreeApi::Packet8), vec!["trace8"]),
            (PeerKind::Embree(EmbreeApi::Packet16), vec!["trace16"]),
            (PeerKind::Tinybvh(TinybvhLayout::OclCwbvh), vec!["trace", "ocl-cwbvh"]),
        ] {
            let want: Vec<&str> = head.into_iter().chain(tail).collect();
            assert_eq!(args(kind), want, "{kind}");
        }
    }

    #[test]
    fn programs_run_embree_once_per_api_then_tinybvh() {
        let names = |p: Vec<PeerProgram>| p.iter().map(|p| p.kind.to_string()).collect::<Vec<_>>();
        let (e, t) = (Some(Path::new("e")), Some(Path::new("t")));
        assert_eq!(names(programs(e, &[], None, &[])), ["embree3", "embree3 packet8"], "the default calls");
        let all = [EmbreeApi::Packet16, EmbreeApi::Ray1, EmbreeApi::Packet16, EmbreeApi::Packet8];
        let p = programs(e, &all, t, &[TinybvhLayout::CpuBvh8]);
        assert_eq!(names(p.clone()), ["embree3 packet16", "embree3", "embree3 packet8", "tinybvh cpu-bvh8"]);
        assert!(p[..3].iter().all(|p| p.program == Path::new("e")) && p[3].program == Path::new("t"));
        assert!(programs(None, &all, None, &[]).is_empty(), "no program, no peer");
    }

    /// A fake `embree_rays` (a shell script) traced as `api` on 4 rays: the error, if any.
    #[cfg(unix)]
    fn fake_trace(api: EmbreeApi, body: &str) -> Result<()> {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let prog = dir.path().join("embree_rays");
        std::fs::write(&prog, format!("#!/bin/sh\n{body}")).unwrap();
        std::fs::set_permissions(&prog, std::fs::Permissions::from_mode(0o755)).unwrap();
        let p = PeerProgram { kind: PeerKind::Embree(api), program: prog };
        let hits = dir.path().join("h.hits");
        p.trace(Path::new("s.obj"), Path::new("r.rays"), &hits, 4).map(|_| ())
    }

    #[cfg(unix)]
    #[test]
    fn a_packet_peer_must_name_its_call_and_an_unsupported_width_says_which_option() {
        // Writes 4 misses (t = inf, prim = ~0) and prints `embree3 $WORD`.
        let ok = |word: &str| {
            format!(
                "for i in 1 2 3 4; do printf '\\000\\000\\200\\177\\377\\377\\377\\377\\0\\0\\0\\0\\0\\0\\0\\0'; done > \"$4\"\n\
                 echo \"embree3 {word} threads=1 rays=4 mrays_per_s=1.00\"\n"
            )
        };
        fake_trace(EmbreeApi::Packet8, &ok("packet8")).unwrap();
        fake_trace(EmbreeApi::Ray1, &ok("default")).unwrap();
        let e = fake_trace(EmbreeApi::Packet8, &ok("default")).unwrap_err().to_string();
        assert!(e.contains("(api packet8, rtcIntersect8)") && e.contains("does not name `packet8`"), "{e}");
        let e = fake_trace(EmbreeApi::Packet16, &ok("packet8")).unwrap_err().to_string();
        assert!(e.contains("does not name `packet16`"), "{e}");
        let refuse = "echo 'embree_rays: trace16 (rtcIntersect16, 16-wide packets) is not supported by this Embree \
                      library on this CPU' >&2; exit 3\n";
        let e = fake_trace(EmbreeApi::Packet16, refuse).unwrap_err().to_string();
        for needle in
            ["api packet16", "embree_rays", "exit status: 3", "not supported", "leave packet16 out of --embree-apis"]
        {
            assert!(e.contains(needle), "`{needle}` not in: {e}");
        }
        // An embree_rays without packet modes: its own error, naming the API.
        let e = fake_trace(EmbreeApi::Packet8, "echo \"unknown mode $1\" >&2; exit 2\n").unwrap_err().to_string();
        assert!(e.contains("api packet8") && e.contains("unknown mode trace8") && !e.contains("leave"), "{e}");
    }

    #[test]
    fn refuses_malformed_lines_naming_the_problem() {
        for (out, needle) in [
            ("", "no result line"),
            ("hello world\n", "no result line"),
            ("mrays_per_s= rays=3\n", "`mrays_per_s=` is not a number"),
            ("mrays_per_s=fast\n", "`mrays_per_s=fast` is not a number"),
            ("mrays_per_s=0\n", "not a positive rate"),
            ("mrays_per_s=nan\n", "not a positive rate"),
            ("mrays_per_s=-3\n", "not a positive rate"),
            ("mrays_per_s=3 rays=-1\n", "`rays=-1` is not a number"),
            ("mrays_per_s=3 rays=1.5\n", "`rays=1.5`"),
            ("mrays_per_s=3 median_ms=inf\n", "not a duration"),
            ("mrays_per_s=3 mrays_per_s=4\n", "appears twice"),
            ("mrays_per_s=3\nmrays_per_s=4\n", "2 result lines"),
        ] {
            let e = parse_line(out).unwrap_err();
            assert!(e.contains(needle), "{out:?}: {e}");
        }
    }

    #[test]
    fn layouts_default_and_opencl() {
        assert_eq!(TinybvhLayout::DEFAULT.map(|l| l.to_string()), ["cpu-bvh8", "ocl-bvh2", "ocl-cwbvh"]);
        let ocl: Vec<_> = TinybvhLayout::ALL.iter().filter(|l| l.is_opencl()).map(|l| l.name()).collect();
        assert_eq!(ocl, ["ocl-bvh2", "ocl-cwbvh"]);
        assert_eq!("OCL-CWBVH".parse::<TinybvhLayout>(), Ok(TinybvhLayout::OclCwbvh));
        let p = programs(Some(Path::new("e")), &[EmbreeApi::Ray1], Some(Path::new("t")), &[]);
        let names: Vec<String> = p.iter().map(|p| p.kind.to_string()).collect();
        assert_eq!(names, ["embree3", "tinybvh cpu-bvh8", "tinybvh ocl-bvh2", "tinybvh ocl-cwbvh"]);
        let p = programs(None, &[], Some(Path::new("t")), &[TinybvhLayout::CpuBvh, TinybvhLayout::CpuBvh]);
        assert_eq!(p.len(), 1, "a layout named twice runs once");
    }

    #[test]
    fn opencl_failures_are_recognised_and_others_are_not() {
        assert_eq!(no_opencl("x\nno OpenCL device\n").as_deref(), Some("no OpenCL device"));
        assert!(no_opencl("layout ocl-bvh2 unknown or not compiled in\n").is_some());
        assert!(no_opencl("Segmentation fault\n").is_none());
        assert_eq!(tail("a\n\n  b  \n\n"), "b");
        assert_eq!(tail(""), "(no output)");
    }

    #[test]
    fn program_checks_name_the_option_and_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let e = check_program("--tinybvh", &dir.path().join("nope")).unwrap_err().to_string();
        assert!(e.contains("--tinybvh") && e.contains("no such file") && e.contains("tinybvh-peer.sh"), "{e}");
        let e = check_program("--embree", dir.path()).unwrap_err().to_string();
        assert!(e.contains("not a file"), "{e}");
        let f = dir.path().join("plain");
        std::fs::write(&f, "#!/bin/sh\n").unwrap();
        #[cfg(unix)]
        {
            let e = check_program("--embree", &f).unwrap_err().to_string();
            assert!(e.contains("not executable"), "{e}");
        }
    }

    #[test]
    fn the_obj_keeps_our_triangles_and_ids() {
        let dir = tempfile::tempdir().unwrap();
        let mesh = Mesh::from_triangles(
            vec![[0.1, 0.0, 1e-7], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [3.3333333, 1e20, -0.0]],
            vec![[0, 1, 2], [2, 1, 3], [0, 0, 1]],
        );
        let p = dir.path().join("m.obj");
        write_obj(&mesh, &p).unwrap();
        let back = crate::scene::load_obj(&p).unwrap();
        assert_eq!(back.triangles, mesh.triangles);
        let bits = |m: &Mesh| m.positions.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back), bits(&mesh), "positions round-trip bit for bit");
    }
}
