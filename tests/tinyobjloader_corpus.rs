//! A second public corpus (issue 51, item 4): tinyobjloader's test models
//! (`tests/data/tinyobjloader/`, its README says from where), each loaded through the library's
//! scene loader on its own thread with a wall-clock limit. Each file loads with the triangles
//! its faces give by the fan rule (a face of n >= 3 vertices is n - 2 triangles), or is refused
//! with an error naming the file and, where one line is at fault, the line: where
//! tinyobjloader's `tests/tester.cc` refuses it, and where a file gives nothing to trace. The expected
//! outcomes below were written from each file's text; docs/obj-mtl.md lists them with why, and
//! must list the same outcomes.

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use trilab::scene::{load_obj, Mesh};

/// How long one file may take to load (each is under 25 KB).
const LIMIT: Duration = Duration::from_secs(20);

#[derive(Debug)]
enum Expect {
    Loads {
        triangles: usize,
    },
    /// The error contains `/` + the file's name + this (`:line: ...` or `: ...`).
    Refused(&'static str),
}

/// Every OBJ file of the corpus, with its outcome.
const FILES: &[(&str, Expect)] = &[
    // 32 quads (and OpenSubdiv's `t` crease tags, ignored with a warning).
    ("catmark_torus_creases0.obj", Expect::Loads { triangles: 64 }),
    ("colorspace-issue-184.obj", Expect::Loads { triangles: 1 }),
    // 18 quads (the front wall's is commented out).
    ("cornell_box.obj", Expect::Loads { triangles: 36 }),
    ("cornell_box_multimaterial.obj", Expect::Loads { triangles: 36 }),
    // 6 quads.
    ("cube-vertex-w-component.obj", Expect::Loads { triangles: 12 }),
    ("cube-vertexcol.obj", Expect::Loads { triangles: 12 }),
    ("cube.obj", Expect::Loads { triangles: 12 }),
    // `f 1` and `f 8 7`: no face of three vertices (tinyobjloader loads it, with no faces).
    ("invalid-face-definition.obj", Expect::Refused(": contains no triangles")),
    // No `v` at all: vertex 1 does not exist (nor does texture coordinate -2 of one).
    ("invalid-relative-texture-index.obj", Expect::Refused(":2: face vertex index 1 is out of range")),
    // `f -4 -3 -2` with no vertex before it.
    ("invalid-relative-vertex-index.obj", Expect::Refused(":1: face vertex index -4 is out of range")),
    // 12 triangles written as triangles.
    ("issue-138.obj", Expect::Loads { triangles: 12 }),
    // `f 0/0/0 ...`: 0 is no OBJ index (tinyobjloader refuses it too).
    ("issue-140-zero-face-idx.obj", Expect::Refused(":16: face vertex index 0 is out of range")),
    ("issue-161-inconsistent-f.obj", Expect::Loads { triangles: 12 }),
    ("issue-162-smoothing-group.obj", Expect::Loads { triangles: 12 }),
    ("issue-235-usemtl-then-o.obj", Expect::Loads { triangles: 2 }),
    // Its MTL is in tinyobjloader's tests/assets, not here: a warning, the default material.
    ("issue-244-mtl-searchpaths.obj", Expect::Loads { triangles: 2 }),
    ("issue-246-usemtl-whitespace.obj", Expect::Loads { triangles: 1 }),
    ("issue-248-texres-texopt.obj", Expect::Loads { triangles: 12 }),
    // 14 quads.
    ("issue-295-trianguation-failure.obj", Expect::Loads { triangles: 28 }),
    // Faces of 7, 8 and 5 vertices: 5 + 6 + 3.
    ("issue-319-002.obj", Expect::Loads { triangles: 14 }),
    // One face of 10 vertices.
    ("issue-319-003.obj", Expect::Loads { triangles: 8 }),
    // A quad and a triangle.
    ("issue-330.obj", Expect::Loads { triangles: 3 }),
    // `mtllib` and `usemtl` only.
    ("issue-356-leading-spaces-newmtl.obj", Expect::Refused(": contains no triangles")),
    ("issue-92.obj", Expect::Loads { triangles: 1 }),
    ("issue-95-2.obj", Expect::Loads { triangles: 1 }),
    ("issue-95.obj", Expect::Loads { triangles: 1 }),
    ("leading-decimal-dot-issue-201.obj", Expect::Loads { triangles: 1 }),
    ("leading-zero-in-exponent-notation-issue-210.obj", Expect::Loads { triangles: 1 }),
    // Two polylines, `l 1 2 3 4` and `l 5 6 7 8` (tobj alone made four triangles of them).
    (
        "line-prim.obj",
        Expect::Refused(": contains no triangles (no `f` lines with 3 or more vertices; it holds polylines"),
    ),
    // 400 triangles, Blender 2.73.
    ("map-bump.obj", Expect::Loads { triangles: 400 }),
    ("missing_material_file.obj", Expect::Loads { triangles: 36 }),
    // Three library names, the last two with escaped spaces; the third exists.
    ("mtl filename with whitespace issue46.obj", Expect::Loads { triangles: 12 }),
    ("mtllib-multiple-files-issue-112.obj", Expect::Loads { triangles: 1 }),
    ("no_material.obj", Expect::Loads { triangles: 36 }),
    ("norm-texopt.obj", Expect::Loads { triangles: 1 }),
    // One quad.
    ("pbr-mat-ext.obj", Expect::Loads { triangles: 2 }),
    // `p 1 2 3 4 5 6 7 8`.
    (
        "points-prim.obj",
        Expect::Refused(": contains no triangles (no `f` lines with 3 or more vertices; it holds points"),
    ),
    ("refl.obj", Expect::Loads { triangles: 12 }),
    ("skin-weight.obj", Expect::Loads { triangles: 12 }),
    // A quad and a triangle naming normals the file does not define (their lines are comments).
    ("smoothing-group-two-squares.obj", Expect::Loads { triangles: 3 }),
    // 3 quads.
    ("smoothing-normal.obj", Expect::Loads { triangles: 6 }),
    // `v nan -nan nan`, `v inf ...` parse as numbers; `1.#IND` on line 14 does not.
    ("test-nan.obj", Expect::Refused(":14: cannot parse vertex position `v 1.#IND -1.#IND 1.#IND`")),
    ("texture-filename-with-whitespace.obj", Expect::Loads { triangles: 12 }),
    ("texture-options-issue-85.obj", Expect::Loads { triangles: 1 }),
    ("tr-and-d-issue-43.obj", Expect::Loads { triangles: 400 }),
    // 3 quads, then `usemtl` on the last line.
    ("usemtl-issue-104.obj", Expect::Loads { triangles: 6 }),
    ("usemtl-issue-68.obj", Expect::Loads { triangles: 400 }),
];

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/tinyobjloader")
}

/// Loads `file` of the corpus on its own thread: the mesh or the error's text, or why neither
/// came (a panic, or no answer within [`LIMIT`]).
fn load(file: &str) -> Result<Result<Mesh, String>, String> {
    let path = corpus().join(file);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(load_obj(&path).map_err(|e| e.to_string()));
    });
    match rx.recv_timeout(LIMIT) {
        Ok(r) => Ok(r),
        Err(mpsc::RecvTimeoutError::Timeout) => Err(format!("{file}: no answer in {LIMIT:?}")),
        Err(mpsc::RecvTimeoutError::Disconnected) => Err(format!("{file}: the loader panicked")),
    }
}

#[test]
fn every_file_loads_or_is_refused_by_name() {
    let mut problems = Vec::new();
    for (file, expect) in FILES {
        let outcome = match load(file) {
            Ok(o) => o,
            Err(e) => {
                problems.push(e);
                continue;
            }
        };
        match (outcome, expect) {
            (Ok(m), Expect::Loads { triangles }) if m.triangles.len() == *triangles => {}
            (Err(e), Expect::Refused(needle)) if e.contains(&format!("/{file}{needle}")) => {}
            (Ok(m), _) => problems.push(format!("{file}: loaded {} triangles, expected {expect:?}", m.triangles.len())),
            (Err(e), _) => problems.push(format!("{file}: refused ({e}), expected {expect:?}")),
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

#[test]
fn the_corpus_is_every_obj_file_of_the_folder() {
    let mut found: Vec<String> = std::fs::read_dir(corpus())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.ends_with(".obj"))
        .collect();
    found.sort();
    let mut listed: Vec<String> = FILES.iter().map(|f| f.0.to_owned()).collect();
    listed.sort();
    assert_eq!(found, listed);
}

/// What the libraries give where tinyobjloader's tests look: a `mtllib` naming several files
/// (some missing, some with escaped spaces) finds the one that exists; `usemtl` with two spaces
/// finds its material; texture options and PBR keys are warnings, never refusals.
#[test]
fn libraries_give_the_materials_tinyobjloader_finds() {
    let diffuse = |file: &str| {
        let m = load(file).unwrap().unwrap();
        let mat = &m.materials[m.material_ids[0] as usize];
        (mat.name.clone(), mat.gpu.diffuse, m.warnings)
    };
    let (name, kd, w) = diffuse("mtl filename with whitespace issue46.obj");
    assert_eq!((name.as_str(), kd), ("green", [0.0, 1.0, 0.0]), "{w:?}");
    assert_eq!(w.iter().filter(|w| w.contains("cannot be opened")).count(), 2, "{w:?}");
    assert!(w.iter().any(|w| w.contains("/invalid file with spaces.mtl: material library")), "{w:?}");
    let (name, _, w) = diffuse("mtllib-multiple-files-issue-112.obj");
    assert_eq!(name, "default", "{w:?}");
    let (name, kd, _) = diffuse("issue-246-usemtl-whitespace.obj");
    assert_eq!((name.as_str(), kd), ("1", [1.0; 3]));
    let (_, _, w) = diffuse("texture-options-issue-85.obj");
    assert!(
        w.iter().any(|w| w.contains("texture-options-issue-85.mtl:36: material `bm3`: `disp` -type cube_back")),
        "{w:?}"
    );
    let m = load("pbr-mat-ext.obj").unwrap().unwrap();
    assert_eq!(m.materials[m.material_ids[0] as usize].gpu.emission, [0.1; 3]);
    assert!(m.warnings.iter().any(|w| w.contains("pbr-mat-ext.mtl:7: material `pbr`: `Pr`")), "{:?}", m.warnings);
}

/// docs/obj-mtl.md lists every file with the outcome above.
#[test]
fn the_docs_list_the_same_outcomes() {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/obj-mtl.md")).unwrap();
    let section = "\n## tinyobjloader's test models\n";
    let start = doc.find(section).expect("docs/obj-mtl.md has a section on tinyobjloader's test models");
    let body = &doc[start + section.len()..];
    let body = &body[..body.find("\n## ").unwrap_or(body.len())];
    let mut rows: Vec<(String, String)> = body
        .lines()
        .filter(|l| l.starts_with("| `"))
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").map(str::trim).collect();
            (cells[0].trim_matches('`').to_owned(), cells[1].to_owned())
        })
        .collect();
    rows.sort();
    let mut expected: Vec<(String, String)> = FILES
        .iter()
        .map(|(f, e)| {
            let outcome = match e {
                Expect::Loads { triangles: 1 } => "loads, 1 triangle".to_owned(),
                Expect::Loads { triangles } => format!("loads, {triangles} triangles"),
                Expect::Refused(_) => "refused".to_owned(),
            };
            (f.to_string(), outcome)
        })
        .collect();
    expected.sort();
    assert_eq!(rows, expected);
}
