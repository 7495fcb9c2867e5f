//! `trilab repro`: one cell (scene, method, layout, traversal, access path, rays) handed to a
//! driver developer who will not install trilab: a folder with a GFXReconstruct capture of that
//! dispatch alone (the device created with only what the kernel needs, so it replays on any
//! device that can run it), the SPIR-V and its disassembly, the scene's buffers, the rays, the
//! expected hits (checked against the f64 reference when made) and a README. `--check DIR`
//! replays the dispatch from the folder's files on the device in front of it and compares its
//! hits with the expected ones ray by ray.

mod cell;
pub mod compare;
pub mod folder;
pub mod gfxrecon;
mod readme;
pub mod replay;

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bvh::BuildOptions;
use crate::commands::raycast;
use crate::conditioning::MethodChoice;
use crate::encoding::{AccessPath, Layout, Raycast, SceneAccess, Traversal};
use crate::error::{Error, Result};
use crate::gpu::{Context, Needs};
use crate::kernels::KernelSource;
use crate::named::named_enum;
use crate::pipeline::{HostBinding, HostScene, SceneRequest};
use crate::rays::{self, Hit};
use crate::report::Report;
use crate::scene::load_obj;
use crate::services::provenance::Provenance;

pub use cell::CellRays;
pub use compare::Differences;
pub use folder::{Query, Repro};
pub use gfxrecon::Gfxrecon;

named_enum! {
    /// Whether `trilab repro` captures the dispatch with GFXReconstruct.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum CaptureChoice: "capture" {
        /// where GFXReconstruct is found (scripts/gfxreconstruct.sh, or TRILAB_GFXRECON); without it the folder says why there is no capture
        Auto = "auto" (default),
        /// fail without GFXReconstruct, or when the capture fails
        Required = "required",
        /// no capture
        Off = "off",
    }
}

/// What to make a repro of.
#[derive(Clone, Debug)]
pub struct ReproRequest {
    pub scene: PathBuf,
    pub rays: PathBuf,
    /// Only the first N rays of the file (`None`: all).
    pub first: Option<usize>,
    pub method: MethodChoice,
    pub layout: Layout,
    pub traversal: Traversal,
    /// Texel or storage (or auto, which must not choose the address path).
    pub access: SceneAccess,
    pub build: BuildOptions,
    pub any_hit: bool,
    pub capture: CaptureChoice,
    pub out: PathBuf,
}

/// What `trilab repro` made.
#[derive(Clone, Debug, Serialize)]
pub struct MadeReport {
    pub dir: PathBuf,
    pub kernel: String,
    pub rays: usize,
    pub hits: usize,
    pub validation: String,
    pub passes: bool,
    pub capture: folder::Capture,
    /// Bytes of the folder, and of the capture alone.
    pub bytes: u64,
    pub features: Vec<String>,
}

impl MadeReport {
    /// One line: the kernel, the device's verdict, the capture.
    pub fn summary(&self) -> String {
        let capture = match (&self.capture.file, self.capture.differing) {
            (Some(f), Some(0)) => {
                format!("capture {:.2} MB, its dispatch gave the expected hits", f.bytes as f64 / 1e6)
            }
            (Some(f), Some(n)) => format!("capture {:.2} MB, its dispatch gave {n} other hits", f.bytes as f64 / 1e6),
            (Some(f), None) => format!("capture {:.2} MB", f.bytes as f64 / 1e6),
            (None, _) => format!("no capture ({})", self.capture.note),
        };
        format!(
            "{}: {} rays, {} hit, {} with the f64 reference; {capture}",
            self.kernel,
            self.rays,
            self.hits,
            verdict(self.passes)
        )
    }
}

impl Report for MadeReport {
    fn to_text(&self) -> String {
        let mut s = format!(
            "repro:     {} ({:.2} MB)\nkernel:    {} (device features: {})\nrays:      {} ({} hit)\n",
            self.dir.display(),
            self.bytes as f64 / 1e6,
            self.kernel,
            if self.features.is_empty() { "none beyond Vulkan 1.2".into() } else { self.features.join(", ") },
            self.rays,
            self.hits
        );
        s += &format!("reference: {} with the f64 reference: {}\n", verdict(self.passes), self.validation);
        match &self.capture.file {
            Some(f) => {
                s += &format!("capture:   {} ({:.2} MB, {})", f.file, f.bytes as f64 / 1e6, self.capture.note);
                match self.capture.differing {
                    Some(0) => s += "; its dispatch returned the expected hits\n",
                    Some(n) => s += &format!("; its dispatch returned {n} hits that differ from the expected ones\n"),
                    None => s += "\n",
                }
            }
            None => s += &format!("capture:   none ({})\n", self.capture.note),
        }
        s += &format!(
            "replay:    see {}/README.md; check here with `trilab repro --check {}`\n",
            self.dir.display(),
            self.dir.display()
        );
        s
    }
}

fn verdict(passes: bool) -> &'static str {
    if passes {
        "agrees"
    } else {
        "DISAGREES"
    }
}

/// A cell's label (`bunny primary mt bvh2`) as the name of its repro's folder: letters, digits
/// and dashes, every other character a dash (`bunny-primary-mt-bvh2`).
pub fn folder_name(label: &str) -> String {
    label.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '-' }).collect()
}

/// Refuses an existing `dir` given as `option` (`--repro`), before any work: repros go into a
/// new folder, nothing is overwritten.
pub fn refuse_existing(option: &str, dir: &Path) -> Result<()> {
    if dir.exists() {
        return Err(Error::Usage(format!(
            "{option} {}: exists; the repros go into a new folder (nothing is overwritten)",
            dir.display()
        )));
    }
    Ok(())
}

/// Makes the repro: casts the cell here (the expected hits, validated), writes the folder, and
/// captures the dispatch in a child under GFXReconstruct's layer. Bad input and an existing
/// `out` are refused before any of it.
pub fn make(ctx: &Context, req: &ReproRequest, mut note: impl FnMut(&str)) -> Result<MadeReport> {
    let gfxrecon = check_and_find_capture(req)?;
    let staged = folder::Staged::new(&req.out)?;
    let mesh = load_obj(&req.scene)?;
    let mut rays = rays::read_rays(&req.rays)?;
    rays::check_reach(&req.rays, &rays, &mesh.bounds())?;
    if let Some(n) = req.first {
        rays.truncate(n);
    }
    let host = HostScene::build(crate::scene::scene_name(&req.scene), &mesh, &req.build)?;
    let request = SceneRequest::new(req.method).access(req.access).layout(req.layout).traversal(req.traversal);
    let placement = host.place(ctx, &request)?;
    if placement.access == AccessPath::Address {
        return Err(address_refused());
    }
    let kind = if req.any_hit { Raycast::Any } else { Raycast::Closest };
    let source = placement.key(kind).source()?;
    ctx.capabilities().traversal(placement.traversal)?;
    let needs = replay::needs(source)?;
    let bindings = placement.host_bindings()?;
    let (method, access, layout, traversal) =
        (placement.method, placement.access, placement.layout, placement.traversal);

    // The expected hits: this device, from the buffers the folder keeps, every ray in one
    // dispatch, as the replay casts them.
    let result = replay::cast(ctx, source, access, &bindings, &rays)?;
    let validation = raycast::validate(&host, &rays, &result, req.any_hit);
    let hits = result.hits.iter().filter(|h| h.is_hit()).count();
    if !validation.passes() {
        note("warning: the hits disagree with the f64 reference here (the repro keeps them as the expected hits)");
    }

    let mut manifest = folder::Manifest {
        format: folder::FORMAT.to_owned(),
        made: made_here(ctx),
        cell: folder::Cell {
            scene: host.name.clone(),
            triangles: mesh.triangle_count(),
            method,
            layout,
            traversal,
            access,
            leaf_size: req.build.max_leaf_size,
            leaf_policy: req.build.leaf_policy,
            sah_group: req.build.sah_group,
            builder: req.build.builder,
            query: if req.any_hit { Query::Any } else { Query::Closest },
        },
        kernel: write_kernel(ctx, &staged, source, &needs)?,
        bindings: write_bindings(&staged, &bindings)?,
        rays: staged.write(folder::RAYS, bytemuck::cast_slice(&rays))?,
        expected: folder::Expected {
            data: staged.write(folder::EXPECTED, bytemuck::cast_slice(&result.hits))?,
            hits,
            validation: validation.summary(),
            passes: validation.passes(),
        },
        capture: folder::Capture { file: None, note: String::new(), differing: None },
    };
    write_manifest(&staged.dir, &manifest)?;
    manifest.capture = capture(ctx, req, &staged, gfxrecon, manifest.cell.query, &result.hits, &mut note)?;
    write_manifest(&staged.dir, &manifest)?;
    std::fs::write(staged.dir.join(folder::README), readme::text(&manifest))
        .map_err(|e| Error::io(&staged.dir.join(folder::README), e))?;
    let bytes = folder_bytes(&staged.dir);
    let dir = staged.finish()?;
    Ok(MadeReport {
        dir,
        kernel: manifest.kernel.name.clone(),
        rays: rays.len(),
        hits,
        validation: manifest.expected.validation.clone(),
        passes: manifest.expected.passes,
        capture: manifest.capture.clone(),
        bytes,
        features: manifest.kernel.features.clone(),
    })
}

/// Refuses a request that cannot make a repro, before any work, and finds GFXReconstruct: the
/// reason there is none where the capture is not required.
fn check_and_find_capture(req: &ReproRequest) -> Result<std::result::Result<Gfxrecon, String>> {
    req.build.check()?;
    if req.access == SceneAccess::Address {
        return Err(address_refused());
    }
    if req.first == Some(0) {
        return Err(Error::Usage("--first 0: a repro needs at least one ray".into()));
    }
    let gfxrecon = match req.capture {
        CaptureChoice::Off => Err("not asked for (--capture off)".to_owned()),
        _ => Gfxrecon::find().map_err(|e| e.to_string()),
    };
    if let (CaptureChoice::Required, Err(why)) = (req.capture, &gfxrecon) {
        return Err(Error::Unsupported(why.clone()));
    }
    Ok(gfxrecon)
}

/// Who made the repro: this trilab, its commit, the date, the device and its driver.
fn made_here(ctx: &Context) -> folder::Made {
    let provenance = Provenance::of(ctx);
    folder::Made {
        trilab: format!("trilab {}", env!("CARGO_PKG_VERSION")),
        commit: provenance.commit.clone(),
        date: provenance.date.clone(),
        device: ctx.info().name.clone(),
        driver: ctx.info().driver_label(),
    }
}

/// Writes the kernel's SPIR-V and its disassembly into the folder; what the manifest says of it.
fn write_kernel(
    ctx: &Context,
    staged: &folder::Staged,
    source: &'static KernelSource,
    needs: &Needs,
) -> Result<folder::KernelFile> {
    let words = source.spirv();
    let kernel = folder::KernelFile {
        name: source.name.to_owned(),
        spirv: staged.write(folder::SPIRV, &words)?,
        disassembly: folder::DISASSEMBLY.to_owned(),
        local_size: ctx.kernel(source)?.layout.local_size.0,
        subgroup_size: ctx.info().subgroup_size,
        features: needs.features.iter().map(|f| f.name().to_owned()).collect(),
        full_subgroups: needs.full_subgroups,
    };
    let asm = crate::spirv::disassemble(&source.words())
        .map_err(|m| Error::Spirv { kernel: source.name.into(), message: m })?;
    staged.write(folder::DISASSEMBLY, asm.as_bytes())?;
    Ok(kernel)
}

/// Writes each scene buffer into the folder; what the manifest says of them.
fn write_bindings(staged: &folder::Staged, bindings: &[HostBinding]) -> Result<Vec<folder::BindingFile>> {
    bindings
        .iter()
        .map(|b| {
            Ok(folder::BindingFile {
                binding: b.binding,
                name: b.name.clone(),
                texel: b.texel,
                data: staged.write(&folder::binding_file(b), &b.bytes)?,
            })
        })
        .collect()
}

/// Captures the dispatch from the folder's files with GFXReconstruct where it was found, and
/// compares the capture's hits with the expected ones. A failed capture is a note, unless the
/// capture is required.
fn capture(
    ctx: &Context,
    req: &ReproRequest,
    staged: &folder::Staged,
    gfxrecon: std::result::Result<Gfxrecon, String>,
    query: Query,
    expected: &[Hit],
    note: &mut impl FnMut(&str),
) -> Result<folder::Capture> {
    let g = match gfxrecon {
        Err(why) => return Ok(folder::Capture { file: None, note: why, differing: None }),
        Ok(g) => g,
    };
    note(&format!("capturing the dispatch with GFXReconstruct {} ...", g.version));
    let path = staged.dir.join(folder::CAPTURE);
    Ok(match g.capture(&staged.dir, ctx.info().index, &path) {
        Ok(got) => {
            let differing = Differences::of(query, expected, &got);
            let bytes = std::fs::metadata(&path).map_err(|e| Error::io(&path, e))?.len();
            folder::Capture {
                file: Some(folder::DataFile { file: folder::CAPTURE.to_owned(), bytes }),
                note: format!("GFXReconstruct {}", g.version),
                differing: Some(differing.rays - differing.identical),
            }
        }
        Err(e) if req.capture == CaptureChoice::Required => return Err(e),
        Err(e) => {
            let _ = std::fs::remove_file(&path);
            note(&format!("warning: no capture: {e}"));
            folder::Capture { file: None, note: format!("the capture failed: {e}"), differing: None }
        }
    })
}

fn address_refused() -> Error {
    Error::Usage(
        "--scene-access address: the address path's buffers hold device addresses, which do not replay on another \
         device; a repro uses the texel or the storage path"
            .into(),
    )
}

fn write_manifest(dir: &Path, m: &folder::Manifest) -> Result<()> {
    let path = dir.join(folder::MANIFEST);
    let text = serde_json::to_string_pretty(m).expect("manifests serialise");
    std::fs::write(&path, text + "\n").map_err(|e| Error::io(&path, e))
}

/// Bytes of every file under `dir`.
fn folder_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    let mut stack = vec![dir.to_owned()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            match e.file_type() {
                Ok(t) if t.is_dir() => stack.push(e.path()),
                Ok(_) => total += e.metadata().map(|m| m.len()).unwrap_or(0),
                Err(_) => {}
            }
        }
    }
    total
}

/// What `trilab repro --check` found.
#[derive(Clone, Debug, Serialize)]
pub struct CheckReport {
    pub dir: PathBuf,
    pub kernel: String,
    /// Where the repro was made, and where it was checked.
    pub made_on: String,
    pub device: String,
    pub driver: String,
    pub differences: Differences,
    /// `gfxrecon-replay` of the capture on this driver, when asked for.
    pub gfxrecon_replay: Option<gfxrecon::Replayed>,
    /// The hits `gfxrecon-replay`'s dispatch read back, against the expected ones.
    pub gfxrecon_differences: Option<Differences>,
}

impl CheckReport {
    /// An error (exit 1) when any ray differs or the capture did not replay cleanly.
    pub fn verdict(&self) -> Result<()> {
        if !self.differences.same() {
            return Err(Error::Usage(format!("repro {}: {}", self.dir.display(), self.differences.verdict())));
        }
        match &self.gfxrecon_replay {
            Some(r) if !r.clean() => Err(Error::Usage(format!(
                "repro {}: gfxrecon-replay did not replay the capture cleanly ({})",
                self.dir.display(),
                r.status
            ))),
            _ => Ok(()),
        }
    }
}

impl Report for CheckReport {
    fn to_text(&self) -> String {
        let mut s = format!(
            "repro:     {} ({})\nmade on:   {}\nchecked on: {} ({})\n",
            self.dir.display(),
            self.kernel,
            self.made_on,
            self.device,
            self.driver
        );
        s += &self.differences.to_text();
        if let Some(r) = &self.gfxrecon_replay {
            let tail: Vec<_> = r.output.lines().rev().take(4).collect::<Vec<_>>().into_iter().rev().collect();
            s += &format!(
                "gfxrecon-replay: {} ({})\n  {}\n",
                if r.clean() { "replayed" } else { "FAILED" },
                r.status,
                tail.join("\n  ")
            );
            match &self.gfxrecon_differences {
                Some(d) => s += &format!("gfxrecon-replay's hits: {}", d.to_text()),
                None => s += "gfxrecon-replay's hits: none read back\n",
            }
        }
        s
    }
}

/// Replays `repro` on `ctx` (made by [`replay::context`]: only what its kernel needs) and
/// compares the hits; with `gfxrecon`, also replays its capture with `gfxrecon-replay` on the same
/// device. An error before any work when `gfxrecon` is asked for and there is no capture or no
/// GFXReconstruct.
pub fn check(ctx: &Context, repro: &Repro, gfxrecon: bool) -> Result<CheckReport> {
    let dir = &repro.dir;
    let replay_tool = match gfxrecon {
        true => {
            let capture = match &repro.manifest.capture.file {
                Some(f) => dir.join(&f.file),
                None => {
                    return Err(Error::Usage(format!(
                        "repro {}: holds no capture ({}); check without --gfxrecon",
                        dir.display(),
                        repro.manifest.capture.note
                    )))
                }
            };
            Some((Gfxrecon::find()?, capture))
        }
        false => None,
    };
    let got = replay::dispatch(ctx, repro)?;
    let differences = Differences::of(repro.manifest.cell.query, &repro.expected, &got);
    let info = ctx.info();
    let gfxrecon_replay = match replay_tool {
        Some((g, capture)) => Some(g.replay(&capture, Some(info.index), repro.expected.len() as u64 * 16)?),
        None => None,
    };
    let gfxrecon_differences = gfxrecon_replay
        .as_ref()
        .and_then(|r| r.hits.as_ref())
        .filter(|h| h.len() == repro.expected.len())
        .map(|h| Differences::of(repro.manifest.cell.query, &repro.expected, h));
    Ok(CheckReport {
        dir: dir.clone(),
        kernel: repro.kernel.name.to_owned(),
        made_on: format!("{} ({})", repro.manifest.made.device, repro.manifest.made.driver),
        device: info.name.clone(),
        driver: info.driver_label(),
        differences,
        gfxrecon_replay,
        gfxrecon_differences,
    })
}
