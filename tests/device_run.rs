//! The device run rehearsed on lavapipe (issue 23): `scripts/device-run.sh pack`, then `run`
//! unchanged (lavapipe instead of the GPU, a small budget), then `unpack`, so the first lent GPU
//! meets a script that has already worked end to end. What comes back from the device tool is at
//! most 8 files of 16 MiB, at most two folders down: the run leaves one archive at `$OUT`'s top.
//! A stopped run and a run without a device still leave an archive with what finished.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const ARCHIVE: &str = "trilab-results.tar.gz";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// `scripts/device-run.sh ARGS` with `env`, killed after `timeout`.
fn script(args: &[&str], env: &[(&str, &str)], timeout: Duration) -> Output {
    let mut c = Command::new("bash");
    c.arg(root().join("scripts/device-run.sh")).args(args).current_dir(root());
    // The run validates as every test does (any message fails the part that saw it).
    c.env("TRILAB_VALIDATION", "1");
    for (k, v) in env {
        c.env(k, v);
    }
    let child = c.stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped()).spawn().unwrap();
    let pid = child.id();
    let start = Instant::now();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(child.wait_with_output()).ok());
    match rx.recv_timeout(timeout) {
        Ok(o) => o.unwrap(),
        Err(_) => {
            // SAFETY: kill(2) with a pid this test spawned and has not reaped (the waiting thread
            // still holds the child); no memory is touched.
            unsafe { libc::kill(pid as i32, libc::SIGKILL) };
            panic!("device-run.sh {args:?} ran past {:?} ({:?})", timeout, start.elapsed());
        }
    }
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// `trilab repro --check DIR`, validated, killed past two minutes.
fn repro_check(dir: &Path) -> Output {
    let mut c = Command::new("timeout");
    c.args(["-k", "5", "120", env!("CARGO_BIN_EXE_trilab"), "repro", "--check"]).arg(dir);
    c.env("TRILAB_VALIDATION", "1").output().expect("timeout(1) runs trilab")
}

/// Packs once per test process (the tests share `.travel/`).
fn packed() -> String {
    static PACK: Mutex<Option<String>> = Mutex::new(None);
    let mut p = PACK.lock().unwrap_or_else(|e| e.into_inner());
    if p.is_none() {
        let o = script(&["pack"], &[], Duration::from_secs(600));
        assert!(o.status.success(), "pack failed:\n{}", text(&o));
        *p = Some(text(&o));
    }
    p.clone().unwrap()
}

/// The archive's entries.
fn entries(archive: &Path) -> Vec<String> {
    let o = Command::new("tar").arg("-tzf").arg(archive).output().unwrap();
    assert!(o.status.success(), "{}: not a readable archive", archive.display());
    String::from_utf8(o.stdout).unwrap().lines().map(String::from).collect()
}

/// What the device tool brings back from `out`: plain files at most two folders down, at most
/// 8 of them, each at most 16 MiB.
fn assert_comes_back(out: &Path) -> PathBuf {
    let mut files = vec![];
    for e in walk(out) {
        let depth = e.strip_prefix(out).unwrap().components().count() - 1;
        assert!(depth <= 2, "{} is {depth} folders down", e.display());
        assert!(std::fs::metadata(&e).unwrap().len() <= 16 << 20, "{} is over 16 MiB", e.display());
        files.push(e);
    }
    assert!(files.len() <= 8, "{} files under $OUT: {files:?}", files.len());
    let archive = out.join(ARCHIVE);
    assert!(files.contains(&archive), "no {ARCHIVE} under $OUT: {files:?}");
    archive
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = vec![];
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

#[test]
fn pack_fits_the_budget_and_names_the_carry_list_and_the_command() {
    let said = packed();
    assert!(said.contains("carry:     [\".travel\"]"), "{said}");
    assert!(said.contains("command:   bash scripts/device-run.sh run"), "{said}");
    let total = said.lines().find(|l| l.trim_start().starts_with("total")).unwrap_or_else(|| panic!("{said}"));
    let mib: f64 = total.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(mib > 10.0 && mib <= 60.0, "{total}");
    // The binary travels stripped: no symbol table, no line tables.
    let exe = root().join(".travel/trilab");
    let o = Command::new("readelf").args(["-S", "--wide"]).arg(&exe).output().unwrap();
    let sections = String::from_utf8_lossy(&o.stdout);
    assert!(!sections.contains(".symtab") && !sections.contains(".debug_line"), "{} is not stripped", exe.display());
    assert!(std::fs::metadata(&exe).unwrap().len() < 24 << 20, "the stripped binary grew past 24 MiB");
    for deb in ["libvulkan1_", "ocl-icd-libopencl1_"] {
        let found = std::fs::read_dir(root().join(".travel/debs"))
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().starts_with(deb));
        assert!(found, "no {deb}*.deb in .travel/debs");
    }
    // The peer is built for a portable x86-64 (x86-64-v3), not this host's CPU: no AVX-512.
    // (Its source is the project's ../shared/peers/tinybvh; a clone without it packs no peer
    // and says so.)
    let peer = root().join(".travel/peers/tinybvh/tinybvh_rays");
    if !peer.exists() {
        assert!(said.contains("no tinybvh source"), "no peer packed, and pack did not say why:\n{said}");
        return;
    }
    let o = Command::new("objdump").args(["-d", "--no-show-raw-insn"]).arg(&peer).output().unwrap();
    let asm = String::from_utf8_lossy(&o.stdout);
    assert!(asm.lines().count() > 1000, "objdump read {}", peer.display());
    assert!(!asm.contains("%zmm"), "{} uses AVX-512 registers: built for this host, not portable", peer.display());
}

/// The rehearsal: `run` as the GPU machine runs it, with a budget that gives the suite its
/// smoke sizes, then `unpack` into a scratch checkout root.
#[test]
fn the_rehearsal_runs_end_to_end_and_unpacks() {
    packed();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("OUT");
    std::fs::create_dir(&out).unwrap();
    let o = script(&["run", "2"], &[("OUT", out.to_str().unwrap())], Duration::from_secs(300));
    let said = text(&o);
    assert!(o.status.success(), "run failed:\n{said}");
    assert!(said.contains("suite completed"), "{said}");
    assert!(said.contains("roofline completed"), "{said}");
    let archive = assert_comes_back(&out);
    let files = entries(&archive);
    for want in [
        "run.log",
        "results/lavapipe/run.log",
        "results/lavapipe/suite/summary.md",
        "results/lavapipe/suite/bench/rows.jsonl",
        "results/lavapipe/suite/study/rows.jsonl",
        "results/lavapipe/roofline/rows.jsonl",
        "results/lavapipe/roofline/roofline.md",
    ] {
        assert!(files.iter().any(|f| f.trim_start_matches("./") == want), "{want} not in the archive: {files:?}");
    }

    let checkout = dir.path().join("checkout");
    std::fs::create_dir_all(checkout.join("results")).unwrap();
    let readme = std::fs::read_to_string(root().join("results/README.md")).unwrap();
    std::fs::write(checkout.join("results/README.md"), &readme).unwrap();
    let o = script(&["unpack", archive.to_str().unwrap(), checkout.to_str().unwrap()], &[], Duration::from_secs(120));
    let said = text(&o);
    assert!(o.status.success(), "unpack failed:\n{said}");
    // The repro step (issue 41): the packed repro checked on this driver, both dispatches the
    // same; one made here comes back whole, and checks the same here.
    let repro = checkout.join("results/lavapipe/repro");
    let check: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(repro.join("check-of-packed.json")).unwrap()).unwrap();
    for d in [&check["differences"], &check["gfxrecon_differences"]] {
        assert!(d["rays"].as_u64() == Some(1024) && d["identical"] == d["rays"], "{check}");
    }
    let made = repro.join("made-here");
    let o = repro_check(&made);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("same: all 1024 rays"), "{}", text(&o));
    let suite = checkout.join("results/lavapipe/suite");
    let md = std::fs::read_to_string(suite.join("summary.md")).unwrap();
    // Four layouts in the study and the bench (qbvh4, issue 42, among them); tinybvh's OpenCL
    // kernels (PoCL here, the GPU's own OpenCL there) beside trilab's, validated.
    for layout in ["bvh2", "bvh4", "qbvh4", "cwbvh"] {
        assert!(md.contains(layout), "summary.md does not mention {layout}:\n{md}");
    }
    // tinybvh's OpenCL layouts ran, or the bench says why not: on an AMD host PoCL's device is
    // named "...AMD EPYC", so the peer (as tinyocl) compiles its AMD-GPU path, which PoCL 3.1
    // refuses; on an Intel host and on NVIDIA they run.
    let bench = std::fs::read_to_string(suite.join("bench/bench.md")).unwrap();
    let log = std::fs::read_to_string(checkout.join("results/lavapipe/run.log")).unwrap();
    let peer_packed = root().join(".travel/peers/tinybvh/tinybvh_rays").exists();
    assert_eq!(log.contains("no tinybvh peer packed"), !peer_packed, "{log}");
    for layout in ["ocl-bvh2", "ocl-cwbvh"].into_iter().filter(|_| peer_packed) {
        let reported = bench.lines().any(|l| {
            l.contains(layout)
                && (l.contains("skipped, no OpenCL: ") || l.split('|').any(|c| c.trim().parse::<f64>().is_ok()))
        });
        assert!(reported, "tinybvh {layout}: neither measured nor said why not:\n{bench}");
    }
    assert!(log.contains("TRILAB_COMMIT=") && !log.contains("TRILAB_COMMIT=unknown"), "{log}");
    let merged = std::fs::read_to_string(checkout.join("results/merged-lavapipe/merge.md")).unwrap();
    assert!(merged.contains("## The paper's claims per device"), "{merged}");
    // The device's verdicts fill the claims table's last column; the lavapipe column stays.
    let filled = std::fs::read_to_string(checkout.join("results/README.md")).unwrap();
    let table = |t: &str| -> Vec<Vec<String>> {
        t.lines()
            .skip_while(|l| !l.starts_with("| claim |"))
            .take_while(|l| l.starts_with('|'))
            .map(|l| l.split('|').map(|c| c.trim().to_string()).collect())
            .collect()
    };
    let (before, after) = (table(&readme), table(&filled));
    assert_eq!(after.len(), 5, "header, rule and claims (a)-(c):\n{filled}");
    assert_eq!(before.len(), after.len());
    for (b, a) in before.iter().zip(&after) {
        assert_eq!(b[..b.len() - 2], a[..a.len() - 2], "only the last column changes");
    }
    // The last column (cells split on `|` have an empty first and last element).
    let last = |row: &Vec<String>| row[row.len() - 2].clone();
    assert!(last(&after[0]).starts_with("llvmpipe") && last(&after[0]) != last(&before[0]), "{:?}", after[0]);
    for row in &after[2..] {
        let cell = &last(row);
        assert!(cell.starts_with("**") && cell != "not measured", "{row:?}");
    }
    assert_eq!(filled.len() - filled.trim_end().len(), readme.len() - readme.trim_end().len());
    // Unpacking again never overwrites what is there.
    let o = script(&["unpack", archive.to_str().unwrap(), checkout.to_str().unwrap()], &[], Duration::from_secs(60));
    assert!(!o.status.success() && text(&o).contains("exists"), "{}", text(&o));
}

/// A run stopped at its deadline, and a run that finds no device, still leave the archive with
/// what finished and the log that says why.
#[test]
fn a_stopped_or_deviceless_run_still_leaves_an_archive() {
    packed();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("OUT");
    std::fs::create_dir(&out).unwrap();
    // 0.6 minutes: the suite is stopped 6 s in, mid-part.
    let o = script(&["run", "0.6"], &[("OUT", out.to_str().unwrap())], Duration::from_secs(120));
    let said = text(&o);
    assert!(said.contains("stopped at the deadline"), "{said}");
    let archive = assert_comes_back(&out);
    let files = entries(&archive);
    assert!(files.iter().any(|f| f.ends_with("suite/devices.txt")), "what finished is kept: {files:?}");

    let out2 = dir.path().join("OUT2");
    std::fs::create_dir(&out2).unwrap();
    let bogus = dir.path().join("no_icd.json");
    let o = script(
        &["run", "1"],
        &[("OUT", out2.to_str().unwrap()), ("VK_DRIVER_FILES", bogus.to_str().unwrap())],
        Duration::from_secs(120),
    );
    assert!(!o.status.success(), "a run without a device fails: {}", text(&o));
    let archive = assert_comes_back(&out2);
    let x = Command::new("tar").arg("-xzOf").arg(&archive).arg("run.log").output().unwrap();
    let log = String::from_utf8_lossy(&x.stdout);
    assert!(log.contains("no usable Vulkan device"), "{log}");
}
