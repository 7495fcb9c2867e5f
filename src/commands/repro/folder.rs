//! A repro folder on disk: `cell.json` (the [`Manifest`]) and the files it names, written whole
//! or not at all, and read back with every file checked against the manifest before a device is
//! touched.
//!
//! ```text
//! DIR/cell.json        what the cell is, who made it where, and every file below with its size
//! DIR/README.md        for the driver developer: the replay commands and what to look at
//! DIR/kernel.spv       the kernel's SPIR-V, as trilab created the pipeline from it
//! DIR/kernel.spvasm    its disassembly
//! DIR/bindings/B-NAME.bin   each scene buffer at descriptor binding B, as uploaded
//! DIR/cell.rays        the rays (32 bytes each: docs/formats.md)
//! DIR/expected.hits    the hits of the device that made it (16 bytes each), checked against
//!                      trilab's f64 reference when it was made
//! DIR/capture.gfxr     the GFXReconstruct capture of the dispatch (when the layer was found)
//! ```

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bvh::{Builder, LeafPolicy};
use crate::encoding::{AccessPath, Layout, Method, Traversal};
use crate::error::{Error, Result};
use crate::kernels::{KernelSource, KERNELS};
use crate::pipeline::HostBinding;
use crate::rays::{self, Hit, Ray};
use crate::shared::Texel;

/// `cell.json`'s `format`: a reader refuses any other.
pub const FORMAT: &str = "trilab-repro 1";
pub const MANIFEST: &str = "cell.json";
pub const README: &str = "README.md";
pub const SPIRV: &str = "kernel.spv";
pub const DISASSEMBLY: &str = "kernel.spvasm";
pub const RAYS: &str = "cell.rays";
pub const EXPECTED: &str = "expected.hits";
pub const CAPTURE: &str = "capture.gfxr";
pub const BINDINGS: &str = "bindings";

/// `cell.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    /// Who made it, where.
    pub made: Made,
    pub cell: Cell,
    pub kernel: KernelFile,
    /// The scene's buffers in binding order.
    pub bindings: Vec<BindingFile>,
    pub rays: DataFile,
    pub expected: Expected,
    /// The capture, or why there is none.
    pub capture: Capture,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Made {
    pub trilab: String,
    pub commit: String,
    pub date: String,
    pub device: String,
    pub driver: String,
}

/// The cell, in trilab's words (what `trilab raycast` would be given to cast it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cell {
    pub scene: String,
    pub triangles: usize,
    pub method: Method,
    pub layout: Layout,
    pub traversal: Traversal,
    pub access: AccessPath,
    pub leaf_size: u32,
    /// The rest of the tree's build options, so `trilab` can build the same tree again (a
    /// folder from before they were recorded reads the defaults).
    #[serde(default)]
    pub leaf_policy: LeafPolicy,
    #[serde(default = "classic_sah_group")]
    pub sah_group: u32,
    #[serde(default)]
    pub builder: Builder,
    /// `closest` or `any` (an occlusion query: only hit or miss counts).
    pub query: Query,
}

/// What a folder without `sah_group` was built with: the builder's classic SAH.
fn classic_sah_group() -> u32 {
    crate::bvh::BuildOptions::new(1).sah_group
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Query {
    Closest,
    Any,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct KernelFile {
    /// The registry's name (`raycast.mt.closest`): the replay creates the pipeline of this
    /// trilab's kernel of that name, which must be the file's bytes.
    pub name: String,
    pub spirv: DataFile,
    pub disassembly: String,
    /// Workgroup size (x) and the subgroup size it ran at.
    pub local_size: u32,
    pub subgroup_size: u32,
    /// The device features its capabilities need (none: Vulkan 1.2's core), and whether it needs
    /// full subgroups: the capture's device enabled these alone.
    pub features: Vec<String>,
    pub full_subgroups: bool,
}

/// A file beside `cell.json` and its size, checked on reading.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DataFile {
    pub file: String,
    pub bytes: u64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BindingFile {
    pub binding: u32,
    pub name: String,
    pub texel: Texel,
    #[serde(flatten)]
    pub data: DataFile,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Expected {
    #[serde(flatten)]
    pub data: DataFile,
    /// Rays that hit.
    pub hits: usize,
    /// The f64 reference's verdict on these hits when the repro was made.
    pub validation: String,
    pub passes: bool,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Capture {
    /// `capture.gfxr`, or none.
    pub file: Option<DataFile>,
    /// GFXReconstruct's version, or why there is no capture.
    pub note: String,
    /// Rays whose hits in the captured dispatch differ from `expected.hits` (0: the capture holds
    /// the expected run).
    pub differing: Option<usize>,
}

/// A repro read back: its manifest and its inputs, every size checked.
pub struct Repro {
    pub dir: PathBuf,
    pub manifest: Manifest,
    pub kernel: &'static KernelSource,
    pub bindings: Vec<HostBinding>,
    pub rays: Vec<Ray>,
    pub expected: Vec<Hit>,
}

impl Repro {
    /// Reads `dir`: an error naming the file and the problem for a missing or short file, a
    /// manifest of another format, a kernel this trilab does not have or whose SPIR-V differs from
    /// `kernel.spv`, hits that do not match the rays one for one.
    pub fn read(dir: &Path) -> Result<Repro> {
        let path = dir.join(MANIFEST);
        if !dir.is_dir() {
            return Err(Error::Usage(format!("repro {}: not a folder", dir.display())));
        }
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let value: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::bad_input(&path, Some(e.line()), format!("not JSON: {e}")))?;
        match value.get("format").and_then(|f| f.as_str()) {
            Some(FORMAT) => {}
            Some(other) => {
                return Err(Error::bad_input(&path, None, format!("format `{other}`; this trilab reads `{FORMAT}`")))
            }
            None => return Err(Error::bad_input(&path, None, format!("no `format` (a trilab repro has `{FORMAT}`)"))),
        }
        let manifest: Manifest = serde_json::from_value(value)
            .map_err(|e| Error::bad_input(&path, None, format!("not a repro manifest: {e}")))?;
        let kernel = KERNELS.iter().find(|k| k.name == manifest.kernel.name).ok_or_else(|| {
            Error::bad_input(&path, None, format!("kernel `{}`: this trilab has no such kernel", manifest.kernel.name))
        })?;
        let spirv = read_data(dir, &manifest.kernel.spirv)?;
        if spirv != kernel.spirv() {
            return Err(Error::bad_input(
                &dir.join(&manifest.kernel.spirv.file),
                None,
                format!(
                    "differs from this trilab's `{}`: replay the capture with gfxrecon-replay, or check with the trilab \
                     that made it ({})",
                    kernel.name, manifest.made.trilab
                ),
            ));
        }
        let bindings = manifest
            .bindings
            .iter()
            .map(|b| {
                let bytes = read_data(dir, &b.data)?;
                if !bytes.len().is_multiple_of(b.texel.size()) {
                    return Err(Error::bad_input(
                        &dir.join(&b.data.file),
                        None,
                        format!("{} bytes is not a whole number of {}-byte texels", bytes.len(), b.texel.size()),
                    ));
                }
                Ok(HostBinding { name: b.name.clone(), binding: b.binding, texel: b.texel, bytes })
            })
            .collect::<Result<Vec<_>>>()?;
        let rays_path = dir.join(&manifest.rays.file);
        let rays = rays::parse_rays(&rays_path, &read_data(dir, &manifest.rays)?)?;
        let hits_path = dir.join(&manifest.expected.data.file);
        let expected = rays::parse_hits(&hits_path, &read_data(dir, &manifest.expected.data)?)?;
        if expected.len() != rays.len() {
            return Err(Error::bad_input(
                &hits_path,
                None,
                format!("{} hits for {} rays ({})", expected.len(), rays.len(), manifest.rays.file),
            ));
        }
        Ok(Repro { dir: dir.to_owned(), manifest, kernel, bindings, rays, expected })
    }
}

/// The bytes of `f` in `dir`, refused when its size is not the manifest's or its name leaves
/// the folder.
fn read_data(dir: &Path, f: &DataFile) -> Result<Vec<u8>> {
    let rel = Path::new(&f.file);
    if rel.is_absolute() || rel.components().any(|c| !matches!(c, std::path::Component::Normal(_))) {
        return Err(Error::bad_input(
            &dir.join(MANIFEST),
            None,
            format!("file `{}` is not a plain path inside the folder", f.file),
        ));
    }
    let path = dir.join(rel);
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    if bytes.len() as u64 != f.bytes {
        return Err(Error::bad_input(
            &path,
            None,
            format!("{} bytes; {MANIFEST} says {} (a cut or changed file)", bytes.len(), f.bytes),
        ));
    }
    Ok(bytes)
}

/// A repro folder being written: files go into a hidden folder beside `out`, renamed to `out`
/// when complete ([`Staged::finish`]); dropped unfinished, it is removed.
pub struct Staged {
    pub dir: PathBuf,
    out: PathBuf,
    done: bool,
}

impl Staged {
    /// Refuses an `out` that exists (a repro is never written over anything).
    pub fn new(out: &Path) -> Result<Staged> {
        if out.exists() {
            return Err(Error::Usage(format!(
                "--out {}: exists; a repro goes into a new folder (nothing is overwritten)",
                out.display()
            )));
        }
        let parent = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "repro".into());
        let dir = tempfile::Builder::new()
            .prefix(&format!(".{name}."))
            .tempdir_in(&parent)
            .map_err(|e| Error::io(&parent, e))?
            .keep();
        std::fs::create_dir(dir.join(BINDINGS)).map_err(|e| Error::io(&dir, e))?;
        Ok(Staged { dir, out: out.to_owned(), done: false })
    }

    /// Writes `bytes` to `rel` in the folder; returns its [`DataFile`].
    pub fn write(&self, rel: &str, bytes: &[u8]) -> Result<DataFile> {
        let path = self.dir.join(rel);
        std::fs::write(&path, bytes).map_err(|e| Error::io(&path, e))?;
        Ok(DataFile { file: rel.to_owned(), bytes: bytes.len() as u64 })
    }

    /// Renames the folder to `out`.
    pub fn finish(mut self) -> Result<PathBuf> {
        std::fs::rename(&self.dir, &self.out).map_err(|e| Error::io(&self.out, e))?;
        self.done = true;
        Ok(self.out.clone())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// A binding's file name: `bindings/<binding>-<name>.bin`, the name's letters and digits only.
pub fn binding_file(b: &HostBinding) -> String {
    let name: String =
        b.name.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    format!("{BINDINGS}/{}-{}.bin", b.binding, name.trim_matches('-'))
}
