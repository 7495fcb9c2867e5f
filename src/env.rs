//! The environment variables trilab reads, listed once: `trilab --help` names them, and
//! docs/commands.md (`trilab man --markdown`, held to it by a test) explains them. Ground floor:
//! it imports nothing.

/// One environment variable and what it does (one line).
#[derive(Clone, Copy, Debug)]
pub struct EnvVar {
    pub name: &'static str,
    pub help: &'static str,
}

/// Every environment variable trilab (or the lavapipe driver it is measured on) reads.
pub const ENV_VARS: &[EnvVar] = &[
    EnvVar {
        name: "TRILAB_VALIDATION",
        help: "1: load the Khronos validation layer and fail on any message (as --validation)",
    },
    EnvVar {
        name: "TRILAB_SCENES",
        help: "folder searched for bundled scene names (bunny, dragon, buddha, cornell, bsdfs)",
    },
    EnvVar { name: "TRILAB_MAX_SCENE_BYTES", help: "most bytes of OBJ text read after decompression (default 2 GiB)" },
    EnvVar {
        name: "TRILAB_MAX_MEMORY",
        help: "bytes a command may allocate, checked before it does (default: MemAvailable); larger sizes are refused",
    },
    EnvVar { name: "TRILAB_COMMIT", help: "the commit recorded in reports instead of the working directory's (a copy without .git; the gate's base build)" },
    EnvVar {
        name: "TRILAB_INJECT_FAULT",
        help: "device-lost@N or oom@N: fake a fault at the N-th marked submit (tests of fault reports)",
    },
    EnvVar {
        name: "TRILAB_INJECT_SLOWDOWN",
        help: "NAME:F: every ray-casting dispatch of kernels named *NAME* does F times its work (the whole dispatch \
               floor(F) times, then the first frac(F) of its rays again; tests of the regression gate and `ab`'s \
               sensitivity)",
    },
    EnvVar { name: "TRILAB_TEST_LIMITS", help: "lower device limits for tests, e.g. max_texel_buffer_elements=4096" },
    EnvVar {
        name: "TRILAB_STOCK_MESA",
        help: "where scripts/stock-mesa.sh unpacked Debian 12's own Mesa (default ~/.cache/trilab/stock-mesa): \
               `driver-stats --targets ... --mesa stock` compiles with its RADV (radv_icd.json there)",
    },
    EnvVar { name: "LP_NUM_THREADS", help: "lavapipe: rasterizer/compute threads (0: run on the calling thread)" },
    EnvVar {
        name: "LP_NATIVE_VECTOR_WIDTH",
        help: "lavapipe: SIMD width in bits (128, 256 or 512: 4, 8 or 16 lanes); trilab then keeps lavapipe's shader \
               cache per width (below)",
    },
    EnvVar {
        name: "GALLIUM_OVERRIDE_CPU_CAPS",
        help: "lavapipe: compile for a smaller CPU (Mesa's values nosse, sse, sse2, sse3, ssse3, sse4.1, avx; each \
               removes one feature and all that need it: avx removes AVX-512, sse4.1 AVX and AVX2); `trilab devices` \
               and every report's provenance name the features it compiles for; trilab then keeps lavapipe's shader \
               cache per setting (below)",
    },
    EnvVar {
        name: "MESA_SHADER_CACHE_DIR",
        help: "Mesa's on-disk shader cache; while LP_NATIVE_VECTOR_WIDTH or GALLIUM_OVERRIDE_CPU_CAPS is set, trilab \
               uses the folder mesa-shader-cache[-lp<bits>][-<caps>] inside it (unset: inside <XDG_CACHE_HOME or \
               ~/.cache>/trilab), as lavapipe 25.0.7 reuses image functions cached at another width \
               (docs/driver-defects.md)",
    },
    EnvVar {
        name: "VK_DRIVER_FILES",
        help: "the Vulkan loader's ICD files; where it names one file with a `version` file beside it (scripts/stock-mesa.sh, scripts/swiftshader.sh), reports name that package (`driver_package`)",
    },
];

/// The list as help text: one `NAME  what` line each.
pub fn help_text() -> String {
    let width = ENV_VARS.iter().map(|v| v.name.len()).max().unwrap_or(0);
    ENV_VARS.iter().map(|v| format!("  {:width$}  {}\n", v.name, v.help)).collect()
}

/// The list as Markdown (docs/commands.md's "Environment variables").
pub fn markdown() -> String {
    ENV_VARS.iter().map(|v| format!("- `{}`: {}.\n", v.name, v.help)).collect()
}

/// Where lavapipe's shader cache goes for SIMD width `bits` and CPU features `caps` (each as set
/// in `LP_NATIVE_VECTOR_WIDTH` and `GALLIUM_OVERRIDE_CPU_CAPS`, `None` where unset): one folder
/// per setting inside `base` (the caller's MESA_SHADER_CACHE_DIR, else trilab's folder in
/// XDG_CACHE_HOME or ~/.cache).
///
/// lavapipe 25.0.7 stores its precompiled texture and image functions in Mesa's on-disk cache
/// under a key that leaves out the SIMD width, so a process at 16 lanes finds the 8-lane code a
/// default run stored and calls it with 16-lane vectors: lanes 8-15 of every imageLoad read
/// wrong values, or the process crashes, depending on the CPU (docs/driver-defects.md). The CPU
/// override changes the width too (`sse4.1` gives 128 bits), so it keys the folder as well.
pub fn lavapipe_cache_dir(base: &std::path::Path, bits: Option<&str>, caps: Option<&str>) -> std::path::PathBuf {
    // A value only names a folder: nothing in it can leave `base`.
    let clean = |v: &str, keep: &dyn Fn(char) -> bool| v.chars().filter(|&c| keep(c)).collect::<String>();
    let mut name = "mesa-shader-cache".to_owned();
    if let Some(bits) = bits {
        name += &format!("-lp{}", clean(bits, &|c| c.is_ascii_alphanumeric()));
    }
    if let Some(caps) = caps {
        name += &format!("-{}", clean(caps, &|c| c.is_ascii_alphanumeric() || c == '.').replace("..", ""));
    }
    base.join(name)
}

/// Keeps lavapipe's shader cache per code-generation setting: where `LP_NATIVE_VECTOR_WIDTH` or
/// `GALLIUM_OVERRIDE_CPU_CAPS` is set (and `MESA_SHADER_CACHE_DISABLE` is not), points
/// `MESA_SHADER_CACHE_DIR` at [`lavapipe_cache_dir`] inside the folder it named (unset: trilab's
/// folder in the user's cache). Inside it, not the folder itself: a caller at one width
/// (scripts/test-width.sh) that runs trilab at another (`coop_at_16_lanes`) would otherwise hand
/// the child the first width's cache. Returns the folder it chose, if any.
///
/// Call it first in `main`, before any thread starts and before the Vulkan loader reads the
/// environment: it changes the process's environment.
pub fn keep_lavapipe_cache_per_target() -> Option<std::path::PathBuf> {
    let bits = std::env::var("LP_NATIVE_VECTOR_WIDTH").ok().filter(|v| !v.is_empty());
    let caps = std::env::var("GALLIUM_OVERRIDE_CPU_CAPS").ok().filter(|v| !v.is_empty());
    if (bits.is_none() && caps.is_none()) || std::env::var_os("MESA_SHADER_CACHE_DISABLE").is_some() {
        return None;
    }
    let base = match std::env::var_os("MESA_SHADER_CACHE_DIR").filter(|d| !d.is_empty()) {
        Some(d) => std::path::PathBuf::from(d),
        None => std::env::var_os("XDG_CACHE_HOME")
            .filter(|h| !h.is_empty())
            .map(std::path::PathBuf::from)
            .or_else(|| std::env::var_os("HOME").map(|h| std::path::PathBuf::from(h).join(".cache")))?
            .join("trilab"),
    };
    let dir = lavapipe_cache_dir(&base, bits.as_deref(), caps.as_deref());
    std::env::set_var("MESA_SHADER_CACHE_DIR", &dir);
    Some(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_width_and_cpu_setting_has_its_own_cache_folder() {
        let base = std::path::Path::new("/c/trilab");
        let folders = [
            lavapipe_cache_dir(base, Some("256"), None),
            lavapipe_cache_dir(base, Some("512"), None),
            lavapipe_cache_dir(base, Some("512"), Some("avx")),
            lavapipe_cache_dir(base, None, Some("avx")),
            lavapipe_cache_dir(base, None, Some("sse4.1")),
        ];
        for (i, a) in folders.iter().enumerate() {
            assert!(a.starts_with("/c/trilab") && a.parent() == Some(base), "{a:?}");
            assert!(folders[i + 1..].iter().all(|b| b != a), "{a:?} twice in {folders:?}");
        }
        assert_eq!(folders[2], std::path::PathBuf::from("/c/trilab/mesa-shader-cache-lp512-avx"));
        // A hostile value cannot leave the folder.
        assert_eq!(
            lavapipe_cache_dir(base, Some("../../etc"), Some("../..")),
            std::path::PathBuf::from("/c/trilab/mesa-shader-cache-lpetc-")
        );
    }
}
