//! `trilab study --layouts` end to end under the validation layer: the node layout is an axis of
//! the study. Checked: one row per (leaf, method) on each layout asked, every row validated
//! (agreement with the f64 reference, traversal counted) and naming its layout, the claims judged
//! per layout, and study.md's answer to issue 15's question (does the best intersector and the
//! best leaf size change with the layout?). Bad layout lists are refused before any work.

mod common;

use common::cli::{expect_error, ok, trilab};

#[test]
fn smoke_study_on_two_layouts_has_validated_rows_for_both_and_answers_the_question() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let o = trilab(
        &["study", "--preset", "smoke", "--layouts", "bvh2,bvh8", "--validation", "--out", out.to_str().unwrap()],
        600,
    );
    let err = ok(&o);
    assert!(!err.contains("validation:"), "validation messages: {err}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).unwrap()).unwrap();
    assert_eq!(json["options"]["layouts"], serde_json::json!(["bvh2", "bvh8"]));
    let rows = json["rows"].as_array().unwrap();
    // The smoke preset: the bunny, 6 leaf sizes x the paper's 4 methods, on each layout.
    assert_eq!(rows.len(), 2 * 6 * 4);
    for layout in ["bvh2", "bvh8"] {
        let mine: Vec<_> = rows.iter().filter(|r| r["layout"] == layout).collect();
        assert_eq!(mine.len(), 6 * 4, "{layout}");
        let mut cells: Vec<String> =
            mine.iter().map(|r| format!("{} {}", r["leaf_size"], r["method"].as_str().unwrap())).collect();
        cells.sort();
        cells.dedup();
        assert_eq!(cells.len(), 24, "{layout}: every (leaf, method) once");
        for r in mine {
            let what = format!("{layout} leaf {} {}", r["leaf_size"], r["method"]);
            // The kernels that ran are the layout's own variants.
            let kernel = r["raycast_kernel"].as_str().unwrap();
            assert_eq!(kernel.ends_with("_bvh8"), layout == "bvh8", "{what}: {kernel}");
            let render = r["render_kernel"].as_str().unwrap();
            assert_eq!(render.ends_with("_bvh8"), layout == "bvh8", "{what}: {render}");
            let sets = r["sets"].as_array().unwrap();
            assert_eq!(sets.len(), 3, "{what}");
            for s in sets {
                assert!(s["agreement"].as_f64().unwrap() >= 0.9999, "{what} {}: agreement", s["set"]);
                assert!(s["traversal"]["nodes"]["mean"].as_f64().unwrap() >= 1.0, "{what}: traversal counted");
                assert!(s["mrays_per_s"]["median"].as_f64().unwrap() > 0.0);
            }
            assert!(r["render"]["ms"]["median"].as_f64().unwrap() > 0.0);
        }
    }
    // A wide layout visits fewer nodes than the binary tree on the same rays (a wide node
    // replaces several binary ones), and tests more boxes per node.
    let nodes = |layout: &str| {
        let r = rows.iter().find(|r| r["layout"] == layout && r["leaf_size"] == 4 && r["method"] == "mt").unwrap();
        r["sets"][0]["traversal"]["nodes"]["mean"].as_f64().unwrap()
    };
    assert!(nodes("bvh8") < nodes("bvh2"), "bvh8 {} vs bvh2 {}", nodes("bvh8"), nodes("bvh2"));

    let csv = std::fs::read_to_string(out.join("study.csv")).unwrap();
    assert!(csv.lines().next().unwrap().contains(",method,layout,"), "{csv}");
    assert_eq!(csv.lines().filter(|l| l.contains(",bvh8,")).count(), 24);

    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    for needle in [
        "### BVH2 (`bvh2`)",
        "### BVH8 (`bvh8`)",
        "| claim | BVH2 (bvh2) | BVH8 (bvh8) |",
        "### On BVH8 (`bvh8`)",
        "## Does the best intersector, and the best leaf size, change with the layout?",
        "**BVH8 (`bvh8`)** against `bvh2`: does the best intersector change?",
        "Does the best leaf size change?",
        "| scene | layout | fastest method (leaf) |",
        "| scene | method | best leaf on bvh2 | best leaf on bvh8 |",
        // One timed round: shown, not judged.
        "**This run cannot judge it:**",
    ] {
        assert!(md.contains(needle), "study.md lacks `{needle}`:\n{md}");
    }
    for png in ["study-time-vs-leaf.png", "study-mrays-per-set.png", "study-instructions-vs-time.png"] {
        let img = image::open(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        // Two panels (one per layout) side by side.
        assert!(img.width() >= 1280, "{png} is {}x{}", img.width(), img.height());
    }
}

#[test]
fn study_refuses_bad_layout_lists_before_any_work() {
    expect_error(&trilab(&["study", "--preset", "smoke", "--layouts", "bvh3"], 60), &["bvh3", "bvh2"]);
    expect_error(&trilab(&["study", "--preset", "smoke", "--layouts", "bvh8,bvh8"], 60), &["--layouts", "twice"]);
}
