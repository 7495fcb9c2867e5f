//! The material libraries an OBJ names (`mtllib`): which files one `mtllib` line names, and
//! reading each through the MTL check ([`super::mtl`]) and tobj, keeping what that found in the
//! order tobj appends the materials.
//!
//! The spec lets one `mtllib` line name several files ("the first file listed is searched first
//! for the material definition, the second file is searched next, and so on"); Blender writes a
//! single name with spaces in it, unescaped; tinyobjloader splits names at spaces and reads a
//! space after a backslash as part of a name. So a line is one file when a file of its whole
//! text opens; otherwise it names the files its words name (`\ ` a space in a name), each read
//! in turn, the first to define a material name giving it.

use std::path::{Path, PathBuf};

use super::material::MtlLines;
use super::mtl::check_mtl;
use super::text::{self, Format};
use crate::error::Error;

/// What reading an OBJ's material libraries gathered.
pub(super) struct Libraries<'a> {
    obj: &'a Path,
    dir: PathBuf,
    source: &'a dyn Fn(&Path) -> Option<Vec<u8>>,
    /// The first problem, already as the error to report (tobj keeps going past a library it
    /// could not read when another gave materials).
    pub failure: Option<Error>,
    /// Each MTL file read, with how many materials it gave, in tobj's order.
    pub files: Vec<(PathBuf, usize)>,
    /// The line of each key of each material, in tobj's order.
    pub lines: Vec<MtlLines>,
    /// Libraries that cannot be opened and what the MTL check found, in the order read.
    pub warnings: Vec<String>,
    /// Each MTL file with `newmtl` lines without a name, and their lines.
    pub unnamed_newmtl: Vec<(PathBuf, Vec<usize>)>,
}

impl<'a> Libraries<'a> {
    /// For the OBJ `obj`, whose libraries `source` serves by path (`None`: cannot be opened).
    pub fn new(obj: &'a Path, source: &'a dyn Fn(&Path) -> Option<Vec<u8>>) -> Self {
        Libraries {
            obj,
            dir: obj.parent().map(Path::to_owned).unwrap_or_default(),
            source,
            failure: None,
            files: Vec::new(),
            lines: Vec::new(),
            warnings: Vec::new(),
            unnamed_newmtl: Vec::new(),
        }
    }

    /// tobj's material loader: the materials of the files one `mtllib` line names (`names`, the
    /// line after the key, as tobj gives it). A file that cannot be opened is a warning (geometry
    /// needs no materials: its materials become the default material); one that cannot be read
    /// is the error [`Self::failure`].
    pub fn load(&mut self, names: &Path) -> tobj::MTLLoadResult {
        let names = names.to_string_lossy();
        // tobj's own map type, which this crate does not name.
        let mut result: tobj::MTLLoadResult = Ok((Vec::new(), Default::default()));
        let Ok((materials, by_name)) = &mut result else { unreachable!("made Ok above") };
        for (full, bytes) in self.files_named(&names) {
            let Some(bytes) = bytes else {
                self.warnings.push(format!(
                    "{}: material library named by {} (mtllib) cannot be opened: its materials are replaced by the \
                     default material (grey Lambert)",
                    full.display(),
                    self.obj.display()
                ));
                continue;
            };
            let (mats, map) = self.read(full, &bytes)?;
            let offset = materials.len();
            materials.extend(mats);
            for (name, i) in map {
                by_name.entry(name).or_insert(offset + i);
            }
        }
        result
    }

    /// The files `names` names, each with its bytes when it opens (module documentation).
    fn files_named(&self, names: &str) -> Vec<(PathBuf, Option<Vec<u8>>)> {
        let open = |name: &str| {
            let full = self.dir.join(text::file_name(name));
            let bytes = (self.source)(&full);
            (full, bytes)
        };
        let whole = open(names);
        if whole.1.is_some() {
            return vec![whole];
        }
        let split = split_names(names);
        if split.len() == 1 && split[0] == names {
            return vec![whole];
        }
        split.iter().map(|n| open(n)).collect()
    }

    /// One MTL file's materials: decoded, checked, parsed by tobj; what it found is kept.
    fn read(&mut self, full: PathBuf, bytes: &[u8]) -> Result<(Vec<tobj::Material>, ByName), tobj::LoadError> {
        match self.parse(&full, bytes) {
            Ok(mtl) => {
                self.lines.extend(mtl.lines);
                self.warnings.extend(mtl.warnings);
                if !mtl.unnamed_newmtl.is_empty() {
                    self.unnamed_newmtl.push((full.clone(), mtl.unnamed_newmtl));
                }
                self.files.push((full, mtl.materials.len()));
                Ok((mtl.materials, mtl.by_name))
            }
            Err((e, kind)) => {
                self.failure.get_or_insert(e);
                Err(kind)
            }
        }
    }

    fn parse(&self, full: &Path, bytes: &[u8]) -> Result<ParsedMtl, (Error, tobj::LoadError)> {
        let decoded = text::decode(full, bytes, Format::Mtl).map_err(|e| (e, tobj::LoadError::ReadError))?;
        let checked = check_mtl(full, &decoded.text).map_err(|e| (e, tobj::LoadError::MaterialParseError))?;
        let (materials, by_name) = tobj::load_mtl_buf(&mut checked.text.as_bytes()).map_err(|e| {
            let message = format!("material library named by {} (mtllib): {e}", self.obj.display());
            (Error::bad_input(full, None, message), e)
        })?;
        // One block per `newmtl`, as tobj makes one material per `newmtl`.
        let mut lines = checked.lines;
        lines.resize_with(materials.len(), MtlLines::new);
        let by_name = by_name.into_iter().collect();
        Ok(ParsedMtl { materials, by_name, lines, warnings: checked.warnings, unnamed_newmtl: decoded.unnamed_newmtl })
    }

    /// The MTL file material `i` (in tobj's order) came from.
    pub fn file_of(&self, i: usize) -> PathBuf {
        let mut end = 0;
        for (f, n) in &self.files {
            end += n;
            if i < end {
                return f.clone();
            }
        }
        PathBuf::from("<mtllib>")
    }
}

/// Which material (its index among one file's) each name selects.
type ByName = Vec<(String, usize)>;

/// One MTL file as [`Libraries::parse`] read it.
struct ParsedMtl {
    materials: Vec<tobj::Material>,
    by_name: ByName,
    lines: Vec<MtlLines>,
    warnings: Vec<String>,
    unnamed_newmtl: Vec<usize>,
}

/// The names of an `mtllib` line: its words, a backslash before a space or tab making that
/// part of the name (tinyobjloader's rule).
fn split_names(line: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut name = String::new();
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\\' && chars.peek().is_some_and(|n| *n == ' ' || *n == '\t') {
            name.extend(chars.next());
        } else if c.is_whitespace() {
            if !name.is_empty() {
                names.push(std::mem::take(&mut name));
            }
        } else {
            name.push(c);
        }
    }
    if !name.is_empty() {
        names.push(name);
    }
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mtllib_names_split_at_spaces_not_escaped_ones() {
        assert_eq!(split_names("a.mtl"), ["a.mtl"]);
        assert_eq!(split_names(" a.mtl  b.mtl "), ["a.mtl", "b.mtl"]);
        assert_eq!(split_names(r"my\ file.mtl b.mtl"), ["my file.mtl", "b.mtl"]);
        assert_eq!(split_names(r"c:\mtl\a.mtl"), [r"c:\mtl\a.mtl"]);
        assert!(split_names("").is_empty());
    }

    #[test]
    fn a_name_with_spaces_is_one_file_when_that_file_opens() {
        let serve = |p: &Path| match p.to_str() {
            Some("d/my file.mtl") => Some(b"newmtl a\n".to_vec()),
            Some("d/b.mtl") => Some(b"newmtl b\nnewmtl a\nKd 1 0 0\n".to_vec()),
            _ => None,
        };
        let mut libs = Libraries::new(Path::new("d/x.obj"), &serve);
        let (mats, _) = libs.load(Path::new("my file.mtl")).unwrap();
        assert_eq!(mats.len(), 1);
        assert!(libs.warnings.is_empty(), "{:?}", libs.warnings);
        let (mats, map) = libs.load(Path::new(r"missing.mtl my\ file.mtl b.mtl")).unwrap();
        assert_eq!(mats.iter().map(|m| m.name.as_str()).collect::<Vec<_>>(), ["a", "b", "a"]);
        // The first file listed defines `a`.
        assert_eq!(map["a"], 0);
        assert_eq!(libs.warnings.len(), 1);
        assert!(
            libs.warnings[0].starts_with("d/missing.mtl: material library named by d/x.obj"),
            "{:?}",
            libs.warnings
        );
        assert_eq!(libs.file_of(3), Path::new("d/b.mtl"));
    }
}
