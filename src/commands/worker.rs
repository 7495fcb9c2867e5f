//! `trilab __worker` (hidden; `__ab-worker` by its older name): the child side of the worker
//! service ([`crate::services::worker`]). It reads typed requests on stdin, one JSON object a
//! line, and answers each on stdout with a typed message, until `quit` or the end of its input:
//! a bench under the `LP_NUM_THREADS` it was started with ([`profile::threads::measure`]), the
//! kernels dispatched under `GALLIVM_DEBUG=asm` ([`driver_stats::emit_for_parent`]), an `ab`
//! side's driver statistics ([`driver_stats::collect`]). Given a workload and a hits folder it
//! is an `ab` side instead ([`ab::worker::serve`]). A failure is [`Message::Failed`] and the end
//! of the process. Nothing else is printed on stdout: progress goes to stderr.

use std::io::{BufRead, Write};
use std::path::Path;

use crate::commands::{ab, profile, repro};
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::report::Status;
use crate::services::driver_stats::{self, CollectOptions, Selection};
use crate::services::worker::protocol::DriverStatsRequest;
use crate::services::worker::{say, this_exe, Message, Request};

/// An `ab` side's work: its workload and where its cells' first-round hits go.
pub struct AbSide<'a> {
    pub workload: &'a ab::worker::Workload,
    pub hits_dir: &'a Path,
}

/// Serves `input`'s requests on `output` (`validation`: the worker was started with the
/// validation layer, and starts its own children so); with `side`, an `ab` side.
pub fn serve(
    ctx: &Context,
    validation: bool,
    side: Option<AbSide>,
    input: impl BufRead,
    mut output: impl Write,
) -> Result<()> {
    if let Some(s) = side {
        return ab::worker::serve(ctx, s.workload, s.hits_dir, input, output);
    }
    for line in input.lines() {
        let line = line.map_err(|e| Error::io(Path::new("stdin"), e))?;
        let answer = Request::parse(&line).map_err(|e| Error::Usage(format!("worker: {e}"))).and_then(|r| match r {
            Request::Quit => Ok(None),
            r => answer(ctx, validation, r).map(Some),
        });
        match answer {
            Ok(Some(m)) => say(&mut output, &m)?,
            Ok(None) => return Ok(()),
            Err(e) => {
                say(&mut output, &Message::Failed { error: e.to_string() })?;
                return Err(e);
            }
        }
    }
    Ok(())
}

/// The refusal of a request that dispatches, on a device that only compiles (the worker of a GPU
/// target is made on one): before any work, naming the device.
fn runs(ctx: &Context, what: &str) -> Result<()> {
    ctx.capabilities().runs().map_err(|u| Error::Unsupported(format!("worker: {what} runs kernels, and {u}")))
}

/// One request's answer.
fn answer(ctx: &Context, validation: bool, r: Request) -> Result<Message> {
    let dispatches = match &r {
        Request::BenchThreads(_) => Some("a bench"),
        Request::DispatchKernels { .. } => Some("dispatching kernels"),
        Request::ReproDispatch { .. } => Some("a repro's dispatch"),
        Request::MakeRepro(_) => Some("making a repro"),
        _ => None,
    };
    if let Some(what) = dispatches {
        runs(ctx, what)?;
    }
    match r {
        Request::BenchThreads(b) => Ok(Message::Measured { measurements: profile::threads::measure(ctx, &b)? }),
        Request::DispatchKernels { kernels } => {
            driver_stats::emit_for_parent(ctx, &kernels)?;
            Ok(Message::Dispatched { kernels: kernels.len() })
        }
        Request::DriverStats(d) => driver_statistics(ctx, validation, d),
        Request::ReproDispatch { dir, hits } => {
            let repro = repro::Repro::read(&dir)?;
            let got = repro::replay::dispatch(ctx, &repro)?;
            crate::rays::write_hits(&hits, &got)?;
            Ok(Message::ReproDispatched { rays: got.len() })
        }
        Request::MakeRepro(spec) => {
            let req = repro::ReproRequest {
                scene: spec.scene,
                rays: spec.rays,
                first: None,
                method: spec.method.into(),
                layout: spec.layout,
                traversal: spec.traversal,
                access: spec.access,
                build: spec.build,
                any_hit: false,
                capture: repro::CaptureChoice::Auto,
                out: spec.out,
            };
            let made = repro::make(ctx, &req, |l| eprintln!("trilab: {l}"))?;
            Ok(Message::ReproMade { summary: made.summary() })
        }
        Request::CompileKernels(c) => {
            Ok(Message::Compiled(driver_stats::compile::compile_kernels(ctx, &c.kernels, c.subgroup_size)?))
        }
        Request::Round | Request::Cell { .. } => Err(Error::Usage(
            "worker: rounds and cells are an ab side's (`__ab-worker WORKLOAD --hits-dir DIR`)".into(),
        )),
        Request::Quit => Err(Error::Usage("worker: quit has no answer".into())),
    }
}

/// What `trilab driver-stats --kernels --variants --methods --layouts` measures, as its rows:
/// none, with the reason, where the driver has no statistics.
fn driver_statistics(ctx: &Context, validation: bool, d: DriverStatsRequest) -> Result<Message> {
    let selection = Selection { kernels: d.kernels, variants: d.variants, methods: d.methods, layouts: d.layouts };
    let kernels = selection.kernels()?;
    eprintln!("  {} kernel variants", kernels.len());
    let o = CollectOptions { exe: this_exe()?, device_index: ctx.info().index, validation, asm_dir: None };
    let report = driver_stats::collect(ctx, &kernels, &o)?;
    let rows = if report.status == Status::Measured { driver_stats::rows(&report) } else { vec![] };
    Ok(Message::DriverStats { status: report.status, note: report.note, rows })
}
