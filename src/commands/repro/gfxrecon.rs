//! GFXReconstruct, as `scripts/gfxreconstruct.sh` unpacks it (Debian 12's 0.9.18, never
//! installed over anything): its capture layer, which records a repro's dispatch in a child trilab
//! (the worker service, with the layer named in its environment), and `gfxrecon-replay`, which
//! plays the capture back on whatever driver the loader finds.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::error::{Error, Result};
use crate::services::worker::{self, Launch, Message, Request};

/// Where `scripts/gfxreconstruct.sh` puts it, unless `TRILAB_GFXRECON` names another folder.
pub const ENV: &str = "TRILAB_GFXRECON";
pub const LAYER: &str = "VK_LAYER_LUNARG_gfxreconstruct";

/// An unpacked GFXReconstruct.
#[derive(Clone, Debug)]
pub struct Gfxrecon {
    pub root: PathBuf,
    /// Its Debian version (`0.9.18+dfsg-1`).
    pub version: String,
}

impl Gfxrecon {
    /// `TRILAB_GFXRECON`, else `~/.cache/trilab/gfxreconstruct`; an error saying what is missing
    /// and how to get it.
    pub fn find() -> Result<Gfxrecon> {
        let root = match std::env::var_os(ENV) {
            Some(d) if !d.is_empty() => PathBuf::from(d),
            _ => {
                let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_default();
                home.join(".cache/trilab/gfxreconstruct")
            }
        };
        let g = Gfxrecon { version: String::new(), root };
        let missing: Vec<_> = [g.manifest(), g.replay_exe(), g.root.join("version")]
            .into_iter()
            .filter(|p| !p.is_file())
            .map(|p| p.display().to_string())
            .collect();
        if !missing.is_empty() {
            return Err(Error::Unsupported(format!(
                "GFXReconstruct not found ({} missing): run scripts/gfxreconstruct.sh, or set {ENV} to the folder it made",
                missing.join(", ")
            )));
        }
        let version = std::fs::read_to_string(g.root.join("version")).unwrap_or_default().trim().to_owned();
        Ok(Gfxrecon { version, ..g })
    }

    fn manifest(&self) -> PathBuf {
        self.root.join("layer/VkLayer_gfxreconstruct.json")
    }

    pub fn replay_exe(&self) -> PathBuf {
        self.root.join("bin/gfxrecon-replay")
    }

    /// The environment that loads the capture layer, writing `capture` (its log to `log`, not
    /// stdout, which is the worker's).
    fn capture_env(&self, capture: &Path, log: &Path) -> Vec<(OsString, OsString)> {
        let kv = |k: &str, v: &std::ffi::OsStr| (OsString::from(k), v.to_owned());
        vec![
            kv("VK_LAYER_PATH", self.root.join("layer").as_os_str()),
            kv("VK_INSTANCE_LAYERS", LAYER.as_ref()),
            kv("GFXRECON_CAPTURE_FILE", capture.as_os_str()),
            kv("GFXRECON_CAPTURE_FILE_TIMESTAMP", "false".as_ref()),
            // Each buffer on its own pages: the page guard then never mixes one buffer's host
            // writes with another's device writes (the layer warns otherwise).
            kv("GFXRECON_PAGE_GUARD_ALIGN_BUFFER_SIZES", "true".as_ref()),
            kv("GFXRECON_CAPTURE_COMPRESSION_TYPE", "ZSTD".as_ref()),
            kv("GFXRECON_LOG_LEVEL", "warning".as_ref()),
            kv("GFXRECON_LOG_OUTPUT_TO_CONSOLE", "false".as_ref()),
            kv("GFXRECON_LOG_FILE", log.as_os_str()),
        ]
    }

    /// Runs the repro in `dir` once in a child trilab on device `device` under the capture
    /// layer, writing `capture`; returns the hits the captured dispatch read back.
    pub fn capture(&self, dir: &Path, device: usize, capture: &Path) -> Result<Vec<crate::rays::Hit>> {
        let scratch = tempfile::tempdir().map_err(|e| Error::io(Path::new("a temporary folder"), e))?;
        let log = scratch.path().join("gfxrecon.log");
        let hits = scratch.path().join("captured.hits");
        let mut launch = Launch::new(worker::this_exe()?).device(device).validation(false);
        launch.env = self.capture_env(capture, &log);
        launch.args = vec!["--repro".into(), dir.into()];
        // VK_LAYER_PATH names the capture layer's folder alone: the validation layer is not found
        // there, and a capture must not hold it anyway.
        launch.unset = vec!["TRILAB_VALIDATION".into()];
        launch.timeout = Some(Duration::from_secs(600));
        let request = Request::ReproDispatch { dir: dir.to_owned(), hits: hits.clone() };
        let answer = worker::call(&launch, "the capture (trilab under GFXReconstruct's layer)", &request)
            .map_err(|e| with_log(e, &log))?;
        match answer.message {
            Message::ReproDispatched { .. } => {}
            m => return Err(worker::unexpected("the capture", "repro-dispatched", &m)),
        }
        if !capture.is_file() {
            return Err(with_log(Error::Usage(format!("GFXReconstruct's layer wrote no {}", capture.display())), &log));
        }
        crate::rays::read_hits(&hits)
    }

    /// `gfxrecon-replay` of `capture` on the loader's device `gpu` (`None`: its first), with
    /// the drivers this process's environment names, under trilab's read-back layer
    /// (`readback_layer.c`), which keeps the `hits_bytes` the replayed dispatch read back; its
    /// exit status, output and those bytes' hits.
    pub fn replay(&self, capture: &Path, gpu: Option<usize>, hits_bytes: u64) -> Result<Replayed> {
        let layer = ReadbackLayer::write()?;
        let kept = layer.dir.path().join("readback.hits");
        let mut cmd = std::process::Command::new(self.replay_exe());
        if let Some(i) = gpu {
            cmd.arg("--gpu").arg(i.to_string());
        }
        // Memory types matched by what they offer, not by index: a capture made on another
        // driver names that driver's types (harmless on the same driver).
        cmd.args(["-m", "remap"])
            .arg(capture)
            .env("VK_LAYER_PATH", layer.dir.path())
            .env("VK_INSTANCE_LAYERS", READBACK_LAYER)
            .env("TRILAB_READBACK_FILE", &kept)
            .env("TRILAB_READBACK_BYTES", hits_bytes.to_string())
            .env("TRILAB_READBACK_USAGE", READBACK_USAGE.to_string());
        let out = crate::children::output(&mut cmd).map_err(|e| Error::io(&self.replay_exe(), e))?;
        let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        let hits = match std::fs::read(&kept) {
            Ok(bytes) => Some(crate::rays::parse_hits(&kept, &bytes)?),
            Err(_) => None,
        };
        Ok(Replayed { success: out.status.success(), status: out.status.to_string(), output: text, hits })
    }
}

/// The read-back layer's name (its manifest, written beside the library).
pub const READBACK_LAYER: &str = "VK_LAYER_TRILAB_readback";
/// The usage of the buffer trilab reads results back through (`Context::download`):
/// `VK_BUFFER_USAGE_TRANSFER_DST_BIT` alone.
const READBACK_USAGE: u32 = ash::vk::BufferUsageFlags::TRANSFER_DST.as_raw();

/// `src/commands/repro/readback_layer.c`, built by build.rs (empty where it could not be).
static READBACK_LIBRARY: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/libtrilab_readback.so"));

/// The layer's library and manifest written to a temporary folder (for `VK_LAYER_PATH`).
struct ReadbackLayer {
    dir: tempfile::TempDir,
}

impl ReadbackLayer {
    fn write() -> Result<ReadbackLayer> {
        if READBACK_LIBRARY.is_empty() {
            return Err(Error::Unsupported(
                "this trilab was built without its read-back layer (build.rs needs a C compiler and the Vulkan \
                 headers: libvulkan-dev, which install-deps.sh installs)"
                    .into(),
            ));
        }
        let dir = tempfile::tempdir().map_err(|e| Error::io(Path::new("a temporary folder"), e))?;
        let lib = dir.path().join("libtrilab_readback.so");
        std::fs::write(&lib, READBACK_LIBRARY).map_err(|e| Error::io(&lib, e))?;
        let manifest = serde_json::json!({
            "file_format_version": "1.1.2",
            "layer": {
                "name": READBACK_LAYER,
                "type": "GLOBAL",
                "library_path": lib,
                "api_version": "1.3.0",
                "implementation_version": "1",
                "description": "trilab: keeps the hits a replayed dispatch reads back",
            }
        });
        let json = dir.path().join("VkLayer_trilab_readback.json");
        std::fs::write(&json, manifest.to_string()).map_err(|e| Error::io(&json, e))?;
        Ok(ReadbackLayer { dir })
    }
}

/// What `gfxrecon-replay` did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Replayed {
    pub success: bool,
    pub status: String,
    pub output: String,
    /// The hits the replayed dispatch read back (`None`: the layer kept none).
    #[serde(skip)]
    pub hits: Option<Vec<crate::rays::Hit>>,
}

impl Replayed {
    /// Whether it ran to the end with nothing worse than a warning in its log.
    pub fn clean(&self) -> bool {
        self.success && !self.output.contains("[gfxrecon] ERROR") && !self.output.contains("[gfxrecon] FATAL")
    }
}

/// `e` with the capture layer's log appended (what it said before the failure).
fn with_log(e: Error, log: &Path) -> Error {
    match std::fs::read_to_string(log) {
        Ok(l) if !l.trim().is_empty() => {
            let tail: Vec<_> = l.lines().rev().take(12).collect();
            let tail: Vec<_> = tail.into_iter().rev().collect();
            Error::Usage(format!("{e}\nGFXReconstruct's log:\n  {}", tail.join("\n  ")))
        }
        _ => e,
    }
}
