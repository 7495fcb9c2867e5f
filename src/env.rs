//! The environment variables trilab reads, listed once: `trilab --help` prints this list and a
//! test holds README.md to it. Ground floor: it imports nothing.

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
        help: "bytes a command may plan to allocate (default: MemAvailable); larger sizes are refused",
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
    EnvVar { name: "LP_NUM_THREADS", help: "lavapipe: rasterizer/compute threads (0: run on the calling thread)" },
    EnvVar { name: "LP_NATIVE_VECTOR_WIDTH", help: "lavapipe: SIMD width in bits (128 or 256)" },
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

/// The list as README.md's Markdown (between its `env: begin`/`env: end` markers).
pub fn markdown() -> String {
    ENV_VARS.iter().map(|v| format!("- `{}`: {}.\n", v.name, v.help)).collect()
}
