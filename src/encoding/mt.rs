//! Möller–Trumbore (T. Möller, B. Trumbore, "Fast, minimum storage ray-triangle intersection",
//! JGT 2(1), 1997), one triangle at a time (`glsl/intersect/mt.glsl`). Its layout, the vertex
//! list plus one index triple and material per slot (`glsl/mt_scene.glsl`), is also read by the
//! watertight and f64 intersectors, so comparing them with MT measures the arithmetic only.

use std::mem::{offset_of, size_of};

use bytemuck::{Pod, Zeroable};

use super::{slot_layout, BufferPlacement, Encoding, HostStruct, Intersector, SceneBuffer, SceneCounts};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_INDICES, BINDING_PRIMS};

pub const INTERSECTOR: Intersector = Intersector {
    name: "mt",
    glsl: "mt",
    title: "Moller-Trumbore",
    about: "Möller–Trumbore, one triangle at a time (vertex list + 16-byte index triple per triangle).",
    in_paper: true,
    encode,
    placement,
    prim_binding: BINDING_INDICES,
    prim_struct: LAYOUT,
};

/// [`MtTriangle`]'s layout, shared with the intersectors that read MT's data.
pub(super) const LAYOUT: HostStruct =
    HostStruct { size: size_of::<MtTriangle>(), offsets: &[offset_of!(MtTriangle, v), offset_of!(MtTriangle, material)] };

/// GLSL `MtTriangle { uvec3 v; uint material; }` (std430: 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct MtTriangle {
    pub v: [u32; 3],
    pub material: u32,
}

const _: () = assert!(std::mem::size_of::<MtTriangle>() == 16);

/// MT's buffers: the vertex list (an empty mesh still uploads one vertex) and a triangle per slot.
pub(super) fn placement(c: &SceneCounts) -> Vec<BufferPlacement> {
    vec![
        BufferPlacement::new("mt vertices", BINDING_PRIMS, Texel::Rgba32Float, c.vertices.max(1), 16),
        BufferPlacement::new("mt triangles", BINDING_INDICES, Texel::Rgba32Uint, c.slots, size_of::<MtTriangle>()),
    ]
}

pub(super) fn encode(mesh: &Mesh, bvh: &Bvh) -> Encoding {
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
    Encoding {
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
