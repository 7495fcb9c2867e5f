//! `scripts/device-run.sh unpack` against hostile and damaged archives (issue 39 item 4). What
//! comes back from a lent GPU machine is read as untrusted: the whole archive is checked before
//! anything is written, only regular files and folders under `results/<device>/` are unpacked,
//! and a refusal exits non-zero naming the archive, the offending entry and why. Nothing is ever
//! written outside `results/<device>/`: each test unpacks into a scratch checkout root, three
//! folders down in its own temporary folder, and compares a listing of that whole temporary
//! folder (names, kinds, contents) before and after. Archives are written with Python's
//! `tarfile`, which writes `..`, absolute and link members as given. No GPU, no build of trilab:
//! the archives hold no `suite/`, so unpack merges nothing.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::Duration;

/// Every subprocess here takes well under a second; past this it has hung.
const TIMEOUT: Duration = Duration::from_secs(60);

/// `cmd` with `stdin` fed to it and both pipes drained while it runs; panics (after killing it)
/// past [`TIMEOUT`].
fn run(cmd: &mut Command, stdin: &[u8], what: &str) -> Output {
    common::cli::output_within(cmd, Some(stdin), TIMEOUT, what)
}

/// One member of an archive the test writes.
enum Entry<'a> {
    File(&'a str, &'a str),
    Dir(&'a str),
    Symlink(&'a str, &'a str),
    Hardlink(&'a str, &'a str),
}

/// Writes `entries`, in order and as named, into a gzip-compressed tar at `path`.
fn write_archive(path: &Path, entries: &[Entry]) {
    const WRITER: &str = r#"
import io, json, sys, tarfile
with tarfile.open(sys.argv[1], "w:gz", format=tarfile.GNU_FORMAT) as t:
    for kind, name, arg in json.load(sys.stdin):
        ti = tarfile.TarInfo(name)
        ti.mtime = 0
        data = None
        if kind == "file":
            data = arg.encode()
            ti.size, ti.mode = len(data), 0o644
        elif kind == "dir":
            ti.type, ti.mode = tarfile.DIRTYPE, 0o755
        elif kind == "symlink":
            ti.type, ti.linkname = tarfile.SYMTYPE, arg
        elif kind == "hardlink":
            ti.type, ti.linkname = tarfile.LNKTYPE, arg
        t.addfile(ti, io.BytesIO(data) if data is not None else None)
"#;
    let spec: Vec<serde_json::Value> = entries
        .iter()
        .map(|e| match e {
            Entry::File(n, text) => serde_json::json!(["file", n, text]),
            Entry::Dir(n) => serde_json::json!(["dir", n, ""]),
            Entry::Symlink(n, to) => serde_json::json!(["symlink", n, to]),
            Entry::Hardlink(n, to) => serde_json::json!(["hardlink", n, to]),
        })
        .collect();
    let input = serde_json::to_vec(&spec).unwrap();
    let o = run(Command::new("python3").arg("-c").arg(WRITER).arg(path), &input, "python3 (the archive writer)");
    assert!(o.status.success(), "writing {}: {}", path.display(), String::from_utf8_lossy(&o.stderr));
    // What tar itself lists: the hostile names went in as written.
    let o = run(Command::new("tar").args(["--quoting-style=literal", "-tzf"]).arg(path), b"", "tar -tzf");
    assert!(o.status.success(), "tar cannot list {}", path.display());
    let listed = String::from_utf8_lossy(&o.stdout);
    for e in entries {
        let (Entry::File(n, _) | Entry::Dir(n) | Entry::Symlink(n, _) | Entry::Hardlink(n, _)) = e;
        assert!(listed.lines().any(|l| l.trim_end_matches('/') == n.trim_end_matches('/')), "{n} not in:\n{listed}");
    }
}

/// A scratch checkout root three folders down in its own temporary folder, with a results/
/// folder (as a checkout has), and a name no file anywhere has (for what must never appear).
struct Scratch {
    dir: tempfile::TempDir,
    root: PathBuf,
    evil: String,
}

fn scratch(case: &str) -> Scratch {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("outer/inner/checkout");
    std::fs::create_dir_all(root.join("results")).unwrap();
    std::fs::write(dir.path().join("outer/keep.txt"), "beside the checkout").unwrap();
    std::fs::write(root.join("results/README.md"), "# results\n").unwrap();
    let evil = format!("trilab-unpack-evil-{case}-{}", std::process::id());
    Scratch { dir, root, evil }
}

impl Scratch {
    fn top(&self) -> &Path {
        self.dir.path()
    }

    fn archive(&self, name: &str, entries: &[Entry]) -> PathBuf {
        let path = self.top().join(name);
        write_archive(&path, entries);
        path
    }

    /// `scripts/device-run.sh unpack ARCHIVE ROOT`, run from the temporary folder (so a
    /// relative path could only land in what the listing covers).
    fn unpack(&self, archive: &Path) -> Output {
        let mut c = Command::new("bash");
        c.arg(repo().join("scripts/device-run.sh")).arg("unpack").arg(archive).arg(&self.root).current_dir(self.top());
        run(&mut c, b"", &format!("device-run.sh unpack {}", archive.display()))
    }

    /// No file named `evil` in the checkout's results/ folder, nor in any folder above it, up
    /// to `/` (where a `..` or an absolute entry resolved against any of them would land).
    fn assert_no_evil(&self) {
        for dir in self.root.join("results").ancestors() {
            let p = dir.join(&self.evil);
            assert!(std::fs::symlink_metadata(&p).is_err(), "{} was written", p.display());
        }
    }
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every path under `dir` (links not followed) with what it is: a folder, a link and its target,
/// or a file and its bytes.
fn listing(dir: &Path) -> BTreeMap<PathBuf, String> {
    let mut out = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let meta = std::fs::symlink_metadata(&p).unwrap();
            let what = if meta.file_type().is_symlink() {
                format!("link -> {}", std::fs::read_link(&p).unwrap().display())
            } else if meta.is_dir() {
                todo.push(p.clone());
                "folder".to_string()
            } else {
                format!("file {:?}", String::from_utf8_lossy(&std::fs::read(&p).unwrap()))
            };
            out.insert(p.strip_prefix(dir).unwrap().to_path_buf(), what);
        }
    }
    out
}

/// Fails unless `before` and `after` list the same tree, naming what differs.
fn assert_same_tree(before: &BTreeMap<PathBuf, String>, after: &BTreeMap<PathBuf, String>, what: &str) {
    let changed: Vec<String> = before
        .keys()
        .chain(after.keys())
        .filter(|k| before.get(*k) != after.get(*k))
        .map(|k| format!("{}: {:?} -> {:?}", k.display(), before.get(k), after.get(k)))
        .collect();
    assert!(changed.is_empty(), "{what} changed the tree:\n{}", changed.join("\n"));
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Fails unless the unpack failed, its stderr naming `archive` and every needle; its stderr.
fn assert_refused(o: &Output, archive: &Path, needles: &[&str]) -> String {
    let e = stderr(o);
    assert!(!o.status.success(), "unpack of {} should be refused:\n{e}", archive.display());
    assert!(e.contains(&archive.display().to_string()), "the refusal should name {}:\n{e}", archive.display());
    for n in needles {
        assert!(e.contains(n), "the refusal should mention `{n}`:\n{e}");
    }
    e
}

/// Refused, naming the archive and `needles`, with the whole temporary folder as it was and no
/// file named `evil` anywhere above the checkout's results/.
fn assert_refused_untouched(s: &Scratch, archive: &Path, needles: &[&str]) -> String {
    let before = listing(s.top());
    let o = s.unpack(archive);
    let e = assert_refused(&o, archive, needles);
    assert_same_tree(&before, &listing(s.top()), &format!("a refused unpack of {}", archive.display()));
    s.assert_no_evil();
    e
}

#[test]
fn an_entry_with_dotdot_is_refused_before_anything_is_written() {
    let s = scratch("dotdot");
    let (up2, deep) = (format!("../../{}", s.evil), format!("results/dev/../../../../{}", s.evil));
    // The sound entries first: a script that extracted as it read would have written them.
    let a = s.archive(
        "dotdot.tar.gz",
        &[
            Entry::Dir("results/"),
            Entry::Dir("results/dev/"),
            Entry::File("results/dev/run.log", "a run"),
            Entry::File(&up2, "climbed out"),
            Entry::File(&deep, "climbed out of the device"),
        ],
    );
    let e = assert_refused_untouched(&s, &a, &[&up2, &deep, "'..'"]);
    assert!(e.contains("nothing unpacked"), "{e}");
    assert!(!s.root.join("results/dev").exists(), "the sound entries were unpacked before the refusal");
}

#[test]
fn an_absolute_entry_is_refused() {
    let s = scratch("absolute");
    // Into the test's own temporary folder, where the listing would see it, and into /tmp.
    let inside = s.top().join(&s.evil).display().to_string();
    let tmp = format!("/tmp/{}", s.evil);
    let a = s.archive(
        "absolute.tar.gz",
        &[Entry::Dir("results/dev/"), Entry::File(&inside, "absolute"), Entry::File(&tmp, "absolute")],
    );
    assert_refused_untouched(&s, &a, &[&inside, &tmp, "absolute path"]);
    assert!(!Path::new(&inside).exists() && !Path::new(&tmp).exists());
    assert!(!s.root.join("results/dev").exists());
}

#[test]
fn link_entries_and_files_written_through_them_are_refused() {
    let s = scratch("links");
    let outside = s.top().join("outside");
    std::fs::create_dir(&outside).unwrap();
    let outside = outside.display().to_string();

    // A symbolic link out of the checkout, alone.
    let a = s.archive("etc.tar.gz", &[Entry::Dir("results/dev/"), Entry::Symlink("results/dev/link", "/etc")]);
    assert_refused_untouched(&s, &a, &["results/dev/link", "symbolic link", "/etc"]);

    // A relative link up and out, and a file written through it.
    let through = format!("results/dev/up/{}", s.evil);
    let a = s.archive(
        "up.tar.gz",
        &[Entry::Dir("results/dev/"), Entry::Symlink("results/dev/up", "../../.."), Entry::File(&through, "through")],
    );
    assert_refused_untouched(&s, &a, &["'results/dev/up'", "symbolic link", "'../../..'", &through]);

    // An absolute link into a folder the listing sees, and a file written through it.
    let through = format!("results/dev/out/{}", s.evil);
    let a = s.archive(
        "out.tar.gz",
        &[Entry::Dir("results/dev/"), Entry::Symlink("results/dev/out", &outside), Entry::File(&through, "through")],
    );
    let e = assert_refused_untouched(&s, &a, &["'results/dev/out'", &outside, &through]);
    assert!(e.contains("under 'results/dev/out'"), "the file through the link should be named as such:\n{e}");
    assert!(!Path::new(&outside).join(&s.evil).exists());

    // A hard link to a file outside.
    let a =
        s.archive("hard.tar.gz", &[Entry::Dir("results/dev/"), Entry::Hardlink("results/dev/passwd", "/etc/passwd")]);
    assert_refused_untouched(&s, &a, &["results/dev/passwd", "hard link"]);
    assert!(!s.root.join("results/dev").exists());
}

#[test]
fn a_truncated_archive_is_refused() {
    let s = scratch("truncated");
    // Enough incompressible text that the cuts fall inside members, not only in the trailer.
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let noise: String = (0..200_000)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            char::from(b'a' + (x % 26) as u8)
        })
        .collect();
    let whole = s.archive(
        "whole.tar.gz",
        &[
            Entry::Dir("results/dev/"),
            Entry::File("results/dev/run.log", "a run"),
            Entry::File("results/dev/roofline/rows.jsonl", &noise),
            Entry::File("results/dev/z.txt", &noise[..1000]),
        ],
    );
    let bytes = std::fs::read(&whole).unwrap();
    assert!(bytes.len() > 100_000, "the archive is {} bytes", bytes.len());
    for cut in [bytes.len() / 2, bytes.len() / 4, bytes.len() - 9, bytes.len() - 1] {
        let a = s.top().join(format!("cut-{cut}.tar.gz"));
        std::fs::write(&a, &bytes[..cut]).unwrap();
        assert_refused_untouched(&s, &a, &["truncated", "nothing unpacked"]);
        assert!(!s.root.join("results/dev").exists(), "cut at {cut} of {}: something was unpacked", bytes.len());
    }
    // The whole archive unpacks (the cuts, not the archive, were refused).
    let o = s.unpack(&whole);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(s.root.join("results/dev/roofline/rows.jsonl")).unwrap(), noise);
}

#[test]
fn a_second_unpack_of_a_device_never_overwrites_what_git_holds() {
    let s = scratch("twice");
    let git = |args: &[&str]| {
        let mut c = Command::new("git");
        c.args(["-c", "user.name=test", "-c", "user.email=test@example.com"]).args(args).current_dir(&s.root);
        for v in ["GIT_DIR", "GIT_WORK_TREE", "GIT_INDEX_FILE"] {
            c.env_remove(v);
        }
        let o = run(&mut c, b"", &format!("git {args:?}"));
        assert!(o.status.success(), "git {args:?}: {}", stderr(&o));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    git(&["init", "-q"]);
    let first = s.archive(
        "first.tar.gz",
        &[
            Entry::Dir("results/dev/"),
            Entry::File("results/dev/run.log", "run 1"),
            Entry::File("results/dev/roofline/rows.jsonl", "{\"run\": 1}\n"),
        ],
    );
    let o = s.unpack(&first);
    assert!(o.status.success(), "the first unpack: {}", stderr(&o));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains(&format!("unpacked {}", s.root.join("results/dev").display())), "{said}");
    git(&["add", "-A"]);
    git(&["commit", "-q", "-m", "run 1"]);

    let second = s.archive(
        "second.tar.gz",
        &[
            Entry::Dir("results/dev/"),
            Entry::File("results/dev/run.log", "run 2"),
            Entry::File("results/dev/roofline/rows.jsonl", "{\"run\": 2}\n"),
            Entry::File("results/dev/new.txt", "only in run 2"),
        ],
    );
    let e = assert_refused_untouched(
        &s,
        &second,
        &["results/dev", "exists", "results/dev/run.log", "results/dev/roofline/rows.jsonl", "tracked by git"],
    );
    assert!(!e.contains("results/dev/new.txt"), "new.txt overwrites nothing: {e}");
    assert_eq!(std::fs::read_to_string(s.root.join("results/dev/run.log")).unwrap(), "run 1");
    assert_eq!(git(&["status", "--porcelain", "--untracked-files=all"]), "", "the refused unpack left files behind");
}

#[test]
fn a_device_name_that_would_escape_results_is_refused() {
    let s = scratch("device");
    let bad = [
        (format!("results/../{}", s.evil), "device name '..'"),
        (format!("results//{}", s.evil), "device name ''"),
        (format!("results/./{}", s.evil), "device name '.'"),
        ("results/.hidden/run.log".to_string(), "device name '.hidden'"),
        ("results/-rf/run.log".to_string(), "device name '-rf'"),
        ("results/Some GPU/run.log".to_string(), "device name 'Some GPU'"),
        ("results/a\\b/run.log".to_string(), "backslash"),
        ("results/merged-dev/run.log".to_string(), "device name 'merged-dev'"),
        ("results/dev".to_string(), "a file where the device's folder belongs"),
        (format!("{}/results/dev/run.log", s.evil), "outside results/<device>/"),
    ];
    for (i, (name, why)) in bad.iter().enumerate() {
        let a = s.archive(
            &format!("device-{i}.tar.gz"),
            &[Entry::Dir("results/"), Entry::File("results/ok/run.log", "a run"), Entry::File(name, "x")],
        );
        // The entry as the refusal quotes it (Python's repr doubles a backslash).
        let quoted = format!("'{}'", name.replace('\\', "\\\\"));
        assert_refused_untouched(&s, &a, &[&quoted, why]);
        assert!(!s.root.join("results/ok").exists(), "{name}: the sound device was unpacked before the refusal");
    }

    // A device is the one folder right under results/ (`results/<device>/<folder>/...`): `a/b/run.log`
    // there is device `a` with a folder `b`, unpacked into device `a`'s folder and nowhere else.
    let before = listing(s.top());
    let a = s.archive("a-b.tar.gz", &[Entry::File("results/a/b/run.log", "a run")]);
    let o = s.unpack(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut after = listing(s.top());
    after.remove(Path::new("a-b.tar.gz"));
    let checkout = s.root.strip_prefix(s.top()).unwrap();
    let added: Vec<_> = after.keys().filter(|k| !before.contains_key(*k)).collect();
    let want: Vec<PathBuf> =
        ["results/a", "results/a/b", "results/a/b/run.log"].iter().map(|p| checkout.join(p)).collect();
    assert_eq!(added, want.iter().collect::<Vec<_>>(), "{}", stderr(&o));
}

#[test]
fn a_sound_archive_unpacks_into_results_device_and_nowhere_else() {
    let s = scratch("sound");
    let before = listing(s.top());
    let a = s.archive(
        "sound.tar.gz",
        &[
            Entry::File("run.log", "the run's log"),
            Entry::Dir("results/"),
            Entry::Dir("results/nvidia-h200/"),
            Entry::File("results/nvidia-h200/run.log", "the run's log"),
            Entry::File("results/nvidia-h200/roofline/roofline.md", "# roofline\n"),
        ],
    );
    let o = s.unpack(&a);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut after = listing(s.top());
    after.remove(Path::new("sound.tar.gz"));
    let dev = s.root.join("results/nvidia-h200");
    for (k, v) in &after {
        if !before.contains_key(k) {
            assert!(s.top().join(k).starts_with(&dev), "{} appeared outside {}: {v}", k.display(), dev.display());
        }
    }
    assert_eq!(std::fs::read_to_string(dev.join("roofline/roofline.md")).unwrap(), "# roofline\n");
    // An archive without results/ (a run that found no device) is refused, showing its log.
    let a = s.archive("nodevice.tar.gz", &[Entry::File("run.log", "trilab devices failed: no usable Vulkan device")]);
    assert_refused_untouched(&s, &a, &["holds no results/", "no usable Vulkan device"]);
}
