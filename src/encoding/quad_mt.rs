//! Quad Möller–Trumbore layout: four triangles' vertices per quad in SoA form
//! (`glsl/intersect/quad_mt.glsl`; Shumskiy & Parshin sec. 3.1 and the data-layout figure).

use bytemuck::{Pod, Zeroable};

use super::{quad_layout, slot_id, EncodedScene, Method, SceneBuffer};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::Texel;
use crate::shared::BINDING_PRIMS;

/// GLSL `QuadMt`: lane k of each vec4 belongs to triangle slot 4q + k (144 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct QuadMt {
    pub v0x: [f32; 4],
    pub v0y: [f32; 4],
    pub v0z: [f32; 4],
    pub v1x: [f32; 4],
    pub v1y: [f32; 4],
    pub v1z: [f32; 4],
    pub v2x: [f32; 4],
    pub v2y: [f32; 4],
    pub v2z: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<QuadMt>() == 144);

pub(super) fn encode(mesh: &Mesh, bvh: &Bvh) -> EncodedScene {
    let (nodes, quads) = quad_layout(bvh);
    let mut slot_ids = Vec::with_capacity(4 * quads.len());
    let mut out = Vec::with_capacity(quads.len());
    for q in &quads {
        // Padding lanes put all three vertices on one point (the quad's first vertex, to keep
        // the numbers tame): both edges are exactly zero, det == 0, never hit.
        let anchor = match q[0] {
            PAD_SLOT => mesh.positions.first().copied().unwrap_or([0.0; 3]),
            id => mesh.positions[mesh.triangles[id as usize][0] as usize],
        };
        let mut quad = QuadMt::default();
        for (k, &p) in q.iter().enumerate() {
            slot_ids.push(slot_id(p));
            let [a, b, c] = match p {
                PAD_SLOT => [anchor; 3],
                id => mesh.triangles[id as usize].map(|i| mesh.positions[i as usize]),
            };
            for (axis, lanes) in [
                (a, [&mut quad.v0x, &mut quad.v0y, &mut quad.v0z]),
                (b, [&mut quad.v1x, &mut quad.v1y, &mut quad.v1z]),
                (c, [&mut quad.v2x, &mut quad.v2y, &mut quad.v2z]),
            ] {
                for (dim, lane) in lanes.into_iter().enumerate() {
                    lane[k] = axis[dim];
                }
            }
        }
        out.push(quad);
    }
    EncodedScene {
        method: Method::QuadMt,
        leaf_size: bvh.options.max_leaf_size,
        nodes,
        slot_ids,
        prims: vec![SceneBuffer {
            name: "quad mt",
            binding: BINDING_PRIMS,
            texel: Texel::Rgba32Float,
            bytes: bytemuck::cast_slice(&out).to_vec(),
        }],
        unrepresentable: vec![],
    }
}
