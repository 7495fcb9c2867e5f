//! Where a scene comes from: a path, or a name (`bunny`) looked up from any working directory.
//!
//! A scene spec that names an existing file (or a `synth:` spec) is used as it is. Otherwise a
//! spec of one path component (`bunny`, `dragon.obj`, `mine.obj.gz`) is a name, looked up, in
//! order, as `<dir>/<name>`, `<dir>/<name>.obj` and `<dir>/<name>.obj.gz` in:
//!
//! 1. the folder given by `--scene-dir` ([`set_scene_dir`]),
//! 2. the folder in `TRILAB_SCENES`,
//! 3. `scenes/` beside the executable and in its ancestors up to three levels
//!    (`target/release/trilab` -> the repository's `scenes/`),
//! 4. the copy of the bunny compiled into the binary (`bunny` only: `trilab bench` works with no
//!    files at all),
//! 5. `scenes/` of the source tree trilab was built from.
//!
//! A name found nowhere is an error listing every place looked at. Every resolution is
//! recorded ([`resolved_scenes`]) so reports can say where their scenes came from.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

use serde::Serialize;

use crate::error::{Error, Result};

/// The scenes shipped in the repository's `scenes/` folder.
pub const BUNDLED: [&str; 5] = ["bunny", "dragon", "buddha", "cornell", "bsdfs"];

/// The path the compiled-in bunny goes by (messages, `scene_name` -> `bunny`).
pub const BUILTIN_BUNNY: &str = "<built-in>/bunny.obj";
pub(crate) const BUNNY_OBJ: &[u8] = include_bytes!("../../scenes/bunny.obj");
pub(crate) const BUNNY_MTL: &[u8] = include_bytes!("../../scenes/bunny.mtl");

/// Where a scene spec resolved to.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct SceneSource {
    /// As the user (or a default list) gave it.
    pub spec: String,
    /// The file read ([`BUILTIN_BUNNY`] for the compiled-in copy).
    pub path: PathBuf,
    /// How it was found: `path`, `--scene-dir`, `TRILAB_SCENES`, `beside the executable`,
    /// `built into trilab`, `source tree`, `synthetic`.
    pub found: String,
}

impl std::fmt::Display for SceneSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} -> {} ({})", self.spec, self.path.display(), self.found)
    }
}

fn scene_dir_cell() -> &'static Mutex<Option<PathBuf>> {
    static DIR: OnceLock<Mutex<Option<PathBuf>>> = OnceLock::new();
    DIR.get_or_init(|| Mutex::new(None))
}

fn record() -> &'static Mutex<Vec<SceneSource>> {
    static SEEN: OnceLock<Mutex<Vec<SceneSource>>> = OnceLock::new();
    SEEN.get_or_init(|| Mutex::new(Vec::new()))
}

/// Sets the folder of `--scene-dir`, searched first for scene names; it must be a folder.
pub fn set_scene_dir(dir: Option<PathBuf>) -> Result<()> {
    if let Some(d) = &dir {
        if !d.is_dir() {
            return Err(Error::Usage(format!("--scene-dir {}: not a folder", d.display())));
        }
    }
    *scene_dir_cell().lock().unwrap_or_else(|e| e.into_inner()) = dir;
    Ok(())
}

/// Every scene resolved so far in this process, in order, each once.
pub fn resolved_scenes() -> Vec<SceneSource> {
    record().lock().unwrap_or_else(|e| e.into_inner()).clone()
}

/// True for the path of the compiled-in bunny.
pub fn is_builtin(path: &Path) -> bool {
    path == Path::new(BUILTIN_BUNNY)
}

/// A folder to search, and what it is.
type Place = (PathBuf, &'static str);

/// The folders searched for a name, in order, with what each is (for `found` and messages).
/// The compiled-in bunny sits between the last two (see the module's documentation).
fn search_dirs() -> (Vec<Place>, Vec<Place>) {
    let mut before = Vec::new();
    if let Some(d) = scene_dir_cell().lock().unwrap_or_else(|e| e.into_inner()).clone() {
        before.push((d, "--scene-dir"));
    }
    if let Some(d) = std::env::var_os("TRILAB_SCENES").filter(|d| !d.is_empty()) {
        before.push((PathBuf::from(d), "TRILAB_SCENES"));
    }
    if let Ok(exe) = std::env::current_exe() {
        let mut dir = exe.parent().map(Path::to_owned);
        for _ in 0..4 {
            let Some(d) = dir else { break };
            before.push((d.join("scenes"), "beside the executable"));
            dir = d.parent().map(Path::to_owned);
        }
    }
    let after = vec![(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"), "source tree")];
    (before, after)
}

/// The file names a name may have in a folder.
fn candidates(name: &str) -> Vec<String> {
    let mut c = vec![name.to_owned()];
    if !name.ends_with(".obj") && !name.ends_with(".gz") {
        c.push(format!("{name}.obj"));
        c.push(format!("{name}.obj.gz"));
    }
    c
}

/// Resolves a scene spec (a path, a `synth:` spec or a name) to the file to read, or an error
/// naming every place it looked. Does not read the scene.
pub fn resolve(spec: &Path) -> Result<SceneSource> {
    let source = resolve_quiet(spec)?;
    let mut seen = record().lock().unwrap_or_else(|e| e.into_inner());
    if !seen.contains(&source) {
        seen.push(source.clone());
    }
    Ok(source)
}

fn resolve_quiet(spec: &Path) -> Result<SceneSource> {
    let text = spec.to_string_lossy().into_owned();
    let found = |path: PathBuf, how: &str| SceneSource { spec: text.clone(), path, found: how.to_owned() };
    if crate::scene::synthetic::is_spec(spec) {
        return Ok(found(spec.to_owned(), "synthetic"));
    }
    if is_builtin(spec) {
        return Ok(found(spec.to_owned(), "built into trilab"));
    }
    let is_name = spec.components().count() == 1 && !text.is_empty() && !text.ends_with(std::path::MAIN_SEPARATOR);
    // A folder called `bunny` in the working directory does not hide the scene.
    if spec.is_file() || (spec.exists() && !is_name) {
        return Ok(found(spec.to_owned(), "path"));
    }
    if !is_name {
        let stem = crate::scene::scene_name(spec);
        let hint = if BUNDLED.contains(&stem.as_str()) {
            format!(" (the bundled scene's name, `{stem}`, is found from any folder)")
        } else {
            String::new()
        };
        return Err(Error::bad_input(spec, None, format!("no such file{hint}")));
    }
    let names = candidates(&text);
    let (before, after) = search_dirs();
    let mut looked = Vec::new();
    if scene_dir_cell().lock().unwrap_or_else(|e| e.into_inner()).is_none() {
        looked.push("--scene-dir (not given)".to_owned());
    }
    if std::env::var_os("TRILAB_SCENES").is_none_or(|d| d.is_empty()) {
        looked.push("TRILAB_SCENES (not set)".to_owned());
    }
    let search = |dirs: &[(PathBuf, &str)], looked: &mut Vec<String>| -> Option<SceneSource> {
        for (dir, how) in dirs {
            for n in &names {
                let p = dir.join(n);
                if p.is_file() {
                    return Some(found(p, how));
                }
            }
            looked.push(format!("{} ({how})", dir.display()));
        }
        None
    };
    if let Some(s) = search(&before, &mut looked) {
        return Ok(s);
    }
    if names.iter().any(|n| n == "bunny" || n == "bunny.obj") {
        return Ok(found(PathBuf::from(BUILTIN_BUNNY), "built into trilab"));
    }
    looked.push("the scenes built into trilab (bunny only)".to_owned());
    if let Some(s) = search(&after, &mut looked) {
        return Ok(s);
    }
    Err(Error::Usage(format!(
        "scene `{text}`: not a file here, and no {} in: {}. Give a path, or set --scene-dir DIR or TRILAB_SCENES",
        names.join(" / "),
        looked.join(", ")
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_win_and_names_resolve() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.obj");
        std::fs::write(&p, "v 0 0 0\n").unwrap();
        assert_eq!(resolve(&p).unwrap().found, "path");
        assert_eq!(resolve(Path::new("synth:sphere:100")).unwrap().found, "synthetic");
        // Unit tests run from the crate root: `scenes/dragon.obj` exists beside no test binary,
        // so it comes from the source tree (or beside the executable when target/ is inside it).
        let d = resolve(Path::new("dragon")).unwrap();
        assert!(d.path.ends_with("scenes/dragon.obj"), "{d}");
        let e = resolve(Path::new("no-such-scene")).unwrap_err().to_string();
        assert!(e.contains("no-such-scene") && e.contains("source tree") && e.contains("built into"), "{e}");
        let e = resolve(Path::new("nowhere/bunny.obj")).unwrap_err().to_string();
        assert!(e.contains("nowhere/bunny.obj") && e.contains("`bunny`"), "{e}");
    }

    #[test]
    fn the_builtin_bunny_is_the_bundled_file() {
        let built = crate::scene::load_obj(Path::new(BUILTIN_BUNNY)).unwrap();
        let file = crate::scene::load_obj(&Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.obj")).unwrap();
        assert_eq!(built.positions, file.positions);
        assert_eq!(built.triangles, file.triangles);
        assert_eq!(built.materials, file.materials);
        assert!(built.mtl_files.is_empty());
        assert_eq!(crate::scene::scene_name(Path::new(BUILTIN_BUNNY)), "bunny");
    }
}
