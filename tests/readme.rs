//! The README says what the program does: its method list is the intersector registry's.

#[test]
fn the_readme_lists_the_registry_s_methods() {
    let readme = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("README.md")).unwrap();
    let (begin, end) = ("<!-- methods: begin -->\n", "<!-- methods: end -->");
    let start = readme.find(begin).expect("README.md has the methods: begin marker") + begin.len();
    let stop = start + readme[start..].find(end).expect("README.md has the methods: end marker");
    let want = trilab::harness::methods::run().markdown();
    assert!(want.lines().count() >= 8, "the registry lists every method");
    assert_eq!(
        &readme[start..stop],
        want,
        "README.md's method list is stale: paste `cargo run --release -- methods --markdown` between the markers"
    );
}
