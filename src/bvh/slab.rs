//! The slab tests of the CPU traversals: [`slab_f64`], the box test of [`WideBvh::trace`] and
//! [`CwBvh::trace`] (on the compressed tree's decoded boxes), and [`slab_ordered`], the f32 test
//! a wide kernel should use, mirrored.
//!
//! [`WideBvh::trace`]: crate::bvh::WideBvh::trace
//! [`CwBvh::trace`]: crate::bvh::CwBvh::trace

use glam::Vec3;

use super::Aabb;

/// Relative widening of the f64 box test, as the f64 reference's (`reference::Reference`):
/// rounding never culls a box the ray touches.
const BOX_SLACK: f64 = 1e-9;

/// The f64 slab test of [`WideBvh::trace`](crate::bvh::WideBvh::trace) and
/// [`CwBvh::trace`](crate::bvh::CwBvh::trace): near and far planes chosen by the direction's sign
/// (no min/max swap), intervals widened by `BOX_SLACK` (1e-9, relative) where finite. Returns the entry
/// distance, or `None` when the ray misses the box within `[tmin, tmax]`. An inverted box
/// (`min > max` on an axis) is always missed.
pub fn slab_f64(origin: [f64; 3], dir: [f64; 3], b: &Aabb, tmin: f64, tmax: f64) -> Option<f64> {
    let widen = |t: f64, s: f64| if t.is_finite() { t + s * BOX_SLACK * t.abs() } else { t };
    let (mut t0, mut t1) = (tmin, tmax);
    for k in 0..3 {
        let (lo, hi) = (b.min[k] as f64, b.max[k] as f64);
        let (o, d) = (origin[k], dir[k]);
        if d == 0.0 {
            if o < lo || o > hi {
                return None;
            }
            continue;
        }
        let (near, far) = if d > 0.0 { (lo, hi) } else { (hi, lo) };
        t0 = t0.max(widen((near - o) / d, -1.0));
        t1 = t1.min(widen((far - o) / d, 1.0));
    }
    (t0 <= t1).then_some(t0)
}

/// The f32 slab test a wide kernel should use, mirrored: `inv_dir` as `make_trace_ray()`
/// computes it (zero components replaced by ±2^-126, f32::MIN_POSITIVE, before the division), near and far planes
/// chosen by the sign of `inv_dir`. With it an empty slot's
/// [`EMPTY_BOX`](crate::bvh::wide::EMPTY_BOX) is never hit, so the
/// kernel needs no per-slot flag test (tested).
pub fn slab_ordered(origin: Vec3, inv_dir: Vec3, b: &Aabb, tmin: f32, tmax: f32) -> Option<f32> {
    let pos = inv_dir.cmpge(Vec3::ZERO);
    let near = Vec3::select(pos, b.min, b.max);
    let far = Vec3::select(pos, b.max, b.min);
    let tn = ((near - origin) * inv_dir).max_element().max(tmin);
    let tf = ((far - origin) * inv_dir).min_element().min(tmax);
    (tn <= tf).then_some(tn)
}
