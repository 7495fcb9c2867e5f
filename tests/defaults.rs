//! Each axis's default lives in one place (`src/defaults.rs`, and the `(default)` marker of a
//! named enum, read as `T::DEFAULT`): the command line's defaults are the library's, and no
//! other place spells them (the source tree is read: code outside test modules, comments left
//! out).

mod common;

use std::path::{Path, PathBuf};

use common::source::{rust_files, without_comment};
use serde_json::Value;
use trilab::bvh::LeafPolicy;
use trilab::defaults;
use trilab::encoding::{Layout, Method, SceneAccess, Traversal};
use trilab::named::Named;

/// Options whose default is not the library's, on purpose: (commands, options, why).
const OWN_DEFAULTS: &[(&[&str], &[&str], &str)] = &[
    (
        &["trilab ab", "trilab gate", "trilab __worker"],
        &["width", "height", "diffuse-per-hit", "random-rays"],
        "ab's sets are small: both sides trace them many times (gate's timings are an ab's)",
    ),
    (
        &["trilab profile"],
        &["diffuse-per-hit", "random-rays"],
        "profile's sets are smaller (mut_arg in src/cli/profile.rs)",
    ),
    (&["trilab bench-render", "trilab render"], &["width", "height"], "a render's image, not a ray set"),
    (&["trilab bench-render"], &["repeat"], "renders are long: three timed runs"),
    (&["trilab render"], &["seed"], "the path tracer's sample sequence, not a ray set's"),
    (&["trilab roofline"], &["seed"], "the roofline's pointer chase, not a ray set's"),
];

/// Whether `command --long` has a default of its own ([`OWN_DEFAULTS`]).
fn own_default(command: &str, long: &str) -> bool {
    OWN_DEFAULTS.iter().any(|(cs, ls, _)| cs.contains(&command) && ls.contains(&long))
}

/// The library's default of each option that has one (by its long name).
fn library_default(long: &str) -> Option<String> {
    Some(match long {
        "method" => Method::DEFAULT.name().to_owned(),
        "layout" => Layout::DEFAULT.name().to_owned(),
        "traversal" => Traversal::DEFAULT.name().to_owned(),
        "scene-access" => SceneAccess::DEFAULT.name().to_owned(),
        "leaf-policy" => LeafPolicy::DEFAULT.name().to_owned(),
        "leaf-size" => defaults::LEAF_SIZE.to_string(),
        "width" => defaults::WIDTH.to_string(),
        "height" => defaults::HEIGHT.to_string(),
        "diffuse-per-hit" => defaults::DIFFUSE_PER_HIT.to_string(),
        "random-rays" | "ray-count" => defaults::RANDOM_RAYS.to_string(),
        "seed" => defaults::SEED.to_string(),
        "repeat" => defaults::REPEAT.to_string(),
        "batch-rays" => defaults::BATCH_RAYS.to_string(),
        _ => return None,
    })
}

#[test]
fn the_command_lines_defaults_are_the_librarys() {
    let o = common::cli::trilab(&["__dump-cli"], 60);
    assert!(o.status.success(), "{}", common::cli::stderr(&o));
    let tree: Value = serde_json::from_slice(&o.stdout).expect("__dump-cli prints JSON");
    let (mut checked, mut own, mut wrong) = (0, vec![], vec![]);
    for cmd in tree.as_array().unwrap() {
        let path = cmd["command"].as_str().unwrap();
        for arg in cmd["args"].as_array().unwrap() {
            let Some(long) = arg["long"].as_str() else { continue };
            let got: Vec<&str> = arg["defaults"].as_array().unwrap().iter().map(|v| v.as_str().unwrap()).collect();
            let Some(want) = library_default(long) else { continue };
            if got.is_empty() {
                continue; // no default: the command says what it takes (a list's default, say)
            }
            if own_default(path, long) {
                own.push((path, long));
                continue;
            }
            if got != [want.as_str()] {
                wrong.push(format!("`{path} --{long}` defaults to {got:?}, the library to {want}"));
            }
            checked += 1;
        }
    }
    assert!(wrong.is_empty(), "defaults that are not the library's (src/defaults.rs):\n{}", wrong.join("\n"));
    assert!(checked >= 30, "only {checked} defaults checked: did __dump-cli stop printing them?");
    for (cs, ls, _) in OWN_DEFAULTS {
        for (c, l) in cs.iter().flat_map(|c| ls.iter().map(move |l| (*c, *l))) {
            assert!(own.contains(&(c, l)), "OWN_DEFAULTS lists `{c} --{l}`, which has no default of its own now");
        }
    }
    // The defaults of list options that are not clap's (bench --layouts, ...) are the library's
    // too: the CLI fills them with `T::DEFAULT`, which the source scan below holds.
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A file's code outside its test modules (from the first `#[cfg(test)]` on; none in a file
/// that is a test module of its own, `tests.rs` or `testing.rs`, which its parent declares under
/// `#[cfg(test)]`), without comments (the rest of a line after `//` outside a string literal),
/// as (line number, line).
fn code_lines(path: &Path) -> Vec<(usize, String)> {
    if path.file_name().is_some_and(|n| n == "tests.rs" || n == "testing.rs") {
        return vec![];
    }
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = vec![];
    for (n, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        out.push((n + 1, without_comment(line).to_owned()));
    }
    out
}

/// A spelling of a default that belongs in one place, and the files that may hold it (path
/// suffixes, with why).
struct Spelling {
    text: &'static str,
    allowed: &'static [&'static str],
}

const SPELLINGS: &[Spelling] = &[
    // The default layout: src/defaults.rs names it; bvh2.rs is the layout's own name.
    Spelling { text: "\"bvh2\"", allowed: &["src/defaults.rs", "src/encoding/layout/bvh2.rs"] },
    Spelling { text: "Layout::Bvh2", allowed: &[] },
    // The default method: src/defaults.rs names it; mt.rs is the method's own name.
    Spelling { text: "\"mt\"", allowed: &["src/defaults.rs", "src/encoding/mt.rs"] },
    // The default traversal: its `(default)` marker in variants.rs. ab's workers of protocol 1
    // know no traversal axis and run while-if, whatever the default is.
    Spelling { text: "\"while-if\"", allowed: &["src/encoding/variants.rs"] },
    Spelling { text: "Traversal::WhileIf", allowed: &["ab/worker.rs", "services/worker/protocol.rs"] },
    // The default leaf size and batch: src/defaults.rs.
    Spelling { text: "BuildOptions::new(4)", allowed: &[] },
    Spelling { text: "batch_rays: 1 << 20", allowed: &[] },
];

#[test]
fn no_default_is_spelled_outside_its_home() {
    let mut files = vec![root().join("build.rs")];
    rust_files(&root().join("src"), &mut files);
    let mut found = vec![];
    for f in &files {
        let rel = f.strip_prefix(root()).unwrap().to_string_lossy().replace('\\', "/");
        for (n, line) in code_lines(f) {
            for s in SPELLINGS {
                if line.contains(s.text) && !s.allowed.iter().any(|a| rel.ends_with(a)) {
                    found.push(format!("{rel}:{n}: {}", line.trim()));
                }
            }
        }
    }
    assert!(found.is_empty(), "a default spelled outside src/defaults.rs or its T::DEFAULT:\n{}", found.join("\n"));
    let build = std::fs::read_to_string(root().join("build.rs")).unwrap();
    assert!(
        build.contains("#[path = \"src/defaults.rs\"]") && build.contains("defaults::LAYOUT"),
        "build.rs reads src/defaults.rs"
    );
}

/// In the command line, an option's default is a `T::DEFAULT` or a `defaults::` value, never the
/// value itself: a typed axis value (`Layout::Bvh4`), an axis's name in a string, or a number
/// for an option the library has a default of (`OWN_DEFAULTS` aside).
#[test]
fn the_command_line_spells_no_default() {
    let typed = ["Layout::", "Traversal::", "SceneAccess::", "LeafPolicy::", "NodeOrder::", "RayOrder::", "Method::"];
    let names = ["mt", "bvh2", "while-if", "auto", "fill", "built", "given"];
    let mut files = vec![];
    rust_files(&root().join("src/cli"), &mut files);
    let mut found = vec![];
    for f in &files {
        let file = f.file_name().unwrap().to_string_lossy().into_owned();
        let lines = code_lines(f);
        for (i, (n, line)) in lines.iter().enumerate() {
            let Some(at) = line.find("default_value") else { continue };
            let value: String = line[at..].split_once('=').map_or("", |(_, v)| v).trim().to_owned();
            let typed_value = typed.iter().any(|t| value.starts_with(t) || value.starts_with(&format!("[{t}")));
            let named_value = names.iter().any(|n| value.starts_with(&format!("\"{n}\"")));
            if (typed_value && !value.contains("::DEFAULT")) || named_value {
                found.push(format!("{file}:{n}: {}", line.trim()));
            }
            // A number for an option with a library default: the field the attribute is on.
            if value.starts_with(|c: char| c.is_ascii_digit()) {
                let field = lines[i + 1..]
                    .iter()
                    .map(|(_, l)| l.trim())
                    .find(|l| !l.starts_with("#[") && !l.starts_with("///") && !l.is_empty() && l.contains(':'))
                    .and_then(|l| l.trim_start_matches("pub ").split(':').next())
                    .unwrap_or("")
                    .replace('_', "-");
                let own = own_default(&format!("trilab {}", file.trim_end_matches(".rs").replace('_', "-")), &field);
                if library_default(&field).is_some() && !own {
                    found.push(format!("{file}:{n}: `{field}` spells its default: {}", line.trim()));
                }
            }
        }
    }
    assert!(found.is_empty(), "command-line defaults spelled in place of src/defaults.rs:\n{}", found.join("\n"));
}
