//! Paths named in comments and docs exist (issue 52). Every comment of the Rust, GLSL and C++
//! sources (`//`, `///`, `//!`, `/* */`), every `#` comment of the scripts and TOML/YAML files,
//! and every Markdown file of the tree is read; a path it names must be in the tree.
//!
//! What counts as a path, and what part of it is checked:
//! - a token that starts a word with one of [`FOLDERS`] and a `/` (`src/gpu/mod.rs`,
//!   `` `glsl/bsdf/` ``); what follows a `/`, `.` or a letter is not a path of the tree
//!   (`/usr/src/x`, `../docs/x.md`, `mysrc/x`). Anything else (`target/...`, `fuzz/work/`, a
//!   command's `--out DIR`) names no file of the tree and is not read;
//! - trailing punctuation and quotes go (`src/io.rs.` `src/io.rs),` ``src/io.rs` ``), and so do a
//!   line suffix (`src/io.rs:12`, `src/io.rs:12-30`) and an anchor (`docs/gate.md#ci`);
//! - a glob or placeholder (`*`, `<name>`, `{a,b}`, `...`, `…`, `$VAR`) is checked up to the folder
//!   before it: `results/<device>/bench.md` needs `results/`, `glsl/intersect/*.glsl` needs
//!   `glsl/intersect/`;
//! - a trailing `/` names a folder, which must be one;
//! - a Markdown link's target (`[text](../../docs/gate.md#y)`, `[label]: gate.md`) is relative to the
//!   Markdown file's folder, whatever its first folder; web addresses and in-page anchors are not
//!   read;
//! - a file stored compressed as results are (`rows.jsonl` as `rows.jsonl.gz`, results/README.md)
//!   is there;
//! - a path the text itself says is gone (`src/harness/ (removed)`), or names in another project's
//!   tree ([`OTHER_TREES`]: Mesa's `src/util/u_cpu_detect.c`), is not checked, and neither are the
//!   few in [`GONE`], records that quote a path as it was.

mod common;

use std::ops::Range;
use std::path::{Component, Path, PathBuf};

use common::source::files;

/// The tree's own folders: a token that starts with one of these and a `/` names a file or folder
/// of the tree (`fuzz/` is not one: it holds what `scripts/fuzz.sh` writes beside its sources).
const FOLDERS: &[&str] =
    &["src", "glsl", "scripts", "docs", "tests", "benches", "results", "crates", "scenes", "spirv"];

/// Where a glob or a placeholder starts: the path is checked up to the folder before it.
const PLACEHOLDERS: &[&str] = &["*", "<", "{", "...", "…", "$", "%"];

/// What a path may be followed by in prose, taken off its end.
const TRAILING: &[char] = &['.', ',', ':', ';', ')', ']', '`', '\'', '"', '*', '!', '?'];

/// What the text may say right after a path that is gone on purpose.
const GONE_MARK: &str = "(removed";

/// Another project's tree: a path right after one of these words is that project's.
const OTHER_TREES: &[&str] = &["Mesa's", "tinyobjloader's"];

/// Paths quoted on purpose though they are gone: (the file that names them, the paths as checked
/// (a link's target as written), why). Each entry must still be used.
const GONE: &[(&str, &[&str], &str)] = &[
    (
        "results/lavapipe/refactor-40/README.md",
        &["src/harness"],
        "the record of issue 40's refactor says where the code moved from",
    ),
    (
        "results/lavapipe/mesa-22.3.6-study-suite3/summary.md",
        &[
            "study/study-instructions-vs-time.png",
            "study/study-mrays-per-set.png",
            "study/study-time-vs-leaf.png",
            "study/study.csv",
            "study/study.json",
        ],
        "the run's own summary, as written; the record keeps only its rows, study.md and devices",
    ),
    (
        "results/lavapipe/mesa-22.3.6-study-suite3/study/study.md",
        &["study-time-vs-leaf.png", "study-mrays-per-set.png", "study-instructions-vs-time.png"],
        "the run's own report, as written; its plots were not kept",
    ),
];

/// Folders of the tree that are not read: build outputs and vendored test data (a third party's
/// Markdown, which names its own tree).
const SKIPPED: &[&str] = &[
    "target",
    "tests/data/tinyobjloader",
    "fuzz/target",
    "fuzz/artifacts",
    "fuzz/corpus",
    "fuzz/coverage",
    "fuzz/work",
];

#[derive(Clone, Copy, Debug, PartialEq)]
enum Syntax {
    /// Rust, GLSL, C++: `//` and `/* */`.
    C,
    /// Shell, Python, TOML, YAML: `#`.
    Hash,
    /// Markdown: all of it.
    Markdown,
}

fn syntax(path: &Path) -> Option<Syntax> {
    let ext = path.extension()?.to_str()?;
    match ext {
        "rs" | "glsl" | "comp" | "rgen" | "rchit" | "rmiss" | "rahit" | "cpp" | "h" | "hpp" => Some(Syntax::C),
        "sh" | "py" | "toml" | "yml" | "yaml" => Some(Syntax::Hash),
        "md" => Some(Syntax::Markdown),
        _ => None,
    }
}

fn root() -> PathBuf {
    common::root()
}

/// `path` relative to the root, with `/` between folders.
fn relative(root: &Path, path: &Path) -> String {
    let rel = path.strip_prefix(root).unwrap();
    rel.iter().map(|c| c.to_string_lossy()).collect::<Vec<_>>().join("/")
}

/// Every file read, relative to the root, sorted, with its syntax.
fn sources(root: &Path) -> Vec<(String, Syntax)> {
    let keep = |p: &Path, is_dir: bool| {
        let rel = relative(root, p);
        let name = p.file_name().unwrap().to_string_lossy();
        if is_dir {
            !name.starts_with('.') && !SKIPPED.contains(&rel.as_str())
        } else {
            syntax(p).is_some()
        }
    };
    let mut found = vec![];
    files(root, &keep, &mut found);
    // Tracked files in folders whose names start with a dot.
    for extra in [".ci/run", ".cargo/config.toml"] {
        if root.join(extra).is_file() {
            found.push(root.join(extra));
        }
    }
    let mut out: Vec<(String, Syntax)> = found
        .iter()
        .map(|p| (relative(root, p), if p.ends_with(".ci/run") { Syntax::Hash } else { syntax(p).unwrap() }))
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The comments of a Rust, GLSL or C++ source, line by line, with 1-based line numbers: `//` to
/// the line's end and `/* */` (nested, as Rust has them), outside string and character literals.
fn c_comments(text: &str) -> Vec<(usize, String)> {
    #[derive(Clone, Copy)]
    enum State {
        Code,
        Line,
        Block(u32),
        Str,
        Raw(usize),
    }
    let chars: Vec<char> = text.chars().collect();
    let at = |i: usize| chars.get(i).copied();
    let (mut out, mut line, mut current) = (vec![], 1, String::new());
    let (mut state, mut i) = (State::Code, 0);
    while i < chars.len() {
        let (c, next) = (chars[i], at(i + 1));
        if c == '\n' {
            if !current.trim().is_empty() {
                out.push((line, std::mem::take(&mut current)));
            }
            current.clear();
            line += 1;
            if let State::Line = state {
                state = State::Code;
            }
            i += 1;
            continue;
        }
        match state {
            State::Code => match (c, next) {
                ('/', Some('/')) => {
                    state = State::Line;
                    i += 1;
                }
                ('/', Some('*')) => {
                    state = State::Block(1);
                    i += 1;
                }
                ('"', _) => state = State::Str,
                ('r', Some('"' | '#')) => {
                    let hashes = chars[i + 1..].iter().take_while(|&&h| h == '#').count();
                    if at(i + 1 + hashes) == Some('"') {
                        state = State::Raw(hashes);
                        i += 1 + hashes;
                    }
                }
                // A character literal ('x', '\n', '\''); a lifetime ('a) is code.
                ('\'', Some('\\')) => {
                    i += 2;
                    while at(i + 1).is_some_and(|e| e != '\'' && e != '\n') {
                        i += 1;
                    }
                    i += 1;
                }
                ('\'', Some(_)) if at(i + 2) == Some('\'') => i += 2,
                _ => {}
            },
            State::Line => current.push(c),
            State::Block(depth) => match (c, next) {
                ('*', Some('/')) => {
                    state = if depth == 1 { State::Code } else { State::Block(depth - 1) };
                    current.push(' ');
                    i += 1;
                }
                ('/', Some('*')) => {
                    state = State::Block(depth + 1);
                    i += 1;
                }
                _ => current.push(c),
            },
            State::Str => match (c, next) {
                ('\\', Some(n)) if n != '\n' => i += 1,
                ('"', _) => state = State::Code,
                _ => {}
            },
            State::Raw(hashes) => {
                if c == '"' && (1..=hashes).all(|k| at(i + k) == Some('#')) {
                    state = State::Code;
                    i += hashes;
                }
            }
        }
        i += 1;
    }
    if !current.trim().is_empty() {
        out.push((line, current));
    }
    out
}

/// The `#` comments of a shell or Python script or a TOML or YAML file, with 1-based line numbers:
/// a `#` that starts a word outside quotes, to the line's end.
fn hash_comments(text: &str) -> Vec<(usize, String)> {
    let mut out = vec![];
    for (n, line) in text.lines().enumerate() {
        let (mut quote, mut prev) = (None, ' ');
        for (i, c) in line.char_indices() {
            match quote {
                Some(q) if c == q && prev != '\\' => quote = None,
                Some(_) => {}
                None if c == '"' || c == '\'' => quote = Some(c),
                None if c == '#' && (i == 0 || prev.is_whitespace()) => {
                    out.push((n + 1, line[i + 1..].to_owned()));
                    break;
                }
                None => {}
            }
            prev = c;
        }
    }
    out
}

/// The targets of the Markdown links on a line, `[text](target "title")` and `[label]: target`,
/// with their byte ranges in the line; web addresses and in-page anchors left out.
fn links(line: &str) -> Vec<(Range<usize>, &str)> {
    // The target in `line[start..]`: up to the first space (a title may follow), or in `<>`.
    let target = |start: usize| -> Option<Range<usize>> {
        let raw = &line[start..];
        let lead = raw.len() - raw.trim_start().len();
        let raw = raw.trim_start();
        let (from, len) = match raw.strip_prefix('<') {
            Some(rest) => (start + lead + 1, rest.find('>').unwrap_or(rest.len())),
            None => (start + lead, raw.find(char::is_whitespace).unwrap_or(raw.len())),
        };
        let t = &line[from..from + len];
        let web = t.contains("://") || t.starts_with("mailto:");
        (!t.is_empty() && !t.starts_with('#') && !web).then_some(from..from + len)
    };
    let mut out = vec![];
    let mut from = 0;
    while let Some(found) = line[from..].find("](") {
        let start = from + found + 2;
        let end = line[start..].find(')').map_or(line.len(), |e| start + e);
        out.extend(target(start).map(|r| r.start..r.end.min(end).max(r.start)).filter(|r| !r.is_empty()));
        from = end;
    }
    let trimmed = line.trim_start();
    if trimmed.starts_with('[') {
        if let Some(colon) = trimmed.find("]: ") {
            out.extend(target(line.len() - trimmed.len() + colon + 3));
        }
    }
    out.into_iter().map(|r| (r.clone(), &line[r])).collect()
}

/// The tokens of `text` that name a path of the tree, with their byte offsets: each starts a word
/// with one of [`FOLDERS`] and a `/`, and runs to a space, a quote, a bracket or a separator.
fn named(text: &str) -> Vec<(usize, &str)> {
    let mut out = vec![];
    let mut prev: Option<char> = None;
    for (i, c) in text.char_indices() {
        let starts_word = prev.is_none_or(|p| !(p.is_alphanumeric() || "_-/.~$@:#\\".contains(p)));
        prev = Some(c);
        if !starts_word {
            continue;
        }
        let rest = &text[i..];
        if !FOLDERS.iter().any(|f| rest.starts_with(f) && rest[f.len()..].starts_with('/')) {
            continue;
        }
        let end = rest.find(|c: char| c.is_whitespace() || "`\"'()[]|,;>".contains(c)).unwrap_or(rest.len());
        out.push((i, &rest[..end]));
    }
    out
}

/// The part of a named path that must exist: punctuation, line suffixes and anchors taken off, and
/// cut at a glob or placeholder to the folder before it. A trailing `/` names a folder.
fn checked(token: &str) -> &str {
    let mut t = token.trim_end_matches(TRAILING);
    if let Some(anchor) = t.find('#') {
        t = &t[..anchor];
    }
    // `path:12`, `path:12-30`, `path:12:4`.
    while let Some(colon) = t.rfind(':') {
        let suffix = &t[colon + 1..];
        if suffix.is_empty() || !suffix.chars().all(|c| c.is_ascii_digit() || c == '-') {
            break;
        }
        t = &t[..colon];
    }
    t = t.trim_end_matches(TRAILING);
    if let Some(at) = PLACEHOLDERS.iter().filter_map(|p| t.find(p)).min() {
        t = &t[..t[..at].rfind('/').map_or(0, |slash| slash + 1)];
    }
    t
}

/// `base` joined with `rel`, `.` and `..` resolved without touching the file system; `None` when
/// it climbs out of `base`'s root.
fn joined(base: &str, rel: &str) -> Option<String> {
    let mut parts: Vec<&str> = base.split('/').filter(|p| !p.is_empty()).collect();
    for part in Path::new(rel).components() {
        match part {
            Component::CurDir => {}
            Component::ParentDir => {
                parts.pop()?;
            }
            Component::Normal(p) => parts.push(p.to_str()?),
            Component::RootDir => parts.clear(),
            Component::Prefix(_) => return None,
        }
    }
    let mut out = parts.join("/");
    if rel.ends_with('/') {
        out.push('/');
    }
    Some(out)
}

/// Whether `path` (relative to `root`; a trailing `/` for a folder) is in the tree.
fn exists(root: &Path, path: &str) -> bool {
    let full = root.join(path);
    if path.ends_with('/') {
        full.is_dir()
    } else {
        full.exists() || root.join(format!("{path}.gz")).is_file()
    }
}

/// What one file names.
#[derive(Default)]
struct Found {
    /// How many named paths were checked.
    checked: usize,
    /// The named paths that are not in the tree: `file:line: what`.
    missing: Vec<String>,
    /// The entries of [`GONE`] used: (file, path).
    gone: Vec<(String, String)>,
}

/// Checks the paths `text` (the file `file`, relative to `root`) names.
fn check(root: &Path, file: &str, syntax: Syntax, text: &str) -> Found {
    let mut found = Found::default();
    let lines: Vec<(usize, String)> = match syntax {
        Syntax::C => c_comments(text),
        Syntax::Hash => hash_comments(text),
        Syntax::Markdown => text.lines().enumerate().map(|(n, l)| (n + 1, l.to_owned())).collect(),
    };
    let folder = file.rfind('/').map_or("", |slash| &file[..slash]);
    for (n, line) in lines {
        let mut prose = line.clone();
        if syntax == Syntax::Markdown {
            for (range, target) in links(&line) {
                // The link's target is checked here; its text and the rest of the line below.
                prose.replace_range(range.clone(), &" ".repeat(range.len()));
                let path = target.split('#').next().unwrap();
                if path.is_empty() {
                    continue;
                }
                if gone(file, path, &mut found) {
                    continue;
                }
                found.checked += 1;
                match joined(folder, path) {
                    Some(to) if exists(root, &to) => {}
                    Some(to) => found.missing.push(format!("{file}:{n}: link `{target}` -> `{to}` does not exist")),
                    None => found.missing.push(format!("{file}:{n}: link `{target}` leaves the tree")),
                }
            }
        }
        for (at, token) in named(&prose) {
            let path = checked(token);
            let after = prose[at + token.len()..].trim_start_matches(['`', '"', '\'', ' ']);
            let before = prose[..at].trim_end_matches(['`', '"', '\'', '(', ' ']);
            let other_tree = OTHER_TREES.iter().any(|word| {
                before
                    .strip_suffix(word)
                    .is_some_and(|rest| rest.chars().next_back().is_none_or(|c| !c.is_alphanumeric()))
            });
            if after.starts_with(GONE_MARK) || other_tree || gone(file, path, &mut found) {
                continue;
            }
            found.checked += 1;
            if !exists(root, path) {
                let what = if path.ends_with('/') { "folder" } else { "path" };
                found.missing.push(format!("{file}:{n}: `{token}`: {what} `{path}` does not exist"));
            }
        }
    }
    found
}

/// Whether `path`, named in `file`, is in [`GONE`] (noted as used).
fn gone(file: &str, path: &str, found: &mut Found) -> bool {
    let listed = GONE.iter().any(|(f, paths, _)| *f == file && paths.contains(&path));
    if listed {
        found.gone.push((file.to_owned(), path.to_owned()));
    }
    listed
}

#[test]
fn named_paths_exist() {
    let root = root();
    let (mut checked, mut missing, mut gone) = (0, vec![], vec![]);
    let mut per_syntax = [0usize; 3];
    for (file, syntax) in sources(&root) {
        let text = std::fs::read_to_string(root.join(&file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let found = check(&root, &file, syntax, &text);
        checked += found.checked;
        per_syntax[syntax as usize] += found.checked;
        missing.extend(found.missing);
        gone.extend(found.gone);
    }
    eprintln!(
        "{checked} named paths checked ({} in Rust/GLSL/C++ comments, {} in # comments, {} in Markdown)",
        per_syntax[0], per_syntax[1], per_syntax[2]
    );
    assert!(missing.is_empty(), "{} named paths do not exist:\n{}", missing.len(), missing.join("\n"));
    // The scan must see the tree: a reader that finds nothing passes every time.
    assert!(per_syntax.iter().all(|&n| n >= 50), "too few paths found: {per_syntax:?}");
    let unused: Vec<_> = GONE
        .iter()
        .flat_map(|(f, paths, _)| paths.iter().map(move |p| (*f, *p)))
        .filter(|(f, p)| !gone.iter().any(|(gf, gp)| gf == f && gp == p))
        .collect();
    assert!(unused.is_empty(), "entries of GONE no file names any more (remove them): {unused:?}");
}

/// Paths in `text` checked as the file `file` of the real tree: the ones missing.
fn missing(file: &str, syntax: Syntax, text: &str) -> Vec<String> {
    check(&root(), file, syntax, text).missing
}

#[test]
fn a_missing_path_in_a_comment_is_reported() {
    let text = "fn f() {} // see src/gpu/no_such_file.rs and src/gpu/mod.rs\n";
    let found = missing("src/made_up.rs", Syntax::C, text);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("src/made_up.rs:1: `src/gpu/no_such_file.rs`"), "{found:?}");
    // The same in a block comment, a doc comment, a GLSL comment and a script's comment.
    assert_eq!(missing("src/a.rs", Syntax::C, "/* docs/gone.md */ fn f() {}").len(), 1);
    assert_eq!(missing("src/a.rs", Syntax::C, "/// `glsl/gone.glsl`\nfn f() {}").len(), 1);
    assert_eq!(missing("glsl/a.glsl", Syntax::C, "float x; // scripts/gone.sh:12\n").len(), 1);
    assert_eq!(missing("scripts/a.sh", Syntax::Hash, "echo hi  # tests/gone.rs\n").len(), 1);
    // A folder named with a trailing `/` must be a folder.
    assert_eq!(missing("src/a.rs", Syntax::C, "// src/io.rs/").len(), 1);
    assert!(missing("src/a.rs", Syntax::C, "// src/gpu/ and src/io.rs").is_empty());
}

#[test]
fn a_markdown_link_is_relative_to_its_file() {
    let md = "See [the gate](../../docs/gate.md#ci) and [gone](../../docs/no_such.md).\n";
    let found = missing("results/radv/README.md", Syntax::Markdown, md);
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].contains("`../../docs/no_such.md` -> `docs/no_such.md`"), "{found:?}");
    // From docs/, a link to `docs/gate.md` looks for a docs folder inside docs: broken, though the
    // link's text is right.
    assert_eq!(missing("docs/x.md", Syntax::Markdown, "[`docs/gate.md`](docs/gate.md)").len(), 1);
    assert!(missing("docs/x.md", Syntax::Markdown, "[`docs/gate.md`](gate.md)").is_empty());
    // Reference definitions, angle brackets and titles.
    assert_eq!(missing("docs/x.md", Syntax::Markdown, "[g]: ./nope.md").len(), 1);
    assert!(missing("docs/x.md", Syntax::Markdown, "[a](<gate.md> \"the gate\") [b](gate.md 'g')").is_empty());
    // Out of the tree, web addresses, in-page anchors.
    assert_eq!(missing("docs/x.md", Syntax::Markdown, "[a](../../x.md)").len(), 1);
    assert!(missing("docs/x.md", Syntax::Markdown, "[a](https://example.com/src/x.rs) [b](#src/x)").is_empty());
}

#[test]
fn punctuation_lines_and_anchors_come_off() {
    for (token, path) in [
        ("src/io.rs.", "src/io.rs"),
        ("src/io.rs,", "src/io.rs"),
        ("src/io.rs:", "src/io.rs"),
        ("src/io.rs;", "src/io.rs"),
        ("src/io.rs).", "src/io.rs"),
        ("src/io.rs`", "src/io.rs"),
        ("src/io.rs\"", "src/io.rs"),
        ("src/io.rs'", "src/io.rs"),
        ("src/io.rs**", "src/io.rs"),
        ("src/io.rs:123", "src/io.rs"),
        ("src/io.rs:12-30", "src/io.rs"),
        ("src/io.rs:12-30).", "src/io.rs"),
        ("src/io.rs:12:4", "src/io.rs"),
        ("docs/gate.md#ci", "docs/gate.md"),
        ("docs/gate.md#ci).", "docs/gate.md"),
        ("src/gpu/", "src/gpu/"),
        ("src/gpu/.", "src/gpu/"),
    ] {
        assert_eq!(checked(token), path, "{token}");
    }
}

#[test]
fn placeholders_leave_their_folder() {
    for (token, path) in [
        ("glsl/intersect/*.glsl", "glsl/intersect/"),
        ("src/**/*.rs", "src/"),
        ("src/encoding/<name>.rs", "src/encoding/"),
        ("results/<device>/bench.md", "results/"),
        ("glsl/{raycast,rayquery}.comp", "glsl/"),
        ("src/gpu/...", "src/gpu/"),
        ("src/gpu/raycast…", "src/gpu/"),
        ("results/$DEVICE/x", "results/"),
        ("src/x/%s.rs", "src/x/"),
    ] {
        assert_eq!(checked(token), path, "{token}");
    }
}

#[test]
fn tokens_start_a_word_with_a_folder_of_the_tree() {
    let tokens = |t: &str| named(t).into_iter().map(|(_, s)| s.to_owned()).collect::<Vec<_>>();
    assert_eq!(tokens("see `src/io.rs`, (glsl/a.glsl) and \"docs/x.md\""), ["src/io.rs", "glsl/a.glsl", "docs/x.md"]);
    assert_eq!(tokens("[`src/io.rs`]: x; <scripts/a.sh>"), ["src/io.rs", "scripts/a.sh"]);
    // Not at a word's start, or not a folder of the tree: not a path of the tree.
    assert!(tokens("/usr/src/x ../docs/x.md fuzz/work/x target/release/x mysrc/x #src/x").is_empty());
    assert!(tokens("src glsl docs: a word is no path").is_empty());
    // A placeholder's `>` ends the token, which is cut at its `<` anyway.
    assert_eq!(tokens("results/<device>/bench.md"), ["results/<device"]);
    // Gone on purpose, and another project's tree.
    assert!(missing("docs/x.md", Syntax::Markdown, "`src/harness/` (removed) held them").is_empty());
    assert!(missing("src/a.rs", Syntax::C, "// src/harness (removed in issue 40)").is_empty());
    assert!(missing("src/a.rs", Syntax::C, "// Mesa's src/util/u_cpu_detect.c, Mesa's (`src/x.c`)").is_empty());
    assert_eq!(missing("src/a.rs", Syntax::C, "// notMesa's src/util/u_cpu_detect.c").len(), 1);
    assert_eq!(missing("src/a.rs", Syntax::C, "// the library's src/gone.rs").len(), 1);
    // A results file stored compressed is there.
    assert!(missing("docs/x.md", Syntax::Markdown, "`results/lavapipe/baseline/radv/rows.jsonl`").is_empty());
}

#[test]
fn comments_are_found_outside_literals() {
    let text = r###"let url = "http://x // src/in_string.rs"; // src/one.rs
let raw = r#"// src/in_raw.rs "quoted" "#; /* src/two.rs
   src/three.rs */ let c = '"'; // src/four.rs
fn f<'a>(x: &'a str) -> char { '\'' } // src/five.rs
/* outer /* nested */ still src/six.rs */ let s = "\" // src/in_escaped.rs";
"###;
    let comments = c_comments(text);
    let lines: Vec<usize> = comments.iter().map(|(n, _)| *n).collect();
    let all: String = comments.iter().map(|(_, c)| c.as_str()).collect::<Vec<_>>().join("|");
    for (want, line) in [("src/one.rs", 1), ("src/two.rs", 2), ("src/three.rs", 3), ("src/four.rs", 3)] {
        assert!(comments.iter().any(|(n, c)| *n == line && c.contains(want)), "{want} on {line}: {comments:?}");
    }
    assert!(all.contains("src/five.rs") && all.contains("src/six.rs"), "{all}");
    assert!(!all.contains("in_string") && !all.contains("in_raw") && !all.contains("in_escaped"), "{all}");
    assert_eq!(lines, [1, 2, 3, 4, 5], "{comments:?}");

    let script = "#!/bin/sh\n# src/one.rs\necho \"# not a comment\" '# nor this' ${#x} # src/two.rs\n";
    let comments = hash_comments(script);
    assert_eq!(comments.len(), 3, "{comments:?}");
    assert_eq!((comments[1].0, comments[1].1.trim()), (2, "src/one.rs"));
    assert_eq!((comments[2].0, comments[2].1.trim()), (3, "src/two.rs"));
}
