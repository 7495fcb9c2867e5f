//! Ray-origin offset schemes for secondary rays, in f32 on the host, written so that a GLSL port
//! can mirror them line for line (`floatBitsToInt`/`intBitsToFloat` for the bit casts).
//!
//! Every scheme takes the hit point reconstructed in f32 from the barycentrics (as pbrt and
//! Wächter & Binder recommend: it lies on the triangle's plane up to the rounding of that sum,
//! whatever error the intersector's t has) and the unit geometric normal `n` already turned to
//! the side the new ray leaves from.

use glam::Vec3;

/// How a secondary ray's origin is moved off the surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Offset {
    /// The hit point itself.
    None,
    /// `p + FIXED_EPSILON * n`: a constant tuned for unit-sized scenes.
    FixedEpsilon,
    /// `p + SCALE_EPSILON * (max|p_i| + max edge) * n`: proportional to the coordinates.
    ScaleEpsilon,
    /// Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray Tracing
    /// Gems ch. 6 (2019): integer ULP steps along n, a float step near the origin.
    WaechterBinder,
    /// pbrt-v4's `OffsetRayOrigin` (Pharr, Jakob & Humphreys, PBR 4th ed., 6.8.6): the hit
    /// point's rounding-error bound projected on n, then rounded away from the surface.
    PbrtV4,
}

/// The scheme the data supports for this project's kernels (zero self-hits in >= 10^5 rays at
/// every scale 10^-8 .. 10^8, for every method; tests/accuracy.rs holds it to that).
pub const RECOMMENDED: Offset = Offset::PbrtV4;

/// Fixed offset along the normal, world units.
pub const FIXED_EPSILON: f32 = 1e-4;
/// Relative offset of the scale-aware scheme (about 2^-13: 128 f32 ULPs of the coordinates).
pub const SCALE_EPSILON: f32 = 1.0 / 8192.0;

/// Wächter & Binder's constants (Ray Tracing Gems, listing 6-1): below `WB_ORIGIN` in a
/// coordinate the offset is `WB_FLOAT_SCALE * n` in floats; elsewhere `WB_INT_SCALE * n` in
/// integer ULP steps.
pub const WB_ORIGIN: f32 = 1.0 / 32.0;
pub const WB_FLOAT_SCALE: f32 = 1.0 / 65536.0;
pub const WB_INT_SCALE: f32 = 256.0;

/// A hit to spawn from: the triangle's f32 vertices, the barycentrics the kernel reported and
/// the unit geometric normal on the outgoing side.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub vertices: [Vec3; 3],
    pub u: f32,
    pub v: f32,
    pub n: Vec3,
}

impl SurfacePoint {
    /// The hit point from the barycentrics in f32: `b0 v0 + b1 v1 + b2 v2`, `b0 = 1 - u - v`.
    pub fn point(&self) -> Vec3 {
        let b0 = 1.0 - self.u - self.v;
        let [v0, v1, v2] = self.vertices;
        v0 * b0 + v1 * self.u + v2 * self.v
    }

    /// pbrt-v4's bound on the error of [`Self::point`]: `gamma(7) (|b0 v0| + |b1 v1| + |b2 v2|)`
    /// per component (PBR 4th ed., 6.8.4, for the barycentric interpolation of a triangle's
    /// hit point); `gamma(n) = n eps / (1 - n eps)`, eps = 2^-24.
    pub fn error_bound(&self) -> Vec3 {
        let b0 = 1.0 - self.u - self.v;
        let [v0, v1, v2] = self.vertices;
        let sum = (v0 * b0).abs() + (v1 * self.u).abs() + (v2 * self.v).abs();
        sum * gamma(7)
    }
}

/// Higham's gamma(n) for f32, as pbrt defines it.
pub fn gamma(n: i32) -> f32 {
    let eps = f32::EPSILON * 0.5;
    (n as f32 * eps) / (1.0 - n as f32 * eps)
}

/// The next f32 above `x` (pbrt's `NextFloatUp`): +inf stays, -0 becomes +0 first.
pub fn next_float_up(x: f32) -> f32 {
    if x.is_infinite() && x > 0.0 {
        return x;
    }
    let x = if x == -0.0 { 0.0 } else { x };
    let bits = x.to_bits();
    f32::from_bits(if x >= 0.0 { bits + 1 } else { bits - 1 })
}

/// The next f32 below `x` (pbrt's `NextFloatDown`).
pub fn next_float_down(x: f32) -> f32 {
    if x.is_infinite() && x < 0.0 {
        return x;
    }
    let x = if x == 0.0 { -0.0 } else { x };
    let bits = x.to_bits();
    f32::from_bits(if x > 0.0 { bits - 1 } else { bits + 1 })
}

impl Offset {
    pub const ALL: [Offset; 5] =
        [Offset::None, Offset::FixedEpsilon, Offset::ScaleEpsilon, Offset::WaechterBinder, Offset::PbrtV4];

    pub const fn name(self) -> &'static str {
        match self {
            Offset::None => "none",
            Offset::FixedEpsilon => "fixed-epsilon",
            Offset::ScaleEpsilon => "scale-epsilon",
            Offset::WaechterBinder => "waechter-binder",
            Offset::PbrtV4 => "pbrt-v4",
        }
    }

    /// The new ray's origin.
    pub fn apply(self, s: &SurfacePoint) -> Vec3 {
        let p = s.point();
        let n = s.n;
        match self {
            Offset::None => p,
            Offset::FixedEpsilon => p + n * FIXED_EPSILON,
            Offset::ScaleEpsilon => {
                let [v0, v1, v2] = s.vertices;
                let edge = (v1 - v0).abs().max((v2 - v0).abs()).max_element();
                p + n * (SCALE_EPSILON * (p.abs().max_element() + edge))
            }
            Offset::WaechterBinder => waechter_binder(p, n),
            Offset::PbrtV4 => pbrt_v4(p, s.error_bound(), n),
        }
    }
}

/// Ray Tracing Gems listing 6-1, `offset_ray(p, n)`.
pub fn waechter_binder(p: Vec3, n: Vec3) -> Vec3 {
    let pa = p.to_array();
    let na = n.to_array();
    let mut out = [0.0f32; 3];
    for i in 0..3 {
        // `int(int_scale * n)` truncates toward zero, as the C++ conversion does.
        let of_i = (WB_INT_SCALE * na[i]) as i32;
        let bits = pa[i].to_bits() as i32;
        let p_i = f32::from_bits(bits.wrapping_add(if pa[i] < 0.0 { -of_i } else { of_i }) as u32);
        out[i] = if pa[i].abs() < WB_ORIGIN { pa[i] + WB_FLOAT_SCALE * na[i] } else { p_i };
    }
    Vec3::from_array(out)
}

/// pbrt-v4 `OffsetRayOrigin(pi, n, w)` with `n` already on w's side: `d = dot(|n|, p_error)`,
/// `p + d n`, then each offset component rounded one more float away from the surface.
pub fn pbrt_v4(p: Vec3, p_error: Vec3, n: Vec3) -> Vec3 {
    let d = n.abs().dot(p_error);
    let offset = n * d;
    let po = (p + offset).to_array();
    let off = offset.to_array();
    let mut out = [0.0f32; 3];
    for i in 0..3 {
        out[i] = if off[i] > 0.0 {
            next_float_up(po[i])
        } else if off[i] < 0.0 {
            next_float_down(po[i])
        } else {
            po[i]
        };
    }
    Vec3::from_array(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed distance of `q` from the plane of `s` (f64), in the direction of `s.n`.
    fn height(s: &SurfacePoint, q: Vec3) -> f64 {
        let [a, b, c] = s.vertices.map(|v| v.as_dvec3());
        let n = (b - a).cross(c - a).normalize();
        let n = if n.dot(s.n.as_dvec3()) < 0.0 { -n } else { n };
        (q.as_dvec3() - a).dot(n)
    }

    fn tilted(scale: f32, shift: f32) -> SurfacePoint {
        let vertices = [Vec3::new(0.1, 0.2, 0.3), Vec3::new(1.3, 0.1, 0.5), Vec3::new(0.4, 1.1, 0.9)]
            .map(|v| v * scale + Vec3::splat(shift));
        let n = (vertices[1] - vertices[0]).cross(vertices[2] - vertices[0]).normalize();
        SurfacePoint { vertices, u: 0.31, v: 0.27, n }
    }

    #[test]
    fn waechter_binder_and_pbrt_leave_the_plane_at_every_scale() {
        for k in -8..=8 {
            let scale = 10f32.powi(k);
            for (shift, what) in [(0.0, "centred"), (3.0 * scale, "shifted")] {
                let s = tilted(scale, shift);
                for scheme in [Offset::WaechterBinder, Offset::PbrtV4] {
                    let q = scheme.apply(&s);
                    assert!(q.is_finite());
                    assert!(height(&s, q) > 0.0, "{scheme:?} 1e{k} {what}: {q:?} not above the plane");
                    let flipped = SurfacePoint { n: -s.n, ..s };
                    assert!(height(&flipped, scheme.apply(&flipped)) > 0.0, "{scheme:?} 1e{k} {what}, other side");
                }
            }
        }
    }

    #[test]
    fn waechter_binder_uses_floats_near_the_origin_and_ulps_far_away() {
        let n = Vec3::new(0.0, 0.0, 1.0);
        let near = waechter_binder(Vec3::new(0.0, 0.0, 0.01), n);
        assert_eq!(near.z, 0.01 + WB_FLOAT_SCALE);
        let far = waechter_binder(Vec3::new(0.0, 0.0, 1e8), n);
        assert_eq!(far.z.to_bits() - 1e8f32.to_bits(), 256);
        let neg = waechter_binder(Vec3::new(0.0, 0.0, -1e8), n);
        assert!(neg.z > -1e8);
    }

    #[test]
    fn pbrt_error_bound_grows_with_the_coordinates() {
        let s = tilted(1.0, 1e6);
        let e = s.error_bound();
        assert!(e.min_element() > 1e6 * 7.0 * 5.9e-8 * 0.9);
        assert!((gamma(7) as f64 - 7.0 * 2f64.powi(-24) / (1.0 - 7.0 * 2f64.powi(-24))).abs() < 1e-12);
    }

    #[test]
    fn next_float_steps_by_one_ulp() {
        assert_eq!(next_float_up(1.0), 1.0 + f32::EPSILON);
        assert_eq!(next_float_down(1.0), 1.0 - f32::EPSILON / 2.0);
        assert_eq!(next_float_up(-0.0), f32::from_bits(1));
        assert_eq!(next_float_down(0.0), -f32::from_bits(1));
        assert_eq!(next_float_up(-1.0), -1.0 + f32::EPSILON / 2.0);
    }

    #[test]
    fn none_stays_on_the_surface_and_fixed_epsilon_fails_far_away() {
        let s = tilted(1.0, 0.0);
        assert!(height(&s, Offset::None.apply(&s)).abs() < 1e-6);
        // At 1e8 the fixed step is below half an ULP and is rounded away entirely.
        let far = tilted(1e3, 1e8);
        assert_eq!(Offset::FixedEpsilon.apply(&far), far.point());
    }
}
