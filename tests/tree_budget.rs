//! The tracked tree travels to a lent GPU: the device tool copies the working tree (tracked
//! files, `../shared/`, and what a run carries: the stripped binary, the Vulkan loaders, the
//! tinybvh peer) and refuses more than 64 MiB in all. `scripts/device-run.sh pack` checks the
//! whole at 60 MiB; this test holds the part that grows with every commit, the tracked tree.
//!
//! Counted: the size in bytes of every file `git ls-files` lists, as it is in the working tree
//! (what the device tool copies), summed. Budget: [`TREE_BUDGET_MIB`] MiB (20.3 MiB at issue 23:
//! scenes 8.9, results 6.4, spirv 1.2, the rest source and docs; 24.08 MiB when the manual moved
//! to docs/ with the generated command reference, docs/commands.md, 0.1 MiB; 25.0 MiB before issue
//! 50, which raised it to 26 for results/radv/ and its code and tests: the pack then measured
//! about 54 MiB, the stripped binary 20.2 MiB and ../shared 7.3 MiB of it; 26.06 MiB when issue
//! 51 added tinyobjloader's test models, tests/data/tinyobjloader/, 0.11 MiB, a second public
//! OBJ/MTL corpus, with the OBJ/MTL statement table and its tests, and raised it to 27).

use std::path::Path;
use std::process::Command;

/// The tracked tree's budget in MiB (2^20 bytes).
const TREE_BUDGET_MIB: u64 = 27;

/// Results files of these kinds above this size are stored gzip-compressed
/// (`scripts/compress-results.sh`, results/README.md "How results are stored").
const BULKY_BYTES: u64 = 256 * 1024;
const BULKY_KINDS: [&str; 3] = [".json", ".csv", ".jsonl"];

fn tracked_files() -> Vec<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new("git")
        .args(["ls-files", "-z"])
        .current_dir(root)
        .output()
        .expect("git runs (the tree budget is counted over `git ls-files`)");
    assert!(out.status.success(), "git ls-files: {}", String::from_utf8_lossy(&out.stderr));
    let files: Vec<String> =
        String::from_utf8(out.stdout).unwrap().split('\0').filter(|f| !f.is_empty()).map(String::from).collect();
    assert!(files.len() > 100, "git ls-files lists the tree ({} files)", files.len());
    files
}

fn size(file: &str) -> u64 {
    // A tracked file deleted in the working tree does not travel.
    std::fs::metadata(Path::new(env!("CARGO_MANIFEST_DIR")).join(file)).map(|m| m.len()).unwrap_or(0)
}

#[test]
fn the_tracked_tree_fits_its_budget() {
    let files = tracked_files();
    let total: u64 = files.iter().map(|f| size(f)).sum();
    let mut largest: Vec<(u64, &String)> = files.iter().map(|f| (size(f), f)).collect();
    largest.sort_by(|a, b| b.cmp(a));
    let top: Vec<String> =
        largest.iter().take(8).map(|(n, f)| format!("{f} {:.2} MiB", *n as f64 / 1048576.0)).collect();
    assert!(
        total <= TREE_BUDGET_MIB << 20,
        "the tracked tree is {:.2} MiB, over its budget of {TREE_BUDGET_MIB} MiB (it travels to lent GPUs, \
         64 MiB in all with the binary and loaders): compress results (scripts/compress-results.sh), keep \
         disassembly out of spirv/ (trilab spirv --out DIR writes it on demand). Largest: {}",
        total as f64 / 1048576.0,
        top.join(", ")
    );
}

#[test]
fn bulky_results_are_stored_compressed() {
    let bulky: Vec<String> = tracked_files()
        .into_iter()
        .filter(|f| f.starts_with("results/") && BULKY_KINDS.iter().any(|k| f.ends_with(k)))
        .filter(|f| size(f) > BULKY_BYTES)
        .collect();
    assert!(
        bulky.is_empty(),
        "results files above {} KiB are stored gzip-compressed (scripts/compress-results.sh DIR): {}",
        BULKY_BYTES / 1024,
        bulky.join(", ")
    );
}
