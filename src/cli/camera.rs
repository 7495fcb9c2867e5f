//! `--camera`, one parser for every command that places a camera (`render`, `rays primary`,
//! `rays diffuse`), so primary rays match a render.

use clap::Args;
use trilab::rays::CameraSpec;

#[derive(Args, Clone, Debug)]
pub struct CameraArg {
    /// `front` (default: the viewer on +z looking down -z, y up, framing the bounding box),
    /// `peer` (the Embree peer's 3/4 view from (0.3, 0.25, 1) framing the bounding sphere: the
    /// camera of every benchmark) or
    /// `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,fov_y_degrees`.
    #[arg(long, default_value = "front", allow_hyphen_values = true)]
    pub camera: CameraSpec,
}
