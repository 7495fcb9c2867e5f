//! The tree's node order in memory on the GPU (issue 27 item 4): `SceneRequest::node_order`
//! reaches every layout, traversal and access path, and `trilab bench --node-orders` times each
//! order side by side. Validation layers on; a wall-clock limit.
//!
//! - Every layout in every node order returns the built order's closest hits and the stats
//!   kernel's traversal counts ray for ray (the tree and every ray's walk are the same; only the
//!   indices moved), on the texel and the address path, and every other traversal's kernels on
//!   treelets return their built-order hits.
//! - `bench --node-orders depth-first,breadth-first,treelets` gives a validated row per order,
//!   layout and set, with `node_order` in each row and cell, and the node order column.

mod common;

use serde_json::Value;
use trilab::bvh::{BuildOptions, NodeOrder};
use trilab::encoding::{AccessPath, Layout, Method, Raycast, SceneAccess, Traversal};
use trilab::gpu::TraversalCounts;
use trilab::named::Named;
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::{primary_rays, random_rays, Camera};

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj");

#[test]
fn every_node_order_gives_the_built_order_s_hits_and_walks() {
    let lines = common::with_gpu(900, |ctx| {
        let bunny = common::bunny();
        let host = HostScene::build("bunny", &bunny, &BuildOptions::new(4)).unwrap();
        let b = bunny.bounds();
        let mut rays = primary_rays(&Camera::peer(&b).unwrap(), 64, 48);
        rays.extend(random_rays(&b, 4000, 3));
        let hits = host.reference().trace_all(&rays, false).iter().filter(|h| h.is_hit()).count();
        assert!(hits * 10 > rays.len(), "{hits} hits of {}: too few to test", rays.len());
        let method = Method::Unit;
        let mut lines = vec![];
        for &layout in Layout::ALL {
            let request = SceneRequest::new(method).layout(layout);
            let built = host.upload(ctx, &request).unwrap();
            assert_eq!(built.node_order, NodeOrder::Built);
            let want = built.cast(ctx, Raycast::Closest, &rays, &common::ONCE).unwrap().hits;
            let want_counts: Vec<TraversalCounts> =
                built.cast(ctx, Raycast::Stats, &rays, &common::ONCE).unwrap().traversal.unwrap();
            for &order in &NodeOrder::ALL[1..] {
                let scene = host.upload(ctx, &request.node_order(order)).unwrap();
                assert_eq!((scene.node_order, scene.bytes), (order, built.bytes), "{layout} {order}");
                let got = scene.cast(ctx, Raycast::Closest, &rays, &common::ONCE).unwrap().hits;
                let differ = (0..rays.len()).filter(|&i| got[i] != want[i]).count();
                assert_eq!(
                    differ,
                    0,
                    "{layout} {order}: {differ} of {} rays' hits differ from the built order's",
                    rays.len()
                );
                let stats = scene.cast(ctx, Raycast::Stats, &rays, &common::ONCE).unwrap();
                assert!(stats.hits == want, "{layout} {order}: the stats kernel's hits differ");
                assert!(
                    stats.traversal.unwrap() == want_counts,
                    "{layout} {order}: the walk (nodes, boxes, leaves, triangles) differs from the built order's"
                );
                let bda = host.upload(ctx, &request.node_order(order).access(SceneAccess::Address)).unwrap();
                assert_eq!(bda.access, AccessPath::Address);
                let got = bda.cast(ctx, Raycast::Closest, &rays, &common::ONCE).unwrap().hits;
                assert!(got == want, "{layout} {order}: the address path's hits differ");
                lines.push(format!("{layout} {order}: {} rays, hits and walk as built, both paths", rays.len()));
            }
            // The other traversals on treelets, against their own built-order hits.
            for &t in &Traversal::ALL[1..] {
                if method.traversal_kernel(Raycast::Closest, AccessPath::Texel, layout, t).is_err() {
                    continue;
                }
                let r = request.traversal(t);
                let want =
                    host.upload(ctx, &r).unwrap().cast(ctx, Raycast::Closest, &rays, &common::ONCE).unwrap().hits;
                let scene = host.upload(ctx, &r.node_order(NodeOrder::Treelets)).unwrap();
                let got = scene.cast(ctx, Raycast::Closest, &rays, &common::ONCE).unwrap().hits;
                assert!(got == want, "{layout} {t} treelets: hits differ from the built order's");
                lines.push(format!("{layout} {t} treelets: hits as built"));
            }
        }
        lines
    });
    println!("{}", lines.join("\n"));
}

#[test]
fn bench_times_every_node_order_side_by_side() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("bench")).unwrap();
    let out = dir.path().join("bench").to_string_lossy().into_owned();
    let args = [
        "bench",
        "--scenes",
        BUNNY,
        "--methods",
        "unit",
        "--layouts",
        "bvh2,bvh4,bvh8,cwbvh",
        "--node-orders",
        "depth-first,breadth-first,treelets",
        "--width",
        "48",
        "--height",
        "32",
        "--random-rays",
        "3000",
        "--repeat",
        "1",
        "--validation",
        "--json",
        "--out",
        &out,
    ];
    let o = common::cli::trilab(&args, 600);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    let j: Value = serde_json::from_slice(&o.stdout).expect("bench --json prints JSON");
    let rows = j["rows"].as_array().unwrap();
    // 3 sets x 4 layouts x 3 node orders, each agreeing with the reference.
    let mut seen: Vec<(String, String, String)> = rows
        .iter()
        .map(|r| {
            assert!(r["agreement"].as_f64().unwrap() >= 0.9999, "{r}");
            let s = |k: &str| r[k].as_str().unwrap_or_default().to_owned();
            (s("ray_set"), s("layout"), s("node_order"))
        })
        .collect();
    assert_eq!(seen.len(), 36, "{seen:?}");
    seen.sort();
    seen.dedup();
    assert_eq!(seen.len(), 36, "one row per set, layout and node order: {seen:?}");
    for set in ["primary", "diffuse", "random"] {
        for layout in ["bvh2", "bvh4", "bvh8", "cwbvh"] {
            for order in ["depth-first", "breadth-first", "treelets"] {
                let want = (set.to_owned(), layout.to_owned(), order.to_owned());
                assert!(seen.contains(&want), "no row {want:?}");
            }
        }
    }
    // rows.jsonl: every cell names its node order (none is the built one).
    let text = std::fs::read_to_string(dir.path().join("bench").join("rows.jsonl")).unwrap();
    let cells: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .filter(|l| l["type"] == "row")
        .map(|l| l["cell"].clone())
        .collect();
    assert_eq!(cells.len(), 36);
    for order in ["depth-first", "breadth-first", "treelets"] {
        assert_eq!(cells.iter().filter(|c| c["node_order"] == order).count(), 12, "{order}");
    }
    let md = std::fs::read_to_string(dir.path().join("bench").join("bench.md")).unwrap();
    assert!(md.contains("node order") && md.contains("breadth-first"), "{md}");
}
