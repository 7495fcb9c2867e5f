//! A timeline of a run, written as Chrome trace JSON (`--timeline FILE` on `bench`, `suite` and
//! `ab`; it opens in Perfetto's UI, https://ui.perfetto.dev, and in chrome://tracing).
//!
//! One recorder per process, off unless a command turns it on ([`start`]): every call below is
//! then one relaxed atomic load and nothing else, so the layers record without being handed a
//! sink (the scene loader, the BVH build, the f64 reference, uploads, pipeline compiles and every
//! ray-casting dispatch record themselves, whichever command drives them). Ground floor: it
//! imports only [`crate::io`] and [`crate::error`].
//!
//! What it records:
//! - **spans** ([`span`], [`span_on`]): complete events (`"ph":"X"`), `ts` and `dur` in
//!   microseconds since [`start`], on the calling thread's track or on a named one ("side A");
//!   a span still open when the file is written (a run stopped by a signal) is written as far as
//!   it got, with `"unfinished": true` in its args;
//! - **timed events** placed by the caller ([`complete`]): the GPU track's dispatches, placed at
//!   the host time of their submit with the duration the GPU's timestamps give;
//! - **labels** ([`labels`]): what the caller is doing (the scene, the ray set, the round, the
//!   kernel's method and layout), kept per thread while a guard lives, and attached by the lower
//!   layers to the events they record (a dispatch does not know which round it is in);
//! - metadata (`"ph":"M"`): the process's and each track's name, the tracks in a fixed order.

use std::borrow::Cow;
use std::cell::RefCell;
use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::thread::ThreadId;
use std::time::Instant;

use serde::Serialize;

use crate::error::{Error, Result};

/// The track of the GPU's dispatches (placed at host submit time, GPU-timestamp durations).
pub const GPU: &str = "GPU (timestamps, placed at host submit)";

/// Whether a recorder is on: the one load every call makes first.
static ON: AtomicBool = AtomicBool::new(false);

static RECORDER: Mutex<Option<Recorder>> = Mutex::new(None);

/// The next span's id.
static NEXT_SPAN: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// The labels of what this thread is doing, outermost first ([`labels`]).
    static LABELS: RefCell<Vec<(&'static str, Arg)>> = const { RefCell::new(Vec::new()) };
}

/// Whether a trace is being recorded. Callers that must do work to describe an event (format
/// a name, read timestamps they would otherwise skip) ask first.
#[inline]
pub fn on() -> bool {
    ON.load(Ordering::Relaxed)
}

/// An event argument: a number, a flag, text, or a list of numbers.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Arg {
    Bool(bool),
    Int(i64),
    Num(f64),
    Text(String),
    Nums(Vec<f64>),
}

impl From<bool> for Arg {
    fn from(v: bool) -> Arg {
        Arg::Bool(v)
    }
}

impl From<usize> for Arg {
    fn from(v: usize) -> Arg {
        Arg::Int(v as i64)
    }
}

impl From<u32> for Arg {
    fn from(v: u32) -> Arg {
        Arg::Int(v.into())
    }
}

impl From<u64> for Arg {
    fn from(v: u64) -> Arg {
        Arg::Int(v as i64)
    }
}

impl From<f64> for Arg {
    fn from(v: f64) -> Arg {
        Arg::Num(v)
    }
}

impl From<&str> for Arg {
    fn from(v: &str) -> Arg {
        Arg::Text(v.to_owned())
    }
}

impl From<String> for Arg {
    fn from(v: String) -> Arg {
        Arg::Text(v)
    }
}

impl From<Vec<f64>> for Arg {
    fn from(v: Vec<f64>) -> Arg {
        Arg::Nums(v)
    }
}

impl std::fmt::Display for Arg {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Arg::Bool(b) => write!(f, "{b}"),
            Arg::Int(i) => write!(f, "{i}"),
            Arg::Num(x) => write!(f, "{x}"),
            Arg::Text(s) => f.write_str(s),
            Arg::Nums(v) => write!(f, "{v:?}"),
        }
    }
}

/// One trace event as the file holds it.
#[derive(Clone, Debug, Serialize)]
struct Event {
    name: String,
    #[serde(skip_serializing_if = "str::is_empty")]
    cat: &'static str,
    ph: &'static str,
    /// Microseconds since the recorder started (absent from metadata).
    #[serde(skip_serializing_if = "Option::is_none")]
    ts: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    dur: Option<f64>,
    pid: u32,
    tid: u32,
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    args: BTreeMap<String, Arg>,
}

/// A span not yet closed.
struct Open {
    tid: u32,
    cat: &'static str,
    name: String,
    start: Instant,
    args: BTreeMap<String, Arg>,
}

struct Recorder {
    start: Instant,
    process: String,
    pid: u32,
    /// Track names; track `i` is thread id `i + 1`.
    tracks: Vec<String>,
    /// The thread that started the recorder (its track is "host").
    host: ThreadId,
    threads: HashMap<ThreadId, u32>,
    events: Vec<Event>,
    open: BTreeMap<u64, Open>,
    other: BTreeMap<String, String>,
}

impl Recorder {
    /// Microseconds from the start to `t`, to the nanosecond (0 for a time before the start).
    fn us(&self, t: Instant) -> f64 {
        t.saturating_duration_since(self.start).as_nanos() as f64 / 1e3
    }

    fn named_track(&mut self, name: &str) -> u32 {
        match self.tracks.iter().position(|t| t == name) {
            Some(i) => i as u32 + 1,
            None => {
                self.tracks.push(name.to_owned());
                self.tracks.len() as u32
            }
        }
    }

    /// The calling thread's track: "host" for the thread that started the recorder, else the
    /// thread's name.
    fn this_thread(&mut self) -> u32 {
        let me = std::thread::current();
        if let Some(&tid) = self.threads.get(&me.id()) {
            return tid;
        }
        let name = match me.id() == self.host {
            true => "host".to_owned(),
            false => format!("host thread {}", me.name().unwrap_or("(unnamed)")),
        };
        self.tracks.push(name);
        let tid = self.tracks.len() as u32;
        self.threads.insert(me.id(), tid);
        tid
    }

    fn close(&mut self, id: u64, end: Instant, unfinished: bool) {
        let Some(mut o) = self.open.remove(&id) else { return };
        if unfinished {
            o.args.insert("unfinished".into(), Arg::Bool(true));
        }
        let ts = self.us(o.start);
        let dur = (self.us(end) - ts).max(0.0);
        let (pid, tid) = (self.pid, o.tid);
        self.events.push(Event {
            name: o.name,
            cat: o.cat,
            ph: "X",
            ts: Some(ts),
            dur: Some(dur),
            pid,
            tid,
            args: o.args,
        });
    }
}

fn recorder() -> MutexGuard<'static, Option<Recorder>> {
    // A thread that panicked while recording leaves the events as they were: still worth writing.
    RECORDER.lock().unwrap_or_else(|e| e.into_inner())
}

/// Starts recording (anew, dropping anything recorded before) for the process named `process`
/// in the viewer (`trilab bench`). The calling thread's track is "host", the first; the others
/// (the GPU's, a side's, another thread's) follow in the order they are first used.
pub fn start(process: &str) {
    let mut r = recorder();
    let me = std::thread::current().id();
    *r = Some(Recorder {
        start: Instant::now(),
        process: process.to_owned(),
        pid: std::process::id(),
        tracks: vec!["host".into()],
        host: me,
        threads: [(me, 1)].into(),
        events: vec![],
        open: BTreeMap::new(),
        other: BTreeMap::new(),
    });
    ON.store(true, Ordering::Relaxed);
}

/// Adds `key: value` to the file's `otherData` (device, driver, commit, command line).
pub fn set_other(key: &str, value: impl Into<String>) {
    if !on() {
        return;
    }
    if let Some(r) = recorder().as_mut() {
        r.other.insert(key.to_owned(), value.into());
    }
}

/// An open span; it is recorded (a complete event) when dropped. Free when not recording.
#[must_use = "a span is recorded when dropped: bind it to a variable for the work it covers"]
pub struct Span(Option<u64>);

/// Opens a span named `name` in category `cat` on the calling thread's track.
pub fn span(cat: &'static str, name: impl Into<Cow<'static, str>>) -> Span {
    if !on() {
        return Span(None);
    }
    open(None, cat, name.into())
}

/// [`span`] with a name made only when recording.
pub fn span_with(cat: &'static str, name: impl FnOnce() -> String) -> Span {
    if !on() {
        return Span(None);
    }
    open(None, cat, name().into())
}

/// Opens a span on the named track `track` (created on first use: "side A").
pub fn span_on(track: &str, cat: &'static str, name: impl Into<Cow<'static, str>>) -> Span {
    if !on() {
        return Span(None);
    }
    open(Some(track), cat, name.into())
}

fn open(track: Option<&str>, cat: &'static str, name: Cow<'static, str>) -> Span {
    let start = Instant::now();
    let mut r = recorder();
    let Some(r) = r.as_mut() else { return Span(None) };
    let tid = match track {
        Some(t) => r.named_track(t),
        None => r.this_thread(),
    };
    // Ids are the process's, so a span left open by an earlier recording never closes one of
    // a later one.
    let id = NEXT_SPAN.fetch_add(1, Ordering::Relaxed);
    r.open.insert(id, Open { tid, cat, name: name.into_owned(), start, args: BTreeMap::new() });
    Span(Some(id))
}

impl Span {
    /// Adds an argument (shown in the viewer's details of the event).
    pub fn arg(&self, key: &str, value: impl Into<Arg>) {
        let Some(id) = self.0 else { return };
        if let Some(o) = recorder().as_mut().and_then(|r| r.open.get_mut(&id)) {
            o.args.insert(key.to_owned(), value.into());
        }
    }

    /// [`Span::arg`], for a span opened in the same expression.
    pub fn with(self, key: &str, value: impl Into<Arg>) -> Span {
        self.arg(key, value);
        self
    }

    /// Whether the span records anything (a recorder was on when it opened).
    pub fn records(&self) -> bool {
        self.0.is_some()
    }
}

impl Drop for Span {
    fn drop(&mut self) {
        let Some(id) = self.0 else { return };
        let end = Instant::now();
        if let Some(r) = recorder().as_mut() {
            r.close(id, end, false);
        }
    }
}

/// Records a complete event placed by the caller: on `track`, from `at` (host clock) for `dur_ms`
/// milliseconds however they were measured (the GPU's dispatches: their timestamps), with the
/// calling thread's [`labels`] and then `args`.
pub fn complete(track: &str, cat: &'static str, name: &str, at: Instant, dur_ms: f64, args: Vec<(&str, Arg)>) {
    if !on() {
        return;
    }
    let labels = current_labels();
    let mut r = recorder();
    let Some(r) = r.as_mut() else { return };
    let tid = r.named_track(track);
    let mut all: BTreeMap<String, Arg> = labels.into_iter().map(|(k, v)| (k.to_owned(), v)).collect();
    all.extend(args.into_iter().map(|(k, v)| (k.to_owned(), v)));
    let dur = ((dur_ms * 1e3).max(0.0) * 1e3).round() / 1e3;
    let ts = r.us(at);
    let pid = r.pid;
    r.events.push(Event { name: name.to_owned(), cat, ph: "X", ts: Some(ts), dur: Some(dur), pid, tid, args: all });
}

/// The labels of what the calling thread is doing, set by [`labels`] guards, outermost first.
pub fn current_labels() -> Vec<(&'static str, Arg)> {
    if !on() {
        return vec![];
    }
    LABELS.with(|l| l.borrow().clone())
}

/// The value of the calling thread's innermost label `key`.
pub fn label(key: &str) -> Option<Arg> {
    if !on() {
        return None;
    }
    LABELS.with(|l| l.borrow().iter().rev().find(|(k, _)| *k == key).map(|(_, v)| v.clone()))
}

/// Labels what the calling thread does while the guard lives (`f` is called only when
/// recording): the events lower layers record meanwhile carry them in their args.
pub fn labels(f: impl FnOnce() -> Vec<(&'static str, Arg)>) -> Labels {
    if !on() {
        return Labels(0);
    }
    let add = f();
    let n = add.len();
    LABELS.with(|l| l.borrow_mut().extend(add));
    Labels(n)
}

/// The guard of [`labels`]: removes its labels when dropped.
#[must_use = "labels hold while the guard lives"]
pub struct Labels(usize);

impl Drop for Labels {
    fn drop(&mut self) {
        if self.0 == 0 {
            return;
        }
        LABELS.with(|l| {
            let mut l = l.borrow_mut();
            let keep = l.len().saturating_sub(self.0);
            l.truncate(keep);
        });
    }
}

/// What a written trace holds, for the command's closing line.
#[derive(Clone, Debug, PartialEq)]
pub struct Written {
    /// Events, metadata included.
    pub events: usize,
    /// Seconds from the first event's start to the last one's end.
    pub span_s: f64,
    /// Spans still open when it was written (a stopped run).
    pub unfinished: usize,
}

impl std::fmt::Display for Written {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} events over {:.1} s", self.events, self.span_s)?;
        if self.unfinished > 0 {
            write!(f, ", {} span(s) unfinished", self.unfinished)?;
        }
        Ok(())
    }
}

/// The file: `{"traceEvents": [...], "displayTimeUnit": "ms", "otherData": {...}}`.
#[derive(Serialize)]
#[allow(non_snake_case)]
struct TraceFile<'a> {
    traceEvents: &'a [Event],
    displayTimeUnit: &'static str,
    otherData: &'a BTreeMap<String, String>,
}

/// Stops recording and writes the trace to `path` atomically: every event sorted by its start
/// (the longer first where two start together, so the enclosing one comes first), after the
/// metadata naming the process and the tracks. Spans still open (a run a signal stopped) are
/// closed now and marked `unfinished`. An error when nothing was recording.
pub fn finish(path: &Path) -> Result<Written> {
    let end = Instant::now();
    ON.store(false, Ordering::Relaxed);
    let Some(mut r) = recorder().take() else {
        return Err(Error::Usage(format!("--timeline {}: nothing was recorded", path.display())));
    };
    let open: Vec<u64> = r.open.keys().copied().collect();
    let unfinished = open.len();
    for id in open {
        r.close(id, end, true);
    }
    let mut events = std::mem::take(&mut r.events);
    events.sort_by(|a, b| {
        let (ta, tb) = (a.ts.unwrap_or(0.0), b.ts.unwrap_or(0.0));
        ta.total_cmp(&tb).then(b.dur.unwrap_or(0.0).total_cmp(&a.dur.unwrap_or(0.0)))
    });
    let first = events.iter().filter_map(|e| e.ts).fold(f64::INFINITY, f64::min);
    let last = events.iter().filter_map(|e| Some(e.ts? + e.dur?)).fold(f64::NEG_INFINITY, f64::max);
    let meta = |name: &str, tid: u32, key: &str, value: Arg| Event {
        name: name.to_owned(),
        cat: "",
        ph: "M",
        ts: None,
        dur: None,
        pid: r.pid,
        tid,
        args: [(key.to_owned(), value)].into(),
    };
    let mut all = vec![meta("process_name", 0, "name", Arg::Text(r.process.clone()))];
    for (i, t) in r.tracks.iter().enumerate() {
        let tid = i as u32 + 1;
        all.push(meta("thread_name", tid, "name", Arg::Text(t.clone())));
        all.push(meta("thread_sort_index", tid, "sort_index", Arg::Int(tid.into())));
    }
    all.extend(events);
    let mut other = r.other.clone();
    other.insert(
        "clock".into(),
        format!(
            "ts and dur in microseconds since the trace started (host clock); on the `{GPU}` track each dispatch \
             starts at the host time of its first submit and lasts what the GPU's timestamps measured (the host's \
             wall time where the device has none, as its args say)"
        ),
    );
    let file = TraceFile { traceEvents: &all, displayTimeUnit: "ms", otherData: &other };
    let bytes =
        serde_json::to_vec(&file).map_err(|e| Error::Usage(format!("--timeline: cannot encode the trace: {e}")))?;
    crate::io::write_atomic(path, &bytes)?;
    let span_s = if last > first { (last - first) / 1e6 } else { 0.0 };
    Ok(Written { events: all.len(), span_s, unfinished })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file as a viewer reads it.
    #[derive(serde::Deserialize)]
    #[serde(rename_all = "camelCase")]
    struct ReadFile {
        trace_events: Vec<ReadEvent>,
        display_time_unit: String,
        other_data: BTreeMap<String, String>,
    }

    #[derive(Debug, serde::Deserialize)]
    struct ReadEvent {
        name: String,
        ph: String,
        ts: Option<f64>,
        dur: Option<f64>,
        tid: u32,
        #[serde(default)]
        args: BTreeMap<String, Arg>,
    }

    /// One test, so that no other test of this binary records meanwhile (the recorder is the
    /// process's).
    #[test]
    fn spans_labels_and_placed_events_are_written_sorted_and_nested() {
        // Off: nothing is recorded and nothing is called.
        assert!(!on());
        let s = span("phase", "ignored");
        assert!(!s.records());
        drop(s);
        let _l = labels(|| panic!("labels are not made when off"));
        drop(_l);

        start("trilab test");
        let outer = span("command", "run");
        {
            let _set = labels(|| vec![("set", "primary".into()), ("round", 2usize.into())]);
            let inner = span("phase", "BVH build").with("triangles", 12usize);
            inner.arg("leaf", 4u32);
            let at = Instant::now();
            complete(GPU, "dispatch", "mt bvh2", at, 1.5, vec![("batches", 1usize.into())]);
            assert_eq!(label("round"), Some(Arg::Int(2)));
        }
        assert_eq!(label("round"), None, "a label ends with its guard");
        let side = span_on("side A", "ab", "cell");
        let open = span("phase", "never closed");
        drop(side);
        std::mem::forget(open);
        set_other("device", "test device");
        drop(outer);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.json");
        let w = finish(&path).unwrap();
        assert!(!on());
        assert_eq!(w.unfinished, 1);

        let file: ReadFile = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(file.display_time_unit, "ms");
        assert_eq!(file.other_data["device"], "test device");
        let events = &file.trace_events;
        assert_eq!(w.events, events.len());
        // (Other tests of this binary, on other threads, may record meanwhile: only this
        // test's events are looked for.)
        let x: Vec<&ReadEvent> = events.iter().filter(|e| e.ph == "X").collect();
        for name in ["run", "BVH build", "mt bvh2", "cell", "never closed"] {
            assert_eq!(x.iter().filter(|e| e.name == name).count(), 1, "{name}: {x:?}");
        }
        let ts: Vec<f64> = x.iter().map(|e| e.ts.unwrap()).collect();
        assert!(ts.windows(2).all(|w| w[0] <= w[1]), "sorted: {ts:?}");
        let by = |name: &str| *x.iter().find(|e| e.name == name).unwrap();
        let (run, bvh, gpu) = (by("run"), by("BVH build"), by("mt bvh2"));
        let end = |e: &ReadEvent| e.ts.unwrap() + e.dur.unwrap();
        assert!(run.ts <= bvh.ts && end(bvh) <= end(run));
        assert_eq!(bvh.args["triangles"], Arg::Int(12));
        assert_eq!(bvh.args["leaf"], Arg::Int(4));
        // The placed event carries the labels around it, and its given duration.
        assert_eq!(gpu.dur, Some(1500.0));
        assert_eq!(gpu.args["set"], Arg::Text("primary".into()));
        assert_eq!(gpu.args["round"], Arg::Int(2));
        assert_eq!(gpu.args["batches"], Arg::Int(1));
        assert_eq!(by("never closed").args["unfinished"], Arg::Bool(true));
        // Tracks: host, GPU, side A, named in metadata; the events sit on them.
        let track = |name: &str| {
            let named = |e: &&ReadEvent| e.ph == "M" && e.name == "thread_name" && e.args["name"] == name.into();
            events.iter().find(named).map(|e| e.tid).unwrap_or_else(|| panic!("no track {name}"))
        };
        assert_eq!(run.tid, track("host"));
        assert_eq!(gpu.tid, track(GPU));
        assert_eq!(by("cell").tid, track("side A"));
        assert!(events.iter().any(|e| e.name == "process_name" && e.args["name"] == "trilab test".into()));
        // Nothing records after finishing, and finishing twice says so.
        assert!(!span("phase", "late").records());
        assert!(finish(&path).is_err());
    }
}
