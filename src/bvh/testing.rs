//! Scenes, a triangle test and a corruption checker for the unit tests of every tree.

use glam::DVec3;

use crate::bvh::{BuildOptions, Bvh};
use crate::rays::Ray;
use crate::scene::Mesh;

/// A jittered grid of small triangles (deterministic).
pub(crate) fn grid(n: usize) -> Mesh {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for i in 0..n {
        let x = (i % 37) as f32 + 0.13 * ((i * 7919) % 11) as f32;
        let y = (i / 37) as f32;
        let z = 0.3 * ((i * 104729) % 13) as f32;
        let b = pos.len() as u32;
        pos.extend([[x, y, z], [x + 0.5, y, z + 0.1], [x, y + 0.5, z - 0.1]]);
        tris.push([b, b + 1, b + 2]);
    }
    Mesh::from_triangles(pos, tris)
}

/// Möller–Trumbore in f64 (the bvh layer cannot import `reference`; tests/wide_bvh.rs uses
/// the reference's own).
pub(crate) fn mt(mesh: &Mesh, ray: &Ray, id: u32, tmax: f64) -> Option<(f64, f64, f64)> {
    let [a, b, c] = mesh.vertices_f64(id as usize);
    let (o, d) = (DVec3::from_array(ray.origin.map(f64::from)), DVec3::from_array(ray.dir.map(f64::from)));
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let tv = o - a;
    let (u, q) = (tv.dot(p) / det, tv.cross(e1));
    let (v, t) = (d.dot(q) / det, e2.dot(q) / det);
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= ray.tmin as f64 && t <= tmax).then_some((t, u, v))
}

/// Trees over grids of 1 to 3,000 triangles, leaf sizes 1 to 16 (a one-leaf tree among them).
pub(crate) fn grid_trees() -> Vec<Bvh> {
    [(1, 3), (40, 4), (3000, 1), (3000, 4), (3000, 16)]
        .into_iter()
        .map(|(n, leaf)| Bvh::build(&grid(n), &BuildOptions::new(leaf)))
        .collect()
}

/// The corruption tests' scene: `grid(2000)` and its tree of leaves of up to 4 triangles.
pub(crate) fn grid_tree() -> (Mesh, Bvh) {
    let mesh = grid(2000);
    let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
    (mesh, bvh)
}

/// A corruption checker for `tree` (valid) and its `validate`: `expect(corrupt, what)`
/// corrupts a copy with `corrupt` and checks that `validate` refuses it, naming `what`.
pub(crate) fn refuses<'a, T: Clone>(
    tree: &'a T,
    validate: impl Fn(&T) -> Result<(), String> + 'a,
) -> impl Fn(&dyn Fn(&mut T), &str) + 'a {
    validate(tree).unwrap();
    move |corrupt: &dyn Fn(&mut T), what: &str| {
        let mut c = tree.clone();
        corrupt(&mut c);
        let e = validate(&c).expect_err(what);
        assert!(e.contains(what), "{e} should say {what}");
    }
}
