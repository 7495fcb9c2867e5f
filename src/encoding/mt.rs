//! Möller–Trumbore layout: the vertex list plus one index triple and material per slot
//! (`glsl/intersect/mt.glsl`).

use bytemuck::{Pod, Zeroable};

use super::{slot_layout, EncodedScene, Method, SceneBuffer};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::Texel;
use crate::shared::{BINDING_INDICES, BINDING_PRIMS};

/// GLSL `MtTriangle { uvec3 v; uint material; }` (std430: 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MtTriangle {
    pub v: [u32; 3],
    pub material: u32,
}

const _: () = assert!(std::mem::size_of::<MtTriangle>() == 16);

pub(super) fn encode(mesh: &Mesh, bvh: &Bvh) -> EncodedScene {
    let (nodes, slot_ids) = slot_layout(bvh);
    let mut vertices: Vec<[f32; 4]> = mesh.positions.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
    if vertices.is_empty() {
        vertices.push([0.0, 0.0, 0.0, 1.0]);
    }
    // A padding slot repeats vertex 0: both edges are exactly zero, so det == 0 rejects it.
    let triangles: Vec<MtTriangle> = bvh
        .prim_ids
        .iter()
        .map(|&p| match p {
            PAD_SLOT => MtTriangle { v: [0; 3], material: 0 },
            id => MtTriangle { v: mesh.triangles[id as usize], material: mesh.material_ids[id as usize] },
        })
        .collect();
    EncodedScene {
        method: Method::Mt,
        leaf_size: bvh.options.max_leaf_size,
        nodes,
        slot_ids,
        prims: vec![
            SceneBuffer {
                name: "mt vertices",
                binding: BINDING_PRIMS,
                texel: Texel::Rgba32Float,
                bytes: bytemuck::cast_slice(&vertices).to_vec(),
            },
            SceneBuffer {
                name: "mt triangles",
                binding: BINDING_INDICES,
                texel: Texel::Rgba32Uint,
                bytes: bytemuck::cast_slice(&triangles).to_vec(),
            },
        ],
        unrepresentable: vec![],
    }
}
