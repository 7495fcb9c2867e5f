//! The tree's node order in memory on the CPU (`trilab::bvh::order`, issue 27 item 4): on the
//! bunny, a synthetic soup and a terrain, every order of every layout's nodes is the same tree
//! (it validates against the binary tree it came from), and the CPU traversal of each layout —
//! the f64 reference and the while-if mirror on the binary nodes, `WideBvh::trace` on bvh4 and
//! bvh8, `CwBvh::trace` on cwbvh — returns exactly the built order's hits and does exactly its
//! work on every ray, closest and any hit; while the node arrays themselves differ from the
//! built ones (so a renumbering that did nothing would fail here). `trilab bvh --layouts
//! --node-orders` reports each layout's bytes per triangle and each order's locality, and
//! without them what it reported before.

mod common;

use std::path::Path;

use trilab::bvh::qbvh4::{QNode4, Qbvh4};
use trilab::bvh::{BuildOptions, Bvh, CwBvh, NodeOrder, NodeTree, WideBvh, WideHit, WideSteps};
use trilab::named::Named;
use trilab::rays::{diffuse_rays, primary_rays, random_rays, Camera, Ray};
use trilab::reference::{intersect, Ray64, RefHit, Reference};
use trilab::scene::{load_obj, Mesh};
use trilab::traversal::ray_steps;

fn scenes() -> Vec<(&'static str, Mesh, u32)> {
    vec![
        ("bunny", load_obj(Path::new("bunny")).expect("the bundled bunny loads by name"), 4),
        ("soup", load_obj(Path::new("synth:soup:5000:3")).unwrap(), 1),
        ("terrain", load_obj(Path::new("synth:terrain:20000:2")).unwrap(), 8),
    ]
}

fn rays(mesh: &Mesh, bvh: &Bvh) -> Vec<Ray> {
    let b = mesh.bounds();
    let primary = primary_rays(&Camera::peer(&b).unwrap(), 48, 36);
    let hits: Vec<_> = Reference::new(mesh, bvh).trace_all(&primary, false).iter().map(RefHit::to_hit).collect();
    let mut rays = diffuse_rays(mesh, &primary, &hits, 2, 3);
    rays.extend(primary);
    rays.extend(random_rays(&b, 3000, 5));
    rays
}

/// A wide layout's walk of every ray: hits and work, closest then any.
fn walk(
    rays: &[Ray],
    mesh: &Mesh,
    trace: impl Fn(&Ray, bool, &dyn Fn(u32, f64) -> Option<(f64, f64, f64)>) -> (WideHit, WideSteps),
) -> Vec<(WideHit, WideSteps, WideHit)> {
    rays.iter()
        .map(|r| {
            let r64 = Ray64::from(r);
            let hit = |id: u32, tmax: f64| intersect(&Ray64 { tmax, ..r64 }, mesh.vertices_f64(id as usize));
            let (h, s) = trace(r, false, &hit);
            let (any, _) = trace(r, true, &hit);
            (h, s, any)
        })
        .collect()
}

#[test]
fn every_node_order_of_every_layout_walks_every_ray_as_the_built_order() {
    for (name, mesh, leaf) in scenes() {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        let rays = rays(&mesh, &bvh);
        let bounds = bvh.nodes[0].aabb();
        // The built order's answers.
        let reference = Reference::new(&mesh, &bvh);
        let (closest, any) = (reference.trace_all(&rays, false), reference.trace_all(&rays, true));
        let steps = ray_steps(&mesh, &bvh, &rays);
        assert!(closest.iter().filter(|h| h.is_hit()).count() * 10 > rays.len(), "{name}: too few hits to test");
        let w4 = WideBvh::<4>::collapse(&bvh);
        let w8 = WideBvh::<8>::collapse(&bvh);
        let cw = CwBvh::build(&bvh).unwrap();
        let walk4 = walk(&rays, &mesh, |r, a, f| w4.trace(r, a, f));
        let walk8 = walk(&rays, &mesh, |r, a, f| w8.trace(r, a, f));
        let walkc = walk(&rays, &mesh, |r, a, f| cw.trace(r, a, f));
        let q4 = Qbvh4::quantize(&w4).unwrap().decoded();
        let walkq = walk(&rays, &mesh, |r, a, f| q4.trace(r, a, f));
        for &order in NodeOrder::ALL {
            let what = format!("{name} leaf {leaf} {order}");
            // bvh2: the f64 reference and the kernels' while-if mirror on the reordered nodes.
            let mut b2 = bvh.clone();
            order.reorder_binary(&mut b2.nodes).unwrap();
            b2.validate(&mesh).unwrap_or_else(|e| panic!("{what} bvh2: {e}"));
            let r2 = Reference::new(&mesh, &b2);
            assert!(r2.trace_all(&rays, false) == closest, "{what} bvh2: closest hits differ");
            assert!(r2.trace_all(&rays, true) == any, "{what} bvh2: any hits differ");
            assert!(ray_steps(&mesh, &b2, &rays) == steps, "{what} bvh2: the walk differs");
            // bvh4, bvh8.
            let mut o4 = w4.clone();
            order.reorder_wide(&mut o4.nodes, &bounds).unwrap();
            o4.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("{what} bvh4: {e}"));
            assert!(walk(&rays, &mesh, |r, a, f| o4.trace(r, a, f)) == walk4, "{what} bvh4: hits or walk differ");
            let mut o8 = w8.clone();
            order.reorder_wide(&mut o8.nodes, &bounds).unwrap();
            o8.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("{what} bvh8: {e}"));
            assert!(walk(&rays, &mesh, |r, a, f| o8.trace(r, a, f)) == walk8, "{what} bvh8: hits or walk differ");
            // qbvh4: bvh4's nodes reordered at its node size, then quantized.
            let mut oq = w4.clone();
            order.reorder_wide_as(&mut oq.nodes, &bounds, std::mem::size_of::<QNode4>()).unwrap();
            let oq = Qbvh4::quantize(&oq).unwrap();
            let dq = oq.decoded();
            assert!(walk(&rays, &mesh, |r, a, f| dq.trace(r, a, f)) == walkq, "{what} qbvh4: hits or walk differ");
            // cwbvh.
            let mut oc = cw.clone();
            order.reorder_cwbvh(&mut oc).unwrap();
            oc.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("{what} cwbvh: {e}"));
            assert!(walk(&rays, &mesh, |r, a, f| oc.trace(r, a, f)) == walkc, "{what} cwbvh: hits or walk differ");
            // The arrays moved exactly where the order is not the layout's built one (bvh2 is
            // built depth first, cwbvh breadth first).
            let built = |alike: NodeOrder| order == NodeOrder::Built || order == alike;
            let same = |moved: bool, built: bool, layout: &str| {
                assert!(
                    moved != built,
                    "{what} {layout}: the nodes moved ({moved}) where the order is not the built one"
                )
            };
            same(b2.nodes != bvh.nodes, built(NodeOrder::DepthFirst), "bvh2");
            same(o4.nodes != w4.nodes, built(NodeOrder::Built), "bvh4");
            same(o8.nodes != w8.nodes, built(NodeOrder::Built), "bvh8");
            same(oc.nodes != cw.nodes, built(NodeOrder::BreadthFirst), "cwbvh");
            eprintln!("{what}: {} rays, every layout as built", rays.len());
        }
    }
}

/// Breadth first is level order and treelets are contiguous on a real scene's layouts: along
/// the array depth never falls; every treelet's nodes are one run of the array.
#[test]
fn breadth_first_and_treelets_on_the_bunny() {
    let mesh = load_obj(Path::new("bunny")).unwrap();
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    let bounds = bvh.nodes[0].aabb();
    let mut b2 = bvh.nodes.clone();
    NodeOrder::BreadthFirst.reorder_binary(&mut b2).unwrap();
    let d = NodeTree::binary(&b2).depths();
    assert!(d.windows(2).all(|w| w[0] <= w[1]), "bvh2 breadth first is level order");
    let mut w8 = WideBvh::<8>::collapse(&bvh).nodes;
    NodeOrder::BreadthFirst.reorder_wide(&mut w8, &bounds).unwrap();
    let d = NodeTree::wide(&w8, &bounds).unwrap().depths();
    assert!(d.windows(2).all(|w| w[0] <= w[1]), "bvh8 breadth first is level order");
    // Treelets: in the built tree's numbering, each treelet is a set of nodes; after the
    // renumbering those sets are consecutive runs in the array, in the treelets' order.
    for (layout, tree) in [
        ("bvh2", NodeTree::binary(&bvh.nodes)),
        ("bvh4", {
            let w = WideBvh::<4>::collapse(&bvh);
            NodeTree::wide(&w.nodes, &bounds).unwrap()
        }),
    ] {
        let treelets = tree.treelets(trilab::bvh::order::TREELET_BYTES);
        let new = tree.permutation(NodeOrder::Treelets).unwrap().unwrap();
        let mut at = 0u32;
        for t in &treelets {
            let mut places: Vec<u32> = t.iter().map(|&i| new[i as usize]).collect();
            places.sort_unstable();
            assert_eq!(places, (at..at + t.len() as u32).collect::<Vec<_>>(), "{layout}: a treelet is one run");
            assert!(t.len() * tree.node_bytes <= trilab::bvh::order::TREELET_BYTES, "{layout}: within a page");
            at += t.len() as u32;
        }
        assert_eq!(at as usize, tree.len());
        assert!(treelets.len() > 10, "{layout}: {} treelets", treelets.len());
    }
}

#[test]
fn bvh_reports_bytes_per_triangle_and_locality_per_layout_and_order() {
    let bunny = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj");
    let run = |extra: &[&str]| {
        let mut args = vec!["bvh", "--scene", bunny, "--leaf-sizes", "4", "--json"];
        args.extend(extra);
        let o = common::cli::trilab(&args, 120);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    // Without either option: the list of builds, as before.
    assert!(run(&[]).is_array());
    let j = run(&["--layouts", "bvh2,cwbvh", "--node-orders", "built,breadth-first,treelets"]);
    assert_eq!(j["builds"].as_array().unwrap().len(), 2, "both builders");
    let layouts = j["layouts"].as_array().unwrap();
    assert_eq!(layouts.len(), 2, "the binned tree's two layouts");
    let leaf = &j["leaf_bytes_per_triangle"]["4"];
    for l in layouts {
        let node = l["node_bytes_per_triangle"].as_f64().unwrap();
        assert!(node > 1.0 && node < 40.0, "{l}");
        for m in ["mt", "unit", "quad-unit"] {
            let total = l["bytes_per_triangle"][m].as_f64().unwrap();
            assert!((total - node - leaf[m].as_f64().unwrap()).abs() < 1e-9, "{l}: nodes + leaves");
        }
        let loc = l["locality"].as_array().unwrap();
        assert_eq!(loc.len(), 3);
        let pages = |k: usize| loc[k][1]["pages_per_step"].as_f64().unwrap();
        assert_eq!(loc[2][0], "treelets");
        assert!(pages(2) < pages(1), "{}: treelets leave a page less often than breadth first", l["layout"]);
    }
    // cwbvh's nodes and leaf table take fewer bytes than bvh2's nodes.
    let node = |k: usize| layouts[k]["node_bytes_per_triangle"].as_f64().unwrap();
    assert!(node(1) < 0.5 * node(0));
}
