//! The study's CI smoke run: `trilab study --preset smoke` end to end under the validation
//! layer (any message fails), then its outputs checked for what the issue promises: the full
//! matrix of leaf sizes x methods, every row validated and carrying its provenance, the paper's
//! table and claims in study.md, and plots that decode as PNG.

mod common;

fn run(args: &[&str], timeout_s: u64) -> std::process::Output {
    common::cli::trilab(args, timeout_s)
}

#[test]
fn smoke_study_writes_the_full_matrix_validated() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let o = run(&["study", "--preset", "smoke", "--validation", "--out", out.to_str().unwrap()], 600);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "study failed: {err}");
    assert!(!err.contains("validation:"), "validation messages: {err}");

    // CSV: 6 leaf sizes x 4 methods for the bunny, each row complete.
    let mut csv = csv::Reader::from_path(out.join("study.csv")).unwrap();
    let headers = csv.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap_or_else(|| panic!("no column {name}"));
    let rows: Vec<csv::StringRecord> = csv.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 6 * 4, "scene x leaf x method rows");
    let mut cells: Vec<(String, String)> =
        rows.iter().map(|r| (r[col("leaf_size")].to_owned(), r[col("method")].to_owned())).collect();
    cells.sort();
    cells.dedup();
    assert_eq!(cells.len(), 24, "every (leaf, method) exactly once");
    for r in &rows {
        assert_eq!(&r[col("scene")], "bunny");
        assert_eq!(&r[col("triangles")], "69451");
        let num = |c: &str| r[col(c)].parse::<f64>().unwrap_or_else(|_| panic!("{c} = {:?}", &r[col(c)]));
        assert!(
            num("render_s") > 0.0 && num("render_s_min") <= num("render_s") && num("render_s") <= num("render_s_max")
        );
        for set in ["primary", "diffuse", "random"] {
            assert!(num(&format!("{set}_agreement")) >= 0.9999, "{set} agreement");
            assert!(num(&format!("{set}_mrays_per_s")) > 0.0);
            assert!(num(&format!("{set}_nodes_mean")) >= 1.0, "{set}: rays visit the BVH");
            assert!(num(&format!("{set}_triangles_mean")) > 0.0);
        }
        assert!(num("sah_cost") > 0.0 && num("epo") > 0.0 && num("epo") < num("sah_cost"));
        assert!(num("scene_mb") > 0.0);
        for c in ["device", "driver", "commit", "date"] {
            assert!(!r[col(c)].is_empty(), "{c} empty");
        }
    }

    // JSON parses and states the workload's scaling against the paper.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 24);
    assert!(json["scaling"].as_str().unwrap().contains("of the paper's"));

    // Markdown: the paper's table, the claims, the plots.
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    for needle in [
        "| Scene | # Triangles per BVH leaf | GPU scene size, MB |",
        "Bunny, 69,451 triangles",
        "**(a) 4 triangles per BVH leaf is optimal:",
        "**(b) Möller-Trumbore is up to 5 % faster than unit triangle:",
        "**(c) Quad unit triangle",
        "## Traversal work per ray",
        "study-time-vs-leaf.png",
    ] {
        assert!(md.contains(needle), "study.md lacks `{needle}`");
    }
    // The card's question on GPUs: the study's kernels compiled for the paper's HD 7850 and today's
    // chips (RADV's null device, issue 50), and the model's bounds beside Table 4's 0.827.
    for needle in [
        "## The paper's question on GPUs: what AMD's compiler makes of the methods",
        "| pitcairn (Radeon HD 7850 (the paper's Table 4)) | GCN 1 | ray casting |",
        "| gfx1201 (Radeon RX 9070 XT) | RDNA 4 | path tracing |",
        "### A model of claim (c) from the compiled code",
        "| 0.827 |",
        "- **pitcairn (GCN 1), path tracing**: Quad unit",
    ] {
        assert!(md.contains(needle), "study.md lacks `{needle}`");
    }
    let model = json["compiled"]["model"].as_array().unwrap();
    assert_eq!(model.len(), 5 * 2, "five chips x (path tracing, ray casting)");
    for m in model {
        let f = |k: &str| m[k].as_f64().unwrap();
        // MT fetches its triangles through an index: more dependent rounds per ray than Quad unit.
        assert!(f("mt_rounds") > f("quad_rounds") && f("quad_rounds") > 0.0, "{m}");
        assert!((f("latency_bound") - f("hidden") * f("mt_subgroups") / f("quad_subgroups")).abs() < 1e-9, "{m}");
        assert!(f("mt_vgprs") > 0.0 && f("quad_vgprs") > 0.0, "{m}");
    }
    for png in ["study-time-vs-leaf.png", "study-mrays-per-set.png", "study-instructions-vs-time.png"] {
        let img = image::open(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert!(img.width() >= 500 && img.height() >= 400, "{png} is {}x{}", img.width(), img.height());
    }
}

#[test]
fn study_rejects_a_missing_scene_and_a_bad_leaf_size() {
    let o = run(&["study", "--preset", "smoke", "--scenes", "no/such.obj"], 60);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("no/such.obj") && !err.contains("panicked"), "{err}");
    let o = run(&["study", "--preset", "smoke", "--leaf-sizes", "0"], 60);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("leaf") && !err.contains("panicked"), "{err}");
}
