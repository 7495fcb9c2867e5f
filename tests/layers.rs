//! The layering rule of ARCHITECTURE.md, checked on the source tree: the library's top-level
//! modules form an order (ground floor, scene, rays, bvh, the CPU reference, encoding, gpu,
//! conditioning, pipeline, path tracer, services, commands), and every module imports only modules before its
//! own. Inside a top-level module, no two modules that are not parent and child import each
//! other, directly or around a longer cycle. The library does not use clap (the command line,
//! `src/main.rs` and `src/cli/`, is the binary's). Comments are not imports.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::path::PathBuf;

use common::source::{rust_files, without_comment};

/// The library's top-level modules, lowest layer first: each may import only those before it.
/// ARCHITECTURE.md explains the layers; `src/lib.rs` declares the modules in this order.
const LAYERS: &[&str] = &[
    // Ground floor: errors, output, named values, the constants shared with GLSL, the kernel
    // registry and SPIR-V.
    "defaults",
    "env",
    "error",
    "io",
    "timeline",
    "children",
    "memory",
    "report",
    "host",
    "rows",
    "named",
    "shared",
    "kernels",
    "spirv",
    // The scene and its rays.
    "scene",
    "rays",
    "bvh",
    // The CPU's truth.
    "reference",
    "agreement",
    "traversal",
    // Intersectors and their layouts.
    "encoding",
    "gpu",
    "conditioning",
    "pipeline",
    // The path tracer.
    "render",
    // What the commands share, the experiment matrix they loop over, then the commands: each in
    // its own room.
    "services",
    "matrix",
    "commands",
];

fn src() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every `.rs` file under `src/`, sorted.
fn source_files() -> Vec<PathBuf> {
    let mut files = vec![];
    rust_files(&src(), &mut files);
    files.sort();
    files
}

/// The library's files (the binary's `main.rs` and `cli/` left out) with their module paths:
/// `src/gpu/raycast.rs` -> ["gpu", "raycast"], `src/gpu/mod.rs` -> ["gpu"].
fn library_modules() -> Vec<(PathBuf, Vec<String>)> {
    let root = src();
    source_files()
        .into_iter()
        .filter_map(|p| {
            let rel = p.strip_prefix(&root).unwrap().to_owned();
            let mut parts: Vec<String> = rel.iter().map(|c| c.to_string_lossy().into_owned()).collect();
            if parts[0] == "main.rs" || parts[0] == "cli" {
                return None;
            }
            let last = parts.pop().unwrap();
            match last.as_str() {
                "lib.rs" | "mod.rs" => {}
                f => parts.push(f.trim_end_matches(".rs").to_owned()),
            }
            Some((p, parts))
        })
        .collect()
}

/// The code of a file without comments (line comments, and the rest of a line after `//`
/// outside a string literal).
fn code(text: &str) -> String {
    text.lines().flat_map(|line| [without_comment(line), "\n"]).collect()
}

/// Module paths a file refers to: `crate::a::b::...` (also `crate::{a, b::c}`) and
/// `super::...` resolved against the file's own path `me`. Each is the path as written, up to
/// the first segment that is not a module name (starts with a capital or is followed by `(`);
/// the caller keeps the longest prefix that is a module.
fn references(code: &str, me: &[String]) -> Vec<Vec<String>> {
    let mut refs = vec![];
    let text = code;
    let ident = |s: &str| -> Vec<String> {
        s.split("::")
            .map(|p| p.trim().to_owned())
            .take_while(|p| {
                !p.is_empty() && p.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
            })
            .collect()
    };
    let mut i = 0;
    loop {
        // The next `crate::` or `super::`, whichever comes first.
        let next = [text[i..].find("crate::"), text[i..].find("super::")].into_iter().flatten().min();
        let Some(off) = next else { break };
        let at = i + off;
        // Only whole path starts: not `foo_crate::` or `a::super::`.
        let before = text[..at].chars().last().unwrap_or(' ');
        let is_crate = text[at..].starts_with("crate::");
        i = at + "crate::".len();
        if before.is_alphanumeric() || before == '_' || (before == ':' && is_crate) {
            continue;
        }
        let mut base: Vec<String> = if is_crate {
            vec![]
        } else {
            // super:: relative to this module; a file `a/b.rs` is module a::b, whose parent is a.
            let mut b = me.to_vec();
            b.pop();
            let mut rest = &text[i..];
            while let Some(r) = rest.strip_prefix("super::") {
                b.pop();
                rest = r;
                i += 7;
            }
            b
        };
        let rest = &text[i..];
        if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for item in group[..end].split(',') {
                let mut p = base.clone();
                p.extend(ident(item.trim()));
                refs.push(p);
            }
        } else {
            let end = rest.find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':')).unwrap_or(rest.len());
            base.extend(ident(&rest[..end]));
            refs.push(base);
        }
    }
    refs
}

/// The longest prefix of `path` that is one of `modules`.
fn module_of(path: &[String], modules: &BTreeSet<Vec<String>>) -> Option<Vec<String>> {
    (1..=path.len()).rev().map(|n| path[..n].to_vec()).find(|p| modules.contains(p))
}

#[test]
fn every_module_imports_only_lower_layers() {
    let modules = library_modules();
    let rank: BTreeMap<&str, usize> = LAYERS.iter().enumerate().map(|(i, m)| (*m, i)).collect();
    let mut violations = vec![];
    let mut checked = 0;
    for (file, me) in &modules {
        let Some(top) = me.first() else { continue };
        let Some(&my_rank) = rank.get(top.as_str()) else {
            violations.push(format!("{}: top-level module `{top}` is not in LAYERS", file.display()));
            continue;
        };
        let text = code(&std::fs::read_to_string(file).unwrap());
        for r in references(&text, me) {
            let Some(other) = r.first() else { continue };
            checked += 1;
            if other == top {
                continue;
            }
            match rank.get(other.as_str()) {
                Some(&rank) if rank < my_rank => {}
                Some(_) => violations.push(format!(
                    "{}: `{}` imports `crate::{}` from a higher layer",
                    file.display(),
                    me.join("::"),
                    r.join("::")
                )),
                None => violations.push(format!("{}: imports unknown module `{other}`", file.display())),
            }
        }
    }
    assert!(checked > 500, "only {checked} references found: the scan is broken");
    assert!(violations.is_empty(), "imports that run upwards:\n{}", violations.join("\n"));
}

#[test]
fn modules_of_one_layer_do_not_import_each_other_in_a_cycle() {
    let modules = library_modules();
    let set: BTreeSet<Vec<String>> = modules.iter().map(|(_, m)| m.clone()).collect();
    let related = |a: &[String], b: &[String]| a.starts_with(b) || b.starts_with(a);
    let mut edges: BTreeMap<Vec<String>, BTreeSet<Vec<String>>> = BTreeMap::new();
    for (file, me) in &modules {
        let text = code(&std::fs::read_to_string(file).unwrap());
        for r in references(&text, me) {
            if let Some(to) = module_of(&r, &set) {
                // Parent and child always know each other (a parent declares its children).
                if !related(me, &to) {
                    edges.entry(me.clone()).or_default().insert(to);
                }
            }
        }
    }
    assert!(edges.len() > 40, "only {} modules import others: the scan is broken", edges.len());
    // Depth-first search for a back edge.
    fn visit(
        m: &Vec<String>,
        edges: &BTreeMap<Vec<String>, BTreeSet<Vec<String>>>,
        state: &mut BTreeMap<Vec<String>, u8>,
        stack: &mut Vec<Vec<String>>,
        cycles: &mut Vec<String>,
    ) {
        state.insert(m.clone(), 1);
        stack.push(m.clone());
        for n in edges.get(m).into_iter().flatten() {
            match state.get(n).copied().unwrap_or(0) {
                0 => visit(n, edges, state, stack, cycles),
                1 => {
                    let from = stack.iter().position(|s| s == n).unwrap();
                    let cycle: Vec<String> = stack[from..].iter().chain([n]).map(|p| p.join("::")).collect();
                    cycles.push(cycle.join(" -> "));
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(m.clone(), 2);
    }
    let mut state = BTreeMap::new();
    let mut cycles = vec![];
    for m in edges.keys() {
        if !state.contains_key(m) {
            visit(m, &edges, &mut state, &mut vec![], &mut cycles);
        }
    }
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}

#[test]
fn the_library_does_not_use_clap() {
    let mut users = vec![];
    for (file, _) in library_modules() {
        let text = code(&std::fs::read_to_string(&file).unwrap());
        if text.contains("clap::") || text.contains("clap ") || text.contains("clap;") {
            users.push(file.display().to_string());
        }
    }
    assert!(users.is_empty(), "clap belongs to the command line (src/cli): {users:?}");
}

#[test]
fn lib_rs_declares_the_modules_in_layer_order() {
    let lib = std::fs::read_to_string(src().join("lib.rs")).unwrap();
    let declared: Vec<&str> =
        lib.lines().filter_map(|l| l.strip_prefix("pub mod ").and_then(|m| m.strip_suffix(';'))).collect();
    assert_eq!(declared, LAYERS, "src/lib.rs lists the modules in LAYERS' order");
}

/// The scan itself: upward, grouped and relative imports are found, comments are not.
#[test]
fn the_scan_finds_imports_and_ignores_comments() {
    let me = vec!["gpu".to_owned(), "raycast".to_owned()];
    let text = code(
        "use crate::{pipeline::HostScene, error::Result};\n\
         // use crate::commands::bench;\n\
         let x = crate::render::render(a); // crate::study\n\
         use super::super::analyze::Frontier;\n\
         use super::context::Context;\n\
         let s = \"crate::not_a_path // really\";\n",
    );
    let refs: Vec<String> = references(&text, &me).iter().map(|r| r.join("::")).collect();
    assert!(refs.contains(&"pipeline".to_owned()), "{refs:?}");
    assert!(refs.contains(&"error".to_owned()), "{refs:?}");
    assert!(refs.contains(&"render::render".to_owned()), "{refs:?}");
    assert!(refs.contains(&"analyze".to_owned()), "{refs:?}");
    assert!(refs.contains(&"gpu::context".to_owned()), "{refs:?}");
    assert!(!refs.iter().any(|r| r.starts_with("commands") || r.starts_with("study")), "{refs:?}");
}

/// Every `.rs` file under `src/` (the command line's too), as `dir/file.rs` relative to `src/`,
/// with its code (comments left out).
fn every_file() -> Vec<(String, String)> {
    let root = src();
    source_files()
        .into_iter()
        .map(|p| {
            let rel = p.strip_prefix(&root).unwrap().to_string_lossy().replace('\\', "/");
            (rel, code(&std::fs::read_to_string(&p).unwrap()))
        })
        .collect()
}

/// Running trilab again, in another environment, is one service's (`services::worker`): it alone
/// finds this executable to run and starts it, and what comes back is typed. Any other module
/// that starts a process runs another program, named here with it; and JSON is read into an
/// untyped `serde_json::Value` only where it is not our own output read back (or is written).
#[test]
fn only_the_worker_service_runs_trilab_again() {
    let files = every_file();
    let mut wrong = vec![];
    // Who may find the running executable: the worker service (to run it), and the scene
    // finder (scenes beside it; it runs nothing).
    let finds_exe = ["services/worker/mod.rs", "scene/find.rs"];
    // Who may start a process, and what it starts.
    let starts = [
        ("services/worker/mod.rs", "trilab itself, in another environment"),
        ("children.rs", "the ground floor every child is started through"),
        ("services/peers.rs", "the peer programs (Embree, tinybvh)"),
        ("commands/build_bench.rs", "the build benchmark's peer programs, and dpkg-query"),
        ("services/provenance.rs", "git, for the commit"),
        ("commands/repro/gfxrecon.rs", "GFXReconstruct's gfxrecon-replay, under trilab's read-back layer"),
    ];
    // Who may hold JSON untyped, and why it is not our output read back untyped.
    let untyped = [
        ("report.rs", "writes reports as pretty JSON through it"),
        ("rows.rs", "checks a rows file's schema before reading the line typed"),
        ("rays/sidecar.rs", "a ray file's free-form settings"),
        ("commands/make_rays.rs", "writes those settings"),
        ("commands/merge/tests.rs", "its tests read merge.json"),
        ("commands/ab/options.rs", "the Vulkan loader's ICD file"),
        ("commands/ab/report.rs", "another build's provenance, carried as it wrote it"),
        ("services/worker/protocol.rs", "another build's provenance in `ready`, read through ProvenanceFields"),
        ("cli/dump.rs", "prints clap's command tree as JSON"),
        ("commands/repro/folder.rs", "checks a repro manifest's format before reading it typed"),
    ];
    let mut seen = BTreeSet::new();
    for (file, text) in &files {
        if text.contains("current_exe") {
            seen.insert("current_exe");
            if !finds_exe.contains(&file.as_str()) {
                wrong.push(format!("{file}: finds the running trilab (std::env::current_exe): use services::worker"));
            }
        }
        let spawns = ["process::Command", "Command::new(", "children::spawn", "children::output", "fn spawn("]
            .iter()
            .any(|p| text.contains(p));
        if spawns {
            seen.insert("spawn");
            if !starts.iter().any(|(f, _)| f == file) {
                wrong.push(format!(
                    "{file}: starts a process: trilab again goes through services::worker; another program is \
                     listed in this test with what it is"
                ));
            }
        }
        if text.contains("serde_json::Value") || (text.contains("serde_json::{") && text.contains("Value")) {
            seen.insert("value");
            if !untyped.iter().any(|(f, _)| f == file) {
                wrong.push(format!(
                    "{file}: holds JSON as serde_json::Value: read our own output as the typed messages of \
                     services::worker::protocol"
                ));
            }
        }
    }
    assert_eq!(seen.len(), 3, "the scan found {seen:?}: it is broken");
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    // Each listed module still does what it is listed for (a stale entry is an open door).
    for (file, why) in starts.iter().chain(&untyped) {
        assert!(files.iter().any(|(f, _)| f == file), "{file} ({why}) is listed but does not exist");
    }
}
