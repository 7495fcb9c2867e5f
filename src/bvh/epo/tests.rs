//! The end-point overlap's tests: hand-built trees, the fast queries against the metric's
//! definition (brute force) on a soup and on piles of copies, and the work limit (the clipping
//! is tested in `clip.rs`).

use super::*;
use crate::bvh::{BuildOptions, Builder, BvhNode};

/// A hand-built tree: root over two leaves of one triangle each.
fn two_leaf_tree(mesh: &Mesh) -> Bvh {
    let node = |id: usize, first: u32| {
        let v = mesh.vertices(id);
        let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
        BvhNode { min: lo.to_array(), left_or_first: first, max: hi.to_array(), count: 1 }
    };
    let (l, r) = (node(0, 0), node(1, 1));
    let root = BvhNode {
        min: [l.min[0].min(r.min[0]), l.min[1].min(r.min[1]), l.min[2].min(r.min[2])],
        left_or_first: 1,
        max: [l.max[0].max(r.max[0]), l.max[1].max(r.max[1]), l.max[2].max(r.max[2])],
        count: 0,
    };
    Bvh {
        nodes: vec![root, l, r],
        prim_ids: vec![0, 1],
        options: BuildOptions::new(1),
        build_seconds: 0.0,
        build_threads: 1,
        degenerate_excluded: 0,
    }
}

#[test]
fn two_overlapping_leaves() {
    // A = (0,0), (2,0), (0,2) and B = (1,1), (3,1), (1,3) in z = 0, area 2 each.
    // A's box [0,2]^2 holds B's unit square [1,2]^2 (area 1); B's box [1,3]^2 holds only
    // A's point (1,1) (area 0). Leaves cost 1 each, the root has no foreign triangles:
    // EPO = (1 * 1 + 1 * 0) / 4.
    let mesh = Mesh::from_triangles(
        vec![[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [1.0, 1.0, 0.0], [3.0, 1.0, 0.0], [1.0, 3.0, 0.0]],
        vec![[0, 1, 2], [3, 4, 5]],
    );
    let mut bvh = two_leaf_tree(&mesh);
    bvh.validate(&mesh).unwrap();
    assert_eq!(epo(&mesh, &bvh), 0.25);
    // With leaves priced 3 tests each it triples.
    bvh.options.cost_intersect = 3.0;
    assert_eq!(epo(&mesh, &bvh), 0.75);
}

#[test]
fn disjoint_boxes_give_zero() {
    let mesh = Mesh::from_triangles(
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 0.0, 0.0], [6.0, 0.0, 0.0], [5.0, 1.0, 0.0]],
        vec![[0, 1, 2], [3, 4, 5]],
    );
    let bvh = two_leaf_tree(&mesh);
    bvh.validate(&mesh).unwrap();
    assert_eq!(epo(&mesh, &bvh), 0.0);
    let built = Bvh::build(&mesh, &BuildOptions::new(1));
    assert_eq!(epo(&mesh, &built), 0.0);
}

/// EPO by its definition: every node against every triangle outside its subtree, clipped.
fn brute(mesh: &Mesh, bvh: &Bvh) -> f64 {
    // Triangles under each node, from the leaves up (children follow their parent).
    let mut under: Vec<Vec<u32>> = vec![vec![]; bvh.nodes.len()];
    for i in (0..bvh.nodes.len()).rev() {
        let n = &bvh.nodes[i];
        let f = n.left_or_first as usize;
        under[i] = if n.is_leaf() {
            bvh.prim_ids[f..f + n.count as usize].to_vec()
        } else {
            [under[f].clone(), under[f + 1].clone()].concat()
        };
    }
    let total: f64 = (0..mesh.triangle_count()).map(|i| triangle_area(&mesh.vertices_f64(i))).sum();
    let mut sum = 0.0;
    for (i, n) in bvh.nodes.iter().enumerate() {
        // Build costs 1 and 1: a leaf costs its triangle count.
        let c = if n.is_leaf() { n.count as f64 } else { 1.0 };
        let bx = Box64::of_node(n);
        let mut outside = vec![true; mesh.triangle_count()];
        for &t in &under[i] {
            outside[t as usize] = false;
        }
        for t in (0..mesh.triangle_count()).filter(|&t| outside[t]) {
            sum += c * clipped_area(&mesh.vertices_f64(t), &bx);
        }
    }
    sum / total
}

fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

/// The BVH-pruned search finds what a brute-force pass over every (node, triangle) pair does.
#[test]
fn matches_brute_force_on_a_random_soup() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let mut pos = vec![];
    let mut tris = vec![];
    for i in 0..400u32 {
        let c = [rng.random::<f32>() * 10.0, rng.random::<f32>() * 10.0, rng.random::<f32>() * 10.0];
        for _ in 0..3 {
            pos.push(c.map(|x| x + rng.random::<f32>() * 2.0 - 1.0));
        }
        tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let mesh = Mesh::from_triangles(pos, tris);
    for (leaf, builder) in [(1, Builder::default()), (4, Builder::Sweep), (8, Builder::default())] {
        let bvh = Bvh::build(&mesh, &BuildOptions { builder, ..BuildOptions::new(leaf) });
        let brute = brute(&mesh, &bvh);
        let fast = epo(&mesh, &bvh);
        assert!(brute > 0.1, "the soup overlaps");
        assert!((fast - brute).abs() <= 1e-12 * brute, "leaf {leaf}: {fast} vs {brute}");
        // Exactly the same on one thread and on four: a count `trilab compare` holds exact.
        let on = |threads: usize| on_threads(threads, || epo(&mesh, &bvh));
        assert_eq!(on(1).to_bits(), on(4).to_bits(), "leaf {leaf}");
        assert_eq!(on(1).to_bits(), fast.to_bits(), "leaf {leaf}");
    }
}

/// Issue 24: copies of one triangle put every triangle in every node's box, and the query
/// clipped each of them at each node (quadratic: 32,000 copies took 20 s per tree). Subtrees
/// inside a node's box, and subtrees of copies, now add their area at once. Exact against the
/// brute force with two piles that cross each other and a few triangles around them, and
/// near-linear in work: far under the (nodes x copies) triangle tests of a per-leaf query.
#[test]
fn piles_of_copies_match_brute_force_in_near_linear_work() {
    let mut pos = vec![];
    let mut tris = vec![];
    let mut add = |p: [[f32; 3]; 3]| {
        let i = pos.len() as u32;
        pos.extend(p);
        tris.push([i, i + 1, i + 2]);
    };
    // 1,500 copies of one triangle, 1,000 of a second across it, 40 small ones here and there.
    for _ in 0..1500 {
        add([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    }
    for _ in 0..1000 {
        add([[0.5, -0.5, -0.5], [0.5, 1.5, -0.5], [0.5, 0.5, 1.5]]);
    }
    for k in 0..40 {
        let x = k as f32 * 0.05 - 0.5;
        add([[x, x, 0.1], [x + 0.2, x, 0.1], [x, x + 0.2, 0.3]]);
    }
    let mesh = Mesh::from_triangles(pos, tris);
    for (leaf, builder) in [(1, Builder::default()), (4, Builder::default()), (4, Builder::Sweep), (16, Builder::Sweep)]
    {
        let bvh = Bvh::build(&mesh, &BuildOptions { builder, ..BuildOptions::new(leaf) });
        let (fast, work) = epo_counted(&mesh, &bvh, u64::MAX);
        let fast = fast.unwrap();
        let brute = brute(&mesh, &bvh);
        assert!(brute > 100.0, "every node's box holds a pile: {brute}");
        assert!((fast - brute).abs() <= 1e-12 * brute, "leaf {leaf} {builder}: {fast} vs {brute}");
        let nodes = bvh.nodes.len() as u64;
        let pairwise = nodes * 1000;
        let elements = nodes + bvh.prim_ids.len() as u64;
        let depth = u64::from(bvh.stats().depth);
        assert!(
            work * 20 < pairwise && work <= 4 * (depth + 1) * elements,
            "leaf {leaf} {builder}: work {work}, depth {depth}, {elements} nodes and triangles"
        );
        assert!(work <= WORK_PER_ELEMENT * elements, "within the default limit: {work}");
        assert_eq!(on_threads(1, || epo(&mesh, &bvh)).to_bits(), on_threads(3, || epo(&mesh, &bvh)).to_bits());
    }
}

/// Copies each moved a little: every leaf's box holds nearly every other copy in part, and
/// each such pair must be clipped. `epo_within` gives the exact value at a limit of the work
/// it needs and none one unit below, on any thread count.
#[test]
fn the_work_limit_is_exact_and_independent_of_the_thread_count() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let mut pos = vec![];
    let mut tris = vec![];
    for i in 0..600u32 {
        let d = [0; 3].map(|_| rng.random::<f32>() * 0.02 - 0.01);
        for v in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            pos.push([v[0] + d[0], v[1] + d[1], v[2] + d[2]]);
        }
        tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let mesh = Mesh::from_triangles(pos, tris);
    let bvh = Bvh::build(&mesh, &BuildOptions::new(2));
    let (value, work) = epo_counted(&mesh, &bvh, u64::MAX);
    let value = value.unwrap();
    let brute = brute(&mesh, &bvh);
    assert!((value - brute).abs() <= 1e-12 * brute, "{value} vs {brute}");
    let leaves = bvh.stats().leaves as u64;
    assert!(work > leaves * 100, "hundreds of the other copies are clipped at each leaf: {work}");
    for threads in [1, 2, 5] {
        on_threads(threads, || {
            assert_eq!(epo_within(&mesh, &bvh, work).map(f64::to_bits), Some(value.to_bits()), "{threads}");
            assert_eq!(epo_within(&mesh, &bvh, work - 1), None, "{threads} threads");
            assert_eq!(epo_within(&mesh, &bvh, work / 3), None, "{threads} threads");
        });
    }
    // A small tree is always priced by default (the limit's floor); `stats_with_epo` says so.
    assert!(default_work_limit(&bvh) > work);
    assert_eq!(bvh.stats_with_epo(&mesh).epo.map(f64::to_bits), Some(value.to_bits()));
}

/// The bundled bunny is far inside the default limit at every leaf size: the limit only
/// stops scenes whose triangles overlap one another far more than real models do.
#[test]
fn the_bunny_is_far_inside_the_default_work_limit() {
    let mesh =
        crate::scene::load_obj(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/bunny.obj")).unwrap();
    for leaf in [1, 4, 16] {
        let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
        let (value, work) = epo_counted(&mesh, &bvh, u64::MAX);
        assert!(value.unwrap() > 1.0);
        assert!(work * 3 < default_work_limit(&bvh), "leaf {leaf}: {work} of {}", default_work_limit(&bvh));
    }
}
