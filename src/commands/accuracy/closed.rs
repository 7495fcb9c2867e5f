//! Closed meshes for leak tests: generators in f64, a closedness proof, and an f64 inside test.
//!
//! A leak needs a ray that must hit. If every undirected edge of a mesh lies in exactly two
//! triangles with opposite orientation (the triangles form a 2-cycle) and a point has winding
//! number 1 with respect to it, every ray from that point crosses the surface: the winding
//! number equals the signed count of crossings of any ray from the point. Both facts depend only
//! on the indices and on the vertices as stored (f32, widened exactly), so a mesh scaled or
//! translated in f64 and rounded to f32 keeps its proof; the origins are re-checked after
//! rounding.

use std::collections::HashMap;

use glam::DVec3;

use crate::scene::Mesh;

/// A closed, outward-oriented (counter-clockwise seen from outside) mesh in f64, with a ball
/// that lies inside it, far from its surface, by construction.
#[derive(Clone, Debug)]
pub struct ClosedMesh {
    pub name: String,
    pub positions: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Centre and radius of the inner ball (origins are drawn from it).
    pub centre: DVec3,
    pub inner_radius: f64,
}

/// An affine placement of a generated mesh: `p * scale + translate`, in f64, then rounded to f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub scale: f64,
    pub translate: DVec3,
}

impl Placement {
    pub const IDENTITY: Placement = Placement { scale: 1.0, translate: DVec3::ZERO };

    pub fn apply(&self, p: DVec3) -> DVec3 {
        p * self.scale + self.translate
    }
}

impl ClosedMesh {
    /// The mesh placed and rounded to f32 (the rounding is the only change; indices stay).
    pub fn to_mesh(&self, place: Placement) -> Mesh {
        let pos = self.positions.iter().map(|&p| place.apply(p).as_vec3().to_array()).collect();
        let mut m = Mesh::from_triangles(pos, self.triangles.clone());
        m.source = self.name.clone().into();
        m
    }
}

/// Undirected edge key.
fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// Icosahedron subdivided `levels` times, vertices on the unit sphere (Loop-style midpoint
/// split, midpoints shared through an edge table so neighbours reuse the same vertex).
pub fn icosphere(levels: u32) -> ClosedMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut pos: Vec<DVec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&p| DVec3::from_array(p).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        let mut midpoint = |a: u32, b: u32, pos: &mut Vec<DVec3>| {
            *mid.entry(key(a, b)).or_insert_with(|| {
                pos.push(((pos[a as usize] + pos[b as usize]) * 0.5).normalize());
                pos.len() as u32 - 1
            })
        };
        for [a, b, c] in tris {
            let ab = midpoint(a, b, &mut pos);
            let bc = midpoint(b, c, &mut pos);
            let ca = midpoint(c, a, &mut pos);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        tris = next;
    }
    // The coarsest icosahedron's inscribed radius is 0.79; subdivision only grows it.
    ClosedMesh {
        name: format!("icosphere-{levels}"),
        positions: pos,
        triangles: tris,
        centre: DVec3::ZERO,
        inner_radius: 0.5,
    }
}

/// A latitude-longitude sphere whose vertices are moved radially by a random factor in
/// [1 - amount, 1 + amount]. The poles are single vertices and the seam reuses the first
/// column's vertices (index-shared, so the seam is exactly shared). Star-shaped about the
/// origin, so the ball of radius (1 - amount) cos(max facet angle) is inside.
pub fn perturbed_sphere(rings: u32, segments: u32, amount: f64, seed: u64) -> ClosedMesh {
    let rings = rings.max(3);
    let segments = segments.max(3);
    let mut rng = super::rng::Rng::new(seed);
    let mut pos = vec![DVec3::Z * (1.0 + amount * rng.symmetric())];
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            let dir = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            pos.push(dir * (1.0 + amount * rng.symmetric()));
        }
    }
    pos.push(-DVec3::Z * (1.0 + amount * rng.symmetric()));
    let south = pos.len() as u32 - 1;
    let at = |i: u32, j: u32| 1 + (i - 1) * segments + (j % segments);
    let mut tris = Vec::new();
    for j in 0..segments {
        tris.push([0, at(1, j), at(1, j + 1)]);
        tris.push([south, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
            tris.push([a, c, d]);
            tris.push([a, d, b]);
        }
    }
    ClosedMesh {
        name: "perturbed-sphere".into(),
        positions: pos,
        triangles: tris,
        centre: DVec3::ZERO,
        inner_radius: 0.5 * (1.0 - amount),
    }
}

/// The cube [-1, 1]^3 with every face an n x n grid of quads (two triangles each); vertices
/// on shared cube edges are shared by index.
pub fn subdivided_cube(n: u32) -> ClosedMesh {
    let n = n.max(1);
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut pos = Vec::new();
    let mut vertex = |g: [u32; 3], pos: &mut Vec<DVec3>| {
        *index.entry(g).or_insert_with(|| {
            pos.push(DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64) * (2.0 / n as f64) - DVec3::ONE);
            pos.len() as u32 - 1
        })
    };
    let mut tris = Vec::new();
    // For each axis and side: the two in-face axes (u, v) chosen so u x v points outward.
    for axis in 0..3 {
        let (u_ax, v_ax) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [0, n] {
            for i in 0..n {
                for j in 0..n {
                    let grid = |di: u32, dj: u32| {
                        let mut g = [0; 3];
                        g[axis] = side;
                        g[u_ax] = i + di;
                        g[v_ax] = j + dj;
                        g
                    };
                    let a = vertex(grid(0, 0), &mut pos);
                    let b = vertex(grid(1, 0), &mut pos);
                    let c = vertex(grid(1, 1), &mut pos);
                    let d = vertex(grid(0, 1), &mut pos);
                    // e_u x e_v = +e_axis (cyclic order), outward on the far side.
                    if side == n {
                        tris.push([a, b, c]);
                        tris.push([a, c, d]);
                    } else {
                        tris.push([a, c, b]);
                        tris.push([a, d, c]);
                    }
                }
            }
        }
    }
    ClosedMesh { name: format!("cube-{n}"), positions: pos, triangles: tris, centre: DVec3::ZERO, inner_radius: 0.5 }
}

/// Proves a mesh closed: every undirected edge in exactly two triangles with opposite
/// orientation, i.e. every directed edge occurs exactly once and so does its reverse, and no
/// triangle repeats an index. The error says how many edges fail and names one.
pub fn prove_closed(triangles: &[[u32; 3]]) -> Result<(), String> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
    for (id, t) in triangles.iter().enumerate() {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return Err(format!("triangle {id} repeats a vertex index: {t:?}"));
        }
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    let mut bad = 0usize;
    let mut example = None;
    for (&(a, b), &n) in &directed {
        let back = directed.get(&(b, a)).copied().unwrap_or(0);
        if n != 1 || back != 1 {
            bad += 1;
            example.get_or_insert((a, b, n, back));
        }
    }
    match example {
        None => Ok(()),
        Some((a, b, n, back)) => Err(format!(
            "{bad} directed edges are not matched by exactly one opposite edge (e.g. {a}->{b}: {n} time(s), \
             {b}->{a}: {back} time(s))"
        )),
    }
}

/// Winding number of the mesh around `p` in f64: the sum of the triangles' signed solid angles
/// (Van Oosterom & Strackee, "The solid angle of a plane triangle", IEEE TBME 30(2), 1983:
/// tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (a·c)|b| + (b·c)|a|)) over 4π. 1 inside a closed
/// outward-oriented mesh, 0 outside; a point on the surface gets a value in between.
pub fn winding_number(mesh: &Mesh, p: DVec3) -> f64 {
    let mut total = 0.0;
    for id in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.vertices_f64(id).map(|v| v - p);
        let (la, lb, lc) = (a.length(), b.length(), c.length());
        let num = a.dot(b.cross(c));
        let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
        total += 2.0 * num.atan2(den);
    }
    total / (4.0 * std::f64::consts::PI)
}

/// Whether `p` is proven inside: winding number within 1e-6 of 1 (the sum's f64 rounding is
/// far below that for any point not within ~1e-10 of the surface).
pub fn proven_inside(mesh: &Mesh, p: DVec3) -> bool {
    (winding_number(mesh, p) - 1.0).abs() < 1e-6
}

/// Signed volume (positive for an outward-oriented closed mesh).
pub fn signed_volume(mesh: &Mesh) -> f64 {
    (0..mesh.triangle_count())
        .map(|id| {
            let [a, b, c] = mesh.vertices_f64(id);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Undirected edges with their two triangles `(a, b, triangle with a->b, triangle with b->a)`,
/// for a mesh that [`prove_closed`] accepted.
pub fn edge_pairs(triangles: &[[u32; 3]]) -> Vec<(u32, u32, u32, u32)> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 3);
    for (id, t) in triangles.iter().enumerate() {
        for k in 0..3 {
            directed.insert((t[k], t[(k + 1) % 3]), id as u32);
        }
    }
    let mut v: Vec<_> = directed
        .iter()
        .filter(|(&(a, b), _)| a < b)
        .filter_map(|(&(a, b), &t1)| directed.get(&(b, a)).map(|&t2| (a, b, t1, t2)))
        .collect();
    v.sort_unstable();
    v
}

/// The generators of the leak study, each proven closed (tested).
pub fn standard_meshes(fine: bool) -> Vec<ClosedMesh> {
    if fine {
        vec![perturbed_sphere(64, 128, 0.05, 11), icosphere(5), subdivided_cube(40)]
    } else {
        vec![perturbed_sphere(16, 32, 0.05, 11), icosphere(3), subdivided_cube(8)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generators_are_closed_outward_and_contain_their_ball() {
        for cm in standard_meshes(false) {
            prove_closed(&cm.triangles).unwrap_or_else(|e| panic!("{}: {e}", cm.name));
            let m = cm.to_mesh(Placement::IDENTITY);
            assert!(signed_volume(&m) > 0.0, "{} is outward", cm.name);
            assert!(m.degenerate_ids().is_empty(), "{}", cm.name);
            assert!(proven_inside(&m, cm.centre), "{}", cm.name);
            assert!(proven_inside(&m, cm.centre + DVec3::new(cm.inner_radius * 0.99, 0.0, 0.0)));
            assert!(winding_number(&m, DVec3::splat(3.0)).abs() < 1e-9, "{} outside", cm.name);
        }
    }

    #[test]
    fn the_proof_rejects_a_removed_or_flipped_face() {
        let cm = icosphere(2);
        let mut removed = cm.triangles.clone();
        removed.remove(17);
        assert!(prove_closed(&removed).is_err());
        let mut flipped = cm.triangles.clone();
        flipped[5].swap(1, 2);
        assert!(prove_closed(&flipped).is_err());
        let mut repeated = cm.triangles.clone();
        repeated.push(repeated[3]);
        assert!(prove_closed(&repeated).is_err());
        let mut degenerate = cm.triangles.clone();
        degenerate[0][1] = degenerate[0][0];
        assert!(prove_closed(&degenerate).is_err());
    }

    #[test]
    fn winding_number_sees_a_removed_face() {
        let cm = subdivided_cube(2);
        let mut m = cm.to_mesh(Placement::IDENTITY);
        assert!(proven_inside(&m, DVec3::new(0.1, -0.2, 0.3)));
        m.triangles.remove(0);
        m.material_ids.remove(0);
        assert!(!proven_inside(&m, DVec3::new(0.1, -0.2, 0.3)));
    }

    #[test]
    fn edge_pairs_cover_every_edge_once() {
        let cm = perturbed_sphere(5, 7, 0.05, 1);
        let pairs = edge_pairs(&cm.triangles);
        assert_eq!(pairs.len() * 2, cm.triangles.len() * 3);
    }
}
