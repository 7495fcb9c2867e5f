//! `trilab bench --embree/--tinybvh` with fake peer programs (shell scripts written here): each
//! peer (each of Embree's calls, each tinybvh layout) is started once in every one of bench's rounds, rotating with trilab's kernels (the
//! fakes log every start, so the order is checked), and its rounds' median, min and max are set
//! beside trilab's best row with the ratios and the speed target; a peer whose hits disagree
//! with the f64 reference is reported as failing, never timed; an OpenCL layout without OpenCL
//! is skipped with a note; a missing program, a garbage line or a crash is an error naming the
//! program and layout, before the long work when the probe finds it, and in the rounds when it
//! starts there; an Embree packet width the library does not run is an error naming the call.
//! The correct fakes get their hits from `trilab raycast` itself, so they are right by
//! construction, not by copying a value from the code under test. Every run has a wall-clock
//! limit and validation on. The real `embree_rays` (all three calls) is run by an ignored test.

mod common;

use std::path::{Path, PathBuf};

use common::cli::{expect_error, ok, s};
use serde_json::Value;

/// The small bench every test runs: the bunny, one method, tiny ray sets, one timed run.
const SMALL: &[&str] = &[
    "bench",
    "--scenes",
    "bunny",
    "--methods",
    "mt",
    "--width",
    "16",
    "--height",
    "12",
    "--diffuse-per-hit",
    "1",
    "--random-rays",
    "500",
];

/// Writes an executable shell script `name` into `dir`.
fn script(dir: &Path, name: &str, body: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, format!("#!/bin/sh\nset -e\n{body}")).unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    p
}

/// `trilab raycast` as a peer would trace: the right hits for `$rays` on `$scene` into `$hits`.
fn raycast_line(scene: &str, rays: &str, hits: &str) -> String {
    format!(
        "'{}' raycast --scene \"{scene}\" --rays \"{rays}\" --out \"{hits}\" --method mt >/dev/null 2>&1\n",
        env!("CARGO_BIN_EXE_trilab")
    )
}

/// The shell lines that append `NAME RAYS-FILE REPEAT RATE` to `peers.log` beside the script
/// (RATE: `$rate`, which they set first, from the count of lines already there: `BASE + k % 3`
/// plus `.FRAC`, so a peer's rounds differ).
fn log_line(name: &str, rays: &str, repeat: &str, base: u32, frac: &str) -> String {
    format!(
        "log=\"$(dirname \"$0\")/peers.log\"\nk=$(cat \"$log\" 2>/dev/null | wc -l)\n\
         rate=\"$(( {base} + k % 3 )).{frac}\"\necho \"{name} $(basename \"{rays}\") {repeat} $rate\" >> \"$log\"\n"
    )
}

/// A fake `embree_rays trace|trace8|trace16 OBJ RAYS HITS REPEAT`: right hits, Embree's line
/// (`embree3 default`, `embree3 packet8`, `embree3 packet16`) at 3.25, 4.25 or 5.25 Mrays/s, logged
/// as `embree3`, `packet8` or `packet16`.
fn fake_embree(dir: &Path) -> PathBuf {
    let body = format!(
        "case \"$1\" in trace) api=embree3; word=default ;; trace8) api=packet8; word=$api ;; \
         trace16) api=packet16; word=$api ;; *) echo \"unknown mode $1\" >&2; exit 2 ;; esac\n\
         n=$(( $(wc -c < \"$3\") / 32 ))\n{}{}\
         echo \"embree3 $word threads=2 tris=1 rays=$n hits=0 build_ms=1.0 best_s=0.001 mrays_per_s=$rate\"\n",
        raycast_line("$2", "$3", "$4"),
        log_line("$api", "$3", "$5", 3, "25")
    );
    script(dir, "embree_rays", &body)
}

/// A fake `tinybvh_rays trace LAYOUT OBJ RAYS HITS REPEATS`: `cpu-bvh8` right at 2.50, 3.50 or
/// 4.50 Mrays/s (its `median_ms`, which bench reads first, the same time to 17 digits), `ocl-bvh2` wrong (every ray "hits" triangle 0 at t = 0), `ocl-cwbvh` without
/// OpenCL; every start logged.
fn fake_tinybvh(dir: &Path) -> PathBuf {
    let body = format!(
        "n=$(( $(wc -c < \"$4\") / 32 ))\n{}\
         case \"$2\" in\n\
         ocl-cwbvh) echo 'no OpenCL device' >&2; exit 3 ;;\n\
         ocl-bvh2) head -c $(( n * 16 )) /dev/zero > \"$5\" ;;\n\
         *) {} ;;\n\
         esac\n\
         ms=$(awk -v n=$n -v r=$rate 'BEGIN {{ printf \"%.17g\", n / (r * 1000) }}')\n\
         echo \"layout=$2 scene=x rays=$n build_ms=1.0 trace_ms=$ms mrays_per_s=$rate threads=2 hits=0 median_ms=$ms repeats=1 builder=BuildHQ\"\n",
        log_line("$2", "$4", "$6", 2, "50"),
        raycast_line("$3", "$4", "$5").trim_end()
    );
    script(dir, "tinybvh_rays", &body)
}

/// `peers.log` beside the fakes: (peer, ray file, REPEAT argument, rate) per start, in order.
fn peer_log(dir: &Path) -> Vec<(String, String, String, f64)> {
    let text = std::fs::read_to_string(dir.join("peers.log")).unwrap();
    text.lines()
        .map(|l| {
            let w: Vec<&str> = l.split_whitespace().collect();
            (w[0].to_owned(), w[1].to_owned(), w[2].to_owned(), w[3].parse().unwrap())
        })
        .collect()
}

/// The small bench with `extra` (one timed round unless `extra` gives `--repeat`).
fn bench(extra: &[&str], timeout_s: u64) -> std::process::Output {
    let mut args = SMALL.to_vec();
    if !extra.contains(&"--repeat") {
        args.extend(["--repeat", "1"]);
    }
    args.extend(extra);
    common::cli::trilab(&args, timeout_s)
}

/// Timed rounds of the main test.
const REPEAT: usize = 3;

#[test]
fn peers_are_validated_then_timed_beside_trilabs_best() {
    let dir = tempfile::tempdir().unwrap();
    let (embree, tinybvh) = (s(&fake_embree(dir.path())), s(&fake_tinybvh(dir.path())));
    let out = s(dir.path());
    let layouts = "cpu-bvh8,ocl-bvh2,ocl-cwbvh";
    let repeat = REPEAT.to_string();
    let o = bench(
        &[
            "--embree",
            &embree,
            "--tinybvh",
            &tinybvh,
            "--tinybvh-layouts",
            layouts,
            "--repeat",
            &repeat,
            "--json",
            "--out",
            &out,
        ],
        600,
    );
    let err = ok(&o);
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let notes: Vec<&str> = j["notes"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
    assert!(
        notes.iter().any(|n| n.contains("tinybvh ocl-cwbvh: skipped") && n.contains("no OpenCL device")),
        "the OpenCL layout without OpenCL is skipped with its reason: {notes:?}"
    );
    // Every start of a peer, in order: the probe's, then per set one in each round.
    let log = peer_log(dir.path());
    assert!(log.iter().all(|l| l.2 == "1"), "each start traces the set once: {log:?}");
    let probes: Vec<&str> = log.iter().filter(|l| l.1 == "probe.rays").map(|l| l.0.as_str()).collect();
    assert_eq!(probes, ["embree3", "packet8", "cpu-bvh8", "ocl-bvh2", "ocl-cwbvh"], "Embree's default calls first");
    let rows = j["rows"].as_array().unwrap();
    let comparisons = j["peers"].as_array().unwrap();
    assert_eq!(comparisons.len(), 3, "one comparison per ray set");
    for c in comparisons {
        let set = c["ray_set"].as_str().unwrap();
        let starts: Vec<&(String, String, String, f64)> =
            log.iter().filter(|l| l.1 == format!("scene0.{set}.rays")).collect();
        // The rounds: trilab's one kernel (mt bvh2) and the four peers, the opener rotating;
        // ocl-bvh2's wrong hits (found in the warm-up round) stop it. So the peers' starts
        // follow from where the kernel stands in each round.
        let units = ["kernel", "embree3", "packet8", "cpu-bvh8", "ocl-bvh2"];
        let mut want = vec![];
        for round in 0..1 + REPEAT {
            for k in 0..units.len() {
                let u = units[(k + round) % units.len()];
                if u != "kernel" && (u != "ocl-bvh2" || round == 0) {
                    want.push(u);
                }
            }
        }
        let got: Vec<&str> = starts.iter().map(|l| l.0.as_str()).collect();
        assert_eq!(got, want, "{set}: the peers' starts, interleaved with the kernel's rounds");
        // trilab's best is the fastest of its own rows on this set, named.
        let mine: Vec<&Value> = rows.iter().filter(|r| r["ray_set"] == set && r["method"] == "mt").collect();
        let best = mine.iter().map(|r| r["mrays_per_s"].as_f64().unwrap()).fold(0.0, f64::max);
        assert!(best > 0.0);
        assert_eq!(c["trilab"]["mrays_per_s"].as_f64().unwrap(), best, "{set}");
        assert_eq!(c["trilab"]["method"], "mt");
        assert_eq!(c["trilab"]["layout"], "bvh2");
        let peers = c["peers"].as_array().unwrap();
        let names: Vec<&str> = peers.iter().map(|p| p["peer"].as_str().unwrap()).collect();
        assert_eq!(names, ["embree3", "embree3 packet8", "tinybvh cpu-bvh8", "tinybvh ocl-bvh2"], "{set}");
        // The right peers are timed over the timed rounds (the warm-up's start not counted):
        // the median, slowest and fastest of the rates their lines gave, after the f64 check.
        let rounds = |peer: &str| {
            let mut r: Vec<f64> = starts.iter().filter(|l| l.0 == peer).skip(1).map(|l| l.3).collect();
            r.sort_by(f64::total_cmp);
            assert_eq!(r.len(), REPEAT, "{set} {peer}: one start per timed round");
            (r[REPEAT / 2], r[0], r[REPEAT - 1])
        };
        let close = |a: &Value, b: f64| (a.as_f64().unwrap() - b).abs() < 1e-9 * b;
        for (p, name) in [(&peers[0], "embree3"), (&peers[1], "packet8"), (&peers[2], "cpu-bvh8")] {
            let (median, min, max) = rounds(name);
            assert_eq!(p["status"], "timed", "{set} {name}");
            assert!(close(&p["mrays_per_s"], median), "{set} {name}: {p} against {median}");
            assert!(close(&p["mrays_per_s_min"], min) && close(&p["mrays_per_s_max"], max), "{set} {name}: {p}");
            assert_eq!(p["trace_ms"]["runs"], REPEAT, "{set} {name}");
            assert_eq!(p["agreement"], 1.0, "{set}: raycast's hits agree with the reference");
        }
        // The wrong peer is reported as failing validation, with no speed.
        assert_eq!(peers[3]["status"], "wrong-hits", "{set}: a peer with wrong hits is not timed: {}", peers[3]);
        assert!(peers[3].get("mrays_per_s").is_none());
        assert!(peers[3]["reason"].as_str().unwrap().contains("disagree with the f64 reference"));
        assert!(peers[3]["agreement"].as_f64().unwrap() < 0.5);
        // Ratios and issue 53's targets, from the medians: on primary rays 1.0x rtcIntersect1
        // and 0.6x rtcIntersect8 (no goal against cpu-bvh8), elsewhere 0.6x rtcIntersect1 and
        // 0.6x cpu-bvh8 (no goal against the packets).
        let rate = |i: usize| peers[i]["mrays_per_s"].as_f64().unwrap();
        let (e, e8, t) = (rate(0), rate(1), rate(2));
        let target = &c["target"];
        let judged = |key: &str, peer: f64, goal: f64| {
            let r = target[key]["ratio"].as_f64().unwrap();
            assert!((r - best / peer).abs() < 1e-9, "{set} {key}: {target}");
            assert_eq!(target[key]["goal"].as_f64(), Some(goal), "{set} {key}: {target}");
            assert_eq!(target[key]["met"], best / peer >= goal, "{set} {key}: {target}");
        };
        if set == "primary" {
            judged("vs_embree", e, 1.0);
            judged("vs_embree_packet", e8, 0.6);
            assert_eq!(target["vs_embree_packet"]["peer"], "embree3 packet8");
            assert!(target["vs_cpu_bvh8"].is_null(), "{target}");
        } else {
            judged("vs_embree", e, 0.6);
            judged("vs_cpu_bvh8", t, 0.6);
            assert!(target["vs_embree_packet"].is_null(), "{target}");
        }
        assert!(target["vs_best_opencl"].is_null(), "no OpenCL layout passed: no OpenCL target cell: {target}");
        for r in mine {
            assert_eq!(r["embree_mrays_per_s"].as_f64(), Some(e));
        }
    }
    assert!(err.contains("tinybvh ocl-bvh2: failed validation"), "{err}");
    // rows.jsonl: a peer's rate over the same rounds as the kernels'.
    let rows = trilab::rows::read(&Path::new(&out).join(trilab::rows::FILE)).unwrap();
    let peer_rows: Vec<_> = rows.rows.iter().filter(|r| r.figures.contains_key("mrays_per_s")).collect();
    assert!(peer_rows.iter().all(|r| r.figures["mrays_per_s"].runs == REPEAT), "{peer_rows:?}");
    // The Markdown file carries the same tables, says which figures they compare and why a
    // peer failed.
    let md = std::fs::read_to_string(Path::new(&out).join("bench.md")).unwrap();
    let e = comparisons[0]["peers"][0]["mrays_per_s"].as_f64().unwrap();
    let e8 = comparisons[0]["peers"][1]["mrays_per_s"].as_f64().unwrap();
    for needle in [
        "| trilab mt bvh2 |",
        &format!("| embree3 | {e:.2} |"),
        &format!("| embree3 packet8 | {e8:.2} |"),
        "- primary rays: >= 1.0 vs embree3, >= 0.6 vs embree3 packet8",
        "no goal",
        "wrong hits",
        "Speed target",
        "failed validation, not timed",
        "compare the medians",
        "kernels and peer programs interleaved in every round",
    ] {
        assert!(md.contains(needle), "bench.md lacks `{needle}`:\n{md}");
    }
    let line = md.lines().find(|l| l.contains("| random |") && l.contains("tinybvh cpu-bvh8")).unwrap();
    let t = comparisons[2]["peers"][2]["mrays_per_s"].as_f64().unwrap();
    assert!(line.contains(&format!("{:.2}", comparisons[2]["trilab"]["mrays_per_s"].as_f64().unwrap() / t)), "{line}");
}

/// A peer that passes the probe and then fails in the rounds (a garbage line, a crash) is an
/// error naming the program, the scene and the set; so is one that traces another number of rays.
#[test]
fn a_peer_that_fails_in_the_rounds_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    // Right on its first two starts (the probe and the primary set's warm-up round), then not.
    let body = |bad: &str| {
        format!(
            "n=$(( $(wc -c < \"$3\") / 32 ))\n{}{}\
             if [ \"$k\" -ge 2 ]; then {bad}; fi\n\
             echo \"embree3 default threads=2 rays=$n mrays_per_s=$rate\"\n",
            raycast_line("$2", "$3", "$4"),
            log_line("embree3", "$3", "$5", 3, "25")
        )
    };
    let cases = [
        ("garbage", "echo hello; exit 0", vec!["no result line", "`hello`"]),
        ("crash", "echo 'Segmentation fault' >&2; exit 139", vec!["failed", "Segmentation fault"]),
        ("short", "echo \"embree3 rays=3 mrays_per_s=1.0\"; exit 0", vec!["traced 3 rays"]),
    ];
    for (name, bad, needles) in cases {
        let sub = dir.path().join(name);
        std::fs::create_dir(&sub).unwrap();
        let p = s(&script(&sub, "embree_rays", &body(bad)));
        let e = expect_error(
            &bench(&["--embree", &p, "--embree-apis", "ray1", "--repeat", "2"], 300),
            &["Embree peer", &p],
        );
        for needle in needles.iter().chain(&["bunny primary"]) {
            assert!(e.contains(needle), "{name}: the error lacks `{needle}`: {e}");
        }
        assert!(e.contains("ray sets ready"), "{name}: found in the rounds, after the probe: {e}");
        assert_eq!(peer_log(&sub).len(), 3, "{name}: no start after the failing one");
    }
}

#[test]
fn a_peer_that_cannot_report_is_an_error_naming_it_before_the_long_work() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("garbage", "echo hello\n", vec!["no result line", "`hello`"]),
        ("crash", "echo 'Segmentation fault' >&2; exit 139\n", vec!["failed", "Segmentation fault"]),
        ("short", "echo \"layout=$2 rays=3 mrays_per_s=1.0\"\n", vec!["traced 3 rays"]),
        ("nohits", "n=$(( $(wc -c < \"$4\") / 32 ))\necho \"layout=$2 rays=$n mrays_per_s=1.0\"\n", vec!["hit file"]),
    ];
    for (name, body, needles) in cases {
        let p = s(&script(dir.path(), name, body));
        for layout in ["cpu-bvh8", "ocl-bvh2"] {
            let o = bench(&["--tinybvh", &p, "--tinybvh-layouts", layout], 120);
            let mut all = vec![p.as_str(), layout];
            all.extend(needles.iter().copied());
            let e = expect_error(&o, &all);
            assert!(!e.contains("ray sets ready"), "{name} {layout}: found before any scene work: {e}");
        }
    }
    // The same for Embree: its program named.
    let p = s(&script(dir.path(), "embree_garbage", "echo 'mrays_per_s=fast'\n"));
    let e = expect_error(&bench(&["--embree", &p], 120), &["Embree peer", &p, "`mrays_per_s=fast` is not a number"]);
    assert!(!e.contains("ray sets ready"), "{e}");
}

#[test]
fn missing_or_unrunnable_peer_programs_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let missing = s(&dir.path().join("tinybvh_rays"));
    let e =
        expect_error(&bench(&["--tinybvh", &missing], 60), &["--tinybvh", &missing, "no such file", "tinybvh-peer.sh"]);
    assert!(!e.contains("ray sets ready"), "{e}");
    let plain = dir.path().join("embree_rays");
    std::fs::write(&plain, "#!/bin/sh\n").unwrap();
    expect_error(&bench(&["--embree", &s(&plain)], 60), &["--embree", &s(&plain), "not executable"]);
    expect_error(&bench(&["--tinybvh", &s(dir.path())], 60), &["--tinybvh", "not a file"]);
    // Layouts without the program is a usage error from the command line.
    let o = bench(&["--tinybvh-layouts", "cpu-bvh8"], 60);
    assert_eq!(o.status.code(), Some(2), "{}", common::cli::stderr(&o));
    expect_error(&o, &["--tinybvh"]);
    let o = bench(&["--tinybvh", &missing, "--tinybvh-layouts", "gpu-magic"], 60);
    expect_error(&o, &["gpu-magic", "cpu-bvh8"]);
    // Embree's calls without its program, or a call it does not have.
    let o = bench(&["--embree-apis", "packet8"], 60);
    assert_eq!(o.status.code(), Some(2), "{}", common::cli::stderr(&o));
    let e = expect_error(&o, &["--embree-apis", "--embree"]);
    assert!(!e.contains("ray sets ready") && !e.contains("checking"), "{e}");
    let o = bench(&["--embree", &s(&plain), "--embree-apis", "ray1,packet4"], 60);
    expect_error(&o, &["packet4", "ray1, packet8, packet16"]);
}

/// Every Embree call asked for runs as its own peer, validated and timed in the rounds; a packet
/// width the library does not run natively is an error before any scene work, naming the call,
/// the program and the option that asked for it.
#[test]
fn each_embree_call_is_its_own_peer_and_an_unsupported_width_is_refused_first() {
    let dir = tempfile::tempdir().unwrap();
    let embree = s(&fake_embree(dir.path()));
    let o = bench(&["--embree", &embree, "--embree-apis", "packet16,ray1", "--json"], 300);
    ok(&o);
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let log = peer_log(dir.path());
    let probes: Vec<&str> = log.iter().filter(|l| l.1 == "probe.rays").map(|l| l.0.as_str()).collect();
    assert_eq!(probes, ["packet16", "embree3"], "the calls in the order given, packet8 not asked for");
    for c in j["peers"].as_array().unwrap() {
        let names: Vec<&str> = c["peers"].as_array().unwrap().iter().map(|p| p["peer"].as_str().unwrap()).collect();
        assert_eq!(names, ["embree3 packet16", "embree3"], "{c}");
        assert!(c["peers"].as_array().unwrap().iter().all(|p| p["status"] == "timed" && p["agreement"] == 1.0), "{c}");
        if c["ray_set"] == "primary" {
            // Only packet16 ran: it is the packet cell.
            assert_eq!(c["target"]["vs_embree_packet"]["peer"], "embree3 packet16", "{c}");
        }
    }
    // The library without 16-wide packets: refused in the probe.
    let sub = dir.path().join("no16");
    std::fs::create_dir(&sub).unwrap();
    let body = "if [ \"$1\" = trace16 ]; then echo 'embree_rays: trace16 (rtcIntersect16, 16-wide packets) is not \
                supported by this Embree library on this CPU: RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED is 0' >&2; \
                exit 3; fi\nexec \"$(dirname \"$0\")/../embree_rays\" \"$@\"\n";
    let p = s(&script(&sub, "embree_rays", body));
    let e = expect_error(
        &bench(&["--embree", &p, "--embree-apis", "ray1,packet16"], 120),
        &["Embree peer", &p, "api packet16", "rtcIntersect16", "not supported", "leave packet16 out of --embree-apis"],
    );
    assert!(!e.contains("ray sets ready"), "found before any scene work: {e}");
}

/// The real Embree peer (`scripts/embree-peer.sh` builds it; `TRILAB_EMBREE_RAYS` or
/// target/peers/embree_rays) with all three calls on the bunny: every call's hits pass the f64
/// check on every set and each is its own row of the peer table. Ignored in CI, where the
/// benchmark-only peer is not built; `cargo test --release --test cli_peers -- --ignored`.
#[test]
#[ignore = "needs the benchmark-only Embree peer (scripts/embree-peer.sh)"]
fn the_real_embree_peer_validates_with_every_call() {
    let peer = std::env::var_os("TRILAB_EMBREE_RAYS")
        .map(PathBuf::from)
        .unwrap_or_else(|| common::root().join("target/peers/embree_rays"));
    assert!(peer.exists(), "no Embree peer at {} (run scripts/embree-peer.sh)", peer.display());
    let dir = tempfile::tempdir().unwrap();
    let out = s(dir.path());
    let o = bench(&["--embree", &s(&peer), "--embree-apis", "ray1,packet8,packet16", "--json", "--out", &out], 600);
    let err = ok(&o);
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let comparisons = j["peers"].as_array().unwrap();
    assert_eq!(comparisons.len(), 3, "{err}");
    for c in comparisons {
        let peers = c["peers"].as_array().unwrap();
        let names: Vec<&str> = peers.iter().map(|p| p["peer"].as_str().unwrap()).collect();
        assert_eq!(names, ["embree3", "embree3 packet8", "embree3 packet16"], "{c}");
        for p in peers {
            assert_eq!(p["status"], "timed", "{}: {p}", c["ray_set"]);
            assert!(p["agreement"].as_f64().unwrap() > 0.999, "{}: {p}", c["ray_set"]);
            assert!(p["mrays_per_s"].as_f64().unwrap() > 0.0);
        }
    }
    let md = std::fs::read_to_string(Path::new(&out).join("bench.md")).unwrap();
    for name in ["| embree3 |", "| embree3 packet8 |", "| embree3 packet16 |"] {
        assert_eq!(md.matches(name).count(), 3, "`{name}` once per ray set in bench.md:\n{md}");
    }
}
