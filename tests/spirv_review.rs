//! spirv/ is the review surface: its disassemblies and instruction counts must be exactly what
//! the current GLSL compiles to. Also cross-checks the word-walking counter against spirv-dis
//! and validates every module with spirv-val.

use std::path::Path;
use std::process::Command;

use trilab::kernels::KERNELS;

const REFRESH: &str = "cargo run --release -- spirv --out spirv --studied";

#[test]
fn committed_spirv_matches_the_kernels() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("spirv");
    // The counts are the compiler's: name both compilers first when they differ, since then every
    // file differs and refreshing would only trade one compiler's review for another's.
    let committed = std::fs::read_to_string(dir.join(trilab::spirv::COMPILER_FILE)).unwrap_or_default();
    assert_eq!(
        committed.trim(),
        trilab::kernels::SPIRV_COMPILER,
        "spirv/ was made by another GLSL compiler than this build's: its counts are that compiler's. The \
         committed review is Debian 12's static shaderc (scripts/install-deps.sh installs libshaderc-dev \
         glslang-dev spirv-tools, and build.rs links them); `{REFRESH}` only where the compiler is meant to change"
    );
    let expected = trilab::spirv::review_files(&trilab::encoding::variants::studied());
    let mut stale = vec![];
    for (name, text) in &expected {
        match std::fs::read_to_string(dir.join(name)) {
            Ok(committed) if &committed == text => {}
            Ok(_) => stale.push(format!("{name} differs")),
            Err(_) => stale.push(format!("{name} is missing")),
        }
    }
    for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".spvasm") && !expected.iter().any(|(n, _)| *n == name) {
            stale.push(format!("{name} is not a studied kernel's (trilab::encoding::variants::studied)"));
        }
    }
    assert!(stale.is_empty(), "spirv/ is out of date ({}); refresh it with `{REFRESH}` and commit", stale.join(", "));
}

fn tool(name: &str) -> String {
    assert!(
        Command::new(name).arg("--version").output().is_ok(),
        "{name} not found: install spirv-tools (scripts/install-deps.sh)"
    );
    name.to_owned()
}

#[test]
fn counts_agree_with_spirv_dis() {
    let dis = tool("spirv-dis");
    let dir = tempfile::tempdir().unwrap();
    for k in KERNELS.iter().filter(|k| k.name == "raycast.mt.closest" || k.name == "raycast.quad-unit.any") {
        let path = dir.path().join(format!("{}.spv", k.name));
        std::fs::write(&path, k.spirv()).unwrap();
        let out = Command::new(&dis).arg("--raw-id").arg(&path).output().unwrap();
        assert!(out.status.success(), "spirv-dis failed: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        let lines: Vec<&str> = text.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with(';')).collect();
        let c = trilab::spirv::count(&k.words()).unwrap();
        assert_eq!(lines.len() as u32, c.module, "{}: instructions in the module", k.name);
        let start = lines.iter().position(|l| l.contains("OpFunction ")).unwrap();
        let end = lines.iter().rposition(|l| l.contains("OpFunctionEnd")).unwrap();
        // Functions are contiguous at the end of a module.
        assert_eq!((end - start + 1) as u32, c.functions, "{}: instructions in function bodies", k.name);
        let loads =
            lines[start..=end].iter().filter(|l| l.contains("= OpLoad ") || l.contains("= OpAccessChain ")).count()
                as u32;
        assert!(loads <= c.memory, "{}: memory class holds every load and access chain", k.name);
    }
}

#[test]
fn every_module_passes_spirv_val() {
    let val = tool("spirv-val");
    let dir = tempfile::tempdir().unwrap();
    for k in KERNELS {
        let path = dir.path().join(format!("{}.spv", k.name));
        std::fs::write(&path, k.spirv()).unwrap();
        let out = Command::new(&val).args(["--target-env", "vulkan1.2"]).arg(&path).output().unwrap();
        assert!(out.status.success(), "{}: {}", k.name, String::from_utf8_lossy(&out.stderr));
    }
}
