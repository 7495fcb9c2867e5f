//! The grid arithmetic of the compressed nodes: a node's grid per axis ([`axis_grid`]), a
//! child's planes on it rounded outwards and checked in the kernel's f32 decode
//! ([`quantize_axis`], [`decode_plane`]), and the check that a decoded box contains a true one
//! ([`check_contains`]). The module docs of [`super`] say why the check is needed.

use super::{CwNode, Q_MAX};
use crate::bvh::Aabb;

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

/// Whether child `s`'s decoded box (both decode variants) contains `truth`, plane by plane.
pub fn check_contains(n: &CwNode, s: usize, truth: &Aabb) -> Result<(), String> {
    let lo = [n.q_lo_x[s], n.q_lo_y[s], n.q_lo_z[s]];
    let hi = [n.q_hi_x[s], n.q_hi_y[s], n.q_hi_z[s]];
    for k in 0..3 {
        if !lo_ok(n.p[k], n.e[k], lo[k], truth.min[k]) {
            return Err(format!(
                "decoded min {:?} > {} on axis {k}",
                decode_plane(n.p[k], n.e[k], lo[k]),
                truth.min[k]
            ));
        }
        if !hi_ok(n.p[k], n.e[k], hi[k], truth.max[k]) {
            return Err(format!(
                "decoded max {:?} < {} on axis {k}",
                decode_plane(n.p[k], n.e[k], hi[k]),
                truth.max[k]
            ));
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
