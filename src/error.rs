//! One error type for the crate (after kajiya's backend): input problems name the file and what
//! is wrong with it; Vulkan and allocator failures carry what was being done.

use std::path::{Path, PathBuf};

use ash::vk;

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },

    /// An input file is malformed. `line` is 1-based where the problem is on one line.
    #[error("{}{}: {message}", path.display(), line.map(|l| format!(":{l}")).unwrap_or_default())]
    BadInput { path: PathBuf, line: Option<usize>, message: String },

    /// A request the tool cannot satisfy (bad option combination, output over an input, ...).
    #[error("{0}")]
    Usage(String),

    /// The Vulkan loader could not be loaded.
    #[error("cannot load the Vulkan loader (libvulkan.so.1): {0}; install libvulkan1 and a driver (see README)")]
    Loader(String),

    /// No usable Vulkan device, or the requested one is absent.
    #[error("{0}")]
    NoDevice(String),

    /// A Vulkan call failed.
    #[error("Vulkan error {result:?} during {during}")]
    Vulkan { result: vk::Result, during: String },

    /// GPU memory allocation failed.
    #[error("GPU allocation `{name}` failed: {source}")]
    Allocation {
        name: String,
        #[source]
        source: gpu_allocator::AllocationError,
    },

    /// SPIR-V could not be parsed or reflected.
    #[error("SPIR-V of kernel {kernel}: {message}")]
    Spirv { kernel: String, message: String },

    /// The device lacks (or the context left off) a feature the request needs, e.g.
    /// "ray query: unsupported on <device>". Never answered with a fallback.
    #[error("{0}")]
    Unsupported(String),

    /// A GPU job took longer than its wall-clock limit.
    #[error("{what} did not finish within {seconds} s")]
    Timeout { what: String, seconds: f64 },

    /// A scene's GPU memory placement (`encoding::placement`) does not fit the device: found
    /// before anything is allocated.
    #[error("{0}")]
    SceneTooLarge(Box<TooLarge>),

    /// The device was lost or ran out of memory (`gpu::markers`): `what` happened during
    /// `during` (the submit or allocation that failed); `markers` names the last dispatch begun
    /// and the last completed, per the GPU breadcrumbs or the host log.
    #[error("{what} during {during}; {markers}")]
    GpuFault { what: String, result: Option<vk::Result>, during: String, markers: String },
}

/// What does not fit, for [`Error::SceneTooLarge`].
#[derive(Debug, Clone)]
pub struct TooLarge {
    pub scene: String,
    pub method: String,
    pub buffer: String,
    pub needed: String,
    pub available: String,
    /// What to try instead.
    pub hint: String,
}

impl std::fmt::Display for TooLarge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "scene `{}` does not fit this device with method {}: buffer `{}` needs {}, the device allows {}; try {}",
            self.scene, self.method, self.buffer, self.needed, self.available, self.hint
        )
    }
}

impl From<vk::Result> for Error {
    fn from(result: vk::Result) -> Self {
        Error::Vulkan { result, during: "a Vulkan call".into() }
    }
}

impl Error {
    pub fn bad_input(path: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        Error::BadInput { path: path.to_owned(), line, message: message.into() }
    }

    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io { path: path.to_owned(), source }
    }
}

/// Attaches what was being done to a failed Vulkan call.
pub trait VkContext<T> {
    fn during(self, what: &str) -> Result<T>;
}

impl<T> VkContext<T> for std::result::Result<T, vk::Result> {
    fn during(self, what: &str) -> Result<T> {
        self.map_err(|result| Error::Vulkan { result, during: what.to_owned() })
    }
}
