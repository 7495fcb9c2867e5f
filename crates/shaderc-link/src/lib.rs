//! Which shaderc trilab's build script was linked against, decided by this crate's build script.
//!
//! trilab compiles its GLSL at build time with the `shaderc` crate (a build-dependency). On Debian
//! 12, `libshaderc-dev`, `glslang-dev` and `spirv-tools` ship that compiler as static libraries,
//! but Debian's `libshaderc_combined.a` holds only shaderc's own objects: glslang and SPIRV-Tools
//! are separate archives. `shaderc-sys` links `shaderc_combined` alone; this crate's build script
//! adds the rest, so the first build takes seconds instead of the 20 minutes a build of shaderc
//! from source takes. Where those libraries are absent, it adds nothing and `shaderc-sys` builds
//! from source (see `build.rs`).

/// What was linked from the system: the Debian packages' versions ("shaderc 2023.2-1, glslang
/// 12.0.0-2, SPIRV-Tools 2023.1-2"), or the folder a `libshaderc_combined.a` was taken from where
/// `dpkg-query` cannot say; empty when `shaderc-sys` built shaderc from its bundled source.
pub const SYSTEM_LIBRARIES: &str = env!("TRILAB_SHADERC_SYSTEM_LIBRARIES");

/// Whether `shaderc-sys` built shaderc, glslang and SPIRV-Tools from source.
pub const fn from_source() -> bool {
    SYSTEM_LIBRARIES.is_empty()
}
