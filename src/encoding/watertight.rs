//! Watertight layout (`glsl/intersect/watertight.glsl`): exactly Möller–Trumbore's (the vertex
//! list plus one index triple and material per slot), so that comparing the two methods measures
//! the intersection arithmetic only.

use super::{mt, EncodedScene, Method};
use crate::bvh::Bvh;
use crate::scene::Mesh;

pub(super) fn encode(mesh: &Mesh, bvh: &Bvh) -> EncodedScene {
    EncodedScene { method: Method::Watertight, ..mt::encode(mesh, bvh) }
}
