//! Ray and scene generators of the accuracy study. Everything is built in f64 and rounded to
//! f32 once, at the end; the f64 reference then judges the rounded rays on the rounded scene.

use glam::{DMat3, DVec3, Vec3};

use super::closed::{edge_pairs, proven_inside, ClosedMesh, Placement};
use crate::rays::Ray;
use crate::scene::Mesh;

pub use super::rng::Rng;

/// A ray from f64 origin and direction, rounded to f32 once.
pub fn ray64(origin: DVec3, dir: DVec3) -> Ray {
    Ray::new(origin.as_vec3().to_array(), dir.as_vec3().to_array())
}

/// Origins drawn from the closed mesh's inner ball (placed, rounded to f32), kept only when the
/// f64 winding number on the rounded mesh proves them inside. Returns the origins and how many
/// candidates were rejected.
pub fn inside_origins(cm: &ClosedMesh, mesh: &Mesh, place: Placement, n: usize, rng: &mut Rng) -> (Vec<Vec3>, usize) {
    let mut out = Vec::with_capacity(n);
    let mut rejected = 0;
    for _ in 0..n * 4 {
        if out.len() == n {
            break;
        }
        let p = place.apply(cm.centre + rng.in_ball() * cm.inner_radius).as_vec3();
        if proven_inside(mesh, p.as_dvec3()) {
            out.push(p);
        } else {
            rejected += 1;
        }
    }
    (out, rejected)
}

/// The kinds of leak ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LeakKind {
    /// Towards uniformly random directions.
    Random,
    /// Aimed at a random vertex (f32 vertex minus origin, in f64, rounded once).
    Vertex,
    /// Aimed at an f32 point on a random shared edge.
    Edge,
}

impl LeakKind {
    pub const ALL: [LeakKind; 3] = [LeakKind::Random, LeakKind::Vertex, LeakKind::Edge];

    pub fn name(self) -> &'static str {
        match self {
            LeakKind::Random => "random",
            LeakKind::Vertex => "vertex",
            LeakKind::Edge => "edge",
        }
    }
}

/// `n` rays of one kind from the proven-inside `origins`: every one must hit the closed mesh.
pub fn leak_rays(mesh: &Mesh, origins: &[Vec3], kind: LeakKind, n: usize, rng: &mut Rng) -> Vec<Ray> {
    if origins.is_empty() {
        return vec![];
    }
    let edges: Vec<[u32; 2]> = if kind == LeakKind::Edge {
        edge_pairs(&mesh.triangles).iter().map(|&(a, b, _, _)| [a, b]).collect()
    } else {
        vec![]
    };
    let mut rays = Vec::with_capacity(n);
    while rays.len() < n {
        let o = origins[rng.below(origins.len())];
        let target: DVec3 = match kind {
            LeakKind::Random => o.as_dvec3() + rng.direction(),
            LeakKind::Vertex => Vec3::from_array(mesh.positions[rng.below(mesh.positions.len())]).as_dvec3(),
            LeakKind::Edge => {
                let [a, b] = edges[rng.below(edges.len())];
                let (a, b) =
                    (Vec3::from_array(mesh.positions[a as usize]), Vec3::from_array(mesh.positions[b as usize]));
                // The point on the edge in f32, as a kernel would compute it.
                (a + (b - a) * rng.unit() as f32).as_dvec3()
            }
        };
        let d = target - o.as_dvec3();
        if d.as_vec3() == Vec3::ZERO || !d.is_finite() {
            continue;
        }
        rays.push(Ray::new(o.to_array(), d.as_vec3().to_array()));
    }
    rays
}

/// Rays aimed just outside silhouette edges of a closed mesh seen from `eye`: for each chosen
/// silhouette edge (one adjacent triangle faces the eye, the other faces away), a point on it is
/// moved by `d` x the edge length, perpendicular to the edge and to the line of sight, away from
/// the front triangle (both triangles lie on that side as seen from the eye). Returned rays start at the eye; the caller keeps those the f64
/// reference says miss.
pub fn silhouette_rays(mesh: &Mesh, eye: DVec3, d: f64, n: usize, rng: &mut Rng) -> Vec<Ray> {
    let normal = |t: u32| {
        let [a, b, c] = mesh.vertices_f64(t as usize);
        (b - a).cross(c - a)
    };
    let facing = |t: u32| {
        let [a, _, _] = mesh.vertices_f64(t as usize);
        normal(t).dot(eye - a)
    };
    let silhouettes: Vec<(u32, u32, u32)> = edge_pairs(&mesh.triangles)
        .into_iter()
        .filter_map(|(a, b, t1, t2)| {
            let (f1, f2) = (facing(t1), facing(t2));
            if f1 > 0.0 && f2 < 0.0 {
                Some((a, b, t1))
            } else if f2 > 0.0 && f1 < 0.0 {
                Some((a, b, t2))
            } else {
                None
            }
        })
        .collect();
    if silhouettes.is_empty() {
        return vec![];
    }
    let origin = eye.as_vec3().as_dvec3();
    (0..n)
        .map(|_| {
            let (a, b, front) = silhouettes[rng.below(silhouettes.len())];
            let tri = mesh.triangles[front as usize];
            let third = *tri.iter().find(|&&v| v != a && v != b).expect("a triangle has three distinct vertices");
            let pa = Vec3::from_array(mesh.positions[a as usize]).as_dvec3();
            let pb = Vec3::from_array(mesh.positions[b as usize]).as_dvec3();
            let pc = Vec3::from_array(mesh.positions[third as usize]).as_dvec3();
            let e = pb - pa;
            let m = pa + e * (0.2 + 0.6 * rng.unit());
            // Perpendicular to the edge and to the line of sight, away from the front triangle:
            // the ray passes d x |e| from the edge's line, measured across the ray. (An offset in
            // the front triangle's plane would shrink to d |e| sin(angle) for the nearly edge-on
            // triangles that silhouettes have.)
            let w = e.cross(m - eye).normalize();
            let w = if w.dot(pc - m) > 0.0 { -w } else { w };
            let target = m + w * (d * e.length());
            ray64(origin, target - origin)
        })
        .collect()
}

/// An `n` x `n` grid of quads (two triangles each) spanning [-1, 1]^2 in z = 0, rotated by
/// `rot` and scaled by `scale` in f64, rounded to f32. Vertices are shared by index.
pub fn grid(n: u32, rot: DMat3, scale: f64) -> Mesh {
    let mut pos = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let p = DVec3::new(2.0 * i as f64 / n as f64 - 1.0, 2.0 * j as f64 / n as f64 - 1.0, 0.0);
            pos.push((rot * p * scale).as_vec3().to_array());
        }
    }
    let at = |i: u32, j: u32| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            tris.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            tris.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    Mesh::from_triangles(pos, tris)
}

/// A strip of `count` slivers covering [0, 1] x [0, count * height] (long edge 1, aspect ratio
/// 1 / height), rotated by `rot`. Vertices are shared by index, so the strip has no gaps.
pub fn sliver_strip(count: u32, height: f64, rot: DMat3) -> Mesh {
    let mut pos = Vec::new();
    for i in 0..=count {
        for x in [0.0, 1.0] {
            pos.push((rot * DVec3::new(x, i as f64 * height, 0.0)).as_vec3().to_array());
        }
    }
    let mut tris = Vec::new();
    for i in 0..count {
        let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
        tris.push([a, b, d]);
        tris.push([a, d, c]);
    }
    Mesh::from_triangles(pos, tris)
}

/// Rays at `angle` radians to the plane through `rot`'s first two columns, aimed at random
/// points of the square [-0.8, 0.8]^2 x `scale` of that plane from distance `scale`.
pub fn grazing_rays(rot: DMat3, scale: f64, angle: f64, n: usize, rng: &mut Rng) -> Vec<Ray> {
    (0..n)
        .map(|_| {
            let target = rot * DVec3::new(0.8 * rng.symmetric(), 0.8 * rng.symmetric(), 0.0) * scale;
            let phi = std::f64::consts::TAU * rng.unit();
            let local = DVec3::new(angle.cos() * phi.cos(), angle.cos() * phi.sin(), -angle.sin());
            let dir = rot * local;
            ray64(target - dir * scale, dir)
        })
        .collect()
}

/// Rays nearly perpendicular to the plane of `rot` aimed at random points of the rectangle
/// [0, width] x [0, height] of that plane.
pub fn plane_rays(rot: DMat3, width: f64, height: f64, n: usize, rng: &mut Rng) -> Vec<Ray> {
    (0..n)
        .map(|_| {
            let target = rot * DVec3::new(width * rng.unit(), height * rng.unit(), 0.0);
            let local = DVec3::new(0.2 * rng.symmetric(), 0.2 * rng.symmetric(), -1.0).normalize();
            let dir = rot * local;
            let dist = width.max(height);
            ray64(target - dir * dist, dir)
        })
        .collect()
}

/// A grid with zero-area triangles mixed in: collinear (a vertex at the midpoint of the other
/// two), repeated indices, and distinct indices at equal positions. Returns the mesh and the ids
/// of the degenerate triangles, and rays aimed at points of the degenerate ones.
pub fn degenerate_scene(n_rays: usize, rng: &mut Rng) -> (Mesh, Vec<u32>, Vec<Ray>) {
    let mut mesh = grid(8, rng.rotation(), 1.0);
    let base = mesh.triangle_count() as u32;
    let mut degenerate_points = Vec::new();
    let np = mesh.positions.len() as u32;
    for k in 0..24u32 {
        let a = (k * 7) % np;
        let b = (k * 13 + 5) % np;
        // Near grid vertices, on a 2^-10 lattice (so sums and midpoints are exact in f32), lifted
        // off the grid's plane so a ray can reach them without touching the grid first.
        let snap = |p: [f32; 3]| (Vec3::from_array(p) * 1024.0).round() / 1024.0;
        let lift = Vec3::new(0.0, 0.0, (k as f32 + 1.0) / 128.0);
        let (qa, qb) = (snap(mesh.positions[a as usize]) + lift, snap(mesh.positions[b as usize]) + lift);
        let i = mesh.positions.len() as u32;
        match k % 3 {
            0 => {
                // Collinear: the midpoint, exact on the lattice.
                let mid = (qa + qb) * 0.5;
                mesh.positions.extend([qa.to_array(), qb.to_array(), mid.to_array()]);
                mesh.triangles.push([i, i + 1, i + 2]);
            }
            1 => {
                mesh.positions.extend([qa.to_array(), qb.to_array()]);
                mesh.triangles.push([i, i, i + 1]);
            }
            _ => {
                mesh.positions.extend([qa.to_array(), qa.to_array(), qb.to_array()]);
                mesh.triangles.push([i, i + 1, i + 2]);
            }
        }
        mesh.material_ids.push(0);
        degenerate_points.push((qa, qb));
    }
    let ids: Vec<u32> = (base..mesh.triangle_count() as u32).filter(|&id| mesh.is_degenerate(id as usize)).collect();
    let rays = (0..n_rays)
        .map(|_| {
            let (a, b) = degenerate_points[rng.below(degenerate_points.len())];
            let target = (a + (b - a) * rng.unit() as f32).as_dvec3();
            let origin = target + rng.direction() * 2.0;
            ray64(origin, target - origin)
        })
        .collect();
    (mesh, ids, rays)
}

#[cfg(test)]
mod tests {
    use super::super::closed::{icosphere, subdivided_cube};
    use super::*;

    #[test]
    fn origins_are_inside_and_leak_rays_are_finite() {
        let cm = subdivided_cube(3);
        let mesh = cm.to_mesh(Placement { scale: 1e3, translate: DVec3::splat(5.0) });
        let mut rng = Rng::new(1);
        let (o, rejected) =
            inside_origins(&cm, &mesh, Placement { scale: 1e3, translate: DVec3::splat(5.0) }, 8, &mut rng);
        assert_eq!((o.len(), rejected), (8, 0));
        for kind in LeakKind::ALL {
            let rays = leak_rays(&mesh, &o, kind, 50, &mut rng);
            assert_eq!(rays.len(), 50);
            assert!(rays.iter().all(|r| r.problem().is_none()), "{kind:?}");
        }
    }

    #[test]
    fn silhouette_rays_start_at_the_eye() {
        let mesh = icosphere(2).to_mesh(Placement::IDENTITY);
        let rays = silhouette_rays(&mesh, DVec3::new(3.0, 2.0, 4.0), 1e-3, 20, &mut Rng::new(3));
        assert_eq!(rays.len(), 20);
        assert!(rays.iter().all(|r| r.origin == [3.0, 2.0, 4.0]));
    }

    #[test]
    fn degenerate_scene_marks_every_added_triangle() {
        let (mesh, ids, rays) = degenerate_scene(10, &mut Rng::new(2));
        assert_eq!(ids.len(), 24, "every added triangle has zero area");
        assert_eq!(rays.len(), 10);
        assert!(mesh.degenerate_ids().len() == 24);
    }
}
