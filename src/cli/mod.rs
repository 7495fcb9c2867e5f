//! The command line: one file per command, each turning its arguments into one library call
//! and printing the typed report it returns (as text, or as JSON with `--json`). Option groups
//! several commands share are defined here once and flattened into each.

pub mod accuracy;
pub mod analyze;
pub mod bench;
pub mod bench_render;
pub mod build_bench;
pub mod bvh;
pub mod camera;
pub mod choice;
pub mod devices;
pub mod methods;
pub mod profile;
pub mod raycast;
pub mod rays;
pub mod render;
pub mod scale;
pub mod spirv;
pub mod steps;
pub mod study;

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::{Arc, OnceLock};

use clap::Args;
use trilab::bvh::{BuildOptions, LeafPolicy};
use trilab::encoding::Method;
use trilab::error::Result;
use trilab::gpu::{Context, ContextOptions, Validation, ValidationLog};
use trilab::report::Report;

use choice::choice;

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
    /// The device's context, with the validation layer when asked for.
    pub fn context(&self) -> Result<Context> {
        let mut o = ContextOptions { device: self.device.clone(), ..Default::default() };
        let env = std::env::var("TRILAB_VALIDATION").unwrap_or_default();
        if self.validation || !matches!(env.trim(), "" | "0" | "off" | "false") {
            o.validation = Validation::Required;
        }
        let ctx = Context::new(&o)?;
        let _ = VALIDATION_LOG.set(ctx.validation_log());
        Ok(ctx)
    }
}

/// How the BVH is built (`--leaf-size`, `--leaf-policy`, `--sah-group`).
#[derive(Args, Clone)]
pub struct BuildArgs {
    /// Max triangles per BVH leaf (1..=16; the paper studies 1, 2, 3, 4, 8, 16).
    #[arg(long, default_value_t = 4)]
    pub leaf_size: u32,
    /// `fill`: nodes with <= leaf-size triangles become leaves (the paper's); `sah`: the SAH
    /// decides and leaf-size is only a cap.
    #[arg(long, value_parser = choice::<LeafPolicy>(), default_value_t = LeafPolicy::Fill)]
    pub leaf_policy: LeafPolicy,
    /// Triangles the SAH prices as one test: 1 (classic), or 4 to price leaves in quads as the
    /// Quad kernels test them.
    #[arg(long, default_value_t = 1)]
    pub sah_group: u32,
}

impl BuildArgs {
    pub fn options(&self) -> BuildOptions {
        BuildOptions { leaf_policy: self.leaf_policy, sah_group: self.sah_group, ..BuildOptions::new(self.leaf_size) }
    }
}

/// Which methods (comma-separated; each command says its default).
#[derive(Args, Clone)]
pub struct MethodsArg {
    #[arg(long, value_parser = choice::<Method>(), value_delimiter = ',')]
    pub methods: Vec<Method>,
}

impl MethodsArg {
    /// The methods given, or every method `ctx`'s device can run.
    pub fn or_device(&self, ctx: &Context) -> Vec<Method> {
        if self.methods.is_empty() {
            trilab::analyze::available_methods(ctx.enabled())
        } else {
            self.methods.clone()
        }
    }
}

/// `--json`: the report as JSON instead of text.
#[derive(Args, Clone, Copy)]
pub struct JsonArg {
    /// Print the report as JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

impl JsonArg {
    /// Prints `report` as this flag asks.
    pub fn print(&self, report: &impl Report) {
        if self.json {
            println!("{}", report.to_json());
        } else {
            print!("{}", report.to_text());
        }
    }
}

/// `results/<device>/<what>` unless `out` is given (`lavapipe` for Mesa's CPU driver).
pub fn results_dir(ctx: &Context, out: Option<PathBuf>, what: &str) -> PathBuf {
    out.unwrap_or_else(|| PathBuf::from("results").join(ctx.info().results_dir()).join(what))
}

/// A line to stderr, as every command reports progress and warnings.
pub fn note(line: &str) {
    eprintln!("trilab: {line}");
}

/// The process's exit: the command's error, or any validation message (the contexts are gone
/// by now, so teardown messages are in the log too), fails it.
pub fn exit(result: Result<()>) -> ExitCode {
    let messages = VALIDATION_LOG.get().map(|l| l.messages()).unwrap_or_default();
    for m in &messages {
        eprintln!("trilab: validation: {m}");
    }
    match result {
        Err(e) => {
            eprintln!("trilab: error: {e}");
            ExitCode::FAILURE
        }
        Ok(()) if !messages.is_empty() => {
            eprintln!("trilab: error: {} validation message(s)", messages.len());
            ExitCode::FAILURE
        }
        Ok(()) => ExitCode::SUCCESS,
    }
}
