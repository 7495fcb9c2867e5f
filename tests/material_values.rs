//! MTL values and render options the path tracer cannot honour (issue 24, defect 4): each is
//! refused naming the file, the line, the material and the key (or the option), before any
//! image is written, or clamped with a warning naming the same, by the rule table of
//! docs/formats.md ("MTL values"). Runs the binary.

mod common;

use std::path::Path;

use common::cli::{expect_error, ok, run, s};

/// `a.obj` (one triangle, material `a`) and `m.mtl` holding `mtl` in `dir`.
fn scene(dir: &Path, mtl: &str) -> String {
    std::fs::write(dir.join("a.obj"), "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    s(&dir.join("a.obj"))
}

fn render(dir: &Path, extra: &[&str]) -> std::process::Output {
    let out = s(&dir.join("r.exr"));
    let args = ["render", "--scene", &s(&dir.join("a.obj")), "--out", &out, "--width", "8", "--height", "6"];
    run(&[&args[..], &["--spp", "1", "--quiet"], extra].concat(), None, &[], 120).0
}

#[test]
fn values_that_cannot_be_meant_are_refused_naming_file_line_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (mtl, needles) in [
        // Rendered all black with exit 0.
        ("newmtl a\nKe inf 1 1\n", &["m.mtl:2:", "material `a`", "`Ke`", "finite"][..]),
        // Dropped samples with a warning naming neither file nor line.
        ("newmtl a\nKd nan 0.5 0.5\n", &["m.mtl:2:", "`Kd`", "finite"]),
        // Blackened the object silently.
        ("newmtl a\nKs 0.5 0.5 0.5\n\nNs inf\n", &["m.mtl:4:", "`Ns`", "finite"]),
        ("newmtl a\nillum 7\nNi nan\n", &["m.mtl:3:", "`Ni`", "finite"]),
        // Made the glass vanish.
        ("newmtl a\nillum 7\nNi 0\n", &["m.mtl:3:", "`Ni` 0", "index of refraction"]),
        ("newmtl a\nNi -1.5\nillum 4\n", &["m.mtl:2:", "`Ni` -1.5", "index of refraction"]),
        // Wrote negative radiance into the EXR.
        ("newmtl a\nKd -1 -1 -1\n", &["m.mtl:2:", "`Kd` -1 -1 -1", "negative"]),
        ("newmtl a\nKe 1 1 -1\n", &["m.mtl:2:", "`Ke`", "negative"]),
        ("newmtl a\nillum 7\nTf 0.5 -1 0.5\n", &["m.mtl:3:", "`Tf`", "negative"]),
        ("newmtl a\nd 2\n", &["m.mtl:2:", "`d` 2"]),
    ] {
        scene(d, mtl);
        let o = render(d, &[]);
        expect_error(&o, needles);
        assert!(!d.join("r.exr").exists() && !d.join("r.png").exists(), "{mtl:?}: refused, yet an image was written");
    }
}

/// An albedo above 1 is clamped to 1 with a warning naming file, line, material and key: the
/// scene then renders exactly as the one that says 1 (same scene hash, which covers the material
/// records the kernels read). `Ni 0` on an opaque material, which exporters write and no BSDF
/// reads, loads without a word.
#[test]
fn albedos_above_one_are_clamped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let hash = |mtl: &str| {
        scene(d, mtl);
        let e = ok(&render(d, &[]));
        let json: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("r.json")).unwrap()).unwrap();
        (json["scene_sha256"].as_str().unwrap().to_owned(), e)
    };
    let (one, e) = hash("newmtl a\nKd 1 1 1\nNi 0\n");
    assert!(!e.contains("warning"), "{e}");
    let (two, e) = hash("newmtl a\nKd 2 2 2\nNi 0\n");
    assert_eq!(one, two, "Kd 2 must render as Kd 1");
    assert!(e.contains("m.mtl:2: material `a`: `Kd` 2 2 2: above 1") && e.contains("clamped to 1"), "{e}");
}

/// `--exposure` that 2^EV cannot scale by (NaN gave a black PNG with exit 0) is refused naming
/// the option, before any work: no output is written.
#[test]
fn exposure_must_be_a_finite_number_of_stops() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    scene(d, "newmtl a\nKd 0.5 0.5 0.5\n");
    for ev in ["nan", "inf", "-inf", "1000"] {
        let o = render(d, &["--exposure", ev]);
        expect_error(&o, &["--exposure", "finite number of stops"]);
        assert!(!d.join("r.png").exists(), "--exposure {ev}: refused, yet a PNG was written");
    }
    ok(&render(d, &["--exposure", "-1.5"]));
}
