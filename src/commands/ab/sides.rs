//! The two sides' workers: each started in its own process, driver and environment
//! ([`super::worker`], a session of the worker service), ready with its cells, asked for its
//! runs and ended; the shader cache it starts with, and its track in the trace.

use std::ffi::OsString;
use std::path::{Path, PathBuf};

use super::options::{AbOptions, Side};
use super::progress::set_stage;
use super::report::{side_label, SideReport};
use super::worker::{self, CellInfo, CellRound, Message, Request, Workload};
use crate::error::{Error, Result};
use crate::services::worker::protocol::SESSION_COMMAND;
use crate::services::worker::{quote, Launch, Session};

/// A running side: its worker ([`worker`], a session of the worker service) and the folder
/// its cells' first-round hits go to.
pub(super) struct Worker {
    pub(super) session: Session,
    hits_dir: PathBuf,
}

impl Worker {
    fn start(o: &AbOptions, w: &Workload, name: &'static str, side: &Side, dir: &Path) -> Result<Worker> {
        let hits_dir = dir.join(name);
        std::fs::create_dir_all(&hits_dir).map_err(|e| Error::io(&hits_dir, e))?;
        let mut args: Vec<OsString> = vec![SESSION_COMMAND.into()];
        let w = Workload { runs_layout: side.layout, ..w.clone() };
        args.extend(w.args().into_iter().map(OsString::from));
        args.extend([OsString::from("--hits-dir"), hits_dir.clone().into()]);
        let launch = Launch {
            timeout: Some(crate::services::worker::session_timeout()),
            ..side.launch(&o.exe).validation(o.validation)
        };
        let session = Session::start(&launch, format!("side {name}"), &args)?.speaking("an ab message");
        Ok(Worker { session, hits_dir })
    }

    pub(super) fn fail(&mut self, what: &str, when: &str) -> Error {
        self.session.fail(what, when)
    }

    fn next(&mut self, when: &str) -> Result<Message> {
        self.session.next(when)
    }

    /// Asks for one run of cell `i` (protocol 2).
    pub(super) fn cell(&mut self, i: usize, when: &str) -> Result<CellRound> {
        match self.session.ask(&Request::Cell { index: i }, when)? {
            Message::Round { mut cells } if cells.len() == 1 => Ok(cells.remove(0)),
            other => Err(self.fail(&format!("expected cell {i}'s round, got {}", quote(&format!("{other:?}"))), when)),
        }
    }

    /// Asks the worker to end and waits for it (killing it past the timeout); its stderr.
    fn finish(self) -> String {
        self.session.finish()
    }
}

/// Starts side A, then side B, each until it says it is ready (`progress` names each step). A
/// side that does not start ends the run; the side started before it is dropped, which ends its
/// worker.
pub(super) fn start_both(
    o: &AbOptions,
    w: &Workload,
    dir: &Path,
    progress: &mut impl FnMut(&str),
) -> Result<[Ready; 2]> {
    let mut ready = vec![];
    for (name, side) in [("A", &o.a), ("B", &o.b)] {
        progress(&format!("side {name}: starting ({})", side.describe()));
        set_stage(format!("side {name}'s start"));
        let starting = crate::timeline::span_on(side_track(name), "ab", "start: worker setup");
        let r = start_side(o, w, name, side, dir)?;
        if starting.records() {
            starting.arg("setup_ms", r.report.setup_ms);
            starting.arg("cells", r.cells.len());
            starting.arg("side", side.describe());
        }
        drop(starting);
        progress(&format!(
            "side {name}: {} ready, {} cells, setup {:.1} s (shader cache {})",
            side_label(&r.report),
            r.cells.len(),
            r.report.setup_ms / 1e3,
            r.report.shader_cache
        ));
        ready.push(r);
    }
    let b = ready.pop().expect("two sides");
    let a = ready.pop().expect("two sides");
    Ok([a, b])
}

/// Ends both sides' workers, each waited for (killed past the timeout); the folders their
/// cells' first-round hits went to.
pub(super) fn finish_both([a, b]: [Worker; 2]) -> [PathBuf; 2] {
    let dirs = [a.hits_dir.clone(), b.hits_dir.clone()];
    let ending = crate::timeline::span("ab", "the workers end");
    a.finish();
    b.finish();
    drop(ending);
    dirs
}

/// A started side that said it is ready.
pub(super) struct Ready {
    pub(super) worker: Worker,
    pub(super) cells: Vec<CellInfo>,
    pub(super) report: SideReport,
    pub(super) invocations: Vec<Option<u64>>,
    pub(super) invocations_note: Option<String>,
}

fn start_side(o: &AbOptions, w: &Workload, name: &'static str, side: &Side, dir: &Path) -> Result<Ready> {
    let cache = shader_cache(&side.env);
    let mut worker = Worker::start(o, w, name, side, dir)?;
    let when = "while it set up (before its first round)";
    let ready = worker.next(when)?;
    let Message::Ready { protocol, provenance, cells, pipeline_ms, invocations, invocations_note } = ready else {
        return Err(worker
            .fail(&format!("the worker's first message was not `ready` but {}", quote(&format!("{ready:?}"))), when));
    };
    if protocol > worker::PROTOCOL {
        return Err(worker.fail(
            &format!(
                "its trilab ({}) speaks ab protocol {protocol}, this one {} (run ab from the newer build)",
                side.exe(&o.exe).display(),
                worker::PROTOCOL
            ),
            when,
        ));
    }
    if invocations.len() != cells.len() {
        return Err(worker.fail(
            &format!("the worker's `ready` names {} cells but {} invocation counts", cells.len(), invocations.len()),
            when,
        ));
    }
    // Its requests from now on in the words of its protocol (an older build's: `cell N`).
    worker.session.speaks_protocol(protocol);
    let report = SideReport {
        name,
        given: side.clone(),
        exe: side.exe(&o.exe).to_owned(),
        protocol,
        provenance,
        shader_cache: cache,
        setup_ms: pipeline_ms,
        rounds: 0,
    };
    Ok(Ready { worker, cells, report, invocations, invocations_note })
}

/// Whether Mesa's on-disk shader cache held anything for this side's environment.
fn shader_cache(env: &[(String, String)]) -> String {
    let get =
        |k: &str| env.iter().rev().find(|(n, _)| n == k).map(|(_, v)| v.clone()).or_else(|| std::env::var(k).ok());
    if get("MESA_SHADER_CACHE_DISABLE").is_some_and(|v| matches!(v.trim(), "1" | "true" | "yes")) {
        return "disabled".into();
    }
    let dir = get("MESA_SHADER_CACHE_DIR").map(PathBuf::from).or_else(|| {
        get("XDG_CACHE_HOME")
            .map(|x| PathBuf::from(x).join("mesa_shader_cache"))
            .or_else(|| get("HOME").map(|h| PathBuf::from(h).join(".cache/mesa_shader_cache")))
    });
    let holds = |d: &Path| std::fs::read_dir(d).is_ok_and(|mut e| e.next().is_some());
    match dir {
        Some(d) if holds(&d) || holds(&PathBuf::from(format!("{}_db", d.display()))) => "warm".into(),
        Some(_) => "cold".into(),
        None => "unknown".into(),
    }
}

/// The trace's track of side `name` ("A" or "B").
pub(super) fn side_track(name: &str) -> &'static str {
    if name == "A" {
        "side A"
    } else {
        "side B"
    }
}
