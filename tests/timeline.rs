//! `--timeline FILE` (issue 41, part 3): the timeline `bench`, `suite` and `ab` write as Chrome trace
//! JSON, read back. The file must parse; its complete events have non-negative times and sit
//! inside the run's span, sorted; on each track the spans nest (a viewer draws nothing else
//! right); `bench`'s GPU track holds one dispatch per kernel run, each timed one's duration the
//! kernel time bench.json reports for that run; `ab` has both sides' runs of every cell in every
//! round on their tracks; a suite stopped by SIGTERM writes the parts it ran, the bench part with
//! its planned and actual seconds, and the part under way marked unfinished. A FILE that is a
//! directory, an input or one of the command's own outputs is refused before any work. Every
//! run has a wall-clock limit and the validation layer on.

mod common;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use common::cli::{expect_error, ok, s, trilab};
use serde_json::Value;

/// Timestamps are written to the nanosecond (0.001 us): two that should meet may differ by that.
const EPS_US: f64 = 0.01;

/// A trace file as the tests read it: its complete events, and the tracks by name.
struct Trace {
    json: Value,
    /// `"ph": "X"` events, in the file's order.
    spans: Vec<Value>,
    tracks: BTreeMap<String, u64>,
}

impl Trace {
    fn read(path: &Path) -> Trace {
        let text = std::fs::read(path).unwrap_or_else(|e| panic!("no trace at {}: {e}", path.display()));
        let json: Value = serde_json::from_slice(&text).expect("the trace is JSON");
        let events = json["traceEvents"].as_array().expect("traceEvents is a list").clone();
        assert_eq!(json["displayTimeUnit"], "ms");
        let mut tracks = BTreeMap::new();
        for e in &events {
            assert!(matches!(e["ph"].as_str(), Some("X" | "M")), "an event of an unknown phase: {e}");
            assert!(e["pid"].is_u64() && e["tid"].is_u64(), "{e}");
            if e["ph"] == "M" && e["name"] == "thread_name" {
                let name = e["args"]["name"].as_str().unwrap().to_owned();
                assert!(tracks.insert(name, e["tid"].as_u64().unwrap()).is_none(), "a track named twice: {e}");
            }
        }
        let spans: Vec<Value> = events.into_iter().filter(|e| e["ph"] == "X").collect();
        for e in &spans {
            let (ts, dur) = (e["ts"].as_f64().unwrap(), e["dur"].as_f64().unwrap());
            assert!(ts.is_finite() && ts >= 0.0 && dur.is_finite() && dur >= 0.0, "negative or missing time: {e}");
            assert!(e["name"].is_string() && e["cat"].is_string(), "{e}");
        }
        let ts: Vec<f64> = spans.iter().map(|e| e["ts"].as_f64().unwrap()).collect();
        assert!(ts.windows(2).all(|w| w[0] <= w[1]), "events are not sorted by start");
        Trace { json, spans, tracks }
    }

    fn track(&self, name: &str) -> u64 {
        *self.tracks.get(name).unwrap_or_else(|| panic!("no track `{name}` among {:?}", self.tracks.keys()))
    }

    fn on(&self, track: &str) -> Vec<&Value> {
        let tid = self.track(track);
        self.spans.iter().filter(|e| e["tid"].as_u64() == Some(tid)).collect()
    }

    fn named(&self, name: &str) -> Vec<&Value> {
        self.spans.iter().filter(|e| e["name"] == name).collect()
    }

    /// The one span of the run (category `command`): every other span lies inside it.
    fn run(&self, name: &str) -> &Value {
        let runs: Vec<&Value> = self.spans.iter().filter(|e| e["cat"] == "command").collect();
        assert_eq!(runs.len(), 1, "one run span: {runs:?}");
        assert_eq!(runs[0]["name"], name);
        assert_eq!(runs[0]["tid"].as_u64(), Some(self.track("host")), "the run is on the host track");
        for e in &self.spans {
            assert!(inside(e, runs[0]), "outside the run's span: {e}");
        }
        runs[0]
    }

    /// On every track, two spans either do not overlap or one holds the other.
    fn nests(&self) {
        for (track, &tid) in &self.tracks {
            let on: Vec<&Value> = self.spans.iter().filter(|e| e["tid"].as_u64() == Some(tid)).collect();
            for (i, a) in on.iter().enumerate() {
                for b in &on[i + 1..] {
                    let apart = end(a) <= start(b) + EPS_US || end(b) <= start(a) + EPS_US;
                    assert!(apart || inside(a, b) || inside(b, a), "on track {track}, {a} and {b} overlap");
                }
            }
        }
    }
}

fn start(e: &Value) -> f64 {
    e["ts"].as_f64().unwrap()
}

fn end(e: &Value) -> f64 {
    start(e) + e["dur"].as_f64().unwrap()
}

/// Whether span `e` lies within span `outer`.
fn inside(e: &Value, outer: &Value) -> bool {
    start(e) >= start(outer) - EPS_US && end(e) <= end(outer) + EPS_US
}

/// The median as `Summary::of` takes it (the mean of the middle two of an even count).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

#[test]
fn a_bench_trace_holds_every_dispatch_with_the_kernel_times_bench_reports() {
    let dir = tempfile::tempdir().unwrap();
    // The trace in the --out folder, which is made when missing (so is the trace's).
    let out = dir.path().join("bench");
    let file = out.join("bench.trace.json");
    let repeat = 2;
    let args = [
        "bench",
        "--scenes",
        "bunny",
        "--methods",
        "mt,unit",
        "--width",
        "32",
        "--height",
        "24",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "500",
        "--repeat",
        "2",
        "--out",
        &s(&out),
        "--timeline",
        &s(&file),
    ];
    let err = ok(&trilab(&args, 300));
    assert!(err.contains("trace: ") && err.contains(&s(&file)), "a closing line names the trace: {err}");
    let t = Trace::read(&file);
    let run = t.run("trilab bench");
    t.nests();
    for key in ["command_line", "commit", "device", "driver"] {
        assert!(t.json["otherData"][key].as_str().is_some_and(|v| !v.is_empty()), "otherData.{key}: {}", t.json);
    }
    assert!(t.json["otherData"]["command_line"].as_str().unwrap().contains("--timeline"));
    assert_eq!(run["args"].get("error"), None, "the run succeeded: {run}");

    // The host phases, on the host track, in the run.
    let host = t.on("host");
    for phase in [
        "device context",
        "scene load",
        "BVH build",
        "ray sets",
        "f64 reference",
        "upload every kernel's scene",
        "encode",
        "buffers to device",
        "pipelines",
        "interleaved rounds",
        "validate against the f64 reference",
        "report writing",
    ] {
        assert!(host.iter().any(|e| e["name"] == phase), "no host phase `{phase}` in the trace");
    }
    for compile in ["mt", "unit"] {
        let name = format!("pipeline compile raycast.{compile}.closest");
        assert!(host.iter().any(|e| e["name"] == name.as_str()), "no `{name}`");
    }
    let load = t.named("scene load");
    assert_eq!(load[0]["args"]["triangles"], 69_451, "{}", load[0]);
    // The report is written after the last round.
    let report = t.named("report writing")[0];
    assert!(t.named("interleaved rounds").iter().all(|r| end(r) <= start(report) + EPS_US));

    // Every dispatch on the GPU track, inside the host's cast that submitted it.
    let gpu = t.on("GPU (timestamps, placed at host submit)");
    assert!(gpu.iter().all(|e| e["cat"] == "dispatch"), "only dispatches on the GPU track");
    let casts: Vec<&&Value> = host.iter().filter(|e| e["cat"] == "cast").collect();
    for d in &gpu {
        assert_eq!(d["args"]["duration"], "GPU timestamps", "lavapipe has timestamps: {d}");
        assert!(casts.iter().any(|c| inside(d, c)), "a dispatch outside every cast on the host: {d}");
    }

    // One timed dispatch per timed run of every row bench.json reports, lasting the run's time.
    let bench: Value = serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    let rows = bench["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2 * 3, "2 methods x 3 sets: {bench}");
    let mut timed_total = 0;
    for row in rows {
        let kernel_ms = &row["kernel_ms"];
        let runs = kernel_ms["runs"].as_u64().unwrap() as usize;
        assert_eq!(runs, repeat);
        let of_row = |warm_up: bool| -> Vec<&&Value> {
            gpu.iter()
                .filter(|d| {
                    let a = &d["args"];
                    a["method"] == row["method"]
                        && a["layout"] == row["layout"]
                        && a["traversal"] == row["traversal"]
                        && a["access"] == row["scene_access"]
                        && a["scene"] == row["scene"]
                        && a["set"] == row["ray_set"]
                        && a["warm_up"] == warm_up
                })
                .collect()
        };
        let (timed, warm) = (of_row(false), of_row(true));
        assert_eq!(timed.len(), runs, "timed dispatches of {row}");
        assert_eq!(warm.len(), 1, "one warm-up round: {row}");
        timed_total += timed.len();
        // Rounds 2..=1+repeat after the one warm-up round, each once.
        let mut rounds: Vec<u64> = timed.iter().map(|d| d["args"]["round"].as_u64().unwrap()).collect();
        rounds.sort();
        assert_eq!(rounds, (2..2 + repeat as u64).collect::<Vec<_>>(), "{row}");
        let name = timed[0]["name"].as_str().unwrap();
        for part in ["method", "layout", "ray_set"] {
            assert!(name.contains(row[part].as_str().unwrap()), "dispatch `{name}` names its {part}: {row}");
        }
        // The report's time of a run is its GPU time (plus the host's reordering, nothing for the
        // given order): equal to the dispatches' durations, to rounding.
        let ms: Vec<f64> = timed.iter().map(|d| d["dur"].as_f64().unwrap() / 1e3).collect();
        let close = |a: f64, b: f64| (a - b).abs() <= 0.02 + 1e-6 * b;
        let (lo, hi) = (ms.iter().copied().fold(f64::INFINITY, f64::min), ms.iter().copied().fold(0.0, f64::max));
        for (what, trace, report) in [("min", lo, "min"), ("max", hi, "max"), ("median", median(ms.clone()), "median")]
        {
            let want = kernel_ms[report].as_f64().unwrap();
            assert!(close(trace, want), "{what} of {row}: trace {trace} ms, bench.json {want} ms");
        }
    }
    // No timed dispatch belongs to no row.
    let timed = gpu.iter().filter(|d| d["args"]["warm_up"] == false).count();
    assert_eq!(timed, timed_total);
}

#[test]
fn an_ab_trace_has_each_sides_run_of_every_cell_in_every_round() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("ab.trace.json");
    let rounds = 2;
    let args = [
        "ab",
        "--methods",
        "mt",
        "--sets",
        "primary,random",
        "--width",
        "32",
        "--height",
        "24",
        "--random-rays",
        "500",
        "--rounds",
        "2",
        "--max-rounds",
        "2",
        "--timeline",
        &s(&file),
        "--json",
    ];
    let o = trilab(&args, 300);
    let err = ok(&o);
    let report: Value = serde_json::from_slice(&o.stdout).unwrap();
    let t = Trace::read(&file);
    t.run("trilab ab");
    t.nests();
    let cells = report["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 2, "{report}");
    let host_rounds: Vec<&Value> = t.on("host").into_iter().filter(|e| e["cat"] == "round").collect();
    assert_eq!(host_rounds.len(), rounds, "a host span per round: {err}");
    for side in ["A", "B"] {
        let track = format!("side {side}");
        let on = t.on(&track);
        assert!(on.iter().any(|e| e["name"] == "start: worker setup"), "side {side}'s setup");
        let runs: Vec<&&Value> = on.iter().filter(|e| e["args"]["cell"].is_string()).collect();
        assert_eq!(runs.len(), rounds * cells.len(), "side {side}: a span per cell and round");
        for r in &runs {
            assert_eq!(r["args"]["side"], side, "{r}");
            assert!(r["args"]["kernel_ms"].as_f64().is_some_and(|ms| ms > 0.0), "the worker's time: {r}");
            // Inside the host's span of its round.
            let round = r["args"]["round"].as_u64().unwrap() as usize;
            assert!((1..=rounds).contains(&round), "{r}");
            assert!(inside(r, host_rounds[round - 1]), "{r} outside round {round}");
        }
        for round in 1..=rounds as u64 {
            let mut named: Vec<&str> = runs
                .iter()
                .filter(|r| r["args"]["round"] == round)
                .map(|r| r["args"]["cell"].as_str().unwrap())
                .collect();
            named.sort();
            named.dedup();
            assert_eq!(named.len(), cells.len(), "side {side}, round {round}: every cell once");
        }
    }
}

/// A suite stopped by SIGTERM during its study: the trace holds the probe and the bench part,
/// with the bench's planned and actual seconds, and the study and the run as far as they got.
#[test]
fn a_stopped_suite_writes_the_trace_of_its_parts_so_far() {
    let dir = tempfile::tempdir().unwrap();
    let (out, file) = (dir.path().join("suite"), dir.path().join("suite.trace.json"));
    let args = [
        "suite",
        "--size",
        "0",
        "--parts",
        "bench,study",
        "--no-threads",
        "--no-driver-stats",
        "--out",
        &s(&out),
        "--timeline",
        &s(&file),
    ];
    let mut r = common::running::Running::start(common::cli::command(&args, None, &[]));
    r.wait_for_line("suite: study:", Duration::from_secs(400));
    let (status, err) = r.signal_and_wait(libc::SIGTERM, Duration::from_secs(60));
    assert_eq!(status.code(), Some(128 + libc::SIGTERM), "{err}");
    assert!(err.contains("trace of the run so far") && err.contains("unfinished"), "{err}");
    let t = Trace::read(&file);
    let run = t.run("trilab suite");
    assert_eq!(run["args"]["unfinished"], true, "the run was stopped: {run}");
    t.nests();
    let part = |name: &str| -> &Value {
        let p = t.named(name);
        assert_eq!(p.len(), 1, "one span `{name}`");
        assert_eq!(p[0]["cat"], "part");
        p[0]
    };
    let (probe, bench, study) = (part("probe (a small bench)"), part("part bench"), part("part study"));
    assert!(end(probe) <= start(bench) + EPS_US && end(bench) <= start(study) + EPS_US, "in order");
    // The bench part: planned against actual, and its work inside it.
    let a = &bench["args"];
    for key in ["share_s", "predicted_s", "took_s"] {
        assert!(a[key].as_f64().is_some_and(|v| v >= 0.0), "bench part's {key}: {bench}");
    }
    assert_eq!(a["completed"], true);
    assert_eq!(a["size_step"], 0, "--size 0");
    assert_eq!(a.get("unfinished"), None);
    // took_s is the span's own length (the part's clock starts and stops around it).
    let took_us = a["took_s"].as_f64().unwrap() * 1e6;
    assert!(took_us <= bench["dur"].as_f64().unwrap() + EPS_US, "{bench}");
    let bench_dispatches =
        t.on("GPU (timestamps, placed at host submit)").into_iter().filter(|d| inside(d, bench)).count();
    assert!(bench_dispatches > 0, "the bench part's dispatches");
    // The study was stopped under way.
    assert_eq!(study["args"]["unfinished"], true, "{study}");
    assert_eq!(study["args"].get("took_s"), None);
}

/// A one-triangle scene in `dir`.
fn scene_file(dir: &tempfile::TempDir) -> std::path::PathBuf {
    let scene = dir.path().join("tri.obj");
    std::fs::write(&scene, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    scene
}

#[test]
fn a_trace_file_that_is_a_folder_an_input_or_an_output_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let folder = s(dir.path());
    let small = ["--methods", "mt", "--width", "8", "--height", "8", "--random-rays", "10"];
    // A folder, for each command that takes --timeline.
    for command in [&["bench"][..], &["suite", "--size", "0"], &["ab", "--rounds", "2"]] {
        let args: Vec<&str> = [command, &["--timeline", &folder]].concat();
        let e = expect_error(&trilab(&args, 60), &["--timeline", &folder, "directory"]);
        assert!(!e.contains("bunny:"), "refused before any work: {e}");
    }
    // `--trace`, the option's name before issue 52, is the same option.
    expect_error(&trilab(&["bench", "--trace", &folder], 60), &["--timeline", &folder, "directory"]);
    // An input: the scene it reads.
    let scene = s(&scene_file(&dir));
    let args: Vec<&str> = [&["bench", "--scenes", &scene, "--timeline", &scene][..], &small].concat();
    expect_error(&trilab(&args, 60), &["--timeline", "input"]);
    assert!(
        std::fs::read_to_string(dir.path().join("tri.obj")).unwrap().starts_with("v 0 0 0"),
        "the input is untouched"
    );
    // One of its own outputs: bench.json in --out.
    let out = dir.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let (dir_arg, json) = (s(&out), s(&out.join("bench.json")));
    let args: Vec<&str> = [&["bench", "--out", &dir_arg, "--timeline", &json][..], &small].concat();
    expect_error(&trilab(&args, 60), &["--timeline", &json, "output"]);
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0, "nothing written");
    // A folder that cannot be made: under a file.
    let under = s(&scene_file(&dir).join("t.json"));
    let args: Vec<&str> = [&["bench", "--timeline", &under][..], &small].concat();
    expect_error(&trilab(&args, 60), &["--timeline", "not a folder"]);
}
