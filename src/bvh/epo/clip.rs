//! The geometry of the end-point overlap: boxes in f64 ([`Box64`]) and the area of the part of
//! a triangle inside a box ([`clipped_area`]: Sutherland–Hodgman clipping against the box's
//! planes, the module docs of [`super`]).

use glam::DVec3;

use crate::bvh::BvhNode;

/// An axis-aligned box in f64 (closed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box64 {
    pub min: DVec3,
    pub max: DVec3,
}

impl Box64 {
    pub(super) fn of_node(n: &BvhNode) -> Box64 {
        Box64 { min: DVec3::from(n.min.map(f64::from)), max: DVec3::from(n.max.map(f64::from)) }
    }

    pub(super) fn of_triangle(v: &[DVec3; 3]) -> Box64 {
        Box64 { min: v[0].min(v[1]).min(v[2]), max: v[0].max(v[1]).max(v[2]) }
    }

    pub(super) fn overlaps(&self, o: &Box64) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }

    pub(super) fn contains(&self, o: &Box64) -> bool {
        self.min.cmple(o.min).all() && o.max.cmple(self.max).all()
    }
}

/// Area of a triangle in f64.
pub fn triangle_area(v: &[DVec3; 3]) -> f64 {
    0.5 * (v[1] - v[0]).cross(v[2] - v[0]).length()
}

/// Most vertices a triangle clipped by six planes can have (3 + 6), rounded up.
const MAX_POLY: usize = 12;

/// A small polygon on the stack.
#[derive(Clone, Copy)]
struct Poly {
    v: [DVec3; MAX_POLY],
    n: usize,
}

impl Poly {
    /// Keeps the part where `sign * (p[axis] - bound) <= 0` (one Sutherland–Hodgman pass).
    fn clip(&self, axis: usize, bound: f64, sign: f64) -> Poly {
        let mut out = Poly { v: [DVec3::ZERO; MAX_POLY], n: 0 };
        let dist = |p: DVec3| sign * (p[axis] - bound);
        for i in 0..self.n {
            let (a, b) = (self.v[i], self.v[(i + 1) % self.n]);
            let (da, db) = (dist(a), dist(b));
            if da <= 0.0 {
                out.v[out.n] = a;
                out.n += 1;
            }
            if (da < 0.0 && db > 0.0) || (da > 0.0 && db < 0.0) {
                let mut p = a + (b - a) * (da / (da - db));
                // Exactly on the plane, whatever the rounding of the interpolation.
                p[axis] = bound;
                out.v[out.n] = p;
                out.n += 1;
            }
        }
        out
    }

    /// Area of a planar polygon: half the length of the sum of its fan's cross products.
    fn area(&self) -> f64 {
        if self.n < 3 {
            return 0.0;
        }
        let o = self.v[0];
        let mut s = DVec3::ZERO;
        for i in 1..self.n - 1 {
            s += (self.v[i] - o).cross(self.v[i + 1] - o);
        }
        0.5 * s.length()
    }
}

/// Area of the part of triangle `v` inside the closed box `b`.
pub fn clipped_area(v: &[DVec3; 3], b: &Box64) -> f64 {
    let tb = Box64::of_triangle(v);
    if !tb.overlaps(b) {
        return 0.0;
    }
    if b.contains(&tb) {
        return triangle_area(v);
    }
    let mut p = Poly { v: [DVec3::ZERO; MAX_POLY], n: 3 };
    p.v[..3].copy_from_slice(v);
    for axis in 0..3 {
        // Only the planes that cut the triangle's box.
        if tb.min[axis] < b.min[axis] {
            p = p.clip(axis, b.min[axis], -1.0);
        }
        if tb.max[axis] > b.max[axis] {
            p = p.clip(axis, b.max[axis], 1.0);
        }
        if p.n < 3 {
            return 0.0;
        }
    }
    p.area()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(min: [f64; 3], max: [f64; 3]) -> Box64 {
        Box64 { min: DVec3::from(min), max: DVec3::from(max) }
    }

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
        [DVec3::from(a), DVec3::from(b), DVec3::from(c)]
    }

    #[test]
    fn clipping_by_hand() {
        // Area 1, symmetric about x = 0: a box holding x >= 0 holds half.
        let t = tri([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        assert_eq!(triangle_area(&t), 1.0);
        assert!((clipped_area(&t, &b([0.0, -5.0, -1.0], [5.0, 5.0, 1.0])) - 0.5).abs() < 1e-15);
        assert_eq!(clipped_area(&t, &b([-5.0; 3], [5.0; 3])), 1.0);
        assert_eq!(clipped_area(&t, &b([2.0, 0.0, 0.0], [3.0, 1.0, 1.0])), 0.0);
        // Right triangle with legs 2: the unit square [0,1]^2 lies wholly inside it.
        let r = tri([0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]);
        assert!((clipped_area(&r, &b([0.0, 0.0, -1.0], [1.0, 1.0, 1.0])) - 1.0).abs() < 1e-15);
        // Above y = 1 it is the triangle (0,1), (1,1), (0,2): area 1/2.
        assert!((clipped_area(&r, &b([-1.0, 1.0, -1.0], [3.0, 3.0, 1.0])) - 0.5).abs() < 1e-15);
        // Tilted out of every axis plane: the plane x + y + z = 1 cut by the unit cube is the
        // whole triangle; cut at x <= 1/2 it loses the corner triangle scaled by 1/2 (area 1/4).
        let s = tri([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let full = 3f64.sqrt() / 2.0;
        assert!((clipped_area(&s, &b([0.0; 3], [1.0; 3])) - full).abs() < 1e-15);
        assert!((clipped_area(&s, &b([0.0; 3], [0.5, 1.0, 1.0])) - 0.75 * full).abs() < 1e-15);
        // A triangle in a box face is inside the closed box.
        assert_eq!(clipped_area(&r, &b([0.0, 0.0, 0.0], [2.0, 2.0, 5.0])), 2.0);
    }
}
