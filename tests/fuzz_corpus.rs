//! Hostile input on stable Rust, without libFuzzer: every committed fuzz corpus file and every
//! regression input (`fuzz/corpus/<target>/`, `fuzz/regressions/<target>/`) replayed through the
//! fuzz targets' own code (`fuzz/pipeline.rs`), small hostile files that must fail fast without
//! allocating in proportion to the numbers they name (a counting allocator, per thread, measures
//! the peak), and the BVH builder and encoders on pathological meshes.

#[path = "../fuzz/pipeline.rs"]
mod pipeline;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::{Path, PathBuf};

use trilab::bvh::{BuildOptions, Builder, Bvh, LeafPolicy};
use trilab::encoding::Method;
use trilab::rays::parse_rays;
use trilab::scene::{parse_obj_bytes, Mesh};

/// Counts the bytes live on the current thread and their peak. Thread-local so that tests
/// running in parallel do not see each other's allocations.
struct Counting;

thread_local! {
    static LIVE: Cell<isize> = const { Cell::new(0) };
    static PEAK: Cell<isize> = const { Cell::new(0) };
}

fn track(delta: isize) {
    let _ = LIVE.try_with(|l| {
        let now = l.get() + delta;
        l.set(now);
        let _ = PEAK.try_with(|p| p.set(p.get().max(now)));
    });
}

// SAFETY: every call forwards to `System` with the caller's layout unchanged; the bookkeeping
// touches only const-initialised thread-locals (no allocation, no destructor to re-enter).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            track(layout.size() as isize);
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            track(layout.size() as isize);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        track(-(layout.size() as isize));
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            track(new_size as isize - layout.size() as isize);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result with the most bytes it had allocated at once (this thread).
fn peak_bytes<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let out = f();
    let peak = PEAK.with(Cell::get) - base;
    (out, peak.max(0) as usize)
}

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// Every file under `fuzz/<kind>/<target>/`, sorted.
fn inputs(kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = fuzz_dir().join(kind).join(target);
    let mut files: Vec<PathBuf> = match std::fs::read_dir(&dir) {
        Ok(rd) => rd.map(|e| e.unwrap().path()).filter(|p| p.is_file()).collect(),
        Err(_) => vec![],
    };
    files.sort();
    files
}

fn replay(target: &str, run: fn(&[u8])) -> usize {
    let mut n = 0;
    for kind in ["corpus", "regressions"] {
        for file in inputs(kind, target) {
            let data = std::fs::read(&file).unwrap();
            if std::panic::catch_unwind(|| run(&data)).is_err() {
                panic!("{} panics in the {target} pipeline", file.display());
            }
            n += 1;
        }
    }
    n
}

#[test]
fn obj_corpus_and_regressions_replay_without_panic() {
    let n = replay("obj_pipeline", pipeline::obj_pipeline);
    assert!(n >= 10, "only {n} obj_pipeline inputs: is fuzz/corpus/obj_pipeline committed?");
}

#[test]
fn ray_corpus_and_regressions_replay_without_panic() {
    let n = replay("ray_file", pipeline::ray_file);
    assert!(n >= 5, "only {n} ray_file inputs: is fuzz/corpus/ray_file committed?");
}

fn obj(text: &str, mtl: Option<&str>) -> trilab::Result<Mesh> {
    parse_obj_bytes(Path::new("hostile.obj"), text.as_bytes(), |_| mtl.map(|m| m.as_bytes().to_vec()))
}

/// Small files naming huge counts: each must give a `BadInput` naming the file and the line,
/// allocating a few times the file's size at most, never in proportion to the number named.
#[test]
fn huge_indices_fail_fast_without_allocating_for_them() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let many_faces: String = (0..40).map(|i| format!("f {} 2 3\n", 4_000_000_000u64 + i)).collect();
    let cases = [
        (format!("{tri}f 1 2 1000000000000\n"), 4, "vertex index 1000000000000 is out of range"),
        (format!("{tri}f 1 2 -1000000000000\n"), 4, "vertex index -1000000000000 is out of range"),
        (format!("{tri}f 1 2 4000000000\n"), 4, "out of range"),
        (format!("{tri}f 1 2 -9223372036854775807\n"), 4, "out of range"),
        (format!("{tri}vt 0 0\nf 1/1 2/4000000000 3/1\n"), 5, "texture coordinate index 4000000000"),
        (format!("{tri}vt 0 0\nf 1/1 2/-9223372036854775807 3/1\n"), 5, "texture coordinate index"),
        (format!("{tri}vn 0 0 1\nf 1//1 2//1 3//4611686018427387904\n"), 5, "normal index"),
        (format!("{tri}vn 0 0 1\nf 1//1 2//-4611686018427387904 3//1\n"), 5, "normal index"),
        (format!("{tri}{many_faces}"), 4, "out of range"),
    ];
    for (text, line, expect) in cases {
        assert!(text.len() <= 1024, "case is not small: {} bytes", text.len());
        let (result, peak) = peak_bytes(|| obj(&text, None));
        let e = result.expect_err(&text).to_string();
        assert!(e.starts_with(&format!("hostile.obj:{line}:")) && e.contains(expect), "{text:?}: {e}");
        assert!(peak < 64 * 1024, "{text:?}: peak allocation {peak} bytes");
    }
}

/// tobj 4 unwraps a colour with fewer than three values (`Kd 1 2` panicked): none or two are
/// a `BadInput` naming the MTL file and line; one is the spec's grey (g and b equal r), which
/// reaches tobj written out as three.
#[test]
fn short_mtl_colour_is_an_error_not_a_panic() {
    let text = "mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    for key in ["Ka", "Kd", "Ks", "Ke", "Tf"] {
        for (values, problem) in [("", "needs a colour"), (" 1 2", "takes one number or three")] {
            let mtl = format!("newmtl a\n{key}{values}\n");
            let e = obj(text, Some(&mtl)).unwrap_err().to_string();
            assert!(e.starts_with("m.mtl:2:") && e.contains(&format!("`{key}` {problem}")), "{e}");
        }
        let m = obj(text, Some(&format!("newmtl a\n{key} 0.5\n"))).unwrap();
        assert_eq!(m.materials.len(), 1, "{key} 0.5");
    }
    let m = obj(text, Some("newmtl a\nKd 0.5 0.5 0.5\n")).unwrap();
    assert_eq!(m.materials.len(), 1);
    // A missing MTL is a warning and the default material (issue 14), not an error.
    let m = obj(text, None).unwrap();
    assert!(m.warnings.iter().any(|w| w.starts_with("m.mtl: ") && w.contains("cannot be opened")), "{:?}", m.warnings);
    assert_eq!(m.materials.len(), 1);
}

#[test]
fn ray_file_of_odd_length_fails_without_allocating_its_records() {
    let good = bytemuck::bytes_of(&trilab::rays::Ray::new([0.0; 3], [0.0, 0.0, 1.0])).to_vec();
    let mut odd = good.repeat(1000);
    odd.push(0);
    let (r, peak) = peak_bytes(|| parse_rays(Path::new("odd.rays"), &odd));
    assert!(r.unwrap_err().to_string().contains("not a multiple of 32"));
    assert!(peak < 4096, "peak {peak}");
    // A bad ray at the end: rejected before any record is copied.
    let mut bad = good.repeat(1000);
    bad[999 * 32..999 * 32 + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let (r, peak) = peak_bytes(|| parse_rays(Path::new("bad.rays"), &bad));
    assert!(r.unwrap_err().to_string().contains("ray 999 (byte offset 31968): origin.x is NaN"));
    assert!(peak < 4096, "peak {peak}");
}

/// Builds with every leaf policy and builder, validates, and encodes with every method.
fn build_all(mesh: &Mesh, builders: &[Builder]) {
    for &builder in builders {
        for leaf_policy in [LeafPolicy::Fill, LeafPolicy::Sah] {
            for leaf in [1, 4, 16] {
                let bvh = Bvh::build(mesh, &BuildOptions { leaf_policy, builder, ..BuildOptions::new(leaf) });
                bvh.validate(mesh).unwrap_or_else(|e| panic!("{builder:?} {leaf_policy} leaf {leaf}: {e}"));
                for m in Method::ALL {
                    m.encode(mesh, &bvh);
                }
            }
        }
    }
}

const BOTH: [Builder; 2] = [Builder::Binned { bins: 32 }, Builder::Sweep];

#[test]
fn pathological_meshes_build_validate_and_encode() {
    // Every triangle collapsed onto one point: all degenerate, one padding leaf.
    let point = Mesh::from_triangles(vec![[1.0, 2.0, 3.0]; 3], vec![[0, 1, 2]; 1000]);
    build_all(&point, &BOTH);
    // Extreme but finite coordinates: box extents and areas overflow f32.
    let big = f32::MAX;
    let extreme = Mesh::from_triangles(
        vec![
            [-big, -big, -big],
            [big, -big, -big],
            [-big, big, big],
            [1e38, 1e38, 0.0],
            [-1e38, 1e38, 1e-38],
            [1e-38, -1e-38, 1e38],
            [1e-38, 0.0, 0.0],
            [0.0, 1e-38, 0.0],
            [0.0, 0.0, 1e-38],
            [1e-45, 0.0, 0.0],
            [0.0, 1e-45, 0.0],
        ],
        vec![[0, 1, 2], [3, 4, 5], [6, 7, 8], [0, 4, 8], [8, 9, 10], [2, 5, 7], [1, 3, 6], [0, 9, 10]],
    );
    build_all(&extreme, &BOTH);
    // Many copies of one triangle: centroids coincide, so no SAH split separates them.
    let copies = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]; 20_000]);
    build_all(&copies, &BOTH);
}

/// 10^6 copies of one triangle through the default builder: the depth limit's median split
/// keeps it O(n log n) and the tree within the traversal stack.
#[test]
fn a_million_copies_of_one_triangle_build() {
    let mesh =
        Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![[0, 1, 2]; 1_000_000]);
    for leaf_policy in [LeafPolicy::Fill, LeafPolicy::Sah] {
        let bvh = Bvh::build(&mesh, &BuildOptions { leaf_policy, ..BuildOptions::new(4) });
        bvh.validate(&mesh).unwrap();
        assert!(bvh.stats().depth <= trilab::bvh::MAX_DEPTH);
        Method::Mt.encode(&mesh, &bvh);
    }
}
