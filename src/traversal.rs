//! A CPU mirror of `glsl/traversal/while_if.glsl` on the binary nodes (`glsl/layout/bvh2.glsl`) that counts work: the same while-if loop, visit order
//! (nearer child first, ties to the left) and f32 slab test, one ray at a time, plus a model of
//! SIMD lock-step: a group of `width` consecutive rays runs as many loop iterations as its
//! slowest ray, and an iteration pays for the leaf code when any lane is at a leaf (as many
//! triangle tests as the fullest such leaf) and for the inner-node code when any lane is at an
//! inner node. This is how lavapipe (8 lanes, or 4 with `LP_NATIVE_VECTOR_WIDTH=128`) and GPU
//! subgroups execute the kernels, and it says how much of a kernel's time is lanes waiting.
//!
//! Triangle tests use the f64 reference, so the counts are those of an exact kernel; f32
//! kernels differ only on rays within a few ULPs of an edge.

use glam::Vec3;
use serde::Serialize;

use crate::bvh::{Bvh, PAD_SLOT};
use crate::rays::Ray;
use crate::reference::{intersect, Ray64};
use crate::scene::Mesh;

/// Work of one ray.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RaySteps {
    /// Loop iterations at inner nodes (each reads both children).
    pub inner: u32,
    /// Loop iterations at leaves.
    pub leaves: u32,
    /// Triangles tested (padding excluded).
    pub triangles: u32,
}

impl RaySteps {
    pub fn iterations(&self) -> u32 {
        self.inner + self.leaves
    }
}

/// Per-ray means and the lock-step totals for one SIMD width.
#[derive(Clone, Debug, Serialize)]
pub struct StepStats {
    pub rays: usize,
    pub width: usize,
    /// Means per ray.
    pub inner: f64,
    pub leaves: f64,
    pub triangles: f64,
    /// Loop iterations per ray if every ray ran alone.
    pub iterations: f64,
    /// Loop iterations per ray in lock-step groups of `width` rays.
    pub simd_iterations: f64,
    /// Of those, iterations per ray that run the inner-node code / the leaf code.
    pub simd_inner: f64,
    pub simd_leaf: f64,
    /// Triangle-test slots per ray in lock-step (the fullest leaf among the lanes at a leaf).
    pub simd_triangles: f64,
    pub max_iterations: u32,
}

impl StepStats {
    /// Lock-step iterations over solo iterations: 1.0 means no lane ever waits.
    pub fn lockstep_overhead(&self) -> f64 {
        self.simd_iterations / self.iterations.max(1e-9)
    }
}

/// The state of one ray in the while-if loop.
struct Walk<'a> {
    mesh: &'a Mesh,
    bvh: &'a Bvh,
    origin: Vec3,
    inv_dir: Vec3,
    /// The conservative box test's per-ray constants, when mirroring it.
    conservative: Option<Conservative>,
    tmin: f32,
    ray: Ray64,
    /// Packed like the kernel: (first, count) of the node to visit next.
    current: Option<(u32, u32)>,
    /// Pushed nodes with their box's entry distance.
    stack: Vec<(u32, u32, f32)>,
    steps: RaySteps,
}

impl<'a> Walk<'a> {
    fn new(mesh: &'a Mesh, bvh: &'a Bvh, ray: &Ray, conservative: bool) -> Walk<'a> {
        // Same guard against zero direction components as make_trace_ray().
        let d = Vec3::from_array(ray.dir);
        let safe =
            Vec3::select(d.cmplt(Vec3::ZERO), -Vec3::ONE, Vec3::ONE) * d.abs().max(Vec3::splat(f32::MIN_POSITIVE));
        let mut w = Walk {
            mesh,
            bvh,
            origin: Vec3::from_array(ray.origin),
            inv_dir: Vec3::ONE / safe,
            conservative: None,
            tmin: ray.tmin,
            ray: Ray64::from(ray),
            current: None,
            stack: Vec::with_capacity(64),
            steps: RaySteps::default(),
        };
        let root = &bvh.nodes[0];
        if conservative {
            w.conservative = Some(Conservative::new(w.origin, w.inv_dir, root.min, root.max));
        }
        if w.hit_box(root.min, root.max).is_some() {
            w.current = Some((root.left_or_first, root.count));
        }
        w
    }

    /// hit_box() of glsl/box.glsl, against the closest hit so far.
    fn hit_box(&self, bmin: [f32; 3], bmax: [f32; 3]) -> Option<f32> {
        if let Some(c) = &self.conservative {
            return c.hit_box(bmin, bmax, self.tmin, self.ray.tmax as f32);
        }
        let t0 = (Vec3::from_array(bmin) - self.origin) * self.inv_dir;
        let t1 = (Vec3::from_array(bmax) - self.origin) * self.inv_dir;
        let tnear = t0.min(t1).max_element().max(self.tmin);
        let tfar = t0.max(t1).min_element().min(self.ray.tmax as f32) * 1.000_000_4;
        (tnear <= tfar).then_some(tnear)
    }

    /// The nearest pushed node whose entry distance is not beyond the closest hit so far (the
    /// kernel skips the others without visiting them).
    fn pop(&mut self) {
        self.current = None;
        while let Some((first, count, t)) = self.stack.pop() {
            if t <= self.ray.tmax as f32 {
                self.current = Some((first, count));
                break;
            }
        }
    }

    /// One loop iteration; returns the leaf size it tested (0 at an inner node).
    fn step(&mut self) -> u32 {
        let Some((first, count)) = self.current else { return 0 };
        if count > 0 {
            self.steps.leaves += 1;
            for &id in &self.bvh.prim_ids[first as usize..(first + count) as usize] {
                if id == PAD_SLOT {
                    continue;
                }
                self.steps.triangles += 1;
                if let Some((t, _, _)) = intersect(&self.ray, self.mesh.vertices_f64(id as usize)) {
                    self.ray.tmax = self.ray.tmax.min(t);
                }
            }
            self.pop();
            count
        } else {
            self.steps.inner += 1;
            let (l, r) = (&self.bvh.nodes[first as usize], &self.bvh.nodes[first as usize + 1]);
            match (self.hit_box(l.min, l.max), self.hit_box(r.min, r.max)) {
                (Some(tl), Some(tr)) => {
                    let (near, far, t_far) = if tl <= tr { (l, r, tr) } else { (r, l, tl) };
                    self.stack.push((far.left_or_first, far.count, t_far));
                    self.current = Some((near.left_or_first, near.count));
                }
                (Some(_), None) => self.current = Some((l.left_or_first, l.count)),
                (None, Some(_)) => self.current = Some((r.left_or_first, r.count)),
                (None, None) => self.pop(),
            }
            0
        }
    }

    fn at_leaf(&self) -> Option<u32> {
        self.current.filter(|c| c.1 > 0).map(|c| c.1)
    }
}

/// The conservative `hit_box()` of glsl/box.glsl (`CONSERVATIVE_TRAVERSAL`), step for step in f32:
/// the kernel computes these `precise` (no FMA), so the bits are the same.
struct Conservative {
    org_lo: Vec3,
    org_hi: Vec3,
    rdir_lo: Vec3,
    rdir_hi: Vec3,
}

impl Conservative {
    /// `make_conservative_ray()`: 2^-20, 1 -+ 2^-20 and 2^-22 as in the kernel.
    fn new(origin: Vec3, inv_dir: Vec3, root_min: [f32; 3], root_max: [f32; 3]) -> Conservative {
        const EPS: f32 = 1.0 / 1_048_576.0;
        let dist = (origin - Vec3::from_array(root_min)).abs().max((origin - Vec3::from_array(root_max)).abs());
        let dmax = dist.x.max(dist.y).max(dist.z);
        let err = EPS * (dist + Vec3::splat(dmax));
        let pad = err + (origin.abs() + err) * (1.0 / 4_194_304.0);
        let down = inv_dir * (1.0 - EPS);
        let up = inv_dir * (1.0 + EPS);
        let pos = inv_dir.cmpge(Vec3::ZERO);
        Conservative {
            org_lo: origin + pad,
            org_hi: origin - pad,
            rdir_lo: Vec3::select(pos, down, up),
            rdir_hi: Vec3::select(pos, up, down),
        }
    }

    fn hit_box(&self, bmin: [f32; 3], bmax: [f32; 3], tmin: f32, tfar: f32) -> Option<f32> {
        let t0 = (Vec3::from_array(bmin) - self.org_lo) * self.rdir_lo;
        let t1 = (Vec3::from_array(bmax) - self.org_hi) * self.rdir_hi;
        let tnear = t0.min(t1).max_element().max(tmin);
        let tf = t0.max(t1).min_element().min(tfar);
        (tnear <= tf).then_some(tnear)
    }
}

/// Work of each ray, traced alone (the plain box test).
pub fn ray_steps(mesh: &Mesh, bvh: &Bvh, rays: &[Ray]) -> Vec<RaySteps> {
    ray_steps_with(mesh, bvh, rays, false)
}

/// Work of each ray, traced alone, with the conservative box test when `conservative` (the
/// kernels of methods whose [`crate::encoding::Method::conservative_traversal`] is true).
pub fn ray_steps_with(mesh: &Mesh, bvh: &Bvh, rays: &[Ray], conservative: bool) -> Vec<RaySteps> {
    use rayon::prelude::*;
    rays.par_iter()
        .map(|r| {
            let mut w = Walk::new(mesh, bvh, r, conservative);
            while w.current.is_some() {
                w.step();
            }
            w.steps
        })
        .collect()
}

/// Totals of one lock-step group.
#[derive(Default)]
struct GroupTotals {
    solo: RaySteps,
    iterations: u64,
    inner: u64,
    leaf: u64,
    triangle_slots: u64,
    max_iterations: u32,
}

/// Per-ray means and lock-step totals for groups of `width` consecutive rays (closest hit).
pub fn step_stats(mesh: &Mesh, bvh: &Bvh, rays: &[Ray], width: usize) -> StepStats {
    use rayon::prelude::*;
    assert!(width > 0);
    let groups: Vec<GroupTotals> = rays
        .par_chunks(width)
        .map(|group| {
            let mut lanes: Vec<Walk> = group.iter().map(|r| Walk::new(mesh, bvh, r, false)).collect();
            let (mut iters, mut inner, mut leaf, mut tris) = (0u64, 0u64, 0u64, 0u64);
            loop {
                let active: Vec<usize> = (0..lanes.len()).filter(|&i| lanes[i].current.is_some()).collect();
                if active.is_empty() {
                    break;
                }
                iters += 1;
                let fullest = active.iter().filter_map(|&i| lanes[i].at_leaf()).max();
                if let Some(n) = fullest {
                    leaf += 1;
                    tris += n as u64;
                }
                if active.iter().any(|&i| lanes[i].at_leaf().is_none()) {
                    inner += 1;
                }
                for &i in &active {
                    lanes[i].step();
                }
            }
            let sum = lanes.iter().fold(RaySteps::default(), |a, w| RaySteps {
                inner: a.inner + w.steps.inner,
                leaves: a.leaves + w.steps.leaves,
                triangles: a.triangles + w.steps.triangles,
            });
            let max_iterations = lanes.iter().map(|w| w.steps.iterations()).max().unwrap_or(0);
            GroupTotals { solo: sum, iterations: iters, inner, leaf, triangle_slots: tris, max_iterations }
        })
        .collect();
    let n = rays.len().max(1) as f64;
    let total = |f: &dyn Fn(&GroupTotals) -> u64| groups.iter().map(f).sum::<u64>() as f64 / n;
    // Lock-step totals are per group; a group of `width` lanes advances `width` rays.
    let per_ray = |f: &dyn Fn(&GroupTotals) -> u64| groups.iter().map(|g| f(g) * width as u64).sum::<u64>() as f64 / n;
    StepStats {
        rays: rays.len(),
        width,
        inner: total(&|g| g.solo.inner as u64),
        leaves: total(&|g| g.solo.leaves as u64),
        triangles: total(&|g| g.solo.triangles as u64),
        iterations: total(&|g| g.solo.iterations() as u64),
        simd_iterations: per_ray(&|g| g.iterations),
        simd_inner: per_ray(&|g| g.inner),
        simd_leaf: per_ray(&|g| g.leaf),
        simd_triangles: per_ray(&|g| g.triangle_slots),
        max_iterations: groups.iter().map(|g| g.max_iterations).max().unwrap_or(0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildOptions;
    use crate::reference::Reference;

    /// Two far-apart unit squares (two triangles each) in z = 0 and z = 10.
    fn two_squares() -> Mesh {
        let mut pos = vec![];
        let mut tris = vec![];
        for (x, z) in [(0.0f32, 0.0f32), (100.0, 10.0)] {
            let b = pos.len() as u32;
            pos.extend([[x, 0.0, z], [x + 1.0, 0.0, z], [x + 1.0, 1.0, z], [x, 1.0, z]]);
            tris.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        }
        Mesh::from_triangles(pos, tris)
    }

    #[test]
    fn counts_on_a_hand_built_tree() {
        let mesh = two_squares();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(2));
        // Root with two leaves of two triangles each.
        assert_eq!(bvh.stats().leaves, 2);
        let hit = Ray::new([0.3, 0.2, -1.0], [0.0, 0.0, 1.0]);
        let miss_box = Ray::new([50.0, 50.0, -1.0], [0.0, 0.0, 1.0]);
        let steps = ray_steps(&mesh, &bvh, &[hit, miss_box]);
        // hit: root (inner), then the near leaf; the far leaf's box is never entered.
        assert_eq!(steps[0], RaySteps { inner: 1, leaves: 1, triangles: 2 });
        assert_eq!(steps[1], RaySteps::default());
        // Lock-step: the missing lane waits for the hitting one.
        let s = step_stats(&mesh, &bvh, &[hit, miss_box], 2);
        assert_eq!((s.iterations, s.simd_iterations, s.lockstep_overhead()), (1.0, 2.0, 2.0));
        assert_eq!((s.simd_inner, s.simd_leaf, s.simd_triangles), (1.0, 1.0, 2.0));
    }

    #[test]
    fn the_mirror_finds_the_reference_hits() {
        // The walk must visit every node the closest hit needs: its final tmax equals the
        // reference's closest t on random rays.
        let mesh =
            crate::scene::load_obj(std::path::Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj")))
                .unwrap();
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let rays = crate::rays::random_rays(&mesh.bounds(), 2000, 5);
        let reference = Reference::new(&mesh, &bvh).trace_all(&rays, false);
        for (r, h) in rays.iter().zip(&reference) {
            // Both box tests (the conservative one only ever visits more).
            for conservative in [false, true] {
                let mut w = Walk::new(&mesh, &bvh, r, conservative);
                while w.current.is_some() {
                    w.step();
                }
                if h.is_hit() {
                    assert_eq!(w.ray.tmax, h.t, "ray {r:?}");
                } else {
                    assert_eq!(w.ray.tmax, f64::INFINITY);
                }
            }
        }
        // The conservative test's boxes are larger: it never visits fewer nodes in all (a ray
        // may, when a grazed box reorders its children).
        let total = |c| ray_steps_with(&mesh, &bvh, &rays, c).iter().map(|s| s.iterations() as u64).sum::<u64>();
        assert!(total(true) >= total(false));
        let s = step_stats(&mesh, &bvh, &rays, 8);
        assert!(s.simd_iterations >= s.iterations && s.lockstep_overhead() > 1.2, "{s:?}");
    }
}
