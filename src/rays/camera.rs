//! Pinhole cameras: the front view a person expects (the default of `render` and `rays primary`),
//! the Embree peer's 3/4 view (every benchmark's camera, so committed measurements stay
//! comparable), or one given by eye, target, up and field of view.
//!
//! Eye and target are computed in f64 from the scene's bounds, and a camera that f32 (the ray
//! files' and the GPU's precision) cannot hold is refused with the scene's bounds in the message.

use std::fmt;
use std::str::FromStr;

use glam::{DVec3, Vec3};

use super::Ray;
use crate::error::{Error, Result};
use crate::scene::Aabb;

/// A pinhole camera, in the f32 the GPU and the ray files use.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub fov_y: f32,
}

/// The peer's view direction, from the scene towards the eye.
const PEER_FROM: [f64; 3] = [0.3, 0.25, 1.0];
/// Vertical field of view of the framing presets, degrees.
const FRAMING_FOV_DEGREES: f64 = 45.0;

impl Camera {
    /// The Embree peer's camera (`gen-primary`): looks at the box centre from direction
    /// (0.3, 0.25, 1), 45 degree vertical field of view, framing the bounding sphere, in the
    /// peer's f32 arithmetic (so primary rays are bit-identical to the committed benchmarks').
    /// Non-finite for scenes whose bounds overflow f32 arithmetic: see [`Camera::peer`].
    pub fn framing(bounds: &Aabb) -> Camera {
        let c = bounds.center();
        let radius = 0.5 * bounds.extent().length();
        let fov_y = 45f32.to_radians();
        let forward = -Vec3::new(0.3, 0.25, 1.0).normalize();
        let eye = c - forward * (radius / (fov_y / 2.0).tan() * 0.9);
        Camera::look(eye, forward, Vec3::Y, fov_y)
    }

    /// [`Camera::framing`] where its f32 arithmetic is finite, else the same camera computed in
    /// f64; refused (naming the bounds) when not even that fits in f32.
    pub fn peer(bounds: &Aabb) -> Result<Camera> {
        check_bounds(bounds)?;
        let f32_camera = Camera::framing(bounds);
        if f32_camera.is_finite() {
            return Ok(f32_camera);
        }
        let (c, radius) = sphere(bounds);
        let fov = FRAMING_FOV_DEGREES.to_radians();
        let forward = -DVec3::from_array(PEER_FROM).normalize();
        let eye = c - forward * (radius / (fov / 2.0).tan() * 0.9);
        Camera::look_f64(eye, c, DVec3::Y, fov).map_err(|e| e.for_bounds(bounds))
    }

    /// The front view (the OBJ convention: the viewer on +z looking down -z, y up): the eye on
    /// the axis through the box centre, in front of the box, far enough that the box's
    /// front face (its x and y extent) fits a 45 degree vertical field of view with a margin,
    /// for any image at least as wide as it is high.
    pub fn front(bounds: &Aabb) -> Result<Camera> {
        check_bounds(bounds)?;
        let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        let c = 0.5 * (min + max);
        let half = (0.5 * (max - min)).max(DVec3::splat(0.0));
        let fov = FRAMING_FOV_DEGREES.to_radians();
        // Half the larger of width and height, seen from the front face, with a 10 % margin.
        let mut reach = half.x.max(half.y) * 1.1 / (fov / 2.0).tan();
        if reach <= 0.0 {
            // A point, or a segment along z: back off by the depth (or one unit).
            reach = if half.z > 0.0 { 4.0 * half.z } else { 1.0 };
        }
        let eye = DVec3::new(c.x, c.y, max.z + reach);
        Camera::look_f64(eye, c, DVec3::Y, fov).map_err(|e| e.for_bounds(bounds))
    }

    /// A camera at `eye` looking along `forward` with `up` roughly up.
    pub fn look(eye: Vec3, forward: Vec3, up: Vec3, fov_y: f32) -> Camera {
        let forward = forward.normalize();
        let right = forward.cross(up).normalize();
        let up = right.cross(forward);
        Camera { eye, forward, right, up, fov_y }
    }

    /// A camera at `eye` looking at `target` with `up` roughly up, computed in f64 and refused
    /// when it is degenerate or does not fit in f32.
    pub fn look_f64(eye: DVec3, target: DVec3, up: DVec3, fov_y: f64) -> std::result::Result<Camera, CameraError> {
        if !(eye.is_finite() && target.is_finite() && up.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        if !(fov_y > 0.0 && fov_y < std::f64::consts::PI) {
            return Err(CameraError::Fov(fov_y.to_degrees()));
        }
        let forward = (target - eye).try_normalize().ok_or(CameraError::TargetIsEye)?;
        let right = forward.cross(up).try_normalize().ok_or(CameraError::UpAlongView)?;
        let up = right.cross(forward);
        let camera = Camera {
            eye: eye.as_vec3(),
            forward: forward.as_vec3(),
            right: right.as_vec3(),
            up: up.as_vec3(),
            fov_y: fov_y as f32,
        };
        if !camera.is_finite() {
            return Err(CameraError::BeyondF32(eye.to_array()));
        }
        Ok(camera)
    }

    /// Whether every component is finite (an f32 camera built from huge bounds may not be).
    pub fn is_finite(&self) -> bool {
        [self.eye, self.forward, self.right, self.up].iter().all(|v| v.is_finite()) && self.fov_y.is_finite()
    }

    /// The ray through the centre of pixel (x, y) of a w x h image (y down).
    pub fn ray(&self, x: u32, y: u32, w: u32, h: u32) -> Ray {
        let th = (self.fov_y / 2.0).tan();
        let aspect = w as f32 / h as f32;
        let px = (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * th * aspect;
        let py = (1.0 - 2.0 * (y as f32 + 0.5) / h as f32) * th;
        let d = (self.forward + self.right * px + self.up * py).normalize();
        Ray::new(self.eye.to_array(), d.to_array())
    }
}

/// Centre and radius of the bounding sphere, in f64.
fn sphere(bounds: &Aabb) -> (DVec3, f64) {
    let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
    (0.5 * (min + max), 0.5 * (max - min).max(DVec3::splat(0.0)).length())
}

/// Refuses an empty or non-finite box before any camera is placed around it.
fn check_bounds(bounds: &Aabb) -> Result<()> {
    if bounds.is_empty() || !bounds.min.is_finite() || !bounds.max.is_finite() {
        return Err(Error::Usage(format!(
            "scene bounds {}: no camera can frame an empty or non-finite box",
            show_bounds(bounds)
        )));
    }
    Ok(())
}

/// `[x, y, z] .. [x, y, z]`, in the shortest form that reads back exactly.
pub fn show_bounds(b: &Aabb) -> String {
    let v = |v: Vec3| format!("[{:e}, {:e}, {:e}]", v.x, v.y, v.z);
    format!("{} .. {}", v(b.min), v(b.max))
}

/// Why a camera cannot be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CameraError {
    #[error("eye, target and up must be finite numbers")]
    NotFinite,
    #[error("the field of view ({0} degrees) must be between 0 and 180 degrees")]
    Fov(f64),
    #[error("the target must differ from the eye")]
    TargetIsEye,
    #[error("up must not lie along the view direction")]
    UpAlongView,
    #[error("the eye would sit at {0:?}, beyond f32's range (about 3.4e38)")]
    BeyondF32([f64; 3]),
}

impl CameraError {
    /// The error for a camera framing a scene of `bounds`.
    fn for_bounds(self, bounds: &Aabb) -> Error {
        Error::Usage(format!(
            "scene bounds {}: cannot place a camera framing them: {self}; rays and images are single \
             precision, so scale or recentre the scene",
            show_bounds(bounds)
        ))
    }
}

/// Which camera: `front` (default), `peer` (the benchmarks'), or eye, target, up and fov.
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CameraSpec {
    /// [`Camera::front`].
    #[default]
    Front,
    /// [`Camera::peer`].
    Peer,
    /// Eye, target and up (x, y, z each) and the vertical field of view in degrees.
    Look { eye: [f64; 3], target: [f64; 3], up: [f64; 3], fov_y_degrees: f64 },
}

impl CameraSpec {
    /// What `--camera` accepts, for help and error texts.
    pub const HELP: &'static str = "`front` (the viewer on +z looking down -z, y up, framing the bounding box), \
        `peer` (the Embree peer's 3/4 view from (0.3, 0.25, 1) framing the bounding sphere: the camera of every \
        benchmark) or `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,fov_y_degrees`";

    /// The camera for a scene of `bounds` (the box is ignored by explicit cameras).
    pub fn camera(&self, bounds: &Aabb) -> Result<Camera> {
        match *self {
            CameraSpec::Front => Camera::front(bounds),
            CameraSpec::Peer => Camera::peer(bounds),
            CameraSpec::Look { eye, target, up, fov_y_degrees } => Camera::look_f64(
                DVec3::from_array(eye),
                DVec3::from_array(target),
                DVec3::from_array(up),
                fov_y_degrees.to_radians(),
            )
            .map_err(|e| Error::Usage(format!("--camera {self}: {e}"))),
        }
    }
}

impl FromStr for CameraSpec {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<CameraSpec, String> {
        match s.trim() {
            "front" => return Ok(CameraSpec::Front),
            "peer" => return Ok(CameraSpec::Peer),
            _ => {}
        }
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|e| format!("`{s}`: {e}; expected {}", CameraSpec::HELP))?;
        if v.len() != 10 || v.iter().any(|x| !x.is_finite()) {
            return Err(format!(
                "`{s}`: {} numbers, expected 10 finite ones (eye, target, up, fov), or a preset: {}",
                v.len(),
                CameraSpec::HELP
            ));
        }
        let spec = CameraSpec::Look {
            eye: [v[0], v[1], v[2]],
            target: [v[3], v[4], v[5]],
            up: [v[6], v[7], v[8]],
            fov_y_degrees: v[9],
        };
        // Refuse a degenerate camera here, where the option is parsed.
        if let CameraSpec::Look { eye, target, up, fov_y_degrees } = spec {
            Camera::look_f64(
                DVec3::from_array(eye),
                DVec3::from_array(target),
                DVec3::from_array(up),
                fov_y_degrees.to_radians(),
            )
            .map_err(|e| format!("`{s}`: {e}"))?;
        }
        Ok(spec)
    }
}

impl fmt::Display for CameraSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CameraSpec::Front => f.write_str("front"),
            CameraSpec::Peer => f.write_str("peer"),
            CameraSpec::Look { eye, target, up, fov_y_degrees } => {
                let v: Vec<String> =
                    eye.iter().chain(target).chain(up).chain([fov_y_degrees]).map(|x| x.to_string()).collect();
                f.write_str(&v.join(","))
            }
        }
    }
}

/// One ray per pixel of a w x h image, row by row.
pub fn primary_rays(camera: &Camera, w: u32, h: u32) -> Vec<Ray> {
    (0..h).flat_map(|y| (0..w).map(move |x| camera.ray(x, y, w, h))).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(s: f32) -> Aabb {
        Aabb { min: Vec3::splat(-s), max: Vec3::splat(s) }
    }

    #[test]
    fn primary_rays_cover_the_image_and_look_at_the_scene() {
        let b = cube(1.0);
        for cam in [Camera::framing(&b), Camera::front(&b).unwrap()] {
            let rays = primary_rays(&cam, 8, 6);
            assert_eq!(rays.len(), 48);
            // The centre pixels point (almost) at the box centre.
            let centre = Vec3::from_array(cam.ray(4, 3, 8, 6).dir);
            let to_c = (b.center() - cam.eye).normalize();
            assert!(centre.dot(to_c) > 0.99);
            // Top-left pixel is up and left of forward.
            let tl = Vec3::from_array(rays[0].dir);
            assert!(tl.dot(cam.up) > 0.0 && tl.dot(cam.right) < 0.0);
        }
    }

    #[test]
    fn front_looks_down_minus_z_with_y_up_and_frames_the_front_face() {
        let b = Aabb { min: Vec3::new(0.0, 0.0, 0.0), max: Vec3::new(1.0, 1.0, 1.0) };
        let cam = Camera::front(&b).unwrap();
        assert!((cam.forward - Vec3::NEG_Z).length() < 1e-6, "{cam:?}");
        assert!((cam.up - Vec3::Y).length() < 1e-6 && (cam.right - Vec3::X).length() < 1e-6);
        assert!(cam.eye.z > 1.0);
        // The front face's corners are inside the vertical field of view.
        let th = (cam.fov_y / 2.0).tan();
        let d = cam.eye.z - 1.0;
        assert!(0.5 / d < th && 0.5 / d > 0.8 * th, "the box fills most of the view");
    }

    #[test]
    fn peer_is_the_committed_f32_camera_and_huge_scenes_go_to_f64_or_are_refused() {
        let b = cube(1.0);
        assert_eq!(Camera::peer(&b).unwrap(), Camera::framing(&b));
        // 1e20: f32's |extent|^2 overflows, f64 frames it.
        let big = cube(1e20);
        assert!(!Camera::framing(&big).is_finite());
        for cam in [Camera::peer(&big).unwrap(), Camera::front(&big).unwrap()] {
            assert!(cam.is_finite() && cam.eye.length() > 1e20, "{cam:?}");
            assert!(primary_rays(&cam, 4, 4).iter().all(|r| r.problem().is_none()));
        }
        // 1e38: the eye itself is beyond f32.
        let huge = cube(1e38);
        for e in [Camera::peer(&huge).unwrap_err(), Camera::front(&huge).unwrap_err()] {
            let e = e.to_string();
            assert!(e.contains("scene bounds [-1e38, -1e38, -1e38] .. [1e38, 1e38, 1e38]"), "{e}");
            assert!(e.contains("beyond f32"), "{e}");
        }
        assert!(Camera::front(&Aabb::EMPTY).unwrap_err().to_string().contains("empty"));
    }

    #[test]
    fn camera_specs_parse_and_print() {
        assert_eq!("front".parse::<CameraSpec>().unwrap(), CameraSpec::Front);
        assert_eq!("peer".parse::<CameraSpec>().unwrap(), CameraSpec::Peer);
        let s: CameraSpec = "0.5,0.5,2.2,0.5,0.5,0,0,1,0,38".parse().unwrap();
        assert_eq!(s.to_string(), "0.5,0.5,2.2,0.5,0.5,0,0,1,0,38");
        let cam = s.camera(&Aabb::EMPTY).unwrap();
        assert!((cam.forward - Vec3::NEG_Z).length() < 1e-6);
        for bad in [
            "side",
            "1,2,3",
            "0,0,0,0,0,0,0,1,0,45",
            "0,0,1,0,0,0,0,0,1,45",
            "0,0,1,0,0,0,0,1,0,180",
            "0,0,1,0,0,0,0,1,0,nan",
        ] {
            assert!(bad.parse::<CameraSpec>().is_err(), "{bad}");
        }
    }
}
