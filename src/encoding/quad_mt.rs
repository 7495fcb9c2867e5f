//! Quad Möller–Trumbore (Shumskiy & Parshin sec. 3.1): the Möller–Trumbore solve for four
//! triangles at once (`glsl/intersect/quad_mt.glsl`). Layout: four triangles' vertices per quad
//! in SoA form (the paper's data-layout figure).

use std::mem::{offset_of, size_of};

use bytemuck::{Pod, Zeroable};

use super::{quad_layout, slot_id, BufferPlacement, Encoding, HostStruct, Intersector, SceneBuffer, SceneCounts};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_PRIMS};

pub const INTERSECTOR: Intersector = Intersector {
    name: "quad-mt",
    glsl: "quad_mt",
    title: "Quad Moller-Trumbore",
    about: "Möller–Trumbore on four triangles at once (SoA quads, 144 B per quad).",
    in_paper: true,
    encode,
    placement,
    prim_binding: BINDING_PRIMS,
    prim_struct: HostStruct {
        size: size_of::<QuadMt>(),
        offsets: &[
            offset_of!(QuadMt, v0x),
            offset_of!(QuadMt, v0y),
            offset_of!(QuadMt, v0z),
            offset_of!(QuadMt, v1x),
            offset_of!(QuadMt, v1y),
            offset_of!(QuadMt, v1z),
            offset_of!(QuadMt, v2x),
            offset_of!(QuadMt, v2y),
            offset_of!(QuadMt, v2z),
        ],
    },
};

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

/// One struct per quad.
fn placement(c: &SceneCounts) -> Vec<BufferPlacement> {
    vec![BufferPlacement::new("quad mt", BINDING_PRIMS, Texel::Rgba32Float, c.quads, size_of::<QuadMt>())]
}

fn encode(mesh: &Mesh, bvh: &Bvh) -> Encoding {
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
    Encoding {
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
