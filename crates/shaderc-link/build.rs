//! Links Debian's static shaderc, glslang and SPIRV-Tools where they are installed.
//!
//! `shaderc-sys` (feature `prefer-static-linking`, with `SHADERC_LIB_DIR` set by trilab's
//! `.cargo/config.toml`) links `libshaderc_combined.a` from that folder when it is there, and
//! builds shaderc from source when it is not. Debian's `libshaderc_combined.a` is not combined:
//! glslang's and SPIRV-Tools' objects live in their own archives (packages `glslang-dev` and
//! `spirv-tools`). This script names those archives to the linker when `libshaderc_combined.a`
//! and `libglslang.a` sit side by side, and nothing otherwise.
//!
//! They are linked unbundled (`static:-bundle`): rustc then passes them after every rlib, so after
//! `shaderc-sys`'s own bundled `shaderc_combined`, whose undefined glslang symbols they resolve.
//! A bundled archive would sit at this crate's place in the link line, which may come before
//! `shaderc-sys`, and a single-pass linker would not look back at it.
use std::path::{Path, PathBuf};
use std::process::Command;

/// glslang's archives in the order `pkg-config --static --libs glslang` gives them, then the
/// SPIRV-Tools optimiser and core that glslang's SPIR-V back end calls.
const ARCHIVES: &[&str] = &[
    "glslang",
    "glslang-default-resource-limits",
    "SPIRV",
    "MachineIndependent",
    "OSDependent",
    "OGLCompiler",
    "GenericCodeGen",
    "SPIRV-Tools-opt",
    "SPIRV-Tools",
];

/// The Debian packages that hold the archives, for the versions `SYSTEM_LIBRARIES` names.
const PACKAGES: &[(&str, &str)] =
    &[("shaderc", "libshaderc-dev"), ("glslang", "glslang-dev"), ("SPIRV-Tools", "spirv-tools")];

fn main() {
    println!("cargo:rerun-if-env-changed=SHADERC_LIB_DIR");
    println!("cargo:rerun-if-env-changed=VULKAN_SDK");
    let dir = lib_dir();
    let combined = dir.join("libshaderc_combined.a");
    println!("cargo:rerun-if-changed={}", combined.display());
    let split = combined.is_file() && dir.join("libglslang.a").is_file();
    if !split {
        if combined.is_file() {
            // A shaderc_combined that holds glslang and SPIRV-Tools itself (the Vulkan SDK's, or
            // one built by hand): shaderc-sys's link line is complete.
            println!("cargo:rustc-env=TRILAB_SHADERC_SYSTEM_LIBRARIES=shaderc_combined from {}", dir.display());
        } else {
            println!(
                "cargo:warning=shaderc: no libshaderc_combined.a in {}: shaderc-sys builds shaderc from source \
                 (10-25 minutes; on Debian 12, scripts/install-deps.sh installs libshaderc-dev glslang-dev spirv-tools)",
                dir.display()
            );
            println!("cargo:rustc-env=TRILAB_SHADERC_SYSTEM_LIBRARIES=");
        }
        return;
    }
    let missing: Vec<String> =
        ARCHIVES.iter().map(|a| format!("lib{a}.a")).filter(|f| !dir.join(f).is_file()).collect();
    if !missing.is_empty() {
        // shaderc-sys has already chosen this folder's libshaderc_combined.a, so there is no
        // falling back to the source build from here: say what to install.
        panic!(
            "shaderc: {} holds libshaderc_combined.a and libglslang.a but not {}: install Debian's \
             spirv-tools and glslang-dev (scripts/install-deps.sh does), or remove libshaderc-dev to build shaderc from source",
            dir.display(),
            missing.join(", ")
        );
    }
    println!("cargo:rustc-link-search=native={}", dir.display());
    for a in ARCHIVES {
        println!("cargo:rustc-link-lib=static:-bundle={a}");
    }
    println!("cargo:rustc-link-lib=dylib=stdc++");
    let packages = package_versions().unwrap_or_else(|| format!("static libraries in {}", dir.display()));
    println!("cargo:warning=shaderc: linking the system's static shaderc ({packages})");
    println!("cargo:rustc-env=TRILAB_SHADERC_SYSTEM_LIBRARIES={packages}");
}

/// The folder shaderc-sys searches: `SHADERC_LIB_DIR` (trilab's `.cargo/config.toml` sets it to
/// Debian's multiarch folder), else that folder for this target.
fn lib_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("SHADERC_LIB_DIR") {
        return PathBuf::from(d);
    }
    let arch = std::env::var("CARGO_CFG_TARGET_ARCH").unwrap_or_default();
    let arch = if arch == "x86" { "i386".to_string() } else { arch };
    Path::new("/usr/lib").join(format!("{arch}-linux-gnu"))
}

/// "shaderc 2023.2-1, glslang 12.0.0-2, SPIRV-Tools 2023.1-2" from dpkg, or None off Debian.
fn package_versions() -> Option<String> {
    let mut parts = Vec::new();
    for (name, package) in PACKAGES {
        let out = Command::new("dpkg-query").args(["-W", "-f=${Version}", package]).output().ok()?;
        let version = String::from_utf8(out.stdout).ok()?;
        if !out.status.success() || version.trim().is_empty() {
            return None;
        }
        parts.push(format!("{name} {}", version.trim()));
    }
    Some(parts.join(", "))
}
