//! The source tree as the tests that read it see it (`tests/layers.rs`, `tests/defaults.rs`,
//! `tests/doc_paths.rs`).

use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
pub fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    files(dir, &|p, is_dir| is_dir || p.extension().is_some_and(|x| x == "rs"), out);
}

/// Every file under `dir` that `keep(path, false)` takes, in the folders `keep(path, true)` takes
/// (`tests/doc_paths.rs` leaves out build folders and vendored data that way).
pub fn files(dir: &Path, keep: &dyn Fn(&Path, bool) -> bool, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        let is_dir = p.is_dir();
        if keep(&p, is_dir) {
            if is_dir {
                files(&p, keep, out);
            } else {
                out.push(p);
            }
        }
    }
}

/// A line without its comment: the rest after `//` outside a string literal.
pub fn without_comment(line: &str) -> &str {
    let (mut in_str, mut prev) = (false, ' ');
    for (i, c) in line.char_indices() {
        if c == '"' && prev != '\\' {
            in_str = !in_str;
        }
        if !in_str && c == '/' && prev == '/' {
            return &line[..i - 1];
        }
        prev = c;
    }
    line
}
