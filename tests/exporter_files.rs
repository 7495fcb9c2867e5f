//! OBJ and MTL files as real exporters write them (issue 24, "Files from real exporters"): the
//! corpus in `tests/data/exporters/` (made by its `make.py`; its README says what each file is)
//! rendered by the binary. Every loadable file describes the scene of `reference.obj` in another
//! encoding or spelling, so it must render with the same scene hash (positions, triangles,
//! material ids and material records, `render`'s JSON): that holds only if every vertex is read
//! and every `usemtl` finds the material of the same bytes. The refused files must fail with an
//! error naming the file and the line, never a panic.

mod common;

use std::path::{Path, PathBuf};

use common::cli::{expect_error, run, s};

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/exporters")
}

/// Renders `name` from the corpus at 8x6, 1 spp into `out`: its stderr and JSON, or why not.
fn try_render(name: &str, out: &Path) -> Result<(String, serde_json::Value), String> {
    try_render_file(&corpus().join(name), out)
}

/// Renders the scene file `scene` as [`try_render`] renders one from the corpus.
fn try_render_file(scene: &Path, out: &Path) -> Result<(String, serde_json::Value), String> {
    let name = scene.file_name().unwrap().to_string_lossy().into_owned();
    let exr = out.join(&name).with_extension("exr");
    let args = ["render", "--scene", &s(scene), "--out", &s(&exr), "--width", "8", "--height", "6", "--spp", "1"];
    let (o, _) = run(&[&args[..], &["--quiet"]].concat(), None, &[], 120);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    if !o.status.success() || e.contains("validation:") {
        return Err(format!("{name}: failed: {e}"));
    }
    let json = std::fs::read_to_string(exr.with_extension("json")).map_err(|x| format!("{name}: no JSON: {x}"))?;
    Ok((e, serde_json::from_str(&json).unwrap()))
}

fn render(name: &str, out: &Path) -> (String, serde_json::Value) {
    try_render(name, out).unwrap_or_else(|e| panic!("{e}"))
}

fn warnings(json: &serde_json::Value) -> Vec<String> {
    json["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap().to_owned()).collect()
}

#[test]
fn exporter_files_load_as_the_reference_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (_, reference) = render("reference.obj", dir.path());
    assert!(warnings(&reference).is_empty(), "{:?}", warnings(&reference));
    let hash = reference["scene_sha256"].as_str().unwrap();
    let mut problems: Vec<String> = Vec::new();
    let mut kinds: Vec<&str> =
        reference["bsdfs_in_scene"].as_array().unwrap().iter().map(|k| k.as_str().unwrap()).collect();
    kinds.sort();
    assert_eq!(kinds, ["glass", "lambert", "mirror"], "the reference scene uses three materials");

    for (file, expect_warnings) in [
        // Latin-1 names, groups and comments (3ds Max), CRLF; `Métal` and `Mètal` differ only in
        // a byte that is not UTF-8, and must stay two materials; a texture name shown lossily.
        (
            "latin1.obj",
            &["latin1.mtl:11: material `Bois`: `map_Kd` bois_clair_\u{FFFD}.jpg: textures are not supported"][..],
        ),
        // An ASCII OBJ whose MTL holds Latin-1 comments (it was "read error").
        ("latin1_mtl.obj", &[]),
        // A byte-order mark right before the first vertex and the first `newmtl`.
        ("bom_utf8.obj", &[]),
        // UTF-16 with a byte-order mark, little- and big-endian, CRLF, OBJ and MTL alike.
        ("utf16le.obj", &[]),
        ("utf16be.obj", &[]),
        // `1e+0`, `1.E+0`, `.5`, `5.e-1`, `+1.`, `-.5e0` for the reference's numbers.
        ("numbers.obj", &[]),
    ] {
        // Every file is tried, so a failure lists all the files that do not load.
        let (_, json) = match try_render(file, dir.path()) {
            Ok(r) => r,
            Err(e) => {
                problems.push(e);
                continue;
            }
        };
        if json["scene_sha256"] != hash {
            problems.push(format!("{file} does not load as reference.obj (scene hash {})", json["scene_sha256"]));
        }
        let w = warnings(&json);
        if w.len() != expect_warnings.len() || !w.iter().zip(expect_warnings).all(|(w, x)| w.contains(x)) {
            problems.push(format!("{file}: warnings {w:?}, expected ones containing {expect_warnings:?}"));
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// `usemtl` with no name gives the faces the default material, as tinyobjloader does, with a
/// warning naming the line; it loads as its twin that names a material no MTL defines.
#[test]
fn usemtl_without_a_name_takes_the_default_material() {
    let dir = tempfile::tempdir().unwrap();
    let (_, twin) = render("usemtl_no_name_twin.obj", dir.path());
    let (stderr, json) = render("usemtl_no_name.obj", dir.path());
    assert_eq!(json["scene_sha256"], twin["scene_sha256"]);
    assert!(
        stderr.contains("usemtl_no_name.obj:12: usemtl without a material name") && stderr.contains("default material"),
        "{stderr}"
    );
}

/// What cannot be meant stays an error naming the file, the line and the problem.
#[test]
fn what_cannot_be_meant_is_refused_with_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    for (file, needles) in [
        ("refused_two_points.obj", &["refused_two_points.obj:2:", "cannot parse vertex position `v 1.2.3 0 0`"][..]),
        ("refused_nan.obj", &["refused_nan.obj:3:", "NaN or infinite"]),
        ("refused_inf.obj", &["refused_inf.obj:2:", "NaN or infinite"]),
        ("refused_latin1_number.obj", &["refused_latin1_number.obj:2:", "`v` line holds byte 0xB7 (column 4)"]),
        ("refused_utf16_truncated.obj", &["refused_utf16_truncated.obj:4:", "UTF-16", "half a character"]),
    ] {
        let exr = dir.path().join(file).with_extension("exr");
        let args = ["render", "--scene", &s(&corpus().join(file)), "--out", &s(&exr), "--width", "8", "--height", "6"];
        let (o, _) = run(&[&args[..], &["--spp", "1", "--quiet"]].concat(), None, &[], 60);
        expect_error(&o, needles);
        assert!(!exr.exists(), "{file}: a refused scene writes no image");
    }
}

/// The corpus's reference scene written into `dir` under the same names with every line ended
/// by the next of `ends` in turn (OBJ and MTL alike), after `edit` changed its lines.
fn reference_with_line_ends(dir: &Path, ends: &[&str], edit: impl Fn(&str) -> String) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for name in ["reference.obj", "reference.mtl"] {
        let text = std::fs::read_to_string(corpus().join(name)).unwrap();
        let out: String = text.lines().zip(ends.iter().cycle()).map(|(l, end)| edit(l) + end).collect();
        std::fs::write(dir.join(name), out).unwrap();
    }
    dir.join("reference.obj")
}

/// Blender 2.61 writes an unnamed material as `usemtl ` in the OBJ and `newmtl ` in the MTL (a
/// space, no name). The faces after that `usemtl` take that material: the reference scene with
/// its third material unnamed this way renders as the reference (the same material records and
/// ids), not as the default material would; a warning names each file and line.
#[test]
fn blender_2_61_unnamed_material_loads_as_the_reference_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (_, reference) = render("reference.obj", dir.path());
    let obj = "# Blender v2.61 (sub 0) OBJ File: ''\n# www.blender.org\nmtllib blender.mtl\no Box01\nv 0 0 0\n\
               v 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 -0.5\nusemtl Metal1\ns off\nf 1 2 3 4\nusemtl Metal2\n\
               s off\nf 1 2 5\nusemtl \ns off\nf 2 3 5\n";
    let mtl = "# Blender MTL File: 'None'\n# Material Count: 3\nnewmtl Metal1\nillum 3\nKs 0.9 0.9 0.9\n\n\
               newmtl Metal2\nillum 7\nNi 1.5\nTf 0.9 1 0.9\n\nnewmtl \nKd 0.6 0.4 0.2\n";
    let scene = dir.path().join("blender.obj");
    std::fs::write(&scene, obj).unwrap();
    std::fs::write(dir.path().join("blender.mtl"), mtl).unwrap();
    let (_, json) = render_file(&scene, dir.path());
    assert_eq!(json["scene_sha256"], reference["scene_sha256"]);
    let mtl_path = dir.path().join("blender.mtl");
    assert_eq!(
        warnings(&json),
        [
            format!(
                "{}:12: newmtl without a material name: it defines the unnamed material, which `usemtl` without a \
                 name selects",
                mtl_path.display()
            ),
            format!(
                "{}:16: usemtl without a material name: the faces that follow take the unnamed material (`newmtl` \
                 without a name, {}:12)",
                scene.display(),
                mtl_path.display()
            ),
        ]
    );

    // Without the unnamed material the third face is default grey: another scene.
    std::fs::write(dir.path().join("blender.mtl"), &mtl[..mtl.find("newmtl \n").unwrap()]).unwrap();
    let (_, json) = render_file(&scene, dir.path());
    assert_ne!(json["scene_sha256"], reference["scene_sha256"]);
    assert!(
        warnings(&json)[0].contains(
            "blender.obj:16: usemtl without a material name: the faces that follow take the default material"
        ),
        "{:?}",
        warnings(&json)
    );
}

fn render_file(scene: &Path, out: &Path) -> (String, serde_json::Value) {
    try_render_file(scene, out).unwrap_or_else(|e| panic!("{e}"))
}

/// Classic Mac OS ends lines with CR alone. The reference scene with CR line ends, and with
/// CRLF, CR and LF in turn, renders as the reference; an error in such a file names the line
/// counted with CR as a line end, in the OBJ and in the MTL.
#[test]
fn lone_cr_line_ends_load_as_the_reference_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (_, reference) = render("reference.obj", dir.path());
    for (sub, ends) in [("cr", &["\r"][..]), ("mixed", &["\r\n", "\r", "\n"][..])] {
        let scene = reference_with_line_ends(&dir.path().join(sub), ends, str::to_owned);
        let (_, json) = render_file(&scene, &dir.path().join(sub));
        assert_eq!(json["scene_sha256"], reference["scene_sha256"], "{sub}");
        assert!(warnings(&json).is_empty(), "{sub}: {:?}", warnings(&json));
    }

    // `v 0 1 0` (OBJ line 7) and `Ni 1.5` (MTL line 6) spoilt in turn.
    for (sub, ends) in [("cr", &["\r"][..]), ("mixed", &["\r\n", "\r", "\n"][..])] {
        for (spoil, needles) in [
            (("v 0 1 0", "v 0 1 x"), ["reference.obj:7: cannot parse vertex position `v 0 1 x`"]),
            (("Ni 1.5", "Ni high"), ["reference.mtl:6: `Ni` needs a number: `Ni high`"]),
        ] {
            let d = dir.path().join(format!("{sub}-bad"));
            let scene = reference_with_line_ends(&d, ends, |l| if l == spoil.0 { spoil.1.into() } else { l.into() });
            let exr = d.join("bad.exr");
            let args = ["render", "--scene", &s(&scene), "--out", &s(&exr), "--width", "8", "--height", "6"];
            let (o, _) = run(&[&args[..], &["--spp", "1", "--quiet"]].concat(), None, &[], 60);
            expect_error(&o, &needles);
            assert!(!exr.exists(), "{sub}: a refused scene writes no image");
        }
    }
}
