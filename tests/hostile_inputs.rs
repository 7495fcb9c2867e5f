//! What a hostile pass found (issue 24, defects 1, 2, 5 and 6), each run through the binary:
//! an output that is a link, a FIFO or a device is refused and left as it was; sizes that cannot
//! fit in memory are refused at once, naming the option; a ray along x that hits a triangle at
//! x = 2^100 is traced, and a miss of it is never called rounding; ray files whose rays the
//! kernels do not honour are refused naming the ray and its byte offset. Every run has a
//! wall-clock limit and the validation layer on.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use common::cli::{expect_error, ok, s};

fn trilab(args: &[&str], timeout_s: u64) -> (std::process::Output, Duration) {
    common::cli::run(args, None, &[], timeout_s)
}

fn fifo(path: &Path) {
    let c = std::ffi::CString::new(path.to_str().unwrap()).unwrap();
    // SAFETY: `c` is a NUL-terminated path that outlives the call.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0, "mkfifo {}", path.display());
}

fn is_fifo(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_fifo())
}

fn is_link(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink())
}

/// Defect 1: renaming a new file over `--out` replaced a device node, a FIFO or a link with a
/// regular file (as root, `rays random ... --out /dev/full` replaced /dev/full). One command of
/// each family that writes: a ray file, a hit file, an image, a report file, a results folder.
#[test]
fn outputs_that_are_not_regular_files_are_refused_and_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let keep = d.join("keep.txt");
    std::fs::write(&keep, "keep").unwrap();
    let link = d.join("link.out");
    std::os::unix::fs::symlink(&keep, &link).unwrap();
    let pipe = d.join("pipe.out");
    fifo(&pipe);
    let image = d.join("image.exr");
    fifo(&image);
    let rays = d.join("r.rays");
    ok(&trilab(&["rays", "random", "--scene", "bunny", "--random-rays", "64", "--out", &s(&rays)], 120).0);

    let merged = d.join("merged");
    std::fs::create_dir(&merged).unwrap();
    fifo(&merged.join("merge.md"));
    let lavapipe = concat!(env!("CARGO_MANIFEST_DIR"), "/results/lavapipe/merge-widths");
    let cases: Vec<(Vec<String>, PathBuf, &str)> = vec![
        (
            ["rays", "random", "--scene", "bunny", "--random-rays", "64", "--out", "/dev/null"]
                .map(String::from)
                .to_vec(),
            PathBuf::from("/dev/null"),
            "device",
        ),
        (
            ["raycast", "--scene", "bunny", "--rays", &s(&rays), "--out", &s(&link), "--validation"]
                .map(String::from)
                .to_vec(),
            link.clone(),
            "symbolic link",
        ),
        (
            ["render", "--scene", "bunny", "--width", "8", "--height", "8", "--spp", "1", "--out", &s(&image)]
                .map(String::from)
                .to_vec(),
            image.clone(),
            "FIFO",
        ),
        (
            ["bench", "--scenes", "bunny", "--random-rays", "64", "--json-out", &s(&pipe)].map(String::from).to_vec(),
            pipe.clone(),
            "FIFO",
        ),
        (["merge", lavapipe, "--out", &s(&merged)].map(String::from).to_vec(), merged.join("merge.md"), "FIFO"),
    ];
    for (args, target, kind) in &cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (o, took) = trilab(&args, 120);
        let e = expect_error(&o, &[&s(target), kind]);
        assert!(took < Duration::from_secs(30), "trilab {args:?} took {took:?} before refusing:\n{e}");
    }
    assert!(is_fifo(&pipe) && is_fifo(&image) && is_fifo(&merged.join("merge.md")) && is_link(&link));
    assert_eq!(std::fs::read_to_string(&keep).unwrap(), "keep");
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::symlink_metadata("/dev/null").unwrap().file_type().is_char_device());
    // Nothing written beside them either (a `.json` sidecar, a `.png`): what the test made.
    let mut names: Vec<String> =
        std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
    names.sort();
    assert_eq!(names, ["image.exr", "keep.txt", "link.out", "merged", "pipe.out", "r.rays", "r.rays.json"]);
}

/// Defect 2: sizes became allocations before anything checked them: `rays random
/// --random-rays 10000000000` aborted (exit 134), `rays primary --width 100000 --height 100000`
/// grew until the kernel killed it, `synth:soup:1073741824` aborted. Each is refused in
/// seconds, naming the option, with `TRILAB_MAX_MEMORY` standing for a machine of 1 GiB so the
/// test means the same on any host; the same sizes under the limit still run.
#[test]
fn sizes_that_cannot_fit_are_refused_before_the_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(&dir.path().join("r.rays"));
    let exr = s(&dir.path().join("i.exr"));
    let gib = ("TRILAB_MAX_MEMORY", "1073741824");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["rays", "random", "--scene", "bunny", "--random-rays", "10000000000", "--out", &out],
            "--random-rays 10000000000",
        ),
        (
            vec!["rays", "primary", "--scene", "bunny", "--width", "100000", "--height", "100000", "--out", &out],
            "--width 100000 --height 100000",
        ),
        (vec!["rays", "random", "--scene", "synth:soup:1073741824", "--out", &out], "synth:soup:1073741824"),
        (
            vec!["rays", "diffuse", "--scene", "bunny", "--diffuse-per-hit", "4000000000", "--out", &out],
            "--diffuse-per-hit 4000000000",
        ),
        (
            vec!["render", "--scene", "bunny", "--width", "100000", "--height", "100000", "--out", &exr],
            "--width 100000 --height 100000",
        ),
        (vec!["bench", "--scenes", "bunny", "--random-rays", "10000000000"], "--random-rays 10000000000"),
        (vec!["scale", "--scenes", "bunny", "--ray-count", "10000000000"], "--ray-count 10000000000"),
    ];
    for (args, option) in &cases {
        let (o, took) = common::cli::run(args, None, &[gib], 60);
        let e = expect_error(&o, &[option, "1.0 GiB of memory available"]);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(took < Duration::from_secs(10), "trilab {args:?} took {took:?} before refusing:\n{e}");
    }
    // Without the stand-in limit, the machine's own memory refuses the same sizes.
    let (o, _) = trilab(&["rays", "random", "--scene", "bunny", "--random-rays", "10000000000", "--out", &out], 60);
    expect_error(&o, &["--random-rays 10000000000", "298.0 GiB"]);
    assert!(!dir.path().join("r.rays").exists());
    // Sizes that fit are not refused.
    let (o, _) = common::cli::run(
        &["rays", "random", "--scene", "bunny", "--random-rays", "1000", "--out", &out],
        None,
        &[gib],
        60,
    );
    ok(&o);
}

/// The scene of defect 5: in each plane x = 2^i (i = 0..=120) a triangle of size 2 at its own
/// y, and three rays along +x through its centre (from x = 0, -1 and -2^(i-1)): 363 rays, each
/// with a hit at t of about 2^i that f32 holds.
fn far_scene(dir: &Path) -> (PathBuf, PathBuf) {
    let mut obj = String::new();
    let mut rays: Vec<f32> = vec![];
    for i in 0..=120 {
        let x = 2f32.powi(i);
        let y = 4.0 * i as f32;
        obj += &format!("v {x} {} -1\nv {x} {} -1\nv {x} {y} 2\nf -3 -2 -1\n", y - 1.0, y + 1.0);
        for ox in [0.0, -1.0, -(2f32.powi((i - 1).max(0)))] {
            rays.extend_from_slice(&[ox, y, 0.0, 0.0, 1.0, 0.0, 0.0, f32::INFINITY]);
        }
    }
    let (o, r) = (dir.join("far.obj"), dir.join("far.rays"));
    std::fs::write(&o, obj).unwrap();
    std::fs::write(&r, rays.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
    (o, r)
}

/// Defect 5: `TINY_DIR = 1e-30` capped a zero direction component's slab near 2e29, so MT (and
/// f64, on the same traversal) missed 14 of 360 such rays at x >= 2^100, and the validator,
/// measuring edge distance in ULPs of the largest coordinate on any axis, said "0 unexplained,
/// max 0.0 ULPs from an edge" with exit 0. Now every method hits all 363, and a hit file that
/// misses the far triangles is called unexplained.
#[test]
fn hits_far_along_an_axis_are_found_and_a_miss_of_them_is_not_rounding() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, rays) = far_scene(dir.path());
    let hits = dir.path().join("mt.hits");
    for method in ["mt", "f64", "watertight"] {
        let (o, _) = trilab(
            &[
                "raycast",
                "--scene",
                &s(&obj),
                "--rays",
                &s(&rays),
                "--out",
                &s(&hits),
                "--method",
                method,
                "--reference",
                "--validation",
            ],
            120,
        );
        let e = ok(&o);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(out.contains("363/363 rays agree") && out.contains("(363 hit)"), "{method}:\n{out}\n{e}");
    }
    // The last 63 rays (x >= 2^100) turned into misses: the reference's hit is far from every
    // edge across the ray, so no rounding explains it.
    let mut bytes = std::fs::read(&hits).unwrap();
    for rec in bytes.chunks_exact_mut(16).skip(300) {
        rec[0..4].copy_from_slice(&f32::INFINITY.to_le_bytes());
        rec[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
        rec[8..16].fill(0);
    }
    let missed = dir.path().join("missed.hits");
    std::fs::write(&missed, &bytes).unwrap();
    let (o, _) = trilab(&["hits", "check", "--scene", &s(&obj), "--rays", &s(&rays), &s(&missed)], 120);
    let e = expect_error(&o, &["63 unexplained"]);
    assert_eq!(o.status.code(), Some(1), "{e}");
}

/// Defect 6: a negative tmin (the box test is conservative for t >= 0 only) missed hits
/// silently, and a direction of 1e-40 asked for t = 1e40, which f32 cannot hold; both loaded.
/// They are refused at load, naming the ray and its byte offset, as other bad rays are; so is
/// a direction too short for the scene it is cast at.
#[test]
fn rays_the_kernels_cannot_honour_are_refused_at_load() {
    let dir = tempfile::tempdir().unwrap();
    let ray = |o: [f32; 3], tmin: f32, d: [f32; 3]| [o[0], o[1], o[2], tmin, d[0], d[1], d[2], f32::INFINITY];
    let good = ray([0.0, 0.1, 3.0], 0.0, [0.0, 0.0, -1.0]);
    let cases = [
        (ray([0.0, 0.1, 3.0], -0.5, [0.0, 0.0, -1.0]), "tmin is -0.5"),
        (ray([0.0, 0.1, 3.0], 0.0, [0.0, 0.0, -1e-40]), "subnormal"),
        (ray([0.0, 0.1, 3.0e4], 0.0, [0.0, 0.0, -1e-35]), "too short for this scene"),
    ];
    let out = s(&dir.path().join("h.hits"));
    for (bad, why) in cases {
        let file = dir.path().join("bad.rays");
        let floats: Vec<f32> = [good, good, bad].concat();
        std::fs::write(&file, floats.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
        let (o, _) = trilab(&["raycast", "--scene", "bunny", "--rays", &s(&file), "--out", &out], 120);
        expect_error(&o, &[&s(&file), "ray 2 (byte offset 64)", why]);
        assert!(!Path::new(&out).exists());
    }
}

/// UTF-16 without a byte-order mark (what `iconv -t UTF-16LE` and .NET's `Encoding.Unicode`
/// write) was read as UTF-8 with a NUL beside every character and refused as "no triangles"
/// with a hint. It is refused when the text is decoded, before any parsing, naming the file (the
/// OBJ or the MTL), the byte order and the `iconv` command that converts it; nothing is written.
#[test]
fn utf16_without_a_byte_order_mark_is_refused_naming_file_and_byte_order() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/exporters");
    let obj = std::fs::read_to_string(corpus.join("reference.obj")).unwrap().replace('\n', "\r\n");
    let mtl = std::fs::read_to_string(corpus.join("reference.mtl")).unwrap();
    let le = |t: &str| t.encode_utf16().flat_map(u16::to_le_bytes).collect::<Vec<u8>>();
    let be = |t: &str| t.encode_utf16().flat_map(u16::to_be_bytes).collect::<Vec<u8>>();
    std::fs::write(d.join("reference.mtl"), &mtl).unwrap();
    std::fs::write(d.join("le.obj"), le(&obj)).unwrap();
    std::fs::write(d.join("be.obj"), be(&obj)).unwrap();
    // A UTF-8 OBJ whose MTL is UTF-16 big-endian without the mark.
    std::fs::write(d.join("m.obj"), obj.replace("reference.mtl", "be.mtl")).unwrap();
    std::fs::write(d.join("be.mtl"), be(&mtl)).unwrap();
    for (file, named, order, iconv) in [
        ("le.obj", "le.obj", "little-endian", "iconv -f UTF-16LE -t UTF-8 le.obj > le.utf8.obj"),
        ("be.obj", "be.obj", "big-endian", "iconv -f UTF-16BE -t UTF-8 be.obj > be.utf8.obj"),
        ("m.obj", "be.mtl", "big-endian", "iconv -f UTF-16BE -t UTF-8 be.mtl > be.utf8.mtl"),
    ] {
        let exr = d.join(file).with_extension("exr");
        let args = ["render", "--scene", &s(&d.join(file)), "--out", &s(&exr), "--width", "8", "--height", "6"];
        let (o, _) = trilab(&[&args[..], &["--spp", "1", "--quiet"]].concat(), 60);
        let shown = format!("{}: looks like UTF-16 {order} text without a byte-order mark", s(&d.join(named)));
        let e = expect_error(&o, &[&shown, iconv]);
        assert!(!e.contains("no triangles"), "{e}");
        assert!(!exr.exists(), "{file}: a refused scene writes no image");
    }
    // The same text with its byte-order mark loads.
    let mut marked = vec![0xFF, 0xFE];
    marked.extend(le(&obj));
    std::fs::write(d.join("marked.obj"), marked).unwrap();
    let exr = d.join("marked.exr");
    let args = ["render", "--scene", &s(&d.join("marked.obj")), "--out", &s(&exr), "--width", "8", "--height", "6"];
    ok(&trilab(&[&args[..], &["--spp", "1", "--quiet"]].concat(), 60).0);
}
