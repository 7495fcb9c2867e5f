//! The README says what the program does: its method list is the intersector registry's.

#[test]
fn the_readme_lists_the_registry_s_methods() {
    let readme = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
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
/// command, which ends with the second pass at lavapipe's other width (scripts/test-width.sh)
/// and the regression gate against the committed baseline (scripts/ci-gate.sh).
#[test]
fn ci_runs_the_readme_s_test_command() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let ci = std::fs::read_to_string(root.join(".ci/run")).unwrap();
    let intro = "Run the tests (the same command CI runs, through `.ci/run`):\n\n";
    let at = readme.find(intro).expect("README.md has the Test paragraph") + intro.len();
    let command = readme[at..].lines().next().unwrap().trim();
    assert!(command.starts_with("./scripts/install-deps.sh") && command.contains("cargo test --release"), "{command}");
    assert!(
        command.ends_with("./scripts/test-width.sh 128 && ./scripts/ci-gate.sh"),
        "the second width pass and the regression gate are part of the command: {command}"
    );
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
