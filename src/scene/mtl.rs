//! MTL statements as the spec (Wavefront's 1991 "MTL material format") writes them, checked line
//! by line and rewritten, line for line, into what `tobj` parses, so that every message still
//! names the file's own line. docs/obj-mtl.md lists each statement and what trilab does with it.
//!
//! tobj reads colours (`Ka`, `Kd`, `Ks`, `Ke`) as exactly three numbers: one number panicked
//! (`parse_float3` unwraps), and the spec's `xyz` and `spectral` forms fail as "material parse
//! error" (or, for `Tf`, which tobj keeps as text, were dropped with a warning). So before tobj
//! sees a colour:
//! - `K r` becomes `K r r r` (the spec: g and b equal r when absent); `K r g` is refused, the
//!   spec allows one or three;
//! - `K xyz x [y z]` becomes `K r g b`, CIE XYZ converted to linear sRGB ([`xyz_to_linear_srgb`]);
//! - `K spectral file.rfl [factor]` is refused by name (trilab reads no `.rfl` reflectance
//!   curves), except for `Ka`, which trilab never reads: that is ignored with a warning.
//!
//! `d -halo factor` is read as `d factor` with a warning, and a texture statement without a file
//! name is ignored with a warning (tobj refused it); any other texture statement reaches tobj
//! as written, options and all, and [`super::Material::from_mtl`] ignores it with a warning.

use std::borrow::Cow;
use std::path::Path;

use super::material::{is_texture_statement, label, MtlLines};
use super::text;
use crate::error::{Error, Result};

/// An MTL file's text as tobj is to read it, and what checking it found.
pub(super) struct CheckedMtl<'a> {
    /// The text with the rewrites of the module documentation, line for line.
    pub text: Cow<'a, str>,
    /// Per `newmtl` block, the line of each key (the last one, whose value tobj keeps), for
    /// the value rules of [`super::Material::from_mtl`].
    pub lines: Vec<MtlLines>,
    /// What was ignored or converted, each naming the file, the line, the material and the key.
    pub warnings: Vec<String>,
}

/// The colour statements: the spec's four and `Ke`, which exporters write the same way.
const COLOURS: [&str; 5] = ["Ka", "Kd", "Ks", "Ke", "Tf"];

/// Checks every MTL line tobj parses strictly, so a malformed one is named by file, line and
/// key (tobj says only "material parse error", or panics on a short colour), and rewrites the
/// statements of the module documentation. The other rules are tobj's: `Ns`, `Ni` and `d` take
/// a number, `illum` an integer 0-255, `newmtl` a name (the loader's text has one:
/// [`text::decode`] names a bare `newmtl` [`text::NO_NAME`]).
pub(super) fn check_mtl<'a>(path: &Path, text: &'a str) -> Result<CheckedMtl<'a>> {
    let mut blocks: Vec<MtlLines> = Vec::new();
    // (0-based line, its replacement), in line order.
    let mut edits: Vec<(usize, String)> = Vec::new();
    let mut warnings = Vec::new();
    let mut material = "before any `newmtl`".to_owned();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let Some(key) = words.next() else { continue };
        // An inline comment ends the statement (tobj reads no further than it needs).
        let args: Vec<&str> = words.take_while(|w| !w.starts_with('#')).collect();
        let at = Place { path, line: n + 1, material: &material, key, text: line };
        let edit = match key {
            k if COLOURS.contains(&k) => colour(&at, &args, &mut warnings)?,
            "d" => dissolve(&at, &args, &mut warnings)?,
            k if is_texture_statement(k) && args.is_empty() => {
                warnings.push(at.warning("names no file; ignored"));
                Some(String::new())
            }
            _ => {
                syntax(&at, &args)?;
                None
            }
        };
        if key == "newmtl" {
            blocks.push(MtlLines::new());
            // tobj's rule: the name is the rest of the line.
            material = label(line.trim()[key.len()..].trim());
        }
        // tobj files `map_bump`, `bump` and the `map_ns` spellings under one name each.
        let key = match key {
            "map_bump" | "bump" => "map_Bump",
            "map_ns" | "map_NS" => "map_Ns",
            k => k,
        };
        if let Some(block) = blocks.last_mut() {
            block.insert(key.to_owned(), n + 1);
        }
        if let Some(e) = edit {
            edits.push((n, e));
        }
    }
    let mut edits = edits.into_iter().peekable();
    let text = text::edit_lines(text, |n, _| edits.next_if(|e| e.0 == n).map(|e| e.1));
    Ok(CheckedMtl { text, lines: blocks, warnings })
}

/// Where a statement is, for its messages.
struct Place<'a> {
    path: &'a Path,
    line: usize,
    /// The material's label ([`label`]).
    material: &'a str,
    key: &'a str,
    /// The whole line.
    text: &'a str,
}

impl Place<'_> {
    /// A statement the loader cannot parse: file, line, key and the line as written.
    fn malformed(&self, what: &str) -> Error {
        let shown = text::shown(self.text.trim());
        Error::bad_input(self.path, Some(self.line), format!("`{}` {what}: `{shown}`", self.key))
    }

    /// A statement that parses but that trilab cannot honour: file, line, material and key.
    fn refuse(&self, problem: &str) -> Error {
        Error::bad_input(self.path, Some(self.line), format!("{}: `{}` {problem}", self.material, self.key))
    }

    fn warning(&self, problem: &str) -> String {
        format!("{}:{}: {}: `{}` {problem}", self.path.display(), self.line, self.material, self.key)
    }
}

/// A colour statement's replacement line (or `None` to keep it), by the module documentation.
fn colour(at: &Place, args: &[&str], warnings: &mut Vec<String>) -> Result<Option<String>> {
    let key = at.key;
    match args.first().copied() {
        Some("spectral") => {
            let file = args.get(1).map_or_else(|| "(no file)".into(), |f| text::shown(f));
            if key == "Ka" {
                warnings.push(at.warning(&format!(
                    "spectral {file}: a .rfl reflectance curve, which trilab does not read; ignored (a path tracer \
                     has no ambient term)"
                )));
                return Ok(Some(String::new()));
            }
            Err(at.refuse(&format!(
                "spectral {file}: a .rfl reflectance curve is not supported (trilab reads no spectral files): give \
                 r g b, or xyz x y z"
            )))
        }
        Some("xyz") => {
            let Some(xyz) = three(at, &args[1..], warnings, "`xyz` x [y z]")? else {
                return Err(at.malformed("xyz needs one number or three (x [y z]; y and z equal x when absent)"));
            };
            let shown = xyz.map(|v| v.to_string()).join(" ");
            if xyz.iter().any(|v| !v.is_finite()) {
                return Err(at.refuse(&format!("xyz {shown}: every MTL number must be finite")));
            }
            let mut rgb = xyz_to_linear_srgb(xyz);
            // `Ka` is never read, so it is not clamped aloud.
            if key != "Ka" {
                if xyz.iter().any(|&v| v < 0.0) {
                    return Err(at.refuse(&format!("xyz {shown}: a CIE XYZ colour cannot be negative")));
                }
                if rgb.iter().any(|&c| c < 0.0) {
                    warnings.push(at.warning(&format!(
                        "xyz {shown}: outside the sRGB gamut (linear r g b {}); the negative components clamped to 0",
                        rgb.map(|c| c.to_string()).join(" ")
                    )));
                    rgb = rgb.map(|c| c.max(0.0));
                }
            }
            Ok(Some(format!("{key} {} {} {}", rgb[0], rgb[1], rgb[2])))
        }
        _ => match three(at, args, warnings, "r [g b]")? {
            None => Err(at.malformed(
                "needs a colour: one number or three (r [g b]; g and b equal r when absent), `xyz x [y z]` or \
                 `spectral file.rfl [factor]`",
            )),
            // Kept unless an inline comment follows, which tobj would keep in `Tf`'s text.
            Some(_) if args.len() == 3 && at.text.split_whitespace().count() == 4 => Ok(None),
            // As written, so messages show the numbers of the file.
            Some(_) if args.len() == 1 => Ok(Some(format!("{key} {0} {0} {0}", args[0]))),
            Some(_) => Ok(Some(format!("{key} {}", args[..3].join(" ")))),
        },
    }
}

/// The numbers of a colour written as one or three (`form` names them for messages): `None`
/// when there are none or one of the first three is not a number, an error for two (the spec
/// allows one or three), and the first three for more (what follows them ignored, as tobj
/// ignores it, with a warning).
fn three(at: &Place, args: &[&str], warnings: &mut Vec<String>, form: &str) -> Result<Option<[f32; 3]>> {
    let v: Vec<f32> = args.iter().map_while(|w| w.parse::<f32>().ok()).collect();
    if v.len() < args.len().min(3) {
        return Ok(None);
    }
    match v.len() {
        0 => Ok(None),
        1 => Ok(Some([v[0]; 3])),
        2 => Err(at.malformed(&format!("takes one number or three ({form}; the spec allows no other count), not two"))),
        _ => {
            if args.len() > 3 {
                warnings.push(at.warning(&format!(
                    "{}: a colour is {form}; what follows the third number is ignored",
                    args.join(" ")
                )));
            }
            Ok(Some([v[0], v[1], v[2]]))
        }
    }
}

/// CIE XYZ to linear sRGB, D65 white: the XYZ-to-RGB matrix of IEC 61966-2-1:1999 (sRGB), to
/// the four decimals the standard prints (Bruce Lindbloom's "RGB/XYZ Matrices", sRGB, D65,
/// gives the same to four places). The MTL spec does not say which white its `xyz` means; sRGB's
/// is what every other colour in an MTL file is read against.
pub(super) fn xyz_to_linear_srgb(xyz: [f32; 3]) -> [f32; 3] {
    const M: [[f32; 3]; 3] = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]];
    M.map(|row| row[0] * xyz[0] + row[1] * xyz[1] + row[2] * xyz[2])
}

/// `d factor`, or the spec's `d -halo factor` read as `d factor` with a warning (a dissolve that
/// depends on the viewing angle; tobj refused the line).
fn dissolve(at: &Place, args: &[&str], warnings: &mut Vec<String>) -> Result<Option<String>> {
    let number = |w: Option<&&str>| w.is_some_and(|w| w.parse::<f32>().is_ok());
    if args.first() == Some(&"-halo") {
        if !number(args.get(1)) {
            return Err(at.malformed("needs a number"));
        }
        warnings.push(at.warning(&format!(
            "-halo {}: a dissolve that changes with the viewing angle is not supported; read as `d {}`",
            args[1], args[1]
        )));
        return Ok(Some(format!("d {}", args[1])));
    }
    if !number(args.first()) {
        return Err(at.malformed("needs a number"));
    }
    Ok(None)
}

/// tobj's rules for the other statements it parses.
fn syntax(at: &Place, args: &[&str]) -> Result<()> {
    let number = |w: &&str| w.parse::<f32>().is_ok();
    let problem = match at.key {
        "Ns" | "Ni" if !args.first().is_some_and(number) => Some("needs a number"),
        "illum" if args.first().is_none_or(|w| w.parse::<u8>().is_err()) => {
            Some("needs an illumination model number (0-10)")
        }
        "newmtl" if args.is_empty() => Some("needs a name"),
        _ => None,
    };
    problem.map_or(Ok(()), |what| Err(at.malformed(what)))
}

/// The material rules of `material.rs`, read through this check (here, not beside them: it is
/// what turns MTL text into what `Material::from_mtl` reads).
#[cfg(test)]
mod material_tests {
    use std::path::Path;

    use crate::error::Result;
    use crate::scene::material::*;

    /// The materials of an MTL text read as the loader reads it, or the first error.
    fn load(text: &str) -> Result<(Vec<Material>, Vec<String>)> {
        let path = Path::new("x.mtl");
        let checked = super::check_mtl(path, text)?;
        let (mats, _) = tobj::load_mtl_buf(&mut checked.text.as_bytes()).unwrap();
        assert_eq!(checked.lines.len(), mats.len());
        let mut warnings = checked.warnings;
        let m = mats
            .iter()
            .zip(&checked.lines)
            .map(|(m, l)| Material::from_mtl(m, path, l, &mut warnings))
            .collect::<Result<_>>()?;
        Ok((m, warnings))
    }

    fn mtl(text: &str) -> (Vec<Material>, Vec<String>) {
        load(text).unwrap()
    }

    #[test]
    fn illum_models_map_to_bsdfs() {
        let (m, w) = mtl(
            "newmtl a\nKd 0.5 0.5 0.5\nillum 2\nKs 0 0 0\nnewmtl b\nKd 0.5 0.4 0.3\nKs 0.2 0.2 0.2\nNs 40\nillum 2\n\
             newmtl c\nillum 3\nnewmtl d\nillum 7\nNi 1.33\nTf 0.9 1 1\nnewmtl e\nKd 1 1 1\nKe 4 4 4\n",
        );
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(
            m.iter().map(|m| m.kind).collect::<Vec<_>>(),
            vec![BsdfKind::Lambert, BsdfKind::BlinnPhong, BsdfKind::Mirror, BsdfKind::Glass, BsdfKind::Lambert]
        );
        assert_eq!(m[1].gpu.exponent, 40.0);
        assert_eq!(m[1].gpu.specular, [0.2; 3]);
        assert_eq!(m[2].gpu.specular, [1.0; 3]);
        assert_eq!((m[3].gpu.ior, m[3].gpu.diffuse), (1.33, [0.9, 1.0, 1.0]));
        assert!(m[4].is_emissive() && m[4].gpu.emission == [4.0; 3]);
    }

    #[test]
    fn explicit_bsdf_key_and_parameters() {
        let (m, w) = mtl("newmtl a\nKd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\ntrilab_bsdf ashikhmin-shirley nu=200 nv=20\n\
             newmtl b\ntrilab_bsdf oren-nayar sigma=0.35\nillum 3\n");
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(m[0].kind, BsdfKind::AshikhminShirley);
        assert_eq!((m[0].gpu.exponent, m[0].gpu.exponent_v), (200.0, 20.0));
        assert_eq!(m[1].kind, BsdfKind::OrenNayar);
        assert_eq!(m[1].gpu.sigma, 0.35);
    }

    #[test]
    fn unsupported_requests_warn_with_file_material_and_key() {
        let (m, w) = mtl("newmtl skin\nKd 1 0 0\nmap_Kd skin.png\nd 0.5\nsheen 0.3\nillum 10\n\
             newmtl x\ntrilab_bsdf velvet\nnewmtl y\ntrilab_bsdf glass roughness=0.1\n");
        assert_eq!(m[0].kind, BsdfKind::Lambert);
        let has = |needle: &str| w.iter().any(|l| l.starts_with("x.mtl:") && l.contains(needle));
        assert!(has(":3: material `skin`: `map_Kd` skin.png: textures are not supported"), "{w:?}");
        assert!(has(":4: material `skin`: `d` 0.5: partial transparency"), "{w:?}");
        assert!(has(":5: material `skin`: `sheen` is not supported"), "{w:?}");
        assert!(has(":6: material `skin`: `illum` 10 is not supported"), "{w:?}");
        assert!(has(":8: material `x`: `trilab_bsdf` unknown BSDF `velvet`"), "{w:?}");
        assert!(has(":10: material `y`: `trilab_bsdf` parameter `roughness=0.1` does not apply to glass"), "{w:?}");
        assert_eq!(w.len(), 6, "{w:?}");
    }

    /// Values no exporter can mean are refused naming the file, the line, the material and the
    /// key; values a BSDF cannot render are clamped with a warning naming the same.
    #[test]
    fn out_of_range_values_are_refused_or_clamped_by_rule() {
        for (text, line, needle) in [
            ("newmtl a\nKe inf 1 1\n", 2, "material `a`: `Ke` inf 1 1: every MTL number must be finite"),
            ("newmtl a\nKd NaN 0 0\n", 2, "`Kd` NaN 0 0: every MTL number must be finite"),
            ("newmtl a\nKa 0 0 nan\n", 2, "`Ka`"),
            ("newmtl a\n\nKs 0.5 0.5 0.5\nNs inf\n", 4, "`Ns` inf"),
            ("newmtl a\nNi nan\n", 2, "`Ni` NaN"),
            ("newmtl a\nillum 7\nNi 0\n", 3, "`Ni` 0: a glass needs an index of refraction from 0.1 to 10"),
            ("newmtl a\nNi -1.5\nillum 4\n", 2, "`Ni` -1.5"),
            ("newmtl a\ntrilab_bsdf glass\nNi 1000\n", 3, "`Ni` 1000"),
            ("newmtl a\nKd -1 -1 -1\n", 2, "`Kd` -1 -1 -1: a reflectance cannot be negative"),
            ("newmtl a\nillum 7\nTf 1 -0.5 1\n", 3, "`Tf`"),
            ("newmtl a\nKe 1 0 -1\n", 2, "`Ke` 1 0 -1: a radiance cannot be negative"),
            ("newmtl a\nKe 1e30 1e30 1e30\n", 2, "`Ke` 1e30 1e30 1e30: above 1e20"),
            ("newmtl a\nNs -3\n", 2, "`Ns` -3"),
            ("newmtl a\nd 1.5\n", 2, "`d` 1.5"),
            ("newmtl a\nTr -0.1\n", 2, "`Tr` -0.1"),
            ("newmtl a\nTf inf\n", 2, "`Tf` inf inf inf"),
            ("newmtl a\ntrilab_bsdf glass ior=0\n", 2, "parameter `ior=0`: 0: a glass needs"),
            ("newmtl a\ntrilab_bsdf oren-nayar sigma=-1\n", 2, "parameter `sigma=-1` cannot be negative"),
            ("newmtl a\ntrilab_bsdf phong exponent=inf\n", 2, "parameter `exponent=inf`: every MTL number"),
            ("newmtl ok\nKd 1 1 1\nnewmtl b\nKd 0 0 0\nKd 0 nan 0\n", 5, "material `b`"),
        ] {
            let e = load(text).err().unwrap_or_else(|| panic!("{text:?} was accepted")).to_string();
            assert!(e.starts_with(&format!("x.mtl:{line}: ")) && e.contains(needle), "{text:?}: {e}");
        }

        // Ni is read by glass only: exporters write `Ni 0` on opaque materials.
        let (m, w) = mtl("newmtl a\nKd 0.5 0.5 0.5\nNi 0\n");
        assert!(w.is_empty() && m[0].kind == BsdfKind::Lambert, "{w:?}");
        // ... and `ior=` replaces it.
        let (m, _) = mtl("newmtl a\ntrilab_bsdf glass ior=1.2\nNi 0\n");
        assert_eq!(m[0].gpu.ior, 1.2);

        let (m, w) = mtl("newmtl a\nKd 2 0.5 1\nnewmtl b\nillum 3\nKs 1.5 1 1\nnewmtl c\nKs 0.1 0.1 0.1\nNs 1e9\n");
        assert_eq!(m[0].gpu.diffuse, [1.0, 0.5, 1.0]);
        assert_eq!(m[1].gpu.specular, [1.0; 3]);
        assert_eq!((m[2].gpu.exponent, m[2].gpu.exponent_v), (MAX_EXPONENT, MAX_EXPONENT));
        assert!(w[0].starts_with("x.mtl:2: material `a`: `Kd` 2 0.5 1: above 1"), "{w:?}");
        assert!(w[1].starts_with("x.mtl:5: material `b`: `Ks` 1.5 1 1: above 1"), "{w:?}");
        assert!(w[2].starts_with("x.mtl:8: material `c`: `Ns` 1e9: above 1e6"), "{w:?}");
        assert_eq!(w.len(), 3, "{w:?}");
        // Unread values are not clamped aloud: Kd of a mirror.
        let (_, w) = mtl("newmtl a\nillum 3\nKd 5 5 5\n");
        assert!(w.is_empty(), "{w:?}");
        // Every accepted material holds finite, non-negative numbers.
        for m in &m {
            let g = m.gpu;
            let all = [g.diffuse, g.specular, g.emission].concat();
            let all = [&all[..], &[g.exponent, g.exponent_v, g.ior, g.sigma]].concat();
            assert!(all.iter().all(|x| x.is_finite() && *x >= 0.0), "{g:?}");
        }
    }

    /// An inline comment ends a colour, in `Tf` (which tobj keeps as text) as in the others.
    #[test]
    fn a_comment_after_a_colour_is_not_part_of_it() {
        let (m, w) = mtl("newmtl a\nillum 7\nTf 0.5 0.25 1 # blue glass\nnewmtl b\nKd 0.5 # grey\n");
        assert!(w.is_empty(), "{w:?}");
        assert_eq!((m[0].gpu.diffuse, m[1].gpu.diffuse), ([0.5, 0.25, 1.0], [0.5; 3]));
    }

    /// Ashikhmin-Shirley nv falls back to Ns, not to nu (as before the value rules).
    #[test]
    fn anisotropic_exponents_keep_their_sources() {
        let (m, w) = mtl("newmtl a\nNs 30\ntrilab_bsdf ashikhmin-shirley nu=200\n");
        assert!(w.is_empty(), "{w:?}");
        assert_eq!((m[0].gpu.exponent, m[0].gpu.exponent_v), (200.0, 30.0));
    }
}
