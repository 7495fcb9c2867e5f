//! OBJ+MTL loading through `tobj`, with errors that name the file, the line and the problem.
//!
//! tobj reports what went wrong but not where; when it fails, [`locate`] re-reads the file
//! with the same rules to find the first offending line.

use std::borrow::Cow;
use std::cell::RefCell;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use super::library::Libraries;
use super::material::MtlLines;
use super::obj_statements;
use super::text::{self, Decoded, Format};
use super::{Material, Mesh};
use crate::error::{Error, Result};

/// Largest OBJ text accepted, after decompression: 2 GiB (about 40 million triangles), or
/// `TRILAB_MAX_SCENE_BYTES`. A gzip file is decoded through a reader that stops one byte past
/// the limit, so a small file that inflates without end (a "zip bomb") is an error, not an
/// allocation of everything it claims.
pub const DEFAULT_MAX_SCENE_BYTES: u64 = 2 << 30;

fn max_scene_bytes() -> u64 {
    std::env::var("TRILAB_MAX_SCENE_BYTES").ok().and_then(|v| v.parse().ok()).unwrap_or(DEFAULT_MAX_SCENE_BYTES)
}

/// Loads a scene: an OBJ file (and the MTL files it names, relative to its directory), the same
/// gzip-compressed (a name ending in `.gz`, read through a decompressing reader), or a synthetic
/// scene (`synth:<kind>:<triangles>`, see [`super::synthetic`]). Polygons are fan-triangulated;
/// points, lines and the other statements trilab does not draw are ignored with a warning
/// ([`super::obj_statements`]; docs/obj-mtl.md lists every statement). Errors: missing or
/// unreadable file, corrupt gzip, text over the size limit, unparsable line, face index out of
/// range, NaN/Inf coordinate, no triangles, malformed MTL.
///
/// `path` may also be a scene's name (`bunny`), found as [`super::find`] says; the mesh's
/// `source` is then the file read.
pub fn load_obj(path: &Path) -> Result<Mesh> {
    let span = crate::timeline::span("scene", "scene load").with("scene", path.display().to_string());
    let mesh = load_mesh(path)?;
    span.arg("triangles", mesh.triangle_count());
    Ok(mesh)
}

/// [`load_obj`], untraced.
fn load_mesh(path: &Path) -> Result<Mesh> {
    if super::synthetic::is_spec(path) {
        return super::synthetic::load(path);
    }
    let found = super::find::resolve(path)?;
    let path = found.path.as_path();
    if super::find::is_builtin(path) {
        let mut mesh = parse_obj_bytes(path, super::find::BUNNY_OBJ, |mtl| {
            (mtl.file_name() == Some("bunny.mtl".as_ref())).then(|| super::find::BUNNY_MTL.to_vec())
        })?;
        // No file on disk that an output could overwrite.
        mesh.mtl_files.clear();
        return Ok(mesh);
    }
    let bytes = read_bytes(path, max_scene_bytes())?;
    parse_obj_bytes(path, &bytes, |mtl| std::fs::read(mtl).ok())
}

/// The file's bytes, gunzipped when its name ends in `.gz`; at most `limit` bytes of them.
fn read_bytes(path: &Path, limit: u64) -> Result<Vec<u8>> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        return Err(Error::bad_input(path, None, "is a directory, not an OBJ file"));
    }
    let too_big = |what: &str| {
        Error::bad_input(
            path,
            None,
            format!("{what} more than {limit} bytes of OBJ text, the limit (set TRILAB_MAX_SCENE_BYTES to raise it)"),
        )
    };
    let gzip = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    let mut bytes = Vec::new();
    if gzip {
        let mut reader = flate2::read::MultiGzDecoder::new(BufReader::new(file)).take(limit + 1);
        reader.read_to_end(&mut bytes).map_err(|e| match e.kind() {
            std::io::ErrorKind::InvalidInput | std::io::ErrorKind::InvalidData | std::io::ErrorKind::UnexpectedEof => {
                Error::bad_input(path, None, format!("is not a valid gzip file: {e}"))
            }
            _ => Error::io(path, e),
        })?;
        if bytes.len() as u64 > limit {
            return Err(too_big("decompresses to"));
        }
    } else {
        if meta.len() > limit {
            return Err(too_big("holds"));
        }
        bytes.reserve_exact(meta.len() as usize);
        BufReader::new(file).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    }
    Ok(bytes)
}

/// Parses OBJ text held in memory; `path` names it in messages and MTL paths are resolved
/// against its directory. `mtl` serves each material library the OBJ names (`mtllib`), given
/// that resolved path, or `None` when it cannot be opened. This is [`load_obj`] without the
/// file system, and what the fuzz targets (`fuzz/`) drive.
pub fn parse_obj_bytes(path: &Path, obj: &[u8], mtl: impl Fn(&Path) -> Option<Vec<u8>>) -> Result<Mesh> {
    let decoded = text::decode(path, obj, Format::Obj)?;
    check_face_indices(path, &decoded.text)?;
    parse_obj(path, &decoded, &mtl)
}

fn parse_obj(path: &Path, decoded: &Decoded<'_>, mtl_source: &dyn Fn(&Path) -> Option<Vec<u8>>) -> Result<Mesh> {
    let survey = obj_statements::survey(&decoded.text);
    let text: Cow<'_, str> = if survey.has_polylines() {
        obj_statements::without_polylines(&decoded.text)
    } else {
        Cow::Borrowed(&decoded.text)
    };
    let read = read_obj(path, &text, mtl_source)?;
    let libraries = &read.libraries;
    let mut warnings = libraries.warnings.clone();
    unnamed_material_warnings(path, decoded, libraries, &mut warnings);
    undefined_materials(path, &text, &read.materials, &mut warnings);
    let no_lines = MtlLines::new();
    let materials: Vec<Material> = read
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| {
            Material::from_mtl(m, &libraries.file_of(i), libraries.lines.get(i).unwrap_or(&no_lines), &mut warnings)
        })
        .collect::<Result<_>>()?;
    let mut mesh = triangles(path, &text, &read.models, materials)?;
    warnings.extend(survey.warnings(path));
    let has = |f: fn(&tobj::Mesh) -> bool| read.models.iter().any(|m| f(&m.mesh));
    if has(|m| !m.normals.is_empty()) {
        warnings.push(format!(
            "{}: vertex normals (`vn`) are ignored: shading uses each triangle's geometric normal",
            path.display()
        ));
    }
    if has(|m| !m.texcoords.is_empty()) {
        warnings
            .push(format!("{}: texture coordinates (`vt`) are ignored: textures are not supported", path.display()));
    }
    if read.colours_dropped || has(|m| !m.vertex_color.is_empty()) {
        warnings.push(format!(
            "{}: vertex colours (`v x y z r g b`) are ignored: surfaces take their material's colours",
            path.display()
        ));
    }
    mesh.warnings = warnings;
    mesh.mtl_files = read.libraries.files.into_iter().map(|(f, _)| f).collect();

    if mesh.positions.iter().flatten().any(|c| !c.is_finite()) {
        return Err(locate_non_finite(path, &text));
    }
    if mesh.triangles.is_empty() {
        // UTF-16 without a byte-order mark reads as text with a NUL after every ASCII character.
        let hint = if text.contains('\0') {
            " (the text holds NUL bytes: UTF-16 without a byte-order mark? Save it as UTF-8, or as UTF-16 with one)"
        } else {
            ""
        };
        return Err(Error::bad_input(
            path,
            None,
            format!("contains no triangles (no `f` lines with 3 or more vertices{}){hint}", survey.undrawn_geometry()),
        ));
    }
    Ok(mesh)
}

/// What tobj read of an OBJ and its material libraries.
struct Loaded<'a> {
    models: Vec<tobj::Model>,
    materials: Vec<tobj::Material>,
    libraries: Libraries<'a>,
    /// Whether the text tobj read had its vertex colours dropped
    /// ([`obj_statements::without_vertex_colours`]).
    colours_dropped: bool,
}

/// tobj over `text`, with its errors located ("file:line: problem"). A file that colours some
/// vertices and not others, which tobj cannot pair with their colours, is read again without
/// its colours, which trilab does not use.
fn read_obj<'a>(path: &'a Path, text: &str, mtl_source: &'a dyn Fn(&Path) -> Option<Vec<u8>>) -> Result<Loaded<'a>> {
    match run_tobj(path, text, mtl_source)? {
        Ok(read) => Ok(read),
        Err(tobj::LoadError::FaceColorOutOfBounds) => {
            let text = obj_statements::without_vertex_colours(text);
            let mut read = run_tobj(path, &text, mtl_source)?.map_err(|e| locate(path, &text, Some(e)))?;
            read.colours_dropped = true;
            Ok(read)
        }
        Err(e) => Err(locate(path, text, Some(e))),
    }
}

/// tobj over `text`: `Ok(Err(e))` when tobj failed with `e`, for the caller to locate; `Err`
/// for a material library that could not be read, or a panic in tobj.
fn run_tobj<'a>(
    path: &'a Path,
    text: &str,
    mtl_source: &'a dyn Fn(&Path) -> Option<Vec<u8>>,
) -> Result<std::result::Result<Loaded<'a>, tobj::LoadError>> {
    let libraries = RefCell::new(Libraries::new(path, mtl_source));
    let options = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let mut reader = BufReader::new(text.as_bytes());
    // tobj indexes with unchecked integer arithmetic on some hostile inputs; [`check_face_indices`]
    // and the MTL check reject those first (the fuzz targets, whose panic hook aborts, check that).
    // Any panic left is contained and reported as bad input rather than crashing the tool.
    let loaded = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &options, |names| libraries.borrow_mut().load(names))
    }));
    let mut libraries = libraries.into_inner();
    let (models, materials) = match loaded {
        Ok(Ok(m)) => m,
        Ok(Err(e)) => return Ok(Err(e)),
        Err(_) => return Err(locate(path, text, None)),
    };
    // tobj keeps going past a library it could not read when another gave materials.
    if let Some(e) = libraries.failure.take() {
        return Err(e);
    }
    let materials = materials.map_err(|e| Error::bad_input(path, None, format!("material library (mtllib): {e}")))?;
    Ok(Ok(Loaded { models, materials, libraries, colours_dropped: false }))
}

/// Warns about `newmtl` and `usemtl` lines without a name (docs/formats.md, "OBJ and MTL text").
fn unnamed_material_warnings(path: &Path, decoded: &Decoded<'_>, libraries: &Libraries, warnings: &mut Vec<String>) {
    let more = |lines: &[usize]| match lines.len() - 1 {
        0 => String::new(),
        n => format!(" ({n} more such lines)"),
    };
    let unnamed_newmtl = &libraries.unnamed_newmtl;
    for (mtl, lines) in unnamed_newmtl {
        warnings.push(format!(
            "{}:{}: newmtl without a material name: it defines the unnamed material, which `usemtl` without a \
             name selects{}",
            mtl.display(),
            lines[0],
            more(lines)
        ));
    }
    if let Some(&first) = decoded.unnamed_usemtl.first() {
        // tobj keeps the last definition of a name.
        let material = match unnamed_newmtl.last() {
            Some((mtl, lines)) => {
                format!("the unnamed material (`newmtl` without a name, {}:{})", mtl.display(), lines[lines.len() - 1])
            }
            None => "the default material (grey Lambert)".to_owned(),
        };
        warnings.push(format!(
            "{}:{first}: usemtl without a material name: the faces that follow take {material}{}",
            path.display(),
            more(&decoded.unnamed_usemtl)
        ));
    }
}

/// The mesh of tobj's models, in file order, with `materials` and the default material for
/// triangles without one (or when there are no materials at all).
fn triangles(path: &Path, text: &str, models: &[tobj::Model], mut materials: Vec<Material>) -> Result<Mesh> {
    let default_material = materials.len() as u32;
    let mut need_default = false;
    let mut mesh = Mesh { source: path.to_owned(), ..Default::default() };
    for model in models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        let nverts = m.positions.len() / 3;
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        let mat = match m.material_id {
            Some(id) => id as u32,
            None => {
                need_default = true;
                default_material
            }
        };
        for t in m.indices.chunks_exact(3) {
            if t.iter().any(|&i| i as usize >= nverts) {
                return Err(locate(path, text, Some(tobj::LoadError::FaceVertexOutOfBounds)));
            }
            mesh.triangles.push([base + t[0], base + t[1], base + t[2]]);
            mesh.material_ids.push(mat);
        }
    }
    if need_default || materials.is_empty() {
        materials.push(Material::default());
    }
    mesh.materials = materials;
    Ok(mesh)
}

/// Rejects face indices that point outside the file's vertex data before tobj sees them: tobj
/// resolves them with unchecked arithmetic (`vt * 2 + 1` on an index near `usize::MAX`
/// overflows), so a hostile `f 1/-99999999999 2 3` must never reach it. The rule is tobj's own:
/// negative indices count back from the elements defined so far, positive ones may point
/// anywhere in the file, and 0 is never valid. Texture and normal indices are only checked
/// when the file has `vt` / `vn` lines at all (tobj ignores them otherwise). Reads the text
/// once, allocating nothing.
fn check_face_indices(path: &Path, text: &str) -> Result<()> {
    const WHAT: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    const DEFINED: [&str; 3] = ["vertices (`v`)", "texture coordinates (`vt`)", "normals (`vn`)"];
    // v, vt, vn defined so far.
    let mut count = [0u64; 3];
    // Per component: the first (line, index) of each sign that is out of range so far. Negative
    // ones are decided on their line; positive ones at the end, against the file's totals.
    let mut bad_negative: [Option<(usize, i64, u64)>; 3] = [None; 3];
    let mut max_positive: [(i64, usize); 3] = [(0, 0); 3]; // (index, line)
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => count[0] += 1,
            Some("vt") => count[1] += 1,
            Some("vn") => count[2] += 1,
            Some("f") => {
                for w in words {
                    for (k, part) in w.split('/').take(3).enumerate() {
                        // Unparsable parts make tobj fail; `locate` names them.
                        let Ok(i) = part.parse::<i64>() else { continue };
                        if i > 0 {
                            if i > max_positive[k].0 {
                                max_positive[k] = (i, n + 1);
                            }
                        } else if (i == 0 || i.unsigned_abs() > count[k]) && bad_negative[k].is_none() {
                            bad_negative[k] = Some((n + 1, i, count[k]));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    for k in 0..3 {
        if k > 0 && count[k] == 0 {
            continue;
        }
        if let Some((line, i, defined)) = bad_negative[k] {
            return Err(Error::bad_input(
                path,
                Some(line),
                format!(
                    "face {} index {i} is out of range: {defined} {} are defined before this line",
                    WHAT[k], DEFINED[k]
                ),
            ));
        }
        if max_positive[k].0 as u64 > count[k] {
            // Rare, so found by a second pass: the first line that points past the end.
            let (line, i) = first_index_over(text, k, count[k]).unwrap_or((max_positive[k].1, max_positive[k].0));
            return Err(Error::bad_input(
                path,
                Some(line),
                format!("face {} index {i} is out of range: the file defines {} {}", WHAT[k], count[k], DEFINED[k]),
            ));
        }
    }
    Ok(())
}

/// The first (line, index) whose component `k` (v, vt, vn) is a positive index above `total`.
fn first_index_over(text: &str, k: usize, total: u64) -> Option<(usize, i64)> {
    text.lines().enumerate().find_map(|(n, line)| {
        let mut words = line.split_whitespace();
        if words.next() != Some("f") {
            return None;
        }
        words
            .filter_map(|w| w.split('/').nth(k)?.parse::<i64>().ok())
            .find(|&i| i > 0 && i as u64 > total)
            .map(|i| (n + 1, i))
    })
}

/// Warns, once per name, about `usemtl` lines naming a material no library defines (tobj
/// gives those triangles no material; they get the default one).
fn undefined_materials(path: &Path, text: &str, materials: &[tobj::Material], warnings: &mut Vec<String>) {
    let mut named: Vec<&str> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        if line.split_whitespace().next() != Some("usemtl") {
            continue;
        }
        // tobj's own rule (a name follows a space; [`text::decode`] turned tabs into one).
        let name = line.split_once(' ').map_or("", |x| x.1).trim();
        if name.is_empty() || name == text::NO_NAME || named.contains(&name) || materials.iter().any(|m| m.name == name)
        {
            continue;
        }
        named.push(name);
        warnings.push(format!(
            "{}:{}: usemtl `{}`: no material library defines it; using the default material (grey Lambert)",
            path.display(),
            n + 1,
            text::shown(name)
        ));
    }
}

/// Finds the first line that breaks tobj's rules, to turn its error into "file:line: problem".
fn locate(path: &Path, text: &str, err: Option<tobj::LoadError>) -> Error {
    let mut positions = 0usize;
    for (n, line) in text.lines().enumerate() {
        let lineno = n + 1;
        let mut words = line.split_whitespace();
        let show = line.trim();
        let show =
            if show.len() > 80 { format!("{}...", &show[..show.floor_char_boundary(77)]) } else { show.to_owned() };
        match words.next() {
            Some("v") => {
                let vals: Vec<&str> = words.collect();
                let ok = vals.len() >= 3 && vals[..3].iter().all(|w| w.parse::<f32>().is_ok());
                if !ok {
                    return Error::bad_input(
                        path,
                        Some(lineno),
                        format!("cannot parse vertex position `{show}` (need three numbers)"),
                    );
                }
                if vals.len() == 4 && vals[3].parse::<f32>().map_or(true, |w| w == 0.0) {
                    return Error::bad_input(path, Some(lineno), format!("bad vertex weight w in `{show}`"));
                }
                if vals.len() == 5 || vals.len() > 6 {
                    return Error::bad_input(
                        path,
                        Some(lineno),
                        format!("vertex has {} values; expected 3, 4 or 6: `{show}`", vals.len()),
                    );
                }
                positions += 1;
            }
            Some("vt") | Some("vn") => {}
            Some("f") => {
                for w in words {
                    let first = w.split('/').next().unwrap_or("");
                    match first.parse::<i64>() {
                        Err(_) => {
                            return Error::bad_input(
                                path,
                                Some(lineno),
                                format!("cannot parse face vertex `{w}` in `{show}`"),
                            )
                        }
                        Ok(i) => {
                            let in_range = (i > 0 && (i as u64) <= positions as u64)
                                || (i < 0 && i.unsigned_abs() <= positions as u64);
                            if !in_range {
                                return Error::bad_input(
                                    path,
                                    Some(lineno),
                                    format!("face vertex index {i} is out of range: {positions} vertices are defined before this line"),
                                );
                            }
                        }
                    }
                }
            }
            _ => {}
        }
    }
    let what = match err {
        Some(e) => format!("cannot be parsed as OBJ ({e})"),
        None => "cannot be parsed as OBJ (the parser failed on malformed input)".to_owned(),
    };
    Error::bad_input(path, None, what)
}

fn locate_non_finite(path: &Path, text: &str) -> Error {
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() == Some("v") {
            let vals: Vec<f32> = words.take(4).filter_map(|w| w.parse().ok()).collect();
            let xyz: Vec<f32> = match vals.as_slice() {
                [x, y, z, w] => vec![x / w, y / w, z / w],
                v => v.iter().take(3).copied().collect(),
            };
            if xyz.iter().any(|c| !c.is_finite()) {
                return Error::bad_input(
                    path,
                    Some(n + 1),
                    format!("vertex coordinate is NaN or infinite: `{}`", line.trim()),
                );
            }
        }
    }
    Error::bad_input(path, None, "a vertex coordinate is NaN or infinite")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Mesh> {
        parse_obj_bytes(Path::new("test.obj"), text.as_bytes(), |_| None)
    }

    fn err(text: &str) -> String {
        parse(text).unwrap_err().to_string()
    }

    #[test]
    fn fan_triangulation_keeps_face_order() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nf 1 2 3 4 5\nf 1 2 5\n").unwrap();
        // (v0 v1 v2), (v0 v2 v3), (v0 v3 v4), then the triangle.
        let tri = |i: usize| m.triangles[i].map(|k| m.positions[k as usize]);
        assert_eq!(m.triangles.len(), 4);
        assert_eq!(tri(0), [[0., 0., 0.], [1., 0., 0.], [1., 1., 0.]]);
        assert_eq!(tri(1), [[0., 0., 0.], [1., 1., 0.], [0., 1., 0.]]);
        assert_eq!(tri(2), [[0., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
        assert_eq!(tri(3), [[0., 0., 0.], [1., 0., 0.], [0., 0., 1.]]);
    }

    #[test]
    fn ids_follow_file_order_across_groups() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\no a\nf 1 2 3\ng b\nf 1 3 4\no c\nf 2 3 4\n").unwrap();
        assert_eq!(m.triangles.len(), 3);
        let tri = |i: usize| m.triangles[i].map(|k| m.positions[k as usize]);
        assert_eq!(tri(1), [[0., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
        assert_eq!(tri(2), [[1., 0., 0.], [0., 1., 0.], [0., 0., 1.]]);
    }

    #[test]
    fn negative_indices_are_relative() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n").unwrap();
        assert_eq!(m.triangles.len(), 1);
        assert!(!m.is_degenerate(0));
    }

    #[test]
    fn bad_inputs_name_line_and_problem() {
        let e = err("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n");
        assert!(e.starts_with("test.obj:2:") && e.contains("cannot parse vertex position"), "{e}");
        let e = err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n");
        assert!(e.starts_with("test.obj:4:") && e.contains("out of range"), "{e}");
        let e = err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n");
        assert!(e.starts_with("test.obj:4:") && e.contains("out of range"), "{e}");
        let e = err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n");
        assert!(e.starts_with("test.obj:4:") && e.contains("cannot parse face vertex"), "{e}");
        let e = err("v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
        assert!(e.starts_with("test.obj:2:") && e.contains("NaN or infinite"), "{e}");
        let e = err("v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n");
        assert!(e.starts_with("test.obj:2:") && e.contains("NaN or infinite"), "{e}");
        let e = err("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        assert!(e.contains("no triangles"), "{e}");
        let e = err("# nothing\n");
        assert!(e.contains("no triangles"), "{e}");
        let e = err("v 0 0 0\nv 1 0 0\nf 1 2\n");
        assert!(e.contains("no triangles"), "{e}");
    }

    #[test]
    fn hostile_index_does_not_panic() {
        let e = err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9223372036854775808\n");
        assert!(e.starts_with("test.obj:4:"), "{e}");
        let e = err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999999\n");
        assert!(e.starts_with("test.obj:4:"), "{e}");
    }

    /// Indices tobj would resolve with overflowing arithmetic (`vt * 2 + 1` panics in a build
    /// with overflow checks, as the fuzz targets have) are rejected before tobj sees them, with
    /// the line; forward references, which tobj resolves against the whole file, still load.
    #[test]
    fn overflowing_indices_never_reach_tobj() {
        let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
        for (face, what) in [
            ("f 1/1 2/1 3/4611686018427387904", "texture coordinate index 4611686018427387904"),
            ("f 1/1 2/-9223372036854775808 3/1", "texture coordinate index -9223372036854775808"),
            ("f 1/1/1 2/1/1 3/1/-3074457345618258602", "normal index -3074457345618258602"),
            ("f 1/1/1 2/1/1 3/1/0", "normal index 0"),
        ] {
            let e = err(&format!("{tri}vt 0 0\nvn 0 0 1\n{face}\n"));
            assert!(e.starts_with("test.obj:6:") && e.contains(what), "{face}: {e}");
        }
        let m = parse(&format!("f 1 2 3\n{tri}")).unwrap();
        assert_eq!(m.triangles.len(), 1);
        // Without `vt` lines tobj ignores texture indices, and so does the check.
        assert_eq!(parse(&format!("{tri}f 1/9 2/9 3/9\n")).unwrap().triangles.len(), 1);
    }

    /// tobj 4 unwraps an MTL colour of fewer than three values (`Kd 1 2` panicked): two
    /// values are refused (the spec allows one or three), and one is read as the spec says.
    #[test]
    fn short_mtl_colour_is_bad_input() {
        let obj = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n";
        let e = parse_obj_bytes(Path::new("d/a.obj"), obj, |_| Some(b"newmtl a\n\nKd 1 2\n".to_vec()));
        let e = e.unwrap_err().to_string();
        assert_eq!(
            e,
            "d/m.mtl:3: `Kd` takes one number or three (r [g b]; the spec allows no other count), not two: `Kd 1 2`"
        );
        let m = parse_obj_bytes(Path::new("d/a.obj"), obj, |_| Some(b"newmtl a\n\nKd 0.25\n".to_vec())).unwrap();
        assert_eq!(m.materials[0].gpu.diffuse, [0.25; 3]);
    }

    #[test]
    fn missing_files_are_named() {
        let e = load_obj(Path::new("/nonexistent/x.obj")).unwrap_err().to_string();
        assert!(e.contains("/nonexistent/x.obj"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("a.obj");
        std::fs::write(&obj, "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        // A missing material library is a warning: geometry needs no materials.
        let m = load_obj(&obj).unwrap();
        assert_eq!(m.materials.len(), 1);
        assert!(
            m.warnings.iter().any(|w| w.contains("missing.mtl") && w.contains("cannot be opened")),
            "{:?}",
            m.warnings
        );
    }

    #[test]
    fn missing_mtllib_and_undefined_usemtl_warn_and_use_the_default() {
        let obj = b"mtllib gone.mtl\nmtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\nusemtl blue\nf 1 2 3\nusemtl blue\nf 1 2 3\n";
        let m = parse_obj_bytes(Path::new("d/a.obj"), obj, |p| {
            (p == Path::new("d/m.mtl")).then(|| b"newmtl red\nKd 1 0 0\n".to_vec())
        })
        .unwrap();
        assert_eq!(m.warnings.len(), 2, "{:?}", m.warnings);
        assert!(m.warnings[0].starts_with("d/gone.mtl: material library named by d/a.obj"), "{:?}", m.warnings);
        assert!(m.warnings[1].starts_with("d/a.obj:8: usemtl `blue`"), "{:?}", m.warnings);
        assert_eq!(m.materials[m.material_ids[0] as usize].name, "red");
        assert_eq!(m.materials[m.material_ids[1] as usize], Material::default());
        assert_eq!(m.material_ids[1], m.material_ids[2]);
    }

    #[test]
    fn malformed_mtl_lines_name_file_line_and_key() {
        let obj = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        for (mtl, line, key) in [
            ("newmtl a\nKd 1 x 0\n", 2, "`Kd`"),
            ("newmtl a\nKd 1 1 1\n\nNs high\n", 4, "`Ns`"),
            ("newmtl a\r\nillum two\r\n", 2, "`illum`"),
            ("newmtl a\nKs 1 2\n", 2, "`Ks`"),
            ("newmtl a\nKe\n", 2, "`Ke` needs a colour"),
        ] {
            let e = parse_obj_bytes(Path::new("d/a.obj"), obj, |_| Some(mtl.as_bytes().to_vec()));
            let e = e.unwrap_err().to_string();
            assert!(e.starts_with(&format!("d/m.mtl:{line}:")) && e.contains(key), "{mtl:?}: {e}");
        }
    }

    #[test]
    fn ignored_vertex_data_is_reported() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\n").unwrap();
        assert_eq!(m.warnings.len(), 2, "{:?}", m.warnings);
        assert!(m.warnings[0].starts_with("test.obj: vertex normals (`vn`) are ignored"), "{:?}", m.warnings);
        assert!(m.warnings[1].contains("texture coordinates (`vt`) are ignored"), "{:?}", m.warnings);
        assert!(parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap().warnings.is_empty());
    }

    #[test]
    fn degenerate_triangles_are_kept_and_detected() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\nf 1 1 4\n").unwrap();
        assert_eq!(m.triangles.len(), 3);
        assert_eq!(m.degenerate_ids(), vec![0, 2]);
    }

    #[test]
    fn gzip_scenes_load_like_plain_ones() {
        use std::io::Write;
        let dir = tempfile::tempdir().unwrap();
        let text = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl red\nf 1 2 3 4\n";
        std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1 0 0\n").unwrap();
        let plain = dir.path().join("a.obj");
        std::fs::write(&plain, text).unwrap();
        let gz = dir.path().join("a.obj.gz");
        let mut enc = flate2::write::GzEncoder::new(std::fs::File::create(&gz).unwrap(), flate2::Compression::fast());
        enc.write_all(text.as_bytes()).unwrap();
        enc.finish().unwrap();
        let (a, b) = (load_obj(&plain).unwrap(), load_obj(&gz).unwrap());
        assert_eq!((a.positions, a.triangles, a.material_ids), (b.positions, b.triangles, b.material_ids));
        assert_eq!(b.materials.len(), 1);

        // Not gzip at all, and a truncated stream: named errors, no panic.
        let fake = dir.path().join("b.obj.gz");
        std::fs::write(&fake, text).unwrap();
        let e = load_obj(&fake).unwrap_err().to_string();
        assert!(e.contains("b.obj.gz") && e.contains("not a valid gzip"), "{e}");
        let cut = dir.path().join("c.obj.gz");
        let whole = std::fs::read(&gz).unwrap();
        std::fs::write(&cut, &whole[..whole.len() / 2]).unwrap();
        let e = load_obj(&cut).unwrap_err().to_string();
        assert!(e.contains("c.obj.gz") && e.contains("gzip"), "{e}");
    }

    #[test]
    fn a_small_gzip_bomb_stops_at_the_limit() {
        use std::io::Write;
        // 64 MiB of comment lines compress to ~64 KiB; with a 1 MiB limit the reader stops after
        // 1 MiB + 1 byte instead of inflating all of it.
        let dir = tempfile::tempdir().unwrap();
        let bomb = dir.path().join("bomb.obj.gz");
        let mut enc = flate2::write::GzEncoder::new(std::fs::File::create(&bomb).unwrap(), flate2::Compression::best());
        let block = vec![b'#'; 1 << 20];
        for _ in 0..64 {
            enc.write_all(&block).unwrap();
        }
        enc.finish().unwrap();
        assert!(std::fs::metadata(&bomb).unwrap().len() < 1 << 20);
        let e = read_bytes(&bomb, 1 << 20).unwrap_err().to_string();
        assert!(e.contains("bomb.obj.gz") && e.contains("decompresses to more than 1048576 bytes"), "{e}");
    }

    const OBJ: &[u8] = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\nusemtl b\nf 1 2 3\n";

    fn with_mtl(obj: &[u8], mtl: &[u8]) -> Result<Mesh> {
        parse_obj_bytes(Path::new("d/a.obj"), obj, |p| (p == Path::new("d/m.mtl")).then(|| mtl.to_vec()))
    }

    /// Names that are not UTF-8 match by their bytes, in OBJ and MTL alike, and show as U+FFFD.
    #[test]
    fn latin1_names_match_by_their_bytes() {
        let obj = b"# \xA9 caf\xE9\nmtllib m.mtl\ng Bo\xEEte\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl M\xE9tal\nf 1 2 3\n\
                    usemtl M\xE8tal\nf 1 2 3\nusemtl Bl\xE9\nf 1 2 3\n";
        let mtl = b"# mat\xE9riaux\nnewmtl M\xE9tal\nillum 3\nnewmtl M\xE8tal\nillum 7\nmap_Kd bois_\xE9.png\n";
        let m = with_mtl(obj, mtl).unwrap();
        let kinds: Vec<_> = m.material_ids.iter().map(|&i| m.materials[i as usize].kind).collect();
        assert_eq!(
            kinds,
            [super::super::BsdfKind::Mirror, super::super::BsdfKind::Glass, super::super::BsdfKind::Lambert]
        );
        assert_eq!(m.materials[0].name, "M\u{FFFD}tal");
        assert!(m.warnings.iter().any(|w| w == "d/a.obj:11: usemtl `Bl\u{FFFD}`: no material library defines it; using the default material (grey Lambert)"), "{:?}", m.warnings);
        assert!(
            m.warnings.iter().any(|w| w.starts_with("d/m.mtl:6: material `M\u{FFFD}tal`: `map_Kd` bois_\u{FFFD}.png")),
            "{:?}",
            m.warnings
        );
    }

    #[test]
    fn usemtl_without_a_name_takes_the_default_material() {
        let obj = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\nusemtl\nf 1 2 3\nusemtl \t\nf 1 2 3\n";
        let m = with_mtl(obj, b"newmtl a\nKd 1 0 0\n").unwrap();
        assert_eq!(m.materials[m.material_ids[0] as usize].name, "a");
        assert_eq!(m.materials[m.material_ids[1] as usize], Material::default());
        assert_eq!(m.material_ids[1], m.material_ids[2]);
        assert_eq!(
            m.warnings,
            ["d/a.obj:7: usemtl without a material name: the faces that follow take the default material \
              (grey Lambert) (1 more such lines)"]
        );
    }

    /// A byte that is not UTF-8 in a line trilab parses is an error naming file, line and byte,
    /// in the OBJ and in the MTL; number spellings Rust's f32 parser reads are accepted.
    #[test]
    fn strict_lines_stay_strict_and_numbers_are_read_as_tobj_reads_them() {
        let e = with_mtl(b"v 0 0 0\nv 1 0\xB70\nv 0 1 0\nf 1 2 3\n", b"").unwrap_err().to_string();
        assert!(e.starts_with("d/a.obj:2: `v` line holds byte 0xB7"), "{e}");
        let e = with_mtl(OBJ, b"newmtl a\nKd 0\xB75 0 0\n").unwrap_err().to_string();
        assert!(e.starts_with("d/m.mtl:2: `Kd` line holds byte 0xB7"), "{e}");
        let m = parse("v 0 0 0\nv 1e+2 0 0\nv 0 2.e+1 0\nv .5 -.5e-3 +1\nf 1 2 3\nf 1 2 4\n").unwrap();
        assert_eq!(m.positions, [[0.0, 0.0, 0.0], [100.0, 0.0, 0.0], [0.0, 20.0, 0.0], [0.5, -0.0005, 1.0]]);
        for (line, what) in [
            ("v 1.2.3 0 0", "cannot parse vertex position"),
            ("v 0 nan 0", "NaN or infinite"),
            ("v 1e39 0 0", "NaN or infinite"),
        ] {
            let e = err(&format!("v 0 0 0\nv 1 0 0\n{line}\nf 1 2 3\n"));
            assert!(e.starts_with("test.obj:3:") && e.contains(what), "{line}: {e}");
        }
    }

    #[test]
    fn a_bad_second_library_is_not_skipped() {
        let obj = b"mtllib m.mtl\nmtllib n.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
        let e = parse_obj_bytes(Path::new("d/a.obj"), obj, |p| {
            Some(if p == Path::new("d/m.mtl") { b"newmtl a\n".to_vec() } else { b"newmtl b\nKd 1 x 1\n".to_vec() })
        });
        let e = e.unwrap_err().to_string();
        assert!(e.starts_with("d/n.mtl:2:") && e.contains("`Kd`"), "{e}");
    }

    /// Refused when the text is decoded, before any parsing, naming the file (the OBJ or the MTL)
    /// and the byte order.
    #[test]
    fn utf16_without_a_bom_is_refused_naming_file_and_byte_order() {
        let text = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n";
        let le: Vec<u8> = text.encode_utf16().flat_map(u16::to_le_bytes).collect();
        let be: Vec<u8> = text.encode_utf16().flat_map(u16::to_be_bytes).collect();
        let e = with_mtl(&le, b"newmtl a\n").unwrap_err().to_string();
        assert!(e.starts_with("d/a.obj: looks like UTF-16 little-endian text without a byte-order mark"), "{e}");
        assert!(e.contains("`iconv -f UTF-16LE -t UTF-8 a.obj > a.utf8.obj`"), "{e}");
        let e = with_mtl(&be, b"newmtl a\n").unwrap_err().to_string();
        assert!(e.starts_with("d/a.obj: looks like UTF-16 big-endian text") && e.contains("UTF-16BE"), "{e}");
        let mtl: Vec<u8> = "newmtl a\nKd 1 0 0\n".encode_utf16().flat_map(u16::to_be_bytes).collect();
        let e = with_mtl(text.as_bytes(), &mtl).unwrap_err().to_string();
        assert!(e.starts_with("d/m.mtl: looks like UTF-16 big-endian text") && e.contains("m.utf8.mtl"), "{e}");
    }

    /// Blender 2.61 writes an unnamed material as a bare `usemtl` in the OBJ and a bare `newmtl`
    /// in the MTL (`newmtl `, with the space): the faces take that material's values, with a
    /// warning naming each file and line.
    #[test]
    fn blender_2_61_unnamed_material_applies_to_faces_after_a_bare_usemtl() {
        let obj = b"# Blender v2.61 (sub 0) OBJ File: ''\n# www.blender.org\nmtllib m.mtl\no Plane\n\
                    v 1 0 -1\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 0 1 0\nusemtl Red\ns off\nf 1 2 3\n\
                    usemtl \ns off\nf 1 3 4\nf 4 1 5\nusemtl Red\nf 2 3 5\n";
        let mtl = b"# Blender MTL File: 'None'\n# Material Count: 2\nnewmtl Red\nNs 96.078431\nKa 0 0 0\n\
                    Kd 0.4 0 0\nKs 0.5 0.5 0.5\nNi 1\nd 1\nillum 2\n\nnewmtl \nNs 96.078431\nKa 0 0 0\n\
                    Kd 0.2 0.4 0.6\nKs 0 0 0\nNi 1\nd 1\nillum 2\n";
        let m = with_mtl(obj, mtl).unwrap();
        assert_eq!(m.triangles.len(), 4);
        let mats: Vec<&Material> = m.material_ids.iter().map(|&i| &m.materials[i as usize]).collect();
        assert_eq!(mats.iter().map(|m| m.name.as_str()).collect::<Vec<_>>(), ["Red", "", "", "Red"]);
        assert_eq!(mats[0].gpu.diffuse, [0.4, 0.0, 0.0]);
        assert_eq!(mats[1].kind, super::super::BsdfKind::Lambert);
        assert_eq!(mats[1].gpu.diffuse, [0.2, 0.4, 0.6]);
        assert_eq!(m.materials.len(), 2, "no default material: every face has one");
        assert_eq!(
            m.warnings,
            [
                "d/m.mtl:12: newmtl without a material name: it defines the unnamed material, which `usemtl` \
                 without a name selects",
                "d/a.obj:13: usemtl without a material name: the faces that follow take the unnamed material \
                 (`newmtl` without a name, d/m.mtl:12)",
            ]
        );

        // Its values follow the same rules as any material's, in messages that call it unnamed.
        let e = with_mtl(obj, b"newmtl Red\nnewmtl\nKd -1 0 0\n").unwrap_err().to_string();
        assert_eq!(
            e,
            "d/m.mtl:3: unnamed material (`newmtl` without a name): `Kd` -1 0 0: a reflectance cannot be negative"
        );
        let m = with_mtl(obj, b"newmtl Red\nnewmtl\nmap_Kd wood.png\n").unwrap();
        assert!(
            m.warnings.contains(
                &"d/m.mtl:3: unnamed material (`newmtl` without a name): `map_Kd` wood.png: textures are not \
                  supported; ignored"
                    .to_owned()
            ),
            "{:?}",
            m.warnings
        );
        // Without a bare `newmtl`, a bare `usemtl` still takes the default material.
        let m = with_mtl(obj, b"newmtl Red\nKd 0.4 0 0\n").unwrap();
        assert_eq!(m.materials[m.material_ids[1] as usize], Material::default());
        assert!(m.warnings[0]
            .starts_with("d/a.obj:13: usemtl without a material name: the faces that follow take the default"));
    }

    /// Classic Mac OS line ends (CR alone) are line ends, in the OBJ and the MTL, alone or mixed
    /// with LF and CRLF; messages count the lines they end.
    #[test]
    fn lone_cr_line_ends_are_line_ends() {
        let obj = b"mtllib m.mtl\rv 0 0 0\rv 1 0 0\rv 0 1 0\rv 1 1 0\rusemtl a\rf 1 2 3\rf 2 4 3\r";
        let m = with_mtl(obj, b"newmtl a\rKd 0.1 0.2 0.3\r").unwrap();
        assert_eq!(m.triangles, [[0, 1, 2], [1, 3, 2]]);
        assert_eq!(m.material_ids, [0, 0]);
        assert_eq!(m.materials[0].gpu.diffuse, [0.1, 0.2, 0.3]);
        assert!(m.warnings.is_empty(), "{:?}", m.warnings);

        let e = with_mtl(obj, b"newmtl a\rKd 1 1 1\r\rNs high\r").unwrap_err().to_string();
        assert!(e.starts_with("d/m.mtl:4: `Ns` needs a number"), "{e}");
        let e = with_mtl(obj, b"newmtl a\rKd 1 1 1\rKd -1 0 0\r").unwrap_err().to_string();
        assert!(e.starts_with("d/m.mtl:3: material `a`: `Kd`"), "{e}");
        let e = err("v 0 0 0\rv 1 x 0\rv 0 1 0\rf 1 2 3\r");
        assert!(e.starts_with("test.obj:2: cannot parse vertex position"), "{e}");
        let e = err("v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 3\rf 1 2 4\r");
        assert!(e.starts_with("test.obj:5: face vertex index 4 is out of range"), "{e}");
        let e = err("v 0 0 0\rv 1 0 0\rv 0 1 0\rv 1 inf 0\rf 1 2 4\r");
        assert!(e.starts_with("test.obj:4: vertex coordinate is NaN or infinite"), "{e}");

        // Mixed: CRLF, CR, LF, CRLF, a blank line ended by CR, CR, LF.
        let mixed = "v 0 0 0\r\nv 1 0 0\rv 0 1 0\nv 0 0 1\r\n\rf 1 2 3\rf 1 2 4\n";
        let m = parse(mixed).unwrap();
        assert_eq!(m.triangles, [[0, 1, 2], [0, 1, 3]]);
        let e = err(&format!("{mixed}usemtl x\rf 1 2 9\r\n"));
        assert!(e.starts_with("test.obj:9: face vertex index 9 is out of range"), "{e}");
        let m = parse(&format!("{mixed}usemtl x\rf 1 2 3\r\n")).unwrap();
        assert_eq!(m.warnings.len(), 1, "{:?}", m.warnings);
        assert!(
            m.warnings[0].starts_with("test.obj:8: usemtl `x`: no material library defines it"),
            "{:?}",
            m.warnings
        );
    }

    #[test]
    fn an_mtllib_name_that_is_not_utf8_opens_the_file_of_its_bytes() {
        let dir = tempfile::tempdir().unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let mtl = dir.path().join(std::ffi::OsStr::from_bytes(b"mat\xE9riaux.mtl"));
            std::fs::write(&mtl, "newmtl a\nillum 3\n").unwrap();
            let obj = dir.path().join("a.obj");
            std::fs::write(&obj, b"mtllib mat\xE9riaux.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl a\nf 1 2 3\n").unwrap();
            let m = load_obj(&obj).unwrap();
            assert!(m.warnings.is_empty(), "{:?}", m.warnings);
            assert_eq!(m.materials[0].kind, super::super::BsdfKind::Mirror);
            assert_eq!(m.mtl_files, [mtl]);
        }
    }
}
