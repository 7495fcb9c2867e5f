//! The README says what the program does: its method list is the intersector registry's. It is a
//! front page (the manual is docs/, indexed by docs/README.md), and every relative link in it and
//! in docs/ leads to a file.

use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn the_readme_lists_the_registry_s_methods() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let (begin, end) = ("<!-- methods: begin -->\n", "<!-- methods: end -->");
    let start = readme.find(begin).expect("README.md has the methods: begin marker") + begin.len();
    let stop = start + readme[start..].find(end).expect("README.md has the methods: end marker");
    let want = trilab::commands::methods::run().markdown();
    assert!(want.lines().count() >= 8, "the registry lists every method");
    assert_eq!(
        &readme[start..stop],
        want,
        "README.md's method list is stale: paste `cargo run --release -- methods --markdown` between the markers"
    );
}

/// CI runs what the README tells a person to run: `.ci/run`'s last line is the README's test
/// command, which ends with the test matrix (scripts/test-matrix.sh): the suite with
/// --no-fail-fast, the passes at lavapipe's other widths and for a smaller CPU
/// (scripts/test-width.sh), and the regression gate against the committed baseline
/// (scripts/ci-gate.sh).
#[test]
fn ci_runs_the_readme_s_test_command() {
    let root = root();
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let ci = std::fs::read_to_string(root.join(".ci/run")).unwrap();
    let intro = "Run the tests (the same command CI runs, through `.ci/run`):\n\n";
    let at = readme.find(intro).expect("README.md has the Test paragraph") + intro.len();
    let command = readme[at..].lines().next().unwrap().trim();
    assert!(
        command.starts_with("./scripts/install-deps.sh") && command.ends_with("./scripts/test-matrix.sh"),
        "{command}"
    );
    let matrix = std::fs::read_to_string(root.join("scripts/test-matrix.sh")).unwrap();
    for pass in [
        "pass suite cargo test --release --no-fail-fast",
        "pass lp128 ./scripts/test-width.sh 128",
        "./scripts/test-width.sh 256 \"$small\"",
        "./scripts/test-width.sh 512 \"$small\"",
        "pass gate ./scripts/ci-gate.sh",
    ] {
        assert!(matrix.contains(pass), "scripts/test-matrix.sh runs `{pass}`");
    }
    assert!(root.join("results/lavapipe/baseline/summary.md").is_file(), "the gate's baseline is committed");
    let last = ci.lines().rev().find(|l| !l.trim().is_empty()).unwrap().trim();
    assert_eq!(last, command, ".ci/run's last line must be README.md's test command");
    let script = std::fs::read_to_string(root.join("scripts/test-width.sh")).unwrap();
    for t in script.split("tests=(").nth(1).unwrap().split(')').next().unwrap().split_whitespace() {
        assert!(
            root.join("tests").join(format!("{t}.rs")).exists(),
            "scripts/test-width.sh names tests/{t}.rs, which is gone"
        );
    }
}

#[test]
fn architecture_holds_the_traversal_support_matrix() {
    let text =
        std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("ARCHITECTURE.md")).unwrap();
    let (begin, end) = ("<!-- traversals: begin -->\n", "<!-- traversals: end -->");
    let start = text.find(begin).expect("ARCHITECTURE.md has the traversal table's begin marker") + begin.len();
    let stop = text[start..].find(end).expect("... and its end marker") + start;
    assert_eq!(
        &text[start..stop],
        trilab::encoding::variants::support_table(),
        "ARCHITECTURE.md's traversal table is stale: paste trilab::encoding::variants::support_table()"
    );
}

/// README.md is a front page: what trilab is, the two commands, what the main job prints, the
/// commands most people use and where to read on. The manual is in docs/.
#[test]
fn the_readme_is_a_front_page() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let lines = readme.lines().count();
    assert!(lines < 300, "README.md has {lines} lines: a front page stays under 300; the manual goes in docs/");
    for heading in ["## Quick start", "## What the main job prints", "## Where to read on"] {
        assert!(readme.contains(heading), "README.md has the section {heading:?}");
    }
    assert!(readme.contains("](docs/README.md)"), "README.md points at the manual's index");
}

/// Every page in docs/ is in the manual's index, and the front page lists the index.
#[test]
fn the_docs_index_lists_every_page() {
    let index = std::fs::read_to_string(root().join("docs/README.md")).expect("docs/README.md is the manual's index");
    for e in std::fs::read_dir(root().join("docs")).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        if name.ends_with(".md") && name != "README.md" {
            assert!(index.contains(&format!("]({name})")), "docs/README.md links docs/{name}");
        }
    }
}

/// The relative links of a Markdown text: `[text](target)` and `![alt](target)`, without the
/// `#anchor`; web addresses and anchors within the page left out.
fn relative_links(text: &str) -> Vec<String> {
    let mut out = vec![];
    let mut rest = text;
    while let Some(at) = rest.find("](") {
        rest = &rest[at + 2..];
        let Some(end) = rest.find(')') else { break };
        let target = rest[..end].trim();
        if !target.is_empty() && !target.contains("://") && !target.starts_with('#') && !target.starts_with("mailto:") {
            out.push(target.split('#').next().unwrap().to_owned());
        }
    }
    out
}

#[test]
fn every_relative_link_in_the_readme_and_docs_leads_to_a_file() {
    let mut pages: Vec<PathBuf> = vec![root().join("README.md")];
    for e in std::fs::read_dir(root().join("docs")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            pages.push(p);
        }
    }
    assert!(pages.len() > 10, "docs/ holds the manual: {pages:?}");
    let mut broken = vec![];
    let mut count = 0;
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        for link in relative_links(&text) {
            count += 1;
            if !page.parent().unwrap().join(&link).exists() {
                broken.push(format!("{}: {link}", page.strip_prefix(root()).unwrap().display()));
            }
        }
    }
    assert!(count > 50, "links found: {count}");
    assert!(
        broken.is_empty(),
        "links to nothing (a path relative to the page, not the repository):\n{}",
        broken.join("\n")
    );
    assert!(relative_links("[a](x.md#b) [c](https://e.org) ![d](img/p.png) [e](#f)") == ["x.md", "img/p.png"]);
}
