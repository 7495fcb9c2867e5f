//! Issue 39 item 4: a hostile pass over `trilab roofline`, `--node-orders` (`bench` and `bvh`)
//! and `scripts/stock-mesa.sh`. Each bad input is refused with a non-zero exit and a message
//! naming the option (or file) and why, never a panic, within a wall-clock limit; a repeated
//! node order is run once and the run says so; nothing is written outside the output folder
//! and nothing given as input is changed. tests/roofline.rs holds the roofline refusals this
//! file does not repeat (3K, 32, 1T, `lots`, `texture`, `--rounds 0`, `--steps 0`,
//! `--invocations 0`, `--out` onto a file).
//!
//! The script runs with apt-get, apt-cache, dpkg and sudo shadowed by logging stubs on PATH
//! (apt-get always fails, as with no mirror; dpkg logs each call, then runs the real one), HOME
//! in a temporary folder: it downloads nothing, and the log shows it never installs.

mod common;

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::cli::{run, s};

/// Every file under `dir` (relative paths) with its bytes.
fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = vec![];
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                out.push((p.strip_prefix(dir).unwrap().join(""), vec![]));
                stack.push(p);
            } else {
                out.push((p.strip_prefix(dir).unwrap().to_owned(), std::fs::read(&p).unwrap_or_default()));
            }
        }
    }
    out.sort();
    out
}

/// Fails unless `o` failed (exit `code` when given) without a panic, and its output holds every
/// needle; the output (stderr then stdout).
fn refused(o: &Output, code: Option<i32>, needles: &[&str]) -> String {
    let text = format!("{}{}", String::from_utf8_lossy(&o.stderr), String::from_utf8_lossy(&o.stdout));
    assert!(!o.status.success(), "should fail:\n{text}");
    if code.is_some() {
        assert_eq!(o.status.code(), code, "{text}");
    }
    assert!(!text.contains("panicked"), "panicked:\n{text}");
    for n in needles {
        assert!(text.contains(n), "should say `{n}`:\n{text}");
    }
    text
}

// ---- roofline ---------------------------------------------------------------------------------

/// `trilab roofline` with the cheapest sweep, in `cwd`.
fn roofline(cwd: &Path, args: &[&str], timeout_s: u64) -> Output {
    let mut a = vec!["roofline", "--invocations", "4096", "--steps", "16"];
    a.extend_from_slice(args);
    run(&a, Some(cwd), &[], timeout_s).0
}

#[test]
fn roofline_refuses_bad_sizes_rounds_and_paths_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let cwd = dir.path();
    let out = cwd.join("out");
    let out_s = s(&out);
    // Refused while the options are read, before a device is opened (one that does not exist
    // is named, and never reached).
    let early = |args: &[&str], needles: &[&str]| {
        let mut a = vec!["--device", "no-such-device-xyz", "--out", &out_s];
        a.extend_from_slice(args);
        let o = roofline(cwd, &a, 60);
        let t = refused(&o, None, needles);
        assert!(!t.contains("no-such-device-xyz"), "refused before any device work: {a:?}\n{t}");
    };
    early(&["--sizes", "0"], &["--sizes", "0 B is not a working-set size"]);
    early(&["--sizes", "-1"], &["--sizes", "`-1` is not a size"]);
    early(&["--sizes", "1Q"], &["--sizes", "unknown unit `q`"]);
    early(&["--sizes", "64G"], &["--sizes", "64 GiB is more than 2^30 nodes"]);
    early(&["--sizes", "99999999999999999999G"], &["--sizes", "is not a size"]);
    early(&["--sizes", "18446744073709551615"], &["--sizes", "power of two"]);
    early(&["--sizes", ""], &["--sizes", "`` is not a size"]);
    early(&["--access", ""], &["--access", "a value is required"]);
    early(&["--access", "texel,bogus"], &["--access", "bogus"]);
    early(&["--rounds", "-1"], &["--rounds", "-1"]);
    early(&["--rounds", "99999999999999999999"], &["--rounds", "not a whole number"]);
    early(&["--seed", "-5"], &["--seed", "-5"]);
    assert!(!out.exists(), "nothing written for a refused command");
    // --out where no folder can be: under a file, in /proc, onto a device.
    let file = cwd.join("a-file");
    std::fs::write(&file, "keep").unwrap();
    for (bad, why) in [
        (file.join("sub"), format!("cannot create it: {} is not a folder", file.display())),
        (PathBuf::from("/proc/trilab-roofline-hostile"), "cannot create it in /proc".to_owned()),
        (PathBuf::from("/dev/null"), "is an existing file; give a folder".to_owned()),
    ] {
        let o = roofline(cwd, &["--device", "no-such-device-xyz", "--out", &s(&bad)], 60);
        refused(&o, Some(1), &[&format!("--out {}: {why}", bad.display())]);
    }
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
    assert!(!Path::new("/proc/trilab-roofline-hostile").exists());
    // A size the checks let through but no device here holds (2^30 nodes): skipped naming why,
    // and with nothing left to measure, refused naming --sizes; nothing written.
    let o = roofline(cwd, &["--sizes", "32G", "--access", "texel", "--rounds", "1", "--out", &out_s], 120);
    refused(&o, Some(1), &["nothing to measure", "every size of --sizes skipped", "32 GiB: "]);
    assert!(!out.join("roofline.json").exists(), "nothing written for a refused sweep");
    let left: Vec<_> = snapshot(cwd).into_iter().map(|(p, _)| p).collect();
    assert_eq!(left, [PathBuf::from("a-file")], "nothing else written in the working folder");
}

#[test]
fn roofline_measures_a_repeated_size_or_path_once_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let args = ["--sizes", "4K,4K", "--access", "texel,texel,storage,texel", "--rounds", "1", "--out", &s(&out)];
    let o = roofline(dir.path(), &args, 120);
    let e = common::cli::ok(&o);
    assert!(e.contains("--sizes: 4 KiB given more than once; each is measured once"), "{e}");
    assert!(e.contains("--access: texel given more than once; each is measured once"), "{e}");
    let rows = trilab::rows::read(&out.join(trilab::rows::FILE)).unwrap();
    let mut keys: Vec<String> = rows.rows.iter().map(|r| r.key()).collect();
    keys.sort();
    let n = keys.len();
    keys.dedup();
    assert_eq!((n, keys.len()), (2, 2), "one row per (size, path): {keys:?}");
}

// ---- --node-orders ----------------------------------------------------------------------------

#[test]
fn node_orders_refuses_unknown_and_empty_lists_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let cwd = dir.path();
    let out = cwd.join("bench");
    std::fs::create_dir(&out).unwrap();
    let bvh = ["bvh", "--scene", "cornell", "--leaf-sizes", "4"];
    let bench = ["bench", "--scenes", "cornell", "--methods", "mt", "--out", &s(&out)];
    // The last of ten thousand names is not an order: refused at once, naming it.
    let long_bad = format!("{}bogus", "built,".repeat(10_000));
    for cmd in [&bvh[..], &bench[..]] {
        for (given, needles) in [
            ("treelet", vec!["invalid value 'treelet' for '--node-orders", "possible values: built"]),
            ("built,Depth-First", vec!["invalid value 'Depth-First' for '--node-orders"]),
            ("", vec!["a value is required for '--node-orders"]),
            (",", vec!["a value is required for '--node-orders"]),
            ("built,,treelets", vec!["a value is required for '--node-orders"]),
            (long_bad.as_str(), vec!["invalid value 'bogus' for '--node-orders"]),
        ] {
            let args: Vec<&str> = [cmd, &["--node-orders", given][..]].concat();
            let (o, took) = run(&args, Some(cwd), &[], 60);
            refused(&o, Some(2), &needles);
            assert!(took < Duration::from_secs(20), "{:?}: took {took:?}", &given[..given.len().min(40)]);
        }
    }
    assert!(std::fs::read_dir(&out).unwrap().next().is_none(), "nothing written for a refused bench");
}

/// The locality rows of `bvh --json`: (layout, order) per row.
fn locality_rows(stdout: &[u8]) -> Vec<(String, String)> {
    let j: serde_json::Value = serde_json::from_slice(stdout).unwrap();
    let mut rows = vec![];
    for l in j["layouts"].as_array().unwrap() {
        for entry in l["locality"].as_array().unwrap() {
            rows.push((l["layout"].as_str().unwrap().to_owned(), entry[0].as_str().unwrap().to_owned()));
        }
    }
    rows
}

#[test]
fn node_orders_given_twice_run_once_and_a_huge_list_is_quick() {
    let dir = tempfile::tempdir().unwrap();
    let cwd = dir.path();
    let bvh = ["bvh", "--scene", "cornell", "--leaf-sizes", "4", "--layouts", "bvh2", "--json"];
    let (o, _) = run(&[&bvh[..], &["--node-orders", "built,treelets,built,built"]].concat(), Some(cwd), &[], 60);
    let e = common::cli::ok(&o);
    assert!(e.contains("--node-orders: built given more than once; each order runs once"), "{e}");
    let want = [("bvh2".to_owned(), "built".to_owned()), ("bvh2".to_owned(), "treelets".to_owned())];
    assert_eq!(locality_rows(&o.stdout), want);
    // Ten thousand names of two orders: each runs once (it used to build ten thousand rows, for
    // minutes), in seconds.
    let huge = "built,treelets,".repeat(5_000);
    let (o, took) = run(&[&bvh[..], &["--node-orders", huge.trim_end_matches(',')]].concat(), Some(cwd), &[], 120);
    let e = common::cli::ok(&o);
    assert!(e.contains("--node-orders: built, treelets given more than once"), "{e}");
    assert_eq!(locality_rows(&o.stdout), want);
    assert!(took < Duration::from_secs(30), "took {took:?}");
    // bench: each order's cells once.
    let out = cwd.join("bench");
    std::fs::create_dir(&out).unwrap();
    let args = [
        "bench",
        "--scenes",
        "cornell",
        "--methods",
        "mt",
        "--width",
        "32",
        "--height",
        "24",
        "--diffuse-per-hit",
        "1",
        "--random-rays",
        "2000",
        "--repeat",
        "1",
        "--node-orders",
        "built,depth-first,built,depth-first",
        "--out",
        &s(&out),
    ];
    let (o, _) = run(&args, Some(cwd), &[], 120);
    let e = common::cli::ok(&o);
    assert!(e.contains("--node-orders: built, depth-first given more than once; each order runs once"), "{e}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).unwrap()).unwrap();
    let orders: Vec<String> = report["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["node_order"].as_str().unwrap_or("built").to_owned())
        .collect();
    assert_eq!(orders.len(), 6, "3 ray sets x 2 orders: {orders:?}");
    assert_eq!(orders.iter().filter(|o| *o == "built").count(), 3, "{orders:?}");
    let left: Vec<_> = snapshot(cwd).into_iter().map(|(p, _)| p).collect();
    assert!(left.iter().all(|p| p.starts_with("bench")), "written outside --out: {left:?}");
}

// ---- scripts/stock-mesa.sh --------------------------------------------------------------------

/// A sandbox for the script: stubs on PATH logging to `log`, HOME in it, a working folder.
struct Sandbox {
    dir: tempfile::TempDir,
}

/// What `apt-cache madison` answers in the sandbox: bookworm's package, or nothing.
#[derive(Clone, Copy, PartialEq)]
enum Madison {
    Bookworm,
    Nothing,
}

const VERSION: &str = "22.3.6-1+deb12u2";

impl Sandbox {
    fn new(madison: Madison) -> Sandbox {
        let dir = tempfile::tempdir().unwrap();
        for sub in ["bin", "home", "cwd", "in"] {
            std::fs::create_dir(dir.path().join(sub)).unwrap();
        }
        let sb = Sandbox { dir };
        let log = s(&sb.log());
        let which = |tool: &str| {
            let o = Command::new("sh").args(["-c", &format!("command -v {tool}")]).output().unwrap();
            String::from_utf8_lossy(&o.stdout).trim().to_owned()
        };
        let dpkg = which("dpkg");
        assert!(!dpkg.is_empty(), "the script needs dpkg (Debian)");
        let madison_line = match madison {
            Madison::Bookworm => {
                format!(" $2 | {VERSION} | http://deb.debian.org/debian bookworm/main amd64 Packages")
            }
            Madison::Nothing => String::new(),
        };
        sb.stub("apt-get", &format!("echo \"apt-get $*\" >>'{log}'\necho 'E: no network in this test' >&2\nexit 100"));
        sb.stub(
            "apt-cache",
            &format!("echo \"apt-cache $*\" >>'{log}'\nif [ \"$1\" = madison ] && [ -n '{madison_line}' ]; then echo \"{madison_line}\"; fi"),
        );
        sb.stub("sudo", &format!("echo \"sudo $*\" >>'{log}'\nexit 1"));
        sb.stub("dpkg", &format!("echo \"dpkg $*\" >>'{log}'\nexec '{dpkg}' \"$@\""));
        sb
    }

    fn stub(&self, name: &str, body: &str) {
        let p = self.dir.path().join("bin").join(name);
        std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    }

    fn log(&self) -> PathBuf {
        self.dir.path().join("calls.log")
    }

    /// The stubs' calls so far.
    fn calls(&self) -> String {
        std::fs::read_to_string(self.log()).unwrap_or_default()
    }

    fn cwd(&self) -> PathBuf {
        self.dir.path().join("cwd")
    }

    fn input(&self, name: &str) -> PathBuf {
        self.dir.path().join("in").join(name)
    }

    /// `scripts/stock-mesa.sh args` in the sandbox; fails past 60 s.
    fn script(&self, args: &[&str]) -> Output {
        let script = common::root().join("scripts/stock-mesa.sh");
        let path = format!("{}:{}", s(&self.dir.path().join("bin")), std::env::var("PATH").unwrap_or_default());
        let mut child = Command::new("bash")
            .arg(&script)
            .args(args)
            .current_dir(self.cwd())
            .env("PATH", path)
            .env("HOME", self.dir.path().join("home"))
            .env_remove("TRILAB_STOCK_MESA")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if start.elapsed() > Duration::from_secs(60) {
                let _ = child.kill();
                panic!("stock-mesa.sh {args:?} did not finish within 60 s");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        child.wait_with_output().unwrap()
    }

    /// A package built here with `dpkg-deb` (`name` at `version`), holding `files` (path in
    /// the package, bytes).
    fn deb(&self, file: &str, name: &str, version: &str, files: &[(&str, Vec<u8>)]) -> PathBuf {
        let root = self.dir.path().join(format!("pkg-{file}"));
        std::fs::create_dir_all(root.join("DEBIAN")).unwrap();
        let control = format!(
            "Package: {name}\nVersion: {version}\nArchitecture: all\nMaintainer: trilab tests <t@example.org>\n\
             Description: a test package\n"
        );
        std::fs::write(root.join("DEBIAN/control"), control).unwrap();
        for (path, bytes) in files {
            let p = root.join(path);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, bytes).unwrap();
        }
        let deb = self.input(file);
        let o = Command::new("dpkg-deb")
            .args(["-Znone", "--root-owner-group", "--build"])
            .arg(&root)
            .arg(&deb)
            .output()
            .unwrap();
        assert!(o.status.success(), "dpkg-deb: {}", String::from_utf8_lossy(&o.stderr));
        std::fs::remove_dir_all(&root).unwrap();
        deb
    }

    /// A stand-in for mesa-vulkan-drivers: a shared object's name on a small executable (ldd
    /// resolves it), and the ICD JSON naming the system's path, as Debian's does.
    fn fake_mesa(&self, file: &str) -> PathBuf {
        let icd = br#"{"file_format_version": "1.0.0", "ICD": {"library_path": "/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so", "api_version": "1.3.0"}}"#;
        self.deb(
            file,
            "mesa-vulkan-drivers",
            "22.3.6-1+test1",
            &[
                ("usr/lib/x86_64-linux-gnu/libvulkan_lvp.so", std::fs::read("/bin/true").unwrap()),
                ("usr/share/vulkan/icd.d/lvp_icd.x86_64.json", icd.to_vec()),
            ],
        )
    }
}

/// The system's Vulkan driver files, to show the script never touches them.
fn system_driver() -> Vec<(PathBuf, Vec<u8>, Option<std::time::SystemTime>)> {
    let mut files = vec![];
    for d in ["/usr/share/vulkan/icd.d", "/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu"] {
        for e in std::fs::read_dir(d).into_iter().flatten().flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.ends_with(".json") || name.starts_with("libvulkan_lvp") {
                let p = e.path();
                let modified = std::fs::metadata(&p).and_then(|m| m.modified()).ok();
                files.push((p.clone(), std::fs::read(&p).unwrap_or_default(), modified));
            }
        }
    }
    files
}

#[test]
fn stock_mesa_refuses_bad_arguments_and_folders_not_its_own() {
    let sb = Sandbox::new(Madison::Bookworm);
    let bad = |args: &[&str], code: i32, needles: &[&str]| {
        let o = sb.script(args);
        refused(&o, Some(code), needles);
    };
    bad(&["--bogus"], 2, &["unknown option `--bogus`", "usage: scripts/stock-mesa.sh"]);
    bad(&["-x", "dir"], 2, &["unknown option `-x`"]);
    bad(&["one", "two"], 2, &["one DIR at most (given `one` and `two`)"]);
    bad(&["--deb"], 2, &["--deb needs a FILE"]);
    bad(&["--deb", ""], 2, &["--deb needs a FILE"]);
    bad(&[""], 2, &["DIR is empty"]);
    // DIR a file, or a folder holding other things: refused, left as it was.
    let file = sb.input("a-file");
    std::fs::write(&file, "keep").unwrap();
    bad(&[&s(&file)], 1, &[&format!("DIR {} exists and is not a folder", file.display())]);
    let other = sb.input("other");
    std::fs::create_dir(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    std::fs::create_dir(other.join("root")).unwrap();
    bad(&[&s(&other)], 1, &["holds other things and is not this script's folder"]);
    assert_eq!(std::fs::read(&file).unwrap(), b"keep");
    assert_eq!(snapshot(&other), [(PathBuf::from("notes.txt"), b"mine".to_vec()), (PathBuf::from("root/"), vec![])]);
    let o = sb.script(&["--help"]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("usage:"), "{o:?}");
    // None of it fetched, unpacked or wrote anything: no folder named after an option either.
    assert_eq!(sb.calls(), "", "no apt or dpkg call for refused arguments");
    assert!(snapshot(&sb.cwd()).is_empty(), "{:?}", snapshot(&sb.cwd()));
    assert!(snapshot(&sb.dir.path().join("home")).is_empty(), "the default folder was not touched");
}

#[test]
fn stock_mesa_refuses_a_missing_or_corrupt_deb_and_downloads_nothing() {
    let sb = Sandbox::new(Madison::Bookworm);
    let dir = sb.dir.path().join("stock");
    let dir_s = s(&dir);
    let nothing_made = |what: &str| {
        for f in ["lvp_icd.json", "env", "version", "root", "root.new", "lvp_icd.json.tmp", "env.tmp"] {
            assert!(!dir.join(f).exists(), "{what}: {f} was left in {}", dir.display());
        }
    };
    // --deb: missing, not a package, cut short, another package, one without the driver.
    let o = sb.script(&["--deb", &s(&sb.input("nope.deb")), &dir_s]);
    refused(&o, Some(1), &["--deb", "nope.deb: no such file"]);
    nothing_made("missing");
    let junk = sb.input("junk.deb");
    let junk_bytes: Vec<u8> = (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8).collect();
    std::fs::write(&junk, &junk_bytes).unwrap();
    let o = sb.script(&["--deb", &s(&junk), &dir_s]);
    refused(&o, Some(1), &["junk.deb: not a Debian package"]);
    assert_eq!(std::fs::read(&junk).unwrap(), junk_bytes, "the input is not changed");
    nothing_made("junk");
    let whole = std::fs::read(sb.fake_mesa("whole.deb")).unwrap();
    let cut = sb.input("cut.deb");
    std::fs::write(&cut, &whole[..whole.len() - whole.len() / 3]).unwrap();
    let o = sb.script(&["--deb", &s(&cut), &dir_s]);
    refused(
        &o,
        Some(1),
        &["cut.deb cannot be unpacked, it is not a whole .deb", "given by --deb: it is left as it is"],
    );
    assert_eq!(std::fs::read(&cut).unwrap().len(), whole.len() - whole.len() / 3);
    nothing_made("cut short");
    let hello = sb.deb("hello.deb", "hello", "1.0", &[("usr/share/doc/hello/README", b"hi".to_vec())]);
    let o = sb.script(&["--deb", &s(&hello), &dir_s]);
    refused(&o, Some(1), &["the package is `hello`, not mesa-vulkan-drivers"]);
    let empty = sb.deb("empty.deb", "mesa-vulkan-drivers", "22.3.6-1+test2", &[("usr/share/doc/x", b"x".to_vec())]);
    let o = sb.script(&["--deb", &s(&empty), &dir_s]);
    refused(&o, Some(1), &["empty.deb holds no libvulkan_lvp.so or lvp_icd*.json"]);
    nothing_made("no driver in it");
    assert!(!sb.calls().contains("apt-get"), "--deb never downloads: {}", sb.calls());
    // The script's own cache holding a corrupt .deb: named, left for the user to delete.
    let cached = dir.join("debs").join(format!("mesa-vulkan-drivers_{VERSION}_amd64.deb"));
    std::fs::create_dir_all(cached.parent().unwrap()).unwrap();
    std::fs::write(&cached, &junk_bytes).unwrap();
    let o = sb.script(&[&dir_s]);
    refused(&o, Some(1), &[&format!("{} cannot be unpacked", cached.display()), "delete it and run again"]);
    assert_eq!(std::fs::read(&cached).unwrap(), junk_bytes);
    nothing_made("corrupt cache");
    assert!(!sb.calls().contains("apt-get"), "a cached .deb is not downloaded again: {}", sb.calls());
    // No .deb and no mirror: the download is tried (the stub refuses it) and the failure named.
    std::fs::remove_file(&cached).unwrap();
    let o = sb.script(&[&dir_s]);
    refused(
        &o,
        Some(1),
        &[&format!("apt-get download mesa-vulkan-drivers={VERSION} failed"), "E: no network in this test"],
    );
    nothing_made("no mirror");
    assert!(sb.calls().contains(&format!("apt-get download -q mesa-vulkan-drivers={VERSION}")), "{}", sb.calls());
    // apt knowing no bookworm package: named, nothing fetched.
    let sb = Sandbox::new(Madison::Nothing);
    let o = sb.script(&[&s(&sb.dir.path().join("stock"))]);
    refused(&o, Some(1), &["apt knows no mesa-vulkan-drivers from bookworm", "sudo apt-get update"]);
    assert!(!sb.calls().contains("apt-get"), "{}", sb.calls());
}

#[test]
fn stock_mesa_unpacks_into_its_own_folder_and_never_installs() {
    let sb = Sandbox::new(Madison::Bookworm);
    let system = system_driver();
    let deb = sb.fake_mesa("mesa.deb");
    let deb_bytes = std::fs::read(&deb).unwrap();
    let dir = sb.dir.path().join("stock");
    let o = sb.script(&["--deb", &s(&deb), &s(&dir)]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    let icd = dir.join("lvp_icd.json");
    assert_eq!(String::from_utf8_lossy(&o.stdout).trim(), format!("VK_DRIVER_FILES={}", icd.display()), "{err}");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&icd).unwrap()).unwrap();
    let lib = json["ICD"]["library_path"].as_str().unwrap();
    assert_eq!(lib, s(&dir.join("root/usr/lib/x86_64-linux-gnu/libvulkan_lvp.so")));
    assert!(Path::new(lib).is_file());
    assert_eq!(std::fs::read_to_string(dir.join("version")).unwrap().trim(), "22.3.6-1+test1");
    assert_eq!(std::fs::read_to_string(dir.join("env")).unwrap(), format!("VK_DRIVER_FILES={}\n", icd.display()));
    // Only `dpkg -x` into its folder: no install, no sudo, no download.
    let calls = sb.calls();
    let lines: Vec<&str> = calls.lines().collect();
    assert_eq!(lines, [format!("dpkg -x {} {}/root.new", deb.display(), dir.display())], "{calls}");
    assert_eq!(std::fs::read(&deb).unwrap(), deb_bytes, "the input .deb is not changed");
    assert_eq!(system_driver(), system, "the system's driver files are untouched");
    // Everything it wrote is in its folder.
    let mut top: Vec<String> = std::fs::read_dir(sb.dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    top.sort();
    assert_eq!(top, ["bin", "calls.log", "cwd", "home", "in", "stock"]);
    assert!(snapshot(&sb.cwd()).is_empty() && snapshot(&sb.dir.path().join("home")).is_empty());
    // Again: already complete, only checked; nothing rewritten.
    let before = snapshot(&dir);
    let o = sb.script(&["--deb", &s(&deb), &s(&dir)]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stderr).contains("already unpacked"), "{o:?}");
    assert_eq!(snapshot(&dir), before);
    assert_eq!(sb.calls().lines().count(), 1, "{}", sb.calls());
}
