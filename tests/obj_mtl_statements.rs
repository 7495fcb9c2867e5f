//! Every OBJ and MTL statement of docs/obj-mtl.md, one case per row of its tables (issue 51,
//! item 4): each case writes a small OBJ (and MTL) holding the statement to a temporary folder,
//! loads it through the library's scene loader, and checks the row's outcome: accepted (loads,
//! with the values the statement gives and no warning), ignored with a warning (loads; a
//! warning names the file and the line), or refused (an error naming the file, the line and the
//! key). The tables and the cases must list the same statements with the same outcomes.

use std::path::Path;

use trilab::scene::{load_obj, BsdfKind, Material, Mesh};

/// What a row says happens.
#[derive(Clone, Debug)]
enum Outcome {
    /// Loads with no warning but those containing one of these (warnings of other statements
    /// the case needs, such as `vt` lines for a face that names them).
    Accepted(&'static [&'static str]),
    /// Loads, and a warning contains `/` + this (the file's name, the line, the key ...).
    Warned(String),
    /// Fails with an error that contains `/` + this.
    Refused(String),
}

impl Outcome {
    /// The table's word for it.
    fn word(&self) -> &'static str {
        match self {
            Outcome::Accepted(_) => "accepted",
            Outcome::Warned(_) => "ignored with a warning",
            Outcome::Refused(_) => "refused",
        }
    }
}

struct Case {
    /// The row's first cell, as the table writes it.
    row: String,
    outcome: Outcome,
    /// The scene's files: `a.obj`, and the libraries it names.
    files: Vec<(&'static str, String)>,
    /// What else the loaded scene must hold.
    check: Box<dyn Fn(&Mesh)>,
}

/// One triangle, lines 1-4.
const TRI: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/// One triangle of material `a` from `m.mtl`: the scene of the MTL cases.
const SCENE: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n";

fn no_check() -> Box<dyn Fn(&Mesh)> {
    Box::new(|_| {})
}

fn obj_case(row: &str, outcome: Outcome, obj: &str, check: Box<dyn Fn(&Mesh)>) -> Case {
    let files = vec![("a.obj", obj.to_owned()), ("m.mtl", "newmtl a\nKd 0.5 0.5 0.5\n".to_owned())];
    Case { row: row.to_owned(), outcome, files, check }
}

/// An OBJ statement `line` after [`TRI`] (so on line 5), ignored with a warning naming it.
fn obj_ignored(row: &str, line: &str) -> Case {
    let key = line.split_whitespace().next().unwrap();
    let warned = Outcome::Warned(format!("a.obj:5: `{key}`"));
    obj_case(row, warned, &format!("{TRI}{line}\n"), Box::new(|m| assert_eq!(m.triangles.len(), 1)))
}

/// `m.mtl` holding `newmtl a` and then `lines` (the statement on line 2), for [`SCENE`].
fn mtl_case(row: &str, outcome: Outcome, lines: &str, check: Box<dyn Fn(&Mesh)>) -> Case {
    let files = vec![("a.obj", SCENE.to_owned()), ("m.mtl", format!("newmtl a\n{lines}\n"))];
    Case { row: row.to_owned(), outcome, files, check }
}

/// An MTL statement on line 2 ignored with a warning that holds `needle` after the material.
fn mtl_warned(row: &str, lines: &str, needle: &str) -> Case {
    mtl_case(row, Outcome::Warned(format!("m.mtl:2: material `a`: {needle}")), lines, no_check())
}

fn material(m: &Mesh) -> &Material {
    &m.materials[m.material_ids[0] as usize]
}

fn close(a: [f32; 3], b: [f32; 3], tolerance: f32) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tolerance)
}

/// Writes `files` to a new temporary folder and loads its `a.obj`.
fn load(files: &[(&str, String)]) -> trilab::Result<Mesh> {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    load_obj(&dir.path().join("a.obj"))
}

/// The colour `key` gives the scene's material, as the BSDF it selects reads it; `lines` is the
/// MTL after `newmtl a` (`Tf` is read by glass only, so `illum 7` follows it).
fn colour(key: &str, lines: &str) -> [f32; 3] {
    let extra = if key == "Tf" { "\nillum 7" } else { "" };
    let m = load(&[("a.obj", SCENE.to_owned()), ("m.mtl", format!("newmtl a\n{lines}{extra}\n"))]).unwrap();
    assert!(m.warnings.is_empty(), "{lines}: {:?}", m.warnings);
    let g = material(&m).gpu;
    match key {
        "Kd" => g.diffuse,
        "Ks" => g.specular,
        "Ke" => g.emission,
        "Tf" => g.diffuse,
        _ => unreachable!("{key} is not observed"),
    }
}

/// IEC 61966-2-1's linear-sRGB-to-XYZ matrix (D65), the inverse of the one the loader converts
/// `xyz` colours with: the XYZ of a known r g b.
fn srgb_to_xyz(rgb: [f32; 3]) -> [f32; 3] {
    let m = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
    m.map(|row: [f32; 3]| row[0] * rgb[0] + row[1] * rgb[1] + row[2] * rgb[2])
}

fn colour_cases() -> Vec<Case> {
    let mut cases = Vec::new();
    for key in ["Ka", "Kd", "Ks", "Ke", "Tf"] {
        // Ks stays small: with the default Kd of 0.8 a sum above 1 is warned about.
        let tf = if key == "Tf" { "\nillum 7" } else { "" };
        let observe = move |expect: [f32; 3], tolerance: f32| -> Box<dyn Fn(&Mesh)> {
            Box::new(move |m: &Mesh| {
                let g = material(m).gpu;
                let got = match key {
                    "Ka" => return,
                    "Kd" | "Tf" => g.diffuse,
                    "Ks" => g.specular,
                    _ => g.emission,
                };
                assert!(close(got, expect, tolerance), "{key}: {got:?}, expected {expect:?}");
            })
        };
        let rgb = format!("{key} 0.1 0.15 0.05{tf}");
        cases.push(mtl_case(&format!("`{key} r g b`"), Outcome::Accepted(&[]), &rgb, observe([0.1, 0.15, 0.05], 0.0)));
        let one = format!("{key} 0.2{tf}");
        cases.push(mtl_case(&format!("`{key} r`"), Outcome::Accepted(&[]), &one, observe([0.2; 3], 0.0)));
        let two = Outcome::Refused(format!("m.mtl:2: `{key}` takes one number or three (r [g b]"));
        cases.push(mtl_case(&format!("`{key} r g`"), two, &format!("{key} 0.2 0.3"), no_check()));
        // The 4-decimal matrices are each other's inverse to about 1e-4.
        let want = [0.16, 0.08, 0.04];
        let [x, y, z] = srgb_to_xyz(want);
        let xyz = format!("{key} xyz {x} {y} {z}{tf}");
        cases.push(mtl_case(&format!("`{key} xyz x y z`"), Outcome::Accepted(&[]), &xyz, observe(want, 1e-3)));
        let check: Box<dyn Fn(&Mesh)> = Box::new(move |_| {
            if key != "Ka" {
                let one = colour(key, &format!("{key} xyz 0.15"));
                assert_eq!(one, colour(key, &format!("{key} xyz 0.15 0.15 0.15")), "{key}");
                // Converted, not read as grey: equal X, Y and Z is redder than sRGB's white.
                assert!(one[0] > one[2] + 0.01, "{key}: {one:?}");
            }
        });
        cases.push(mtl_case(&format!("`{key} xyz x`"), Outcome::Accepted(&[]), &format!("{key} xyz 0.15{tf}"), check));
        let spectral = format!("{key} spectral wood.rfl 0.8{tf}");
        let outcome = if key == "Ka" {
            Outcome::Warned("m.mtl:2: material `a`: `Ka` spectral wood.rfl: a .rfl reflectance curve".into())
        } else {
            Outcome::Refused(format!(
                "m.mtl:2: material `a`: `{key}` spectral wood.rfl: a .rfl reflectance curve is not supported"
            ))
        };
        cases.push(mtl_case(&format!("`{key} spectral file.rfl factor`"), outcome, &spectral, no_check()));
    }
    cases
}

fn kind_is(kind: BsdfKind) -> Box<dyn Fn(&Mesh)> {
    Box::new(move |m| assert_eq!(material(m).kind, kind))
}

fn mtl_cases() -> Vec<Case> {
    let accepted = || Outcome::Accepted(&[]);
    let mut cases = vec![
        mtl_case("`# comment`", accepted(), "# a comment\nKd 0.5 0.5 0.5", no_check()),
        mtl_case("`newmtl name`", accepted(), "", Box::new(|m| assert_eq!(material(m).name, "a"))),
    ];
    cases.extend(colour_cases());
    for (n, kind) in [
        (0, BsdfKind::Lambert),
        (1, BsdfKind::Lambert),
        (2, BsdfKind::BlinnPhong),
        (3, BsdfKind::Mirror),
        (4, BsdfKind::Glass),
        (5, BsdfKind::Mirror),
        (6, BsdfKind::Glass),
        (7, BsdfKind::Glass),
        (8, BsdfKind::Mirror),
        (9, BsdfKind::Glass),
    ] {
        cases.push(mtl_case(&format!("`illum {n}`"), accepted(), &format!("illum {n}\nKs 0.1 0.1 0.1"), kind_is(kind)));
    }
    let texture = |row: &str, line: &str, shown: &str| {
        mtl_warned(row, line, &format!("{shown}: textures are not supported; ignored"))
    };
    cases.extend([
        mtl_warned("`illum 10`", "illum 10", "`illum` 10 is not supported"),
        mtl_case(
            "`illum two`",
            Outcome::Refused("m.mtl:2: `illum` needs an illumination model number".into()),
            "illum two",
            no_check(),
        ),
        mtl_case("`d 1`", accepted(), "d 1", no_check()),
        mtl_warned("`d 0.5`", "d 0.5", "`d` 0.5: partial transparency is not supported"),
        mtl_warned("`d -halo 0.5`", "d -halo 0.5", "`d` -halo 0.5: a dissolve that changes with the viewing angle"),
        mtl_case("`Tr 0`", accepted(), "Tr 0", no_check()),
        mtl_warned("`Tr 0.5`", "Tr 0.5", "`Tr` 0.5: partial transparency is not supported"),
        mtl_case(
            "`Ns 40`",
            accepted(),
            "Ns 40\nKs 0.1 0.1 0.1",
            Box::new(|m| assert_eq!(material(m).gpu.exponent, 40.0)),
        ),
        mtl_case("`Ni 1.33`", accepted(), "Ni 1.33\nillum 7", Box::new(|m| assert_eq!(material(m).gpu.ior, 1.33))),
        mtl_warned("`sharpness 60`", "sharpness 60", "`sharpness` is not supported"),
        texture("`map_Ka file`", "map_Ka wood.png", "`map_Ka` wood.png"),
        texture("`map_Kd file`", "map_Kd wood.png", "`map_Kd` wood.png"),
        texture("`map_Ks file`", "map_Ks wood.png", "`map_Ks` wood.png"),
        texture("`map_Ns file`", "map_Ns wood.png", "`map_Ns` wood.png"),
        texture("`map_d file`", "map_d wood.png", "`map_d` wood.png"),
        // tobj files `map_bump` and `bump` as `map_Bump`, which the warning names.
        texture("`map_bump file`", "map_bump wood.png", "`map_Bump` wood.png"),
        texture("`bump file`", "bump wood.png", "`map_Bump` wood.png"),
        texture("`disp file`", "disp wood.png", "`disp` wood.png"),
        texture("`decal file`", "decal wood.png", "`decal` wood.png"),
        texture("`refl -type sphere file`", "refl -type sphere sky.png", "`refl` -type sphere sky.png"),
        texture("`map_aat on`", "map_aat on", "`map_aat` on"),
        texture(
            "`map_Kd -o u v w -s u v w -t u v w file`",
            "map_Kd -o 0.1 0 0 -s 2 2 1 -t 0.1 0.1 0 wood.png",
            "`map_Kd` -o 0.1 0 0 -s 2 2 1 -t 0.1 0.1 0 wood.png",
        ),
        texture(
            "`map_Kd -blendu on -blendv off -clamp on file`",
            "map_Kd -blendu on -blendv off -clamp on wood.png",
            "`map_Kd` -blendu on -blendv off -clamp on wood.png",
        ),
        texture(
            "`map_Kd -boost 2 -mm 0 1 -texres 512 -cc on file`",
            "map_Kd -boost 2 -mm 0 1 -texres 512 -cc on wood.png",
            "`map_Kd` -boost 2 -mm 0 1 -texres 512 -cc on wood.png",
        ),
        texture(
            "`map_bump -bm 2 -imfchan r file`",
            "map_bump -bm 2 -imfchan r b.png",
            "`map_Bump` -bm 2 -imfchan r b.png",
        ),
        texture("`map_Kd file name with spaces.png`", "map_Kd my wood 01.png", "`map_Kd` my wood 01.png"),
        mtl_warned("`map_Kd` without a file", "map_Kd", "`map_Kd` names no file; ignored"),
        mtl_warned("`Pr 0.2`", "Pr 0.2", "`Pr` (a PBR extension) is not supported"),
        mtl_warned("`Pm 0.3`", "Pm 0.3", "`Pm` (a PBR extension) is not supported"),
        mtl_warned("`Ps 0.4`", "Ps 0.4", "`Ps` (a PBR extension) is not supported"),
        mtl_warned("`Pc 0.5`", "Pc 0.5", "`Pc` (a PBR extension) is not supported"),
        mtl_warned("`Pcr 0.6`", "Pcr 0.6", "`Pcr` (a PBR extension) is not supported"),
        mtl_warned("`aniso 0.7`", "aniso 0.7", "`aniso` (a PBR extension) is not supported"),
        mtl_warned("`anisor 0.8`", "anisor 0.8", "`anisor` (a PBR extension) is not supported"),
        texture("`norm file`", "norm n.png", "`norm` n.png"),
        texture("`map_Pr file`", "map_Pr r.png", "`map_Pr` r.png"),
        texture("`map_Ke file`", "map_Ke e.png", "`map_Ke` e.png"),
        mtl_warned("`Kt r g b`", "Kt 0.1 0.2 0.3", "`Kt` is not an MTL statement"),
        mtl_case(
            "`trilab_bsdf kind name=value`",
            accepted(),
            "trilab_bsdf oren-nayar sigma=0.3",
            Box::new(|m| assert_eq!((material(m).kind, material(m).gpu.sigma), (BsdfKind::OrenNayar, 0.3))),
        ),
    ]);
    cases
}

fn obj_cases() -> Vec<Case> {
    let accepted = || Outcome::Accepted(&[]);
    let warned = |s: &str| Outcome::Warned(s.to_owned());
    let refused = |s: &str| Outcome::Refused(s.to_owned());
    let one = || -> Box<dyn Fn(&Mesh)> { Box::new(|m| assert_eq!(m.triangles.len(), 1)) };
    let positions = |p: [[f32; 3]; 3]| -> Box<dyn Fn(&Mesh)> {
        Box::new(move |m| assert_eq!((m.positions.as_slice(), m.triangles.len()), (&p[..], 1)))
    };
    let unit = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let diffuse = |d: [f32; 3]| -> Box<dyn Fn(&Mesh)> { Box::new(move |m| assert_eq!(material(m).gpu.diffuse, d)) };
    let libs = |obj: &str, files: &[(&'static str, &str)], outcome: Outcome, row: &str, check| {
        let mut c = obj_case(row, outcome, obj, check);
        c.files.extend(files.iter().map(|(n, t)| (*n, t.to_string())));
        c
    };
    let mut cases = vec![
        obj_case("`# comment`", accepted(), &format!("# a comment\n{TRI}"), one()),
        obj_case("`v x y z`", accepted(), TRI, positions(unit)),
        obj_case("`v x y z w`", accepted(), "v 0 0 0\nv 2 0 0 2\nv 0 1 0\nf 1 2 3\n", positions(unit)),
        obj_case(
            "`v x y z 0`",
            refused("a.obj:2: bad vertex weight w"),
            "v 0 0 0\nv 1 0 0 0\nv 0 1 0\nf 1 2 3\n",
            no_check(),
        ),
        obj_case(
            "`v x y`",
            refused("a.obj:2: cannot parse vertex position"),
            "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n",
            no_check(),
        ),
        obj_case(
            "`v x y z r g b`",
            warned("a.obj: vertex colours (`v x y z r g b`) are ignored"),
            "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n",
            positions(unit),
        ),
        obj_case(
            "`v x y z r g b` on some vertices only",
            warned("a.obj: vertex colours (`v x y z r g b`) are ignored"),
            "v 0 0 0 1 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            positions(unit),
        ),
        obj_case(
            "`vt u v w`",
            warned("a.obj: texture coordinates (`vt`) are ignored"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0 0\nf 1/1 2/1 3/1\n",
            positions(unit),
        ),
        obj_case(
            "`vn i j k`",
            warned("a.obj: vertex normals (`vn`) are ignored"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n",
            positions(unit),
        ),
        obj_ignored("`vp u v w`", "vp 0.5 0.5 1"),
        obj_case("`f v1 v2 v3`", accepted(), TRI, positions(unit)),
        obj_case(
            "`f v1 v2 v3 v4 ...`",
            accepted(),
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",
            Box::new(|m| assert_eq!(m.triangles, [[0, 1, 2], [0, 2, 3]])),
        ),
        obj_case(
            "`f v1/vt1/vn1 ...`",
            Outcome::Accepted(&["texture coordinates (`vt`) are ignored", "vertex normals (`vn`) are ignored"]),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\n",
            positions(unit),
        ),
        obj_case(
            "`f v1//vn1 ...`",
            Outcome::Accepted(&["vertex normals (`vn`) are ignored"]),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\n",
            positions(unit),
        ),
        obj_case("`f -3 -2 -1`", accepted(), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n", positions(unit)),
        obj_case(
            "`f v1 v2 v9` (index out of range)",
            refused("a.obj:4: face vertex index 9 is out of range"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            no_check(),
        ),
        obj_case(
            "`f 0 1 2`",
            refused("a.obj:4: face vertex index 0 is out of range"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
            no_check(),
        ),
        obj_case(
            "`f v1 v2`",
            warned("a.obj:5: `f` with fewer than three vertices is not a surface; ignored"),
            &format!("{TRI}f 1 2\n"),
            one(),
        ),
        // tobj alone made a triangle of this polyline.
        obj_ignored("`l v1 v2 v3`", "l 1 2 3"),
        obj_ignored("`p v1 v2`", "p 1 2"),
        obj_case("`o name`", accepted(), &format!("o box\n{TRI}"), one()),
        obj_case("`g name ...`", accepted(), &format!("g box lid\n{TRI}"), one()),
        obj_case("`s 1`", accepted(), &format!("s 1\n{TRI}s off\n"), one()),
        obj_ignored("`mg 1 0.5`", "mg 1 0.5"),
        obj_case(
            "`usemtl name`",
            accepted(),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
            Box::new(|m| assert_eq!((material(m).name.as_str(), material(m).gpu.diffuse), ("a", [0.5; 3]))),
        ),
        obj_case(
            "`usemtl` naming no material",
            warned("a.obj:5: usemtl `zz`: no material library defines it"),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl zz\nf 1 2 3\n",
            Box::new(|m| assert_eq!(material(m), &Material::default())),
        ),
        obj_case(
            "`usemtl` without a name",
            warned("a.obj:5: usemtl without a material name"),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl\nf 1 2 3\n",
            Box::new(|m| assert_eq!(material(m), &Material::default())),
        ),
        obj_case(
            "`mtllib file.mtl`",
            accepted(),
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n",
            diffuse([0.5; 3]),
        ),
        libs(
            "mtllib x.mtl y.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 1 2 3\n",
            &[
                ("x.mtl", "newmtl a\nKd 0.1 0.1 0.1\n"),
                ("y.mtl", "newmtl a\nKd 0.9 0.9 0.9\nnewmtl b\nKd 0.3 0.3 0.3\n"),
            ],
            accepted(),
            "`mtllib a.mtl b.mtl`",
            Box::new(|m| {
                let d = |t: usize| m.materials[m.material_ids[t] as usize].gpu.diffuse;
                assert_eq!((d(0), d(1)), ([0.1; 3], [0.3; 3]), "the first library listed gives `a`");
            }),
        ),
        libs(
            "mtllib my file.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl s\nf 1 2 3\n",
            &[("my file.mtl", "newmtl s\nKd 0.25 0.25 0.25\n")],
            accepted(),
            "`mtllib my file.mtl`",
            diffuse([0.25; 3]),
        ),
        libs(
            "mtllib my\\ file.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl s\nf 1 2 3\n",
            &[("my file.mtl", "newmtl s\nKd 0.25 0.25 0.25\n")],
            accepted(),
            "`mtllib my\\ file.mtl`",
            diffuse([0.25; 3]),
        ),
        obj_case(
            "`mtllib missing.mtl`",
            warned("missing.mtl: material library named by"),
            &format!("mtllib missing.mtl\n{TRI}"),
            one(),
        ),
    ];
    for (row, line) in [
        ("`cstype bspline`", "cstype bspline"),
        ("`deg 3`", "deg 3"),
        ("`bmat u 1 0 0 1`", "bmat u 1 0 0 1"),
        ("`step 1`", "step 1"),
        ("`curv 0 1 1 2`", "curv 0 1 1 2"),
        ("`curv2 1 2`", "curv2 1 2"),
        ("`surf 0 1 0 1 1 2 3`", "surf 0 1 0 1 1 2 3"),
        ("`parm u 0 1`", "parm u 0 1"),
        ("`trim 0 1 1`", "trim 0 1 1"),
        ("`hole 0 1 1`", "hole 0 1 1"),
        ("`scrv 0 1 1`", "scrv 0 1 1"),
        ("`sp 1`", "sp 1"),
        ("`end`", "end"),
        ("`con 1 0 1 1 2 0 1 1`", "con 1 0 1 1 2 0 1 1"),
        ("`bevel on`", "bevel on"),
        ("`c_interp on`", "c_interp on"),
        ("`d_interp on`", "d_interp on"),
        ("`lod 1`", "lod 1"),
        ("`shadow_obj shadow.obj`", "shadow_obj shadow.obj"),
        ("`trace_obj trace.obj`", "trace_obj trace.obj"),
        ("`ctech cparm 1`", "ctech cparm 1"),
        ("`stech cparma 1 1`", "stech cparma 1 1"),
        ("`maplib maps.mpc`", "maplib maps.mpc"),
        ("`usemap name`", "usemap wood"),
        ("`call other.obj`", "call other.obj"),
        ("`csh ls`", "csh ls"),
        ("`vw 0 0 1`", "vw 0 0 1"),
        ("`t crease 2/1/0 1 5 4.7`", "t crease 2/1/0 1 5 4.7"),
    ] {
        cases.push(obj_ignored(row, line));
    }
    cases
}

/// Runs one case: its outcome, then its check.
fn run(case: &Case) -> Result<(), String> {
    let row = &case.row;
    match (load(&case.files), &case.outcome) {
        (Ok(m), Outcome::Accepted(allowed)) => {
            let other: Vec<&String> = m.warnings.iter().filter(|w| !allowed.iter().any(|a| w.contains(a))).collect();
            if !other.is_empty() {
                return Err(format!("{row}: accepted, yet warned: {other:?}"));
            }
            if let Some(a) = allowed.iter().find(|a| !m.warnings.iter().any(|w| w.contains(*a))) {
                return Err(format!("{row}: no warning `{a}`: {:?}", m.warnings));
            }
            (case.check)(&m);
        }
        (Ok(m), Outcome::Warned(needle)) => {
            if !m.warnings.iter().any(|w| w.contains(&format!("/{needle}"))) {
                return Err(format!("{row}: no warning containing `/{needle}`: {:?}", m.warnings));
            }
            (case.check)(&m);
        }
        (Err(e), Outcome::Refused(needle)) => {
            let e = e.to_string();
            if !e.contains(&format!("/{needle}")) {
                return Err(format!("{row}: error `{e}` does not contain `/{needle}`"));
            }
        }
        (Ok(m), Outcome::Refused(_)) => return Err(format!("{row}: loaded ({:?}); should be refused", m.warnings)),
        (Err(e), _) => return Err(format!("{row}: refused: {e}")),
    }
    Ok(())
}

fn run_all(cases: &[Case]) {
    let problems: Vec<String> = cases.iter().filter_map(|c| run(c).err()).collect();
    assert!(problems.is_empty(), "{} of {} cases:\n{}", problems.len(), cases.len(), problems.join("\n"));
}

#[test]
fn obj_statements_do_what_the_table_says() {
    run_all(&obj_cases());
}

#[test]
fn mtl_statements_do_what_the_table_says() {
    run_all(&mtl_cases());
}

/// The rows (first cell, outcome) of the table under the heading `section` of docs/obj-mtl.md.
fn table(section: &str) -> Vec<(String, String)> {
    let doc = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/obj-mtl.md")).unwrap();
    let start =
        doc.find(&format!("\n## {section}\n")).unwrap_or_else(|| panic!("docs/obj-mtl.md has no `## {section}`"));
    let body = &doc[start + section.len() + 5..];
    let body = &body[..body.find("\n## ").unwrap_or(body.len())];
    body.lines()
        .filter(|l| l.starts_with('|'))
        .skip(2) // the header and its rule
        .map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split(" | ").map(str::trim).collect();
            (cells[0].to_owned(), cells[1].to_owned())
        })
        .collect()
}

fn same_rows(section: &str, cases: &[Case]) {
    let doc = table(section);
    let tested: Vec<(String, String)> = cases.iter().map(|c| (c.row.clone(), c.outcome.word().to_owned())).collect();
    let missing: Vec<_> = doc.iter().filter(|r| !tested.contains(r)).collect();
    let extra: Vec<_> = tested.iter().filter(|r| !doc.contains(r)).collect();
    assert!(
        missing.is_empty() && extra.is_empty(),
        "docs/obj-mtl.md `## {section}` and its cases differ: rows without a case (or with another outcome) \
         {missing:?}; cases without a row {extra:?}"
    );
    assert_eq!(doc.len(), tested.len(), "{section}: a row or a case is listed twice");
}

#[test]
fn the_tables_and_the_cases_list_the_same_statements() {
    same_rows("OBJ statements", &obj_cases());
    same_rows("MTL statements", &mtl_cases());
}

/// The user's report: a Blender export read by assimp (`Ks 0`) stopped at "Ks needs three
/// numbers". One-value colours are the spec's; the file loads with the values it means.
#[test]
fn a_blender_material_with_one_value_colours_loads() {
    let mtl = "# Blender MTL File: 'None'\n# Material Count: 1\n\nnewmtl Material\nNs 0\nKa 0\nKs 0\nKd 0.64\n\
               Ni 1\nd 1\nillum 2\n";
    let m = load(&[("a.obj", SCENE.replace("usemtl a", "usemtl Material")), ("m.mtl", mtl.to_owned())]).unwrap();
    assert!(m.warnings.is_empty(), "{:?}", m.warnings);
    let g = material(&m);
    assert_eq!((g.kind, g.gpu.diffuse), (BsdfKind::Lambert, [0.64; 3]), "Ks 0 is black: Lambert");
}

/// An `xyz` colour outside the sRGB gamut has its negative components clamped to 0, with a
/// warning naming the file, the line and the key; a negative X, Y or Z, or one that is not
/// finite, is refused the same way; two numbers after `xyz` are refused as two after the key.
#[test]
fn xyz_colours_outside_srgb_are_clamped_or_refused_by_name() {
    let scene = |line: &str| load(&[("a.obj", SCENE.to_owned()), ("m.mtl", format!("newmtl a\n{line}\n"))]);
    // Pure Y: no sRGB colour has it (r and b come out negative).
    let m = scene("Kd xyz 0 0.5 0").unwrap();
    let d = material(&m).gpu.diffuse;
    assert!(d[0] == 0.0 && d[1] > 0.5 && d[2] == 0.0, "{d:?}");
    assert!(
        m.warnings.iter().any(|w| w.contains("/m.mtl:2: material `a`: `Kd` xyz 0 0.5 0: outside the sRGB gamut")),
        "{:?}",
        m.warnings
    );
    for (line, needle) in [
        ("Ks xyz -0.1 0.2 0.2", "/m.mtl:2: material `a`: `Ks` xyz -0.1 0.2 0.2: a CIE XYZ colour cannot be negative"),
        ("Ke xyz inf", "/m.mtl:2: material `a`: `Ke` xyz inf inf inf: every MTL number must be finite"),
        ("Kd xyz 0.1 0.2", "/m.mtl:2: `Kd` takes one number or three (`xyz` x [y z]"),
        ("Kd xyz", "/m.mtl:2: `Kd` xyz needs one number or three"),
        ("Tf spectral", "/m.mtl:2: material `a`: `Tf` spectral (no file)"),
    ] {
        let e = scene(line).unwrap_err().to_string();
        assert!(e.contains(needle), "{line}: {e}");
    }
}
