//! Ray and hit files (docs/formats.md) and their sidecars, ray-set generators and ray-spawn
//! offsets.
//!
//! Both formats are headerless little-endian records, so the structs below are the records:
//! [`Ray`] (32 bytes) and [`Hit`] (16 bytes) are also the GPU's buffer layouts.

pub mod camera;
mod generate;
pub mod offset;
pub mod order;
pub mod sidecar;

pub use camera::{primary_rays, Camera, CameraSpec};
pub use generate::{check_rays, diffuse_rays, random_rays, random_rays_problem};
pub use sidecar::{check_sidecar, RaySidecar};

use std::path::Path;

use bytemuck::{Pod, Zeroable};

use crate::error::{Error, Result};
use crate::shared::MISS_ID;

/// `origin.xyz, tmin, direction.xyz, tmax`. Hits are reported for `tmin <= t <= tmax`; `t` is
/// in units of the direction's length (directions need not be normalised).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Ray {
    pub origin: [f32; 3],
    pub tmin: f32,
    pub dir: [f32; 3],
    pub tmax: f32,
}

const _: () = assert!(std::mem::size_of::<Ray>() == 32);

/// `t, triangle id, u, v`; a miss is `t = +inf, id = 0xFFFFFFFF`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct Hit {
    pub t: f32,
    pub id: u32,
    pub u: f32,
    pub v: f32,
}

const _: () = assert!(std::mem::size_of::<Hit>() == 16);

impl Hit {
    pub const MISS: Hit = Hit { t: f32::INFINITY, id: MISS_ID, u: 0.0, v: 0.0 };

    pub fn is_hit(&self) -> bool {
        self.id != MISS_ID
    }
}

impl Ray {
    pub fn new(origin: [f32; 3], dir: [f32; 3]) -> Ray {
        Ray { origin, tmin: 0.0, dir, tmax: f32::INFINITY }
    }

    /// Why this ray cannot be traced, if it cannot: NaN anywhere, an infinite origin or
    /// direction component, an infinite tmin, tmax = -inf, a negative tmin (the kernels' box
    /// test is conservative for t >= 0 only: a hit behind the origin would be missed silently),
    /// or a direction that is zero or whose components are all subnormal (below 2^-126: a GPU
    /// may flush them to zero, and crossing a distance of 1 would take t > 2^126, beyond what
    /// the kernels' f32 distances hold).
    pub fn problem(&self) -> Option<String> {
        let names = ["origin.x", "origin.y", "origin.z", "tmin", "direction.x", "direction.y", "direction.z", "tmax"];
        let vals: &[f32; 8] = bytemuck::cast_ref(self);
        for (name, v) in names.iter().zip(vals) {
            if v.is_nan() {
                return Some(format!("{name} is NaN"));
            }
            if v.is_infinite() && !(*name == "tmax" && *v > 0.0) {
                return Some(format!("{name} is {v}"));
            }
        }
        if self.dir == [0.0; 3] {
            return Some("direction is zero".into());
        }
        if self.tmin < 0.0 {
            return Some(format!(
                "tmin is {} < 0; the kernels trace t >= 0 only (move the origin back instead)",
                self.tmin
            ));
        }
        if self.dir.iter().all(|c| c.abs() < f32::MIN_POSITIVE) {
            return Some(format!(
                "direction {:?} is subnormal (every component below 2^-126): a GPU may flush it to zero, and \
                 t would exceed f32 before the ray moved 1 unit; scale the direction up (normalise it)",
                self.dir
            ));
        }
        None
    }
}

/// Rays whose hits are not bitwise identical (all of them when the lengths differ).
pub fn differing_hits(a: &[Hit], b: &[Hit]) -> usize {
    if a.len() != b.len() {
        return a.len().max(b.len());
    }
    a.iter().zip(b).filter(|(x, y)| bytemuck::bytes_of(*x) != bytemuck::bytes_of(*y)).count()
}

/// Reads a `.rays` file, rejecting a size that is not a multiple of 32 bytes and any ray that
/// [`Ray::problem`] rejects (the error names the ray and the field).
pub fn read_rays(path: &Path) -> Result<Vec<Ray>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_rays(path, &bytes)
}

/// [`read_rays`] on bytes already in memory (`path` names them in messages). Validates every
/// ray before allocating the result, so the allocation is the input's size and nothing more.
pub fn parse_rays(path: &Path, bytes: &[u8]) -> Result<Vec<Ray>> {
    if !bytes.len().is_multiple_of(32) {
        return Err(Error::bad_input(
            path,
            None,
            format!("size {} bytes is not a multiple of 32 (one ray = 8 f32); not a ray file?", bytes.len()),
        ));
    }
    if bytes.is_empty() {
        return Err(Error::bad_input(path, None, "holds no rays (empty file)"));
    }
    let mut rays = bytes.chunks_exact(32).map(bytemuck::pod_read_unaligned::<Ray>);
    if let Some((i, why)) = rays.by_ref().enumerate().find_map(|(i, r)| r.problem().map(|p| (i, p))) {
        return Err(Error::bad_input(path, None, format!("ray {i} (byte offset {}): {why}", i * 32)));
    }
    Ok(bytes.chunks_exact(32).map(bytemuck::pod_read_unaligned).collect())
}

/// Refuses the first ray of `path` whose direction is too short for the scene: reaching the
/// far corner of `bounds` (the scene's box) would take a distance t beyond f32's largest
/// value, which the kernels' hit distances cannot hold (a direction of 1e-40 asks for t = 1e40).
/// Names the ray and its byte offset, as [`read_rays`] does.
pub fn check_reach(path: &Path, rays: &[Ray], bounds: &crate::scene::Aabb) -> Result<()> {
    let (lo, hi) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
    let far = |r: &Ray| {
        let o = glam::DVec3::from_array(r.origin.map(f64::from));
        let d = glam::DVec3::from_array(r.dir.map(f64::from));
        ((o - lo).abs().max((o - hi).abs()).length() / d.length(), d.length())
    };
    match rays.iter().map(far).enumerate().find(|(_, (t, _))| t.is_nan() || *t > f64::from(f32::MAX)) {
        None => Ok(()),
        Some((i, (t, len))) => Err(Error::bad_input(
            path,
            None,
            format!(
                "ray {i} (byte offset {}): direction length {len:e} is too short for this scene: crossing its box \
                 takes t up to {t:e}, beyond f32 ({:e}); scale the direction up (normalise it)",
                i * 32,
                f32::MAX
            ),
        )),
    }
}

pub fn write_rays(path: &Path, rays: &[Ray]) -> Result<()> {
    crate::io::write_atomic(path, bytemuck::cast_slice(rays))
}

pub fn read_hits(path: &Path) -> Result<Vec<Hit>> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    parse_hits(path, &bytes)
}

/// [`read_hits`] on bytes already in memory (`path` names them in messages). Any 16-byte
/// record is a hit record (a NaN `t` is data to compare, not a format error).
pub fn parse_hits(path: &Path, bytes: &[u8]) -> Result<Vec<Hit>> {
    if !bytes.len().is_multiple_of(16) {
        return Err(Error::bad_input(
            path,
            None,
            format!("size {} bytes is not a multiple of 16 (one hit record)", bytes.len()),
        ));
    }
    Ok(bytes.chunks_exact(16).map(bytemuck::pod_read_unaligned).collect())
}

pub fn write_hits(path: &Path, hits: &[Hit]) -> Result<()> {
    crate::io::write_atomic(path, bytemuck::cast_slice(hits))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_layout_matches_formats_md() {
        let r = Ray { origin: [1.0, 2.0, 3.0], tmin: 4.0, dir: [5.0, 6.0, 7.0], tmax: f32::INFINITY };
        let b: &[u8] = bytemuck::bytes_of(&r);
        assert_eq!(&b[12..16], &4.0f32.to_le_bytes());
        assert_eq!(&b[16..20], &5.0f32.to_le_bytes());
        assert_eq!(&b[28..32], &f32::INFINITY.to_le_bytes());
        let h = Hit::MISS;
        let b: &[u8] = bytemuck::bytes_of(&h);
        assert_eq!(&b[0..4], &f32::INFINITY.to_le_bytes());
        assert_eq!(&b[4..8], &[0xff; 4]);
    }

    /// A direction of normal but tiny length asks for distances f32 cannot hold in a scene far
    /// enough away; the same ray is fine in a small scene near its origin.
    #[test]
    fn a_direction_too_short_for_the_scene_is_refused() {
        use crate::scene::Aabb;
        let b = |lo: f32, hi: f32| Aabb { min: glam::Vec3::splat(lo), max: glam::Vec3::splat(hi) };
        let p = Path::new("r.rays");
        let short = Ray::new([0.0; 3], [1e-35, 0.0, 0.0]);
        let ok = Ray::new([0.0; 3], [1.0, 0.0, 0.0]);
        check_reach(p, &[ok, short], &b(-1.0, 1.0)).unwrap();
        let e = check_reach(p, &[ok, short], &b(-1e4, 1e4)).unwrap_err().to_string();
        assert!(e.contains("r.rays") && e.contains("ray 1 (byte offset 32)") && e.contains("too short"), "{e}");
    }

    #[test]
    fn bad_ray_files_are_rejected_with_the_reason() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.rays");
        std::fs::write(&p, [0u8; 33]).unwrap();
        let e = read_rays(&p).unwrap_err().to_string();
        assert!(e.contains("not a multiple of 32"), "{e}");
        std::fs::write(&p, []).unwrap();
        assert!(read_rays(&p).unwrap_err().to_string().contains("no rays"));
        for (field, value, expect) in [
            (1, f32::NAN, "origin.y is NaN"),
            (4, f32::INFINITY, "direction.x is inf"),
            (3, f32::NEG_INFINITY, "tmin is -inf"),
            (7, f32::NAN, "tmax is NaN"),
            (7, f32::NEG_INFINITY, "tmax is -inf"),
        ] {
            let mut rays = vec![Ray::new([0.0; 3], [0.0, 0.0, 1.0]); 3];
            bytemuck::cast_mut::<Ray, [f32; 8]>(&mut rays[2])[field] = value;
            write_rays(&p, &rays).unwrap();
            let e = read_rays(&p).unwrap_err().to_string();
            assert!(e.contains("ray 2") && e.contains(expect), "{e}");
        }
        write_rays(&p, &[Ray::new([0.0; 3], [0.0; 3])]).unwrap();
        assert!(read_rays(&p).unwrap_err().to_string().contains("direction is zero"));
        // A negative tmin (the box test covers t >= 0 only) and a subnormal direction; -0 is 0.
        let behind = Ray { tmin: -0.5, ..Ray::new([0.0; 3], [0.0, 0.0, 1.0]) };
        write_rays(&p, &[Ray::new([0.0; 3], [1.0, 0.0, 0.0]), behind]).unwrap();
        let e = read_rays(&p).unwrap_err().to_string();
        assert!(e.contains("ray 1 (byte offset 32)") && e.contains("tmin is -0.5"), "{e}");
        write_rays(&p, &[Ray::new([0.0; 3], [1e-40, 0.0, -1e-39])]).unwrap();
        assert!(read_rays(&p).unwrap_err().to_string().contains("subnormal"));
        write_rays(&p, &[Ray { tmin: -0.0, ..Ray::new([0.0; 3], [1e-40, 1.0, 0.0]) }]).unwrap();
        assert_eq!(read_rays(&p).unwrap().len(), 1);
        // tmax = +inf is the normal case.
        write_rays(&p, &[Ray::new([0.0; 3], [0.0, 1.0, 0.0])]).unwrap();
        assert_eq!(read_rays(&p).unwrap().len(), 1);
    }
}
