//! `trilab ab`, and the worker each of its sides runs (`trilab __worker`, hidden, by its older
//! name `__ab-worker`), which also answers the other one-shot requests of the worker service.

use super::OutArgs;
use std::path::PathBuf;

use clap::Args;
use trilab::commands::ab::{self, worker::Workload, AbOptions, Judge, Side};
use trilab::encoding::{Layout, Method, SceneAccess, Traversal};
use trilab::error::{Error, Result};
use trilab::named::Named;
use trilab::services::rayset::{RaySet, RaySetSizes};

use super::choice::choice;
use super::{scenes_help, signals, GpuArgs, JsonArg, LeafSizeArg, TimelineArg};

/// The workload both sides run, in the bench vocabulary (smaller defaults: many rounds).
#[derive(Args, Clone)]
pub struct WorkloadArgs {
    #[arg(long, value_name = "A,B", value_delimiter = ',', help = concat!(scenes_help!(), "; default: bunny"))]
    scenes: Vec<PathBuf>,
    /// Intersection methods, comma-separated (default: all of them).
    #[arg(long, value_name = "M,...", value_parser = choice::<Method>(), value_delimiter = ',')]
    methods: Vec<Method>,
    /// Node layouts, comma-separated (default: bvh2).
    #[arg(long, value_name = "L,...", value_parser = choice::<Layout>(), value_delimiter = ',')]
    layouts: Vec<Layout>,
    /// A side's worker runs this layout in place of the cells' (what `ab --b-layout` gives side B).
    #[arg(long, value_name = "L", value_parser = choice::<Layout>(), hide = true)]
    runs_layout: Option<Layout>,
    /// Traversals, comma-separated (default: while-if); a layout without a kernel for one is
    /// left out of it.
    #[arg(long, value_name = "T,...", value_parser = choice::<Traversal>(), value_delimiter = ',')]
    traversals: Vec<Traversal>,
    /// Ray sets, comma-separated (default: primary, diffuse, random).
    #[arg(long, value_name = "S,...", value_parser = choice::<RaySet>(), value_delimiter = ',')]
    sets: Vec<RaySet>,
    /// Primary rays: image width.
    #[arg(long, value_name = "W", default_value_t = 160)]
    width: u32,
    /// Primary rays: image height.
    #[arg(long, value_name = "H", default_value_t = 120)]
    height: u32,
    /// Diffuse rays per primary hit.
    #[arg(long, value_name = "N", default_value_t = 2)]
    diffuse_per_hit: u32,
    /// Random rays.
    #[arg(long, value_name = "N", default_value_t = 20_000)]
    random_rays: usize,
    /// Seed of the ray sets (both sides trace the same rays).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::SEED)]
    seed: u64,
    #[command(flatten)]
    leaf: LeafSizeArg,
    /// How the kernels read the scene: `auto` uses texel buffers when every buffer fits one
    /// binding, else buffer device addresses.
    #[arg(long, value_parser = choice::<SceneAccess>(), default_value_t = SceneAccess::DEFAULT)]
    scene_access: SceneAccess,
    /// Most rays per dispatch.
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::BATCH_RAYS)]
    batch_rays: usize,
    /// Add a path-trace cell per scene, method and layout: the path tracer's kernel rendering the
    /// scene at --width x --height, 1 sample a pixel, paths of at most 4 bounces; validated as
    /// bench-render does (no NaN/Inf sample, image mean within 2 % of the scene's first cell),
    /// its pixels compared bit for bit between the sides.
    #[arg(long)]
    pathtrace: bool,
    /// Count each ray-casting cell's compute-shader invocations once per side (a
    /// pipeline-statistics query), and say where they differ.
    #[arg(long)]
    pipeline_stats: bool,
}

impl WorkloadArgs {
    /// The workload these options give, each list left empty taken from `defaults` (the sizes
    /// and settings are always these options').
    pub fn workload_or(&self, defaults: Workload) -> Workload {
        fn or<T: Clone>(given: &[T], d: Vec<T>) -> Vec<T> {
            if given.is_empty() {
                d
            } else {
                given.to_vec()
            }
        }
        let w = self.workload();
        Workload {
            scenes: or(&self.scenes, defaults.scenes),
            methods: or(&self.methods, defaults.methods),
            layouts: or(&self.layouts, defaults.layouts),
            traversals: or(&self.traversals, defaults.traversals),
            sets: or(&self.sets, defaults.sets),
            ..w
        }
    }

    pub fn workload(&self) -> Workload {
        Workload {
            scenes: if self.scenes.is_empty() { vec![PathBuf::from("bunny")] } else { self.scenes.clone() },
            methods: if self.methods.is_empty() { Method::ALL.to_vec() } else { self.methods.clone() },
            layouts: if self.layouts.is_empty() { vec![Layout::DEFAULT] } else { self.layouts.clone() },
            traversals: if self.traversals.is_empty() { vec![Traversal::DEFAULT] } else { self.traversals.clone() },
            sets: if self.sets.is_empty() { RaySet::ALL.to_vec() } else { self.sets.clone() },
            sizes: RaySetSizes {
                width: self.width,
                height: self.height,
                diffuse_per_hit: self.diffuse_per_hit,
                random_rays: self.random_rays,
                seed: self.seed,
            },
            build: self.leaf.options(),
            scene_access: self.scene_access,
            batch_rays: self.batch_rays,
            pathtrace: self.pathtrace,
            pipeline_stats: self.pipeline_stats,
            runs_layout: self.runs_layout,
        }
    }
}

/// How many rounds the sides run, and when they stop (`ab` and `gate`).
#[derive(Args, Clone, Copy)]
pub struct RoundsArgs {
    /// Rounds per side at least (2 or more; time is judged from 4 a side, fewer only shows it).
    #[arg(long, value_name = "N", default_value_t = 6)]
    pub rounds: usize,
    /// Rounds per side at most: rounds are added until every judged interval (each cell's, or
    /// each kernel's with --judge kernels) is narrower than --target.
    #[arg(long, value_name = "N", default_value_t = 20)]
    pub max_rounds: usize,
    /// Stop adding rounds when every judged 95 % interval is within +-PCT percent.
    #[arg(long, value_name = "PCT", default_value_t = 2.0)]
    pub target: f64,
    /// Stop adding rounds after this many seconds.
    #[arg(long, value_name = "S", default_value_t = 300.0)]
    pub time_cap: f64,
    /// A side's worker silent this many seconds (setting up, or in one run of one cell) is
    /// killed and named: the sides could not be compared (exit 2).
    #[arg(long, value_name = "S", default_value_t = ab::DEFAULT_WORKER_TIMEOUT_S)]
    pub worker_timeout: f64,
}

impl RoundsArgs {
    /// Refuses a target, time cap or worker timeout that is not a positive number, naming the
    /// option; then sets the workers' timeout (process-wide: `ab` and `gate` both call this
    /// before their sides start).
    pub fn check(&self, threshold: f64) -> Result<()> {
        for (name, v) in [
            ("--target", self.target),
            ("--threshold", threshold),
            ("--time-cap", self.time_cap),
            ("--worker-timeout", self.worker_timeout),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::Usage(format!("{name} {v}: must be a positive number")));
            }
        }
        // Past a year it is no limit at all; Duration cannot hold every f64.
        ab::set_worker_timeout(std::time::Duration::from_secs_f64(self.worker_timeout.min(3.2e7)));
        Ok(())
    }
}

/// `K=V`.
pub fn env_pair(s: &str) -> std::result::Result<(String, String), String> {
    match s.split_once('=') {
        Some((k, v)) if !k.is_empty() && !k.contains(char::is_whitespace) => Ok((k.into(), v.into())),
        _ => Err(format!("`{s}`: an environment setting is NAME=VALUE")),
    }
}

/// Two drivers, settings or builds in one run, interleaved: B/A per cell and kernel
///
/// Two drivers, driver settings or trilab builds in one run, interleaved: per cell and kernel
/// B/A kernel time with a 95 % interval, the hits compared ray by ray. Exit 0 pass, 1 hurt
/// beyond --threshold or correctness worse, 2 the sides could not be compared.
///
/// The same workload (bench cells; on request a path-trace cell, driver statistics, pipeline
/// statistics) under side A and side B, each its own process (its driver: --a-icd, --a-env; its
/// build: --a-bin), as gpu-trace-perf and Mesa's shader-db compare builds. Every round times each
/// cell's two sides back to back, which first alternating, each run validated against the f64
/// reference; the ratio is paired round by round. Prints only what changed, then the totals.
#[derive(Args)]
#[command(mut_arg("out", |a| a.help("Folder for ab.json, ab.md, rows.jsonl and each side's rows in a/ and b/ (`compare DIR/a DIR/b` and `merge` read them)")))]
pub struct AbArgs {
    #[command(flatten)]
    workload: WorkloadArgs,
    /// Side A's trilab executable (default: this one): two builds of the kernels side by side,
    /// each tracing the same scenes (resolved here) and rays.
    #[arg(long, value_name = "FILE")]
    a_bin: Option<PathBuf>,
    /// Side B's trilab executable, as --a-bin.
    #[arg(long, value_name = "FILE")]
    b_bin: Option<PathBuf>,
    /// Side A's driver: the ICD JSON the Vulkan loader is given (`VK_DRIVER_FILES`); default:
    /// the loader's own choice.
    #[arg(long, value_name = "FILE")]
    a_icd: Option<PathBuf>,
    /// Side B's driver, as --a-icd.
    #[arg(long, value_name = "FILE")]
    b_icd: Option<PathBuf>,
    /// A variable set for side A only (repeatable): `--a-env LP_NATIVE_VECTOR_WIDTH=128`.
    #[arg(long, value_name = "K=V", value_parser = env_pair)]
    a_env: Vec<(String, String)>,
    /// A variable set for side B only (repeatable).
    #[arg(long, value_name = "K=V", value_parser = env_pair)]
    b_env: Vec<(String, String)>,
    /// Side B runs this node layout where side A runs --layouts' one layout: two kernels of one
    /// build side by side (`--layouts bvh4 --b-layout qbvh4`), each cell named by A's layout
    /// (with --pathtrace, B's path tracer runs it too).
    #[arg(long, value_name = "L", value_parser = choice::<Layout>())]
    b_layout: Option<Layout>,
    #[command(flatten)]
    rounds: RoundsArgs,
    /// Exit 1 when a cell's (or kernel's, by --judge) whole interval is slower than this many
    /// percent.
    #[arg(long, value_name = "PCT", default_value_t = 5.0)]
    threshold: f64,
    /// What the verdict judges: each cell, or each kernel over its cells.
    #[arg(long, value_parser = choice::<Judge>(), default_value_t = Judge::Cells)]
    judge: Judge,
    /// After the rounds, each side's driver statistics of the ray-casting kernels (`trilab
    /// driver-stats` in that side's environment: lavapipe's machine code, or the executable
    /// statistics), printed where they differ; a driver without them is named, not a failure.
    #[arg(long)]
    driver_stats: bool,
    /// After the rounds, make each changed ray-casting cell (at most 3, the most changed first)
    /// into a repro of both sides under this new folder: `trilab repro`'s folder made by each
    /// side's own build in its own driver environment, and a README of what differs.
    #[arg(long, value_name = "DIR")]
    repro: Option<PathBuf>,
    #[command(flatten)]
    out: OutArgs,
    #[command(flatten)]
    trace: TimelineArg,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run(a: AbArgs) -> Result<()> {
    // 1 is a verdict (hurt, or a correctness figure worse); 2 means the sides could not be
    // compared, as `compare` and `diff` say.
    super::error_exit(2);
    a.rounds.check(a.threshold)?;
    let files = ["ab.json", "ab.md", trilab::rows::FILE];
    if let Some(dir) = &a.out.dir {
        OutArgs::check(dir, &files, &[])?;
    }
    // The trace is none of the sides' programs or drivers, and none of ab's own files.
    let sides = [&a.a_bin, &a.b_bin, &a.a_icd, &a.b_icd];
    let inputs: Vec<&std::path::Path> = sides.into_iter().flatten().map(PathBuf::as_path).collect();
    let outputs: Vec<PathBuf> = a.out.dir.iter().flat_map(|d| files.map(|f| d.join(f))).collect();
    a.trace.check(&inputs, &outputs)?;
    let trace = a.trace.clone();
    let run = trace.start("ab");
    let result = compare_sides(a);
    let written = trace.finish(run, &result);
    let code = result?;
    written?;
    if code != 0 {
        use std::io::Write;
        let _ = std::io::stdout().flush();
        std::process::exit(code.into());
    }
    Ok(())
}

/// The two sides run and compared, and the report written (`--timeline`'s run span covers it):
/// the exit status its verdict asks for.
fn compare_sides(a: AbArgs) -> Result<u8> {
    // Ctrl-C, SIGTERM or SIGHUP: the workers (each in a process group of its own) get the
    // signal too, then whatever is left of them is killed; say where the run was and what it
    // had measured, remove the workers' temporary folder and exit 128 + the signal's number.
    // Nothing is written: the report needs every round.
    let out = a.out.dir.clone();
    let handler = signals::on_stop(move |signal| {
        // Where the run is, before the workers get the signal (their end is no failure now).
        let at = ab::stop_requested().unwrap_or_else(|| "stopped before the sides started or after the rounds".into());
        let workers = trilab::children::signal_all(signal);
        #[cfg(unix)]
        if workers > 0 {
            // A worker that ignores the signal (or a script's child) does not outlive `ab`.
            std::thread::sleep(std::time::Duration::from_millis(300));
            trilab::children::signal_all(libc::SIGKILL);
        }
        ab::remove_temp();
        let forwarded = if workers > 0 { format!(" (and its {workers} worker(s))") } else { String::new() };
        let written = match &out {
            Some(d) => format!("nothing written to {}", d.display()),
            None => "nothing written".into(),
        };
        eprintln!("ab: stopped by {}{forwarded}; {at}; {written}", signals::name(signal));
        signals::exit_now(signal);
    });
    if let Err(e) = handler {
        super::note(&format!("warning: cannot catch Ctrl-C or SIGTERM ({e}); a stopped run will not say where it was"));
    }
    let exe = trilab::services::worker::this_exe()?;
    let validation = a.gpu.validation_required();
    let o = AbOptions {
        workload: a.workload.workload(),
        a: Side { exe: a.a_bin, icd: a.a_icd, env: a.a_env, layout: None },
        b: Side { exe: a.b_bin, icd: a.b_icd, env: a.b_env, layout: a.b_layout },
        exe,
        rounds: a.rounds.rounds,
        max_rounds: a.rounds.max_rounds,
        target: a.rounds.target / 100.0,
        time_cap_s: a.rounds.time_cap,
        threshold: a.threshold / 100.0,
        judge: a.judge,
        validation,
        driver_stats: a.driver_stats,
        repro: a.repro,
    };
    sigpipe(true);
    let report = ab::run(&o, |m| eprintln!("  {m}"));
    sigpipe(false);
    while ab::stopping() {
        // The stop handler ends the process: a worker its signal ended is not this run's error.
        std::thread::park();
    }
    let report = report?;
    let _span = trilab::timeline::span("report", "report writing");
    if let Some(dir) = &a.out.dir {
        ab::write(&report, dir)?;
        eprintln!("wrote {}", dir.display());
    }
    a.json.print(&report);
    Ok(report.exit_code())
}

/// Sets SIGPIPE's disposition: `ignore` while `ab` writes commands to its workers' stdin (a
/// worker that died then gives an error naming its side, not a silent exit 141), the default
/// again before the report is printed (a closed stdout ends the process quietly, as `main`
/// arranges for every command).
#[cfg(unix)]
pub fn sigpipe(ignore: bool) {
    // SAFETY: `signal` with SIG_IGN or SIG_DFL installs no handler of ours, only a disposition;
    // the worker threads of this process write only to pipes this function is meant to cover.
    unsafe {
        libc::signal(libc::SIGPIPE, if ignore { libc::SIG_IGN } else { libc::SIG_DFL });
    }
}

#[cfg(not(unix))]
pub fn sigpipe(_ignore: bool) {}

/// The worker service's child (run by trilab, not by hand): one-shot requests on stdin, or with
/// --hits-dir one side of `trilab ab`.
#[derive(Args)]
pub struct WorkerArgs {
    #[command(flatten)]
    workload: WorkloadArgs,
    /// Where each cell's first-round hits go: an `ab` side, serving this workload.
    #[arg(long, value_name = "DIR")]
    hits_dir: Option<PathBuf>,
    /// The repro in this folder is what the worker dispatches (`trilab repro`'s capture): its
    /// context enables only what that kernel needs.
    #[arg(long, value_name = "DIR", conflicts_with = "hits_dir")]
    repro: Option<PathBuf>,
    #[command(flatten)]
    gpu: GpuArgs,
}

pub fn run_worker(a: WorkerArgs) -> Result<()> {
    let ctx = match &a.repro {
        Some(dir) => {
            let r = trilab::commands::repro::Repro::read(dir)?;
            let ctx =
                trilab::commands::repro::replay::context(r.kernel, a.gpu.device.clone(), a.gpu.validation_choice())?;
            GpuArgs::watch(&ctx);
            ctx
        }
        // An ab side runs its cells; a one-shot worker may be asked only to compile (a GPU
        // target's driver statistics, on a device that only compiles), and refuses the requests
        // that dispatch on such a device (commands::worker).
        None if a.hits_dir.is_some() => a.gpu.context()?,
        None => a.gpu.compile_context()?,
    };
    let workload = a.workload.workload();
    let side = a.hits_dir.as_deref().map(|hits_dir| trilab::commands::worker::AbSide { workload: &workload, hits_dir });
    let stdin = std::io::stdin();
    trilab::commands::worker::serve(&ctx, a.gpu.validation, side, stdin.lock(), std::io::stdout().lock())
}
