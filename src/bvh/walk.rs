//! One ray's walk through a CPU traversal ([`WideBvh::trace`], [`CwBvh::trace`]), written once
//! for every layout: the ray in f64, the closest hit so far and the ray's far end cut to it, the
//! work counted ([`WideSteps`]); the box test every visit makes ([`slab_f64`] within the ray's
//! interval as cut so far) and the leaf loop. The traversals differ only in the order they visit
//! nodes and leaves in.
//!
//! The leaf loop tests a leaf's triangle slots in order through the caller's triangle test,
//! padding skipped, keeps the closest hit by the tie-break rule ([`closer`]), cuts the ray to
//! it, and with `any` ends the walk at the first hit. The kernels' loop is `glsl/leaf.glsl`'s
//! `intersect_leaf` (which breaks ties its own way: [`super::hit`]).
//!
//! [`WideBvh::trace`]: crate::bvh::WideBvh::trace
//! [`CwBvh::trace`]: crate::bvh::CwBvh::trace

use serde::Serialize;

use super::hit::{closer, WideHit};
use super::slab::slab_f64;
use super::{Aabb, PAD_SLOT};
use crate::rays::Ray;

/// Work of one ray in [`WideBvh::trace`](crate::bvh::WideBvh::trace) or
/// [`CwBvh::trace`](crate::bvh::CwBvh::trace).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct WideSteps {
    /// Wide nodes visited (each tests all its occupied children's boxes).
    pub nodes: u32,
    /// Child boxes tested (occupied slots of the visited nodes; the root box not counted).
    pub boxes: u32,
    /// Leaves visited.
    pub leaves: u32,
    /// Triangles tested (padding excluded).
    pub triangles: u32,
    /// Most stack entries held at once.
    pub stack_peak: u32,
}

/// One ray's walk (module docs).
pub(super) struct Walk {
    origin: [f64; 3],
    dir: [f64; 3],
    tmin: f64,
    /// The ray's far end: its own, then the closest hit's distance.
    pub(super) tmax: f64,
    /// Whether the first hit ends the walk.
    any: bool,
    best: WideHit,
    pub(super) steps: WideSteps,
}

impl Walk {
    /// The walk of `ray` (widened to f64), nothing hit yet; `any`: the first hit ends it.
    pub(super) fn new(ray: &Ray, any: bool) -> Walk {
        Walk {
            origin: ray.origin.map(f64::from),
            dir: ray.dir.map(f64::from),
            tmin: ray.tmin as f64,
            tmax: ray.tmax as f64,
            any,
            best: WideHit::MISS,
            steps: WideSteps::default(),
        }
    }

    /// Where the ray enters box `b` within `[tmin, tmax]` as cut so far ([`slab_f64`]); `None`
    /// when it misses it there.
    pub(super) fn enters(&self, b: &Aabb) -> Option<f64> {
        slab_f64(self.origin, self.dir, b, self.tmin, self.tmax)
    }

    /// The leaf loop over one leaf, `slots` (its range of `prim_ids`): a triangle that
    /// `intersect(id, tmax)` hits becomes the closest hit where [`closer`] says so, and `tmax`
    /// becomes its `t`. Counts the leaf and the triangles tested (padding is neither tested
    /// nor counted). Returns whether the walk is over (`any` and a hit).
    pub(super) fn leaf(
        &mut self,
        slots: &[u32],
        intersect: &mut impl FnMut(u32, f64) -> Option<(f64, f64, f64)>,
    ) -> bool {
        self.steps.leaves += 1;
        for &id in slots {
            if id == PAD_SLOT {
                continue;
            }
            self.steps.triangles += 1;
            if let Some((t, u, v)) = intersect(id, self.tmax) {
                if closer(t, id, &self.best) {
                    self.best = WideHit { t, id, u, v };
                    self.tmax = t;
                    if self.any {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// The closest hit (or the first, with `any`) and the work it took.
    pub(super) fn end(self) -> (WideHit, WideSteps) {
        (self.best, self.steps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A leaf of padding and three triangles, hit at t = 2, 1 and 1 (ids 5, 3, 7), each only
    /// where the ray still reaches.
    fn run(any: bool) -> (bool, Walk, Vec<(u32, f64)>) {
        let slots = [PAD_SLOT, 5, 3, PAD_SLOT, 7];
        let mut walk = Walk::new(&Ray { tmax: 10.0, ..Ray::new([0.0; 3], [0.0, 0.0, 1.0]) }, any);
        let mut calls = vec![];
        let mut test = |id: u32, tmax: f64| {
            calls.push((id, tmax));
            let t = if id == 5 { 2.0 } else { 1.0 };
            (t <= tmax).then_some((t, 0.5, 0.25))
        };
        let over = walk.leaf(&slots, &mut test);
        (over, walk, calls)
    }

    #[test]
    fn the_closest_hit_is_kept_and_the_ray_cut_to_it() {
        let (over, walk, calls) = run(false);
        assert!(!over);
        assert_eq!(walk.tmax, 1.0);
        // Each test sees the ray as cut by the hits before it; padding is never tested.
        assert_eq!(calls, [(5, 10.0), (3, 2.0), (7, 1.0)]);
        let (best, steps) = walk.end();
        // 3 and 7 tie at t = 1: the lower id.
        assert_eq!(best, WideHit { t: 1.0, id: 3, u: 0.5, v: 0.25 });
        assert_eq!((steps.leaves, steps.triangles), (1, 3));
    }

    #[test]
    fn any_hit_stops_at_the_first_hit() {
        let (over, walk, calls) = run(true);
        assert!(over);
        assert_eq!(calls, [(5, 10.0)]);
        let (best, steps) = walk.end();
        assert_eq!((best.id, best.t), (5, 2.0));
        assert_eq!((steps.leaves, steps.triangles), (1, 1));
    }

    /// Boxes are tested within the ray's interval as the hits cut it.
    #[test]
    fn a_box_beyond_the_closest_hit_is_missed() {
        let mut walk = Walk::new(&Ray::new([0.0; 3], [0.0, 0.0, 1.0]), false);
        let b = Aabb { min: glam::Vec3::new(-1.0, -1.0, 3.0), max: glam::Vec3::new(1.0, 1.0, 4.0) };
        assert!(walk.enters(&b).is_some_and(|t| (t - 3.0).abs() < 1e-6));
        walk.leaf(&[0], &mut |_, _| Some((2.0, 0.0, 0.0)));
        assert_eq!(walk.enters(&b), None);
    }
}
