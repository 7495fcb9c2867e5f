//! The command line: one file per command, each turning its arguments into one library call
//! and printing the typed report it returns (as text, or as JSON with `--json`). Option groups
//! several commands share are defined here once and flattened into each.

pub mod ab;
pub mod accuracy;
pub mod analyze;
pub mod bench;
pub mod bench_render;
pub mod build_bench;
pub mod bvh;
pub mod camera;
pub mod choice;
pub mod compare;
pub mod completions;
pub mod devices;
pub mod driver_stats;
pub mod dump;
pub mod gate;
pub mod man;
pub mod merge;
pub mod hits;
pub mod methods;
pub mod profile;
pub mod raycast;
pub mod rays;
pub mod repro;
pub mod render;
pub mod roofline;
pub mod scale;
pub mod signals;
pub mod spirv;
pub mod steps;
pub mod study;
pub mod suite;

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::{Arc, OnceLock};

use clap::Args;
use trilab::bvh::{BuildOptions, LeafPolicy};
use trilab::encoding::Method;
use trilab::error::{Error, Result};
use trilab::gpu::{Context, ContextOptions, Purpose, Validation, ValidationLog};
use trilab::report::Report;
use trilab::services::rayset::RaySetSizes;

use choice::choice;

/// The help of `--scene`: every command takes a bundled scene's name or a path.
macro_rules! scene_help {
    () => {
        "Scene: a name (bunny, dragon, buddha, cornell, bsdfs) or a path (.obj, .obj.gz, synth:<kind>:<N>)"
    };
}
/// The help of `--scenes`.
macro_rules! scenes_help {
    () => {
        "Scenes, comma-separated: names (bunny, dragon, buddha, cornell, bsdfs) or paths (.obj, .obj.gz, synth:<kind>:<N>)"
    };
}
pub(crate) use {scene_help, scenes_help};

/// `--repeat N`: timed runs, at least one (every command; 0 is refused here, at parse time).
pub fn repeat(s: &str) -> std::result::Result<usize, String> {
    let n: usize = s.trim().parse().map_err(|_| format!("`{s}` is not a whole number of timed runs"))?;
    if n == 0 {
        return Err("must be at least 1 (0 timed runs would measure nothing)".into());
    }
    Ok(n)
}

/// The device and the validation layer (every command that uses a device).
#[derive(Args, Clone)]
pub struct GpuArgs {
    /// Vulkan device: index or part of its name/driver (see `trilab devices`). Default: a
    /// discrete GPU if present, else the best other device.
    #[arg(long, global = true)]
    pub device: Option<String>,
    /// Load the Khronos validation layer, synchronization validation included, and fail on
    /// any message (default: on in debug builds only; also TRILAB_VALIDATION=1).
    #[arg(long, global = true)]
    pub validation: bool,
}

/// The validation log of the context a command made, checked before exit.
static VALIDATION_LOG: OnceLock<Arc<ValidationLog>> = OnceLock::new();

impl GpuArgs {
    /// The validation layer as `--validation` or `TRILAB_VALIDATION` ask (else the build's
    /// default).
    pub fn validation_choice(&self) -> Validation {
        let env = std::env::var("TRILAB_VALIDATION").unwrap_or_default();
        if self.validation || !matches!(env.trim(), "" | "0" | "off" | "false") {
            Validation::Required
        } else {
            ContextOptions::default().validation
        }
    }

    /// Whether the validation layer is asked for (`--validation` or `TRILAB_VALIDATION`): what a
    /// command passes on to the trilab workers it starts.
    pub fn validation_required(&self) -> bool {
        self.validation_choice() == Validation::Required
    }

    /// Registers the validation log of a context made elsewhere (a repro's), checked before exit.
    pub fn watch(ctx: &Context) {
        let _ = VALIDATION_LOG.set(ctx.validation_log());
    }

    /// The device's context, with the validation layer when asked for, for a command that runs
    /// kernels: a device that only compiles is refused here, before any work.
    pub fn context(&self) -> Result<Context> {
        self.context_for(Purpose::Run)
    }

    /// The device's context for a command that only compiles (`driver-stats`): a compile-only
    /// device (RADV's null device) is taken too.
    pub fn compile_context(&self) -> Result<Context> {
        self.context_for(Purpose::Compile)
    }

    fn context_for(&self, purpose: Purpose) -> Result<Context> {
        let o = ContextOptions {
            device: self.device.clone(),
            validation: self.validation_choice(),
            purpose,
            ..Default::default()
        };
        let ctx = Context::new(&o)?;
        let _ = VALIDATION_LOG.set(ctx.validation_log());
        Ok(ctx)
    }
}

/// How the BVH is built: `--leaf-size`, `--leaf-policy`, `--sah-group`, turned into the
/// library's [`BuildOptions`] here only. A command that takes some of them flattens the part it
/// takes ([`LeafSizeArg`], [`TreeShapeArgs`], [`SahGroupArg`]), so each flag is declared once.
#[derive(Args, Clone, Copy)]
pub struct BuildArgs {
    #[command(flatten)]
    pub leaf: LeafSizeArg,
    #[command(flatten)]
    pub shape: TreeShapeArgs,
}

impl BuildArgs {
    pub fn options(&self) -> BuildOptions {
        self.shape.options(self.leaf.leaf_size)
    }
}

/// `--leaf-size`: the most triangles in a leaf, the tree otherwise the default one.
#[derive(Args, Clone, Copy)]
pub struct LeafSizeArg {
    /// Max triangles per BVH leaf (1..=16; the paper studies 1, 2, 3, 4, 8, 16).
    #[arg(long, value_name = "N", default_value_t = trilab::defaults::LEAF_SIZE)]
    pub leaf_size: u32,
}

impl LeafSizeArg {
    pub fn options(&self) -> BuildOptions {
        BuildOptions::new(self.leaf_size)
    }
}

/// `--leaf-policy` and `--sah-group`: how the SAH shapes the tree (beside one leaf size, or a
/// list of them).
#[derive(Args, Clone, Copy)]
pub struct TreeShapeArgs {
    /// `fill`: nodes with <= leaf-size triangles become leaves (the paper's); `sah`: the SAH
    /// decides and leaf-size is only a cap.
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::DEFAULT)]
    pub leaf_policy: LeafPolicy,
    #[command(flatten)]
    pub sah_group: SahGroupArg,
}

impl TreeShapeArgs {
    /// The build options of a tree of this shape with at most `leaf_size` triangles a leaf.
    pub fn options(&self, leaf_size: u32) -> BuildOptions {
        BuildOptions {
            leaf_policy: self.leaf_policy,
            sah_group: self.sah_group.sah_group,
            ..BuildOptions::new(leaf_size)
        }
    }
}

/// `--sah-group`: the SAH's pricing of a leaf (`BuildOptions::sah_group`).
#[derive(Args, Clone, Copy)]
pub struct SahGroupArg {
    /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
    /// Quad kernels test them.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub sah_group: u32,
}

/// The three ray sets a benchmark makes (`trilab bench`'s defaults; a command with smaller sets
/// changes the defaults with `mut_arg`), as the harness's [`RaySetSizes`].
#[derive(Args, Clone, Copy)]
pub struct RaySetArgs {
    /// Primary rays: the camera image's width in pixels.
    #[arg(long, value_name = "W", default_value_t = RaySetSizes::default().width)]
    pub width: u32,
    /// Primary rays: the camera image's height in pixels.
    #[arg(long, value_name = "H", default_value_t = RaySetSizes::default().height)]
    pub height: u32,
    /// Diffuse rays: cosine-distributed bounces per primary hit.
    #[arg(long, value_name = "N", default_value_t = RaySetSizes::default().diffuse_per_hit, alias = "per-hit")]
    pub diffuse_per_hit: u32,
    /// Random rays: how many, from a sphere around the scene into its box.
    #[arg(long, value_name = "N", default_value_t = RaySetSizes::default().random_rays, alias = "count")]
    pub random_rays: usize,
    /// Seed of the diffuse and random ray sets.
    #[arg(long, value_name = "N", default_value_t = RaySetSizes::default().seed)]
    pub seed: u64,
}

impl RaySetArgs {
    pub fn sizes(&self) -> RaySetSizes {
        RaySetSizes {
            width: self.width,
            height: self.height,
            diffuse_per_hit: self.diffuse_per_hit,
            random_rays: self.random_rays,
            seed: self.seed,
        }
    }
}

/// Which methods (comma-separated; each command says its default).
#[derive(Args, Clone)]
pub struct MethodsArg {
    /// Intersection methods, comma-separated (`trilab methods` lists them); default: every
    /// method the device runs, unless the command says otherwise.
    #[arg(long, value_name = "M,...", value_parser = choice::<Method>(), value_delimiter = ',')]
    pub methods: Vec<Method>,
}

impl MethodsArg {
    /// The methods given, or every method `ctx`'s device can run.
    pub fn or_device(&self, ctx: &Context) -> Vec<Method> {
        if self.methods.is_empty() {
            trilab::conditioning::available_methods(&ctx.capabilities())
        } else {
            self.methods.clone()
        }
    }
}

/// `--out DIR`, the one output option of every command that writes files: the folder its files
/// go into, checked before any work ([`OutArgs::check`]: not a file, writable, or creatable under
/// a writable folder; none of its files an input) and made when missing. Each command names
/// its files and its default in its own help (`#[command(mut_arg("out", ...))]`).
#[derive(Args, Clone, Debug, Default)]
pub struct OutArgs {
    /// Folder for the command's files, made when missing.
    #[arg(long = "out", id = "out", value_name = "DIR")]
    pub dir: Option<PathBuf>,
}

impl OutArgs {
    /// Checks, before any work, that `dir` can take `files` and that none of them is one of
    /// `inputs` ([`trilab::io::check_output`]); the folder is made once there is something to
    /// write ([`OutArgs::make`]).
    pub fn check(dir: &std::path::Path, files: &[&str], inputs: &[&std::path::Path]) -> Result<()> {
        trilab::io::check_output("--out", trilab::io::Output::Dir(dir, files), inputs)
    }

    /// Makes the folder `dir` (and its parents) when missing.
    pub fn make(dir: &std::path::Path) -> Result<()> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
    }
}

/// `--shard I/N`, the one shard option: run only shard I of N of a command's matrix. Each
/// command says in its help what its unit of sharding is (`#[command(mut_arg("shard", ...))]`).
#[derive(Args, Clone, Copy, Debug, Default)]
pub struct ShardArg {
    /// Run only shard I of N; rows.jsonl names the shard and plans the whole matrix, and
    /// `trilab merge` joins the shards' folders.
    #[arg(long, value_name = "I/N")]
    pub shard: Option<trilab::rows::Shard>,
}

/// `--timeline FILE`, the one timeline option (`bench`, `suite`, `ab`): the run as Chrome trace JSON
/// ([`trilab::timeline`]), checked before any work as every output is ([`TimelineArg::check`]) and
/// written when the run ends, failed or not ([`TimelineArg::finish`]).
#[derive(Args, Clone, Debug, Default)]
pub struct TimelineArg {
    /// Also write a timeline of the run to FILE as Chrome trace JSON, for https://ui.perfetto.dev
    /// or chrome://tracing (docs/benchmarking.md): host phases (scene load, BVH build, upload,
    /// ray sets, the f64 reference, validation, peers, pipeline compiles, report writing) and
    /// rounds, each dispatch on a GPU track lasting what its GPU timestamps measured; suite: each
    /// part, planned against actual seconds; ab: each side's run of each cell in each round (the
    /// sides' dispatches run in their workers and are not in it)
    // `--trace`, its name before issue 52, stays as a hidden alias.
    #[arg(long = "timeline", id = "timeline", alias = "trace", value_name = "FILE")]
    pub file: Option<PathBuf>,
}

impl TimelineArg {
    /// Checks FILE before any work: not an existing directory, not one of `inputs`, not one of
    /// the command's own `outputs` (which would overwrite it, or it them), and in a writable
    /// folder, or one that can be made (the `--out` folder, say, made when missing: so is the
    /// trace's when it is written).
    pub fn check(&self, inputs: &[&std::path::Path], outputs: &[PathBuf]) -> Result<()> {
        let Some(file) = &self.file else { return Ok(()) };
        match (file.parent(), file.file_name()) {
            (Some(dir), Some(name)) if !dir.as_os_str().is_empty() && !dir.exists() => {
                let name = name.to_string_lossy();
                trilab::io::check_output("--timeline", trilab::io::Output::Dir(dir, &[&name]), inputs)?
            }
            _ => trilab::io::check_output("--timeline", trilab::io::Output::File(file), inputs)?,
        }
        for out in outputs {
            if trilab::io::same_file(file, out) {
                return Err(Error::Usage(format!(
                    "--timeline {}: is also the command's output {}; give the timeline a file of its own",
                    file.display(),
                    out.display()
                )));
            }
        }
        Ok(())
    }

    /// Starts recording when FILE is given: the process is named `trilab <command>` in the
    /// viewer and the command line goes into the file's `otherData`. Returns the run's span,
    /// which every other host span nests in.
    pub fn start(&self, command: &str) -> trilab::timeline::Span {
        if self.file.is_none() {
            return trilab::timeline::span("command", "");
        }
        trilab::timeline::start(&format!("trilab {command}"));
        let run = trilab::timeline::span("command", format!("trilab {command}"));
        let line: Vec<String> = std::env::args()
            .map(|a| if a.contains(char::is_whitespace) || a.is_empty() { format!("{a:?}") } else { a })
            .collect();
        trilab::timeline::set_other("command_line", line.join(" "));
        trilab::timeline::set_other("commit", trilab::services::provenance::commit());
        run
    }

    /// Notes the device and driver in the file's `otherData`.
    pub fn device(ctx: &Context) {
        if trilab::timeline::on() {
            let info = ctx.info();
            trilab::timeline::set_other("device", info.name.clone());
            trilab::timeline::set_other("driver", info.driver_label());
        }
    }

    /// Closes the run's span (its args say how the run ended) and writes FILE; a note names it
    /// and what it holds. The run's own error, if any, is the caller's to return.
    pub fn finish<T>(&self, run: trilab::timeline::Span, result: &Result<T>) -> Result<()> {
        let Some(file) = &self.file else { return Ok(()) };
        if let Err(e) = result {
            run.arg("error", e.to_string());
        }
        drop(run);
        let written = TimelineArg::write(file)?;
        note(&format!("trace: {written} in {}", file.display()));
        Ok(())
    }

    /// Writes what was recorded to `file` (its folder made when missing), the spans still open
    /// (a run a signal stopped) marked unfinished; recording stops.
    pub fn write(file: &std::path::Path) -> Result<trilab::timeline::Written> {
        if let Some(dir) = file.parent().filter(|d| !d.as_os_str().is_empty()) {
            OutArgs::make(dir)?;
        }
        trilab::timeline::finish(file)
    }
}

/// `--out DIR` ([`OutArgs`]) for a report written as `<stem>.json` (the report) and `<stem>.md`
/// (its tables), or the old spellings `--json-out FILE` and `--md-out FILE` (hidden) for either
/// file alone.
#[derive(Args, Clone)]
pub struct ReportOutArgs {
    #[command(flatten)]
    pub out: OutArgs,
    /// Old spelling: write the report as JSON to this file (use --out DIR).
    #[arg(long, value_name = "FILE", hide = true)]
    pub json_out: Option<PathBuf>,
    /// Old spelling: write the report's tables as Markdown to this file (use --out DIR).
    #[arg(long, value_name = "FILE", hide = true)]
    pub md_out: Option<PathBuf>,
}

impl ReportOutArgs {
    /// The two report files (`<stem>.json`, `<stem>.md` in `--out`, or the old `--json-out` and
    /// `--md-out` files), each checked before any work: writable, and not one of the `scenes`
    /// (names are resolved to the files they find).
    pub fn files(&self, stem: &str, scenes: &[PathBuf]) -> Result<(Option<PathBuf>, Option<PathBuf>)> {
        let files = scenes.iter().map(|s| trilab::scene::resolve(s).map(|f| f.path)).collect::<Result<Vec<_>>>()?;
        let inputs: Vec<&std::path::Path> = files.iter().map(PathBuf::as_path).collect();
        let (json, md) = match &self.out.dir {
            Some(dir) => {
                // The folder is checked as a folder (made when missing, once the report is ready);
                // an old-spelling file given beside it is checked as a file.
                let (json_name, md_name) = (format!("{stem}.json"), format!("{stem}.md"));
                OutArgs::check(dir, &[&json_name, &md_name], &inputs)?;
                let json = self.json_out.clone().unwrap_or_else(|| dir.join(json_name));
                let md = self.md_out.clone().unwrap_or_else(|| dir.join(md_name));
                (Some(json), Some(md))
            }
            None => (self.json_out.clone(), self.md_out.clone()),
        };
        for (option, given) in [("--json-out", &self.json_out), ("--md-out", &self.md_out)] {
            if let Some(file) = given {
                trilab::io::check_output(option, trilab::io::Output::File(file), &inputs)?;
            }
        }
        Ok((json, md))
    }

    /// Makes the `--out` folder (if given) when missing, once the report is ready to write.
    pub fn create_dir(&self) -> Result<()> {
        match &self.out.dir {
            Some(dir) => OutArgs::make(dir),
            None => Ok(()),
        }
    }
}

/// `--json`: the report as JSON instead of text.
#[derive(Args, Clone, Copy)]
pub struct JsonArg {
    /// Print the report as JSON on stdout instead of text (an error too: `{"error": {"kind",
    /// "message"}}`, with the same exit code).
    #[arg(long)]
    pub json: bool,
}

impl JsonArg {
    /// Prints `report` as this flag asks.
    pub fn print(&self, report: &impl Report) {
        if self.json {
            println!("{}", report.to_json());
            REPORT_PRINTED.store(true, Ordering::Relaxed);
        } else {
            print!("{}", report.to_text());
        }
    }
}

/// The exit status of an error: 1, or 2 for a command whose status 1 is a verdict
/// (`compare`: 1 is a regression, 2 a failure to compare, as `diff`'s 1 and 2) and for `merge`,
/// which compares many runs and gives the same 2 when it cannot.
static ERROR_EXIT: AtomicU8 = AtomicU8::new(1);

/// Makes an error exit with `code` (see [`ERROR_EXIT`]).
pub fn error_exit(code: u8) {
    ERROR_EXIT.store(code, Ordering::Relaxed);
}

/// Whether errors are printed as JSON on stdout (the command was given `--json`).
static JSON_ERRORS: AtomicBool = AtomicBool::new(false);

/// Whether a JSON report is already on stdout: a command whose report carries its own failure
/// (`raycast --reference`, `hits check`, `hits diff`) then leaves stdout one JSON document and
/// says the error on stderr only.
static REPORT_PRINTED: AtomicBool = AtomicBool::new(false);

/// Asks [`exit`] (and [`exit_parse_error`]) to print errors as JSON on stdout.
pub fn json_errors(on: bool) {
    JSON_ERRORS.store(on, Ordering::Relaxed);
}

/// The `kind` of an error as `--json` prints it.
pub fn error_kind(e: &Error) -> &'static str {
    match e {
        Error::Io { .. } => "io",
        Error::BadInput { .. } => "bad-input",
        Error::Usage(_) => "usage",
        Error::Loader(_) => "loader",
        Error::NoDevice(_) => "no-device",
        Error::Vulkan { .. } => "vulkan",
        Error::Allocation { .. } => "allocation",
        Error::Spirv { .. } => "spirv",
        Error::Unsupported(_) => "unsupported",
        Error::Timeout { .. } => "timeout",
        Error::SceneTooLarge(_) => "scene-too-large",
        Error::GpuFault { .. } => "gpu-fault",
    }
}

/// `{"error": {"kind": .., "message": .., "validation": [..]}}`: an error as `--json` prints it.
fn json_error(kind: &str, message: &str, validation: &[String]) -> String {
    let mut e = serde_json::json!({ "kind": kind, "message": message });
    if !validation.is_empty() {
        e["validation"] = serde_json::json!(validation);
    }
    serde_json::json!({ "error": e }).to_string()
}

/// A command line clap refused: its usual message (and exit code 2), or with `--json` among the
/// arguments the message as a JSON error on stdout, kind `arguments`, with the same exit code.
pub fn exit_parse_error(e: clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    let json = std::env::args_os().skip(1).any(|a| a == "--json");
    if !json || matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        e.exit();
    }
    let text = e.render().to_string();
    let message = text.lines().next().unwrap_or_default().trim_start_matches("error: ").to_owned();
    println!("{}", json_error("arguments", &message, &[]));
    ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2))
}

/// `results/<device>/<what>` unless `out` is given (`lavapipe` for Mesa's CPU driver).
pub fn results_dir(ctx: &Context, out: Option<PathBuf>, what: &str) -> PathBuf {
    out.unwrap_or_else(|| PathBuf::from("results").join(ctx.info().results_dir()).join(what))
}

/// A line to stderr, as every command reports progress and warnings.
pub fn note(line: &str) {
    eprintln!("trilab: {line}");
}

/// Ends the process after a stop signal (SIGINT, SIGTERM, SIGHUP: [`signals`]) whose partial
/// output was saved: reports any validation message as [`exit`] does, then exits 128 + the
/// signal's number (130, 143, 129), as a shell reports a process the signal ended; 1 if the
/// layer reported anything.
pub fn exit_interrupted(signal: i32) -> ! {
    let messages = VALIDATION_LOG.get().map(|l| l.messages()).unwrap_or_default();
    for m in &messages {
        eprintln!("trilab: validation: {m}");
    }
    use std::io::Write;
    let _ = std::io::stdout().flush();
    if messages.is_empty() {
        eprintln!("trilab: stopped by {}; the partial output was saved", signals::name(signal));
        std::process::exit(signals::exit_status(signal))
    }
    eprintln!("trilab: error: {} validation message(s)", messages.len());
    std::process::exit(1)
}

/// The process's exit: the command's error, or any validation message (the contexts are gone
/// by now, so teardown messages are in the log too), fails it.
pub fn exit(result: Result<()>) -> ExitCode {
    let messages = VALIDATION_LOG.get().map(|l| l.messages()).unwrap_or_default();
    for m in &messages {
        eprintln!("trilab: validation: {m}");
    }
    let json = JSON_ERRORS.load(Ordering::Relaxed);
    match result {
        Err(e) => {
            eprintln!("trilab: error: {e}");
            if json && !REPORT_PRINTED.load(Ordering::Relaxed) {
                println!("{}", json_error(error_kind(&e), &e.to_string(), &messages));
            }
            ExitCode::from(ERROR_EXIT.load(Ordering::Relaxed))
        }
        Ok(()) if !messages.is_empty() => {
            let message = format!("{} validation message(s)", messages.len());
            eprintln!("trilab: error: {message}");
            if json {
                println!("{}", json_error("validation", &message, &messages));
            }
            ExitCode::FAILURE
        }
        Ok(()) => ExitCode::SUCCESS,
    }
}

/// The top line of `trilab --help`: how many methods there are, from the registry (`trilab
/// methods` names them).
pub fn about() -> String {
    format!(
        "GPU ray-triangle intersection laboratory: BVH traversal in Vulkan compute kernels, {} methods",
        Method::ALL.len()
    )
}

/// After `trilab --help`'s one line per command: where the detail is, in a few lines of at most
/// 100 columns. The environment variables are named (`trilab::env`, the one list) and explained
/// in docs/commands.md, which `trilab man --markdown` writes.
pub fn after_help() -> String {
    let mut text = String::from(
        "`trilab <COMMAND> --help`: what a command does, and its options. `trilab methods`: the methods.\n\
         Manual: docs/README.md; commands, options, variables: docs/commands.md; files: docs/formats.md.\n\
         Environment:",
    );
    let mut column = text.len() - text.rfind('\n').map_or(0, |n| n + 1);
    let names: Vec<&str> = trilab::env::ENV_VARS.iter().map(|v| v.name).collect();
    for (i, name) in names.iter().enumerate() {
        let word = if i + 1 == names.len() { format!("{name}.") } else { format!("{name},") };
        if column + 1 + word.len() > 100 {
            text.push('\n');
            column = 0;
        } else {
            text.push(' ');
            column += 1;
        }
        text += &word;
        column += word.len();
    }
    text
}

/// Whether the (sub)command the user ran was given `--json`.
pub fn asks_for_json(matches: &clap::ArgMatches) -> bool {
    let mut m = matches;
    loop {
        if let Ok(Some(&true)) = m.try_get_one::<bool>("json") {
            return true;
        }
        match m.subcommand() {
            Some((_, sub)) => m = sub,
            None => return false,
        }
    }
}
