//! The grid arithmetic of the quantized layouts (cwbvh's 8-wide nodes, qbvh4's 4-wide ones): a
//! node's grid per axis ([`axis_grid`]), a child's planes on it rounded outwards and checked in
//! the kernel's f32 decode ([`quantize_axis`], [`decode_plane`]), a node's children quantized
//! on the grid of their union ([`quantize_boxes`]), and the check that a decoded box contains a
//! true one ([`check_contains`]). The module docs of [`crate::bvh::cwbvh`] say why the check is
//! needed.

use glam::Vec3;

use crate::bvh::Aabb;

/// Largest grid coordinate.
pub const Q_MAX: u8 = 255;

/// A node's grid: origin `p` and biased exponent `e` (scale `2^(e - 127)`) per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub p: [f32; 3],
    pub e: [u8; 3],
}

/// One child's planes on its node's grid: `(q_lo, q_hi)`, per axis.
pub type Planes = ([u8; 3], [u8; 3]);

impl Grid {
    /// The box of `planes` as the kernel decodes it (without flushing).
    pub fn decode(&self, (lo, hi): Planes) -> Aabb {
        let d = |k: usize, q: u8| decode_plane(self.p[k], self.e[k], q)[0];
        Aabb {
            min: Vec3::new(d(0, lo[0]), d(1, lo[1]), d(2, lo[2])),
            max: Vec3::new(d(0, hi[0]), d(1, hi[1]), d(2, hi[2])),
        }
    }

    /// The whole grid, `p` to `p + 255 scale` per axis (f32, as the kernel would compute it).
    pub fn extent(&self) -> Aabb {
        self.decode(([0; 3], [Q_MAX; 3]))
    }
}

/// The scale `2^(e - 127)` of biased exponent `e` (1..=254), as the kernel makes it
/// (`uintBitsToFloat(e << 23)`).
pub fn scale_of(e: u8) -> f32 {
    f32::from_bits((e as u32) << 23)
}

/// A subnormal result read as a device that flushes denormals reads it (zero, same sign).
fn flushed(x: f32) -> f32 {
    if x.is_subnormal() {
        0.0f32.copysign(x)
    } else {
        x
    }
}

/// Plane `q` of a grid (origin `p`, biased exponent `e`) in the kernel's arithmetic,
/// `p + float(q) * scale` in f32, and that value flushed as a denormal-flushing device would
/// return it. A plane is conservative when both values are.
pub fn decode_plane(p: f32, e: u8, q: u8) -> [f32; 2] {
    let d = p + q as f32 * scale_of(e);
    [d, flushed(d)]
}

fn lo_ok(p: f32, e: u8, q: u8, lo: f32) -> bool {
    decode_plane(p, e, q).iter().all(|&d| d <= lo)
}

fn hi_ok(p: f32, e: u8, q: u8, hi: f32) -> bool {
    decode_plane(p, e, q).iter().all(|&d| d >= hi)
}

/// The grid of one axis of a node box `[lo, hi]`: origin `p <= lo` (never subnormal) and the
/// smallest biased exponent whose 255th step reaches `hi` in the kernel's arithmetic; `None`
/// when none does (a non-finite box).
pub fn axis_grid(lo: f32, hi: f32) -> Option<(f32, u8)> {
    if !lo.is_finite() || !hi.is_finite() || lo > hi {
        return None;
    }
    let p = if lo.is_subnormal() {
        if lo > 0.0 {
            0.0
        } else {
            -f32::MIN_POSITIVE
        }
    } else {
        lo
    };
    let extent = hi as f64 - p as f64;
    let mut e: i32 = if extent > 0.0 { (extent / Q_MAX as f64).log2().ceil() as i32 + 127 } else { 1 };
    e = e.clamp(1, 254);
    // The f64 estimate may be one short (the extent rounded, or the sum rounding down).
    while !hi_ok(p, e as u8, Q_MAX, hi) {
        if e == 254 {
            return None;
        }
        e += 1;
    }
    Some((p, e as u8))
}

/// The unchecked grid coordinates of `[lo, hi]` (floor and ceil in f64, clamped to 0..=255):
/// the first guess [`quantize_axis`] corrects.
fn quantize_guess(p: f32, e: u8, lo: f32, hi: f32) -> (u8, u8) {
    let s = scale_of(e) as f64;
    let ql = ((lo as f64 - p as f64) / s).floor().clamp(0.0, Q_MAX as f64) as u8;
    let qh = ((hi as f64 - p as f64) / s).ceil().clamp(0.0, Q_MAX as f64) as u8;
    (ql, qh)
}

/// The grid coordinates of a child's `[lo, hi]` on one axis of its parent's grid, rounded
/// outwards: the decoded planes (both [`decode_plane`] values) satisfy `q_lo -> <= lo` and
/// `q_hi -> >= hi`. `None` when the grid cannot hold the interval (it is not inside
/// `[p, p + 255 scale]`).
pub fn quantize_axis(p: f32, e: u8, lo: f32, hi: f32) -> Option<(u8, u8)> {
    if lo.partial_cmp(&hi).is_none_or(|o| o == std::cmp::Ordering::Greater) {
        return None;
    }
    let (mut ql, mut qh) = quantize_guess(p, e, lo, hi);
    while !lo_ok(p, e, ql, lo) {
        ql = ql.checked_sub(1)?;
    }
    while !hi_ok(p, e, qh, hi) {
        qh = qh.checked_add(1)?;
    }
    Some((ql, qh))
}

/// `boxes` (a node's children) quantized on the grid of their union: the grid and each box's
/// planes, rounded outwards ([`quantize_axis`]). An empty box (a padding-only leaf) gets planes
/// 0; a node of only empty boxes (an all-degenerate scene) a grid at the origin.
pub fn quantize_boxes(boxes: &[Aabb]) -> Result<(Grid, Vec<Planes>), String> {
    let mut union = Aabb::EMPTY;
    for b in boxes.iter().filter(|b| !b.is_empty()) {
        union.grow(b);
    }
    if union.is_empty() {
        union = Aabb { min: Vec3::ZERO, max: Vec3::ZERO };
    }
    let mut grid = Grid { p: [0.0; 3], e: [0; 3] };
    for k in 0..3 {
        (grid.p[k], grid.e[k]) = axis_grid(union.min[k], union.max[k])
            .ok_or_else(|| format!("a node box [{}, {}] on axis {k} has no grid", union.min[k], union.max[k]))?;
    }
    let planes = boxes
        .iter()
        .map(|b| {
            let (mut lo, mut hi) = ([0u8; 3], [0u8; 3]);
            if !b.is_empty() {
                for k in 0..3 {
                    (lo[k], hi[k]) = quantize_axis(grid.p[k], grid.e[k], b.min[k], b.max[k]).ok_or_else(|| {
                        format!("child box [{}, {}] on axis {k} does not fit its parent's grid", b.min[k], b.max[k])
                    })?;
                }
            }
            Ok((lo, hi))
        })
        .collect::<Result<_, String>>()?;
    Ok((grid, planes))
}

/// Whether the box of `planes` on `grid` (both decode variants) contains `truth`, plane by plane.
pub fn check_contains(grid: &Grid, (lo, hi): Planes, truth: &Aabb) -> Result<(), String> {
    let Grid { p, e } = grid;
    for k in 0..3 {
        if !lo_ok(p[k], e[k], lo[k], truth.min[k]) {
            return Err(format!("decoded min {:?} > {} on axis {k}", decode_plane(p[k], e[k], lo[k]), truth.min[k]));
        }
        if !hi_ok(p[k], e[k], hi[k], truth.max[k]) {
            return Err(format!("decoded max {:?} < {} on axis {k}", decode_plane(p[k], e[k], hi[k]), truth.max[k]));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_are_powers_of_two() {
        assert_eq!(scale_of(127), 1.0);
        assert_eq!(scale_of(1), f32::MIN_POSITIVE);
        assert_eq!(scale_of(128), 2.0);
        assert_eq!(scale_of(254), 2f32.powi(127));
    }
}
