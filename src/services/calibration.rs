//! How fast this host is right now, measured without the Vulkan driver: a fixed CPU workload
//! timed in the same run as the GPU timings, so that `trilab compare` can tell a slower or busier
//! host (the calibration slows as much as the kernels) from a slower driver or kernel (the
//! calibration does not move).
//!
//! On lavapipe the "GPU" is the host CPU: a kernel's time scales with the host's speed and with
//! whatever else runs on it, and the CI gate's baseline was measured on another host. The
//! workload is shaped like what lavapipe runs, so that both scale alike: closest-hit ray casting
//! through a binary BVH over a triangle soup on a sphere (65,536 triangles, a 3 MiB working set,
//! like the bunny's 3.3 MB scene), with f32 slab tests and Möller-Trumbore (Möller and
//! Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection", JGT 1997), on every logical CPU
//! (lavapipe's threads default to the host's CPUs; rayon's pool is the same size).
//!
//! The workload is **frozen**: its scene, tree, rays and code are this file's alone (its own
//! random numbers, its own build and traversal, nothing shared with the code under test), so a
//! change elsewhere in trilab cannot move it. Changing it changes [`WORKLOAD`]; `compare` then
//! finds no calibration pair and says so. Its hit count is recorded beside its time: two runs of
//! one workload hit the same triangles.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::report::Summary;
use crate::rows::{cell, Better, Figure, Row, Source};

/// The workload's name in rows (`cell workload=...`): a new name for any change to this file's
/// scene, tree, rays or traversal.
pub const WORKLOAD: &str = "soup64k-v1";

/// The command name of calibration rows.
pub const COMMAND: &str = "calibration";

const TRIANGLES: usize = 1 << 16;
const RAYS: usize = 1 << 15;
const LEAF: usize = 4;

/// Timed passes at each calibration point.
pub const ROUNDS: usize = 5;

type V3 = [f32; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn scale(a: V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn normalize(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// PCG32 (O'Neill 2014), written out so that no crate update can change the workload.
struct Pcg(u64);

impl Pcg {
    fn next(&mut self) -> u32 {
        let old = self.0;
        self.0 = old.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f32 {
        (self.next() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
    /// Uniform on the unit sphere.
    fn sphere(&mut self) -> V3 {
        let z = 2.0 * self.unit() - 1.0;
        let phi = std::f32::consts::TAU * self.unit();
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    }
}

#[derive(Clone, Copy)]
struct Node {
    min: V3,
    max: V3,
    /// Inner: the left child (the right is `first + 1`); leaf: the first triangle.
    first: u32,
    /// Triangles in a leaf; 0 for an inner node.
    count: u32,
}

/// The scene, its tree and its rays, built once per process (a few tens of milliseconds).
pub struct Workload {
    tris: Vec<[V3; 3]>,
    nodes: Vec<Node>,
    rays: Vec<(V3, V3)>,
}

impl Default for Workload {
    fn default() -> Self {
        Workload::new()
    }
}

impl Workload {
    pub fn new() -> Workload {
        let mut rng = Pcg(0x853c_49e6_748f_ea9b);
        // Small triangles on the unit sphere, each at a jittered radius, edges about the mean
        // spacing of their centres so that neighbours overlap a little, as in a scanned mesh.
        let edge = 2.0 * (4.0 * std::f32::consts::PI / TRIANGLES as f32).sqrt();
        let mut tris: Vec<[V3; 3]> = (0..TRIANGLES)
            .map(|_| {
                let c = scale(rng.sphere(), 1.0 + 0.02 * (rng.unit() - 0.5));
                let a = add(c, scale(rng.sphere(), edge));
                let b = add(c, scale(rng.sphere(), edge));
                [c, a, b]
            })
            .collect();
        let mut nodes = vec![Node { min: [0.0; 3], max: [0.0; 3], first: 0, count: 0 }];
        build(&mut tris, &mut nodes, 0, 0, TRIANGLES);
        // Rays from a sphere of radius 3 towards points within radius 1.2: most hit, some miss.
        let rays = (0..RAYS)
            .map(|_| {
                let o = scale(rng.sphere(), 3.0);
                let target = scale(rng.sphere(), 1.2 * rng.unit());
                (o, normalize(sub(target, o)))
            })
            .collect();
        Workload { tris, nodes, rays }
    }

    /// One pass over every ray on every logical CPU: the rays that hit, and the sum of the
    /// triangles they hit (equal in every run of the workload).
    pub fn pass(&self) -> (u64, u64) {
        self.rays
            .par_chunks(256)
            .map(|chunk| {
                chunk.iter().fold((0u64, 0u64), |(n, s), &(o, d)| match self.trace(o, d) {
                    Some(id) => (n + 1, s + id as u64),
                    None => (n, s),
                })
            })
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// The closest triangle along the ray, nearer child first.
    fn trace(&self, o: V3, d: V3) -> Option<u32> {
        let inv = [1.0 / d[0], 1.0 / d[1], 1.0 / d[2]];
        let mut best = (f32::INFINITY, None);
        let mut stack = [0u32; 64];
        let mut sp = 0;
        let mut i = 0u32;
        loop {
            let n = &self.nodes[i as usize];
            if n.count > 0 {
                for id in n.first..n.first + n.count {
                    if let Some(t) = intersect(o, d, &self.tris[id as usize], best.0) {
                        best = (t, Some(id));
                    }
                }
            } else {
                let (l, r) = (n.first, n.first + 1);
                let tl = slab(o, inv, &self.nodes[l as usize], best.0);
                let tr = slab(o, inv, &self.nodes[r as usize], best.0);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (l, r) } else { (r, l) };
                        stack[sp] = far;
                        sp += 1;
                        i = near;
                        continue;
                    }
                    (Some(_), None) => {
                        i = l;
                        continue;
                    }
                    (None, Some(_)) => {
                        i = r;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                return best.1;
            }
            sp -= 1;
            i = stack[sp];
        }
    }

    /// The closest triangle by testing every one: the tree's answer must equal it.
    #[cfg(test)]
    fn brute_force(&self, o: V3, d: V3) -> Option<u32> {
        let mut best = (f32::INFINITY, None);
        for (id, tri) in self.tris.iter().enumerate() {
            if let Some(t) = intersect(o, d, tri, best.0) {
                best = (t, Some(id as u32));
            }
        }
        best.1
    }
}

/// Entry distance into the node's box, where the ray enters it before `tmax`.
fn slab(o: V3, inv: V3, n: &Node, tmax: f32) -> Option<f32> {
    let (mut t0, mut t1) = (0.0f32, tmax);
    for k in 0..3 {
        let a = (n.min[k] - o[k]) * inv[k];
        let b = (n.max[k] - o[k]) * inv[k];
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some(t0)
}

/// Möller-Trumbore (JGT 1997): the hit distance in (0, tmax), both sides.
fn intersect(o: V3, d: V3, [a, b, c]: &[V3; 3], tmax: f32) -> Option<f32> {
    let (e1, e2) = (sub(*b, *a), sub(*c, *a));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(o, *a);
    let u = dot(s, p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = dot(e2, q) * inv;
    (t > 0.0 && t < tmax).then_some(t)
}

/// Builds the subtree of `tris[lo..hi]` into `nodes[at]`: median split on the longest axis of
/// the centroids' box, `LEAF` triangles or fewer per leaf, children allocated in pairs.
fn build(tris: &mut [[V3; 3]], nodes: &mut Vec<Node>, at: usize, lo: usize, hi: usize) {
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let (mut cmin, mut cmax) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for t in &tris[lo..hi] {
        for k in 0..3 {
            let c = (t[0][k] + t[1][k] + t[2][k]) / 3.0;
            cmin[k] = cmin[k].min(c);
            cmax[k] = cmax[k].max(c);
            for v in t {
                min[k] = min[k].min(v[k]);
                max[k] = max[k].max(v[k]);
            }
        }
    }
    if hi - lo <= LEAF {
        nodes[at] = Node { min, max, first: lo as u32, count: (hi - lo) as u32 };
        return;
    }
    let ext = sub(cmax, cmin);
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let mid = (lo + hi) / 2;
    let key = |t: &[V3; 3]| t[0][axis] + t[1][axis] + t[2][axis];
    tris[lo..hi].select_nth_unstable_by(mid - lo, |a, b| key(a).total_cmp(&key(b)));
    let left = nodes.len();
    nodes.push(Node { min, max, first: 0, count: 0 });
    nodes.push(Node { min, max, first: 0, count: 0 });
    nodes[at] = Node { min, max, first: left as u32, count: 0 };
    build(tris, nodes, left, lo, mid);
    build(tris, nodes, left + 1, mid, hi);
}

/// One calibration point: [`ROUNDS`] timed passes after one untimed pass.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    pub rounds_ms: Vec<f64>,
    pub hits: u64,
    pub checksum: u64,
    /// The one-minute load average after it.
    pub load_1m: Option<f64>,
}

impl Workload {
    /// Times one calibration point.
    pub fn measure(&self) -> Point {
        let (hits, checksum) = self.pass();
        let rounds_ms = (0..ROUNDS)
            .map(|_| {
                let t = Instant::now();
                std::hint::black_box(self.pass());
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        Point { rounds_ms, hits, checksum, load_1m: crate::host::load_1m() }
    }
}

/// A calibration cell: the command whose timings a calibration row calibrates, and the workload
/// that measured the host (what `trilab compare` sets against the other side's).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CalibrationCell {
    pub command: String,
    pub workload: String,
}

impl CalibrationCell {
    /// This file's workload ([`WORKLOAD`]) calibrating `command`.
    pub fn of(command: &str) -> CalibrationCell {
        CalibrationCell { command: command.into(), workload: WORKLOAD.into() }
    }

    /// The cell's coordinates, as `rows.jsonl` names them.
    pub fn coordinates(&self) -> crate::rows::Cell {
        cell([("command", &self.command), ("workload", &self.workload)])
    }
}

impl TryFrom<&crate::rows::Cell> for CalibrationCell {
    /// The coordinate the cell lacks, naming the cell.
    type Error = String;

    /// Reads [`CalibrationCell::coordinates`] back; a cell naming no workload reads as the empty
    /// name, which only another such cell shares.
    fn try_from(c: &crate::rows::Cell) -> std::result::Result<CalibrationCell, String> {
        let command = c.get("command").cloned().ok_or_else(|| {
            format!("{COMMAND} cell `{}` has no `command` coordinate", crate::rows::cell_key(COMMAND, c))
        })?;
        Ok(CalibrationCell { command, workload: c.get("workload").cloned().unwrap_or_default() })
    }
}

/// The calibration of one command's timings: the points measured just before and just after it,
/// pooled (the host's speed while it ran, load included).
pub fn row(command: &str, before: &Point, after: &Point, source: &Source) -> Row {
    let rounds: Vec<f64> = before.rounds_ms.iter().chain(&after.rounds_ms).copied().collect();
    let summary = Summary::of(&rounds).expect("a calibration point has rounds");
    Row::new(COMMAND, CalibrationCell::of(command).coordinates(), source)
        .with("cpu_ms", Figure::timing(summary, "ms", Better::Lower))
        .with("hits", Figure::count(before.hits as f64, "rays"))
        .with("checksum", Figure::count(before.checksum as f64, "sum of ids"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_tree_finds_what_testing_every_triangle_finds() {
        let w = Workload::new();
        // Every 64th ray against all 65,536 triangles.
        let mut hits = 0;
        for &(o, d) in w.rays.iter().step_by(64) {
            let expected = w.brute_force(o, d);
            assert_eq!(w.trace(o, d), expected, "ray from {o:?} along {d:?}");
            hits += usize::from(expected.is_some());
        }
        // Most rays aim inside the sphere of triangles; a few pass between them or miss.
        let tested = w.rays.len() / 64;
        assert!(hits > tested / 2 && hits < tested, "{hits} of {tested} rays hit");
    }

    #[test]
    fn the_workload_is_the_same_in_every_process() {
        let (a, b) = (Workload::new(), Workload::new());
        assert_eq!(a.pass(), b.pass());
        let p = a.measure();
        assert_eq!((p.hits, p.checksum), a.pass());
        assert_eq!(p.rounds_ms.len(), ROUNDS);
        assert!(p.rounds_ms.iter().all(|&t| t > 0.0));
        let s = Source::default();
        let r = row("bench", &p, &p, &s);
        assert_eq!(r.figures["cpu_ms"].runs, 2 * ROUNDS);
        assert_eq!(r.cell["workload"], WORKLOAD);
    }

    #[test]
    fn a_calibration_cell_is_read_back_from_the_coordinates_it_writes() {
        let want = cell([("command", "bench"), ("workload", "soup64k-v1")]);
        assert_eq!(CalibrationCell::of("bench").coordinates(), want);
        let read = CalibrationCell::try_from(&want).unwrap();
        assert_eq!((read.command.as_str(), read.workload.as_str()), ("bench", "soup64k-v1"));
        assert_eq!(read.coordinates(), want);
        // A cell naming no workload: the empty name.
        let bare = CalibrationCell::try_from(&cell([("command", "study")])).unwrap();
        assert_eq!(bare.workload, "");
        let e = CalibrationCell::try_from(&cell([("workload", "soup64k-v1")])).unwrap_err();
        assert!(e.contains("has no `command` coordinate") && e.contains("calibration workload=soup64k-v1"), "{e}");
    }
}
