//! The paper's 32-byte BVH node, shared bit for bit with `glsl/types.glsl`.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use crate::bvh::Aabb;

/// `min, left_or_first, max, count` (Shumskiy & Parshin, sec. 3: "packed in 32 byte BVH node").
/// Inner node: `count == 0`, children at `left_or_first` and `left_or_first + 1`.
/// Leaf: `count > 0` triangles starting at `left_or_first` (in the encoding's units).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BvhNode {
    pub min: [f32; 3],
    pub left_or_first: u32,
    pub max: [f32; 3],
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);
const _: () = assert!(std::mem::align_of::<BvhNode>() == 4);

impl BvhNode {
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    pub fn aabb(&self) -> Aabb {
        Aabb { min: Vec3::from_array(self.min), max: Vec3::from_array(self.max) }
    }

    pub fn set_aabb(&mut self, b: &Aabb) {
        self.min = b.min.to_array();
        self.max = b.max.to_array();
    }
}
