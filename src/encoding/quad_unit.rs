//! Quad unit triangle (Shumskiy & Parshin sec. 3.1, applied to Woop's unit triangle): four
//! triangles' affine maps per quad in SoA form, the ray mapped into all four unit spaces at once
//! (`glsl/intersect/quad_unit.glsl`).

use std::mem::{offset_of, size_of};

use bytemuck::{Pod, Zeroable};

use super::unit::{unit_transform, PAD_ROWS};
use super::{quad_layout, slot_id, BufferPlacement, Encoding, HostStruct, Intersector, SceneBuffer, SceneCounts};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_PRIMS, MISS_ID};

pub const INTERSECTOR: Intersector = Intersector {
    name: "quad-unit",
    glsl: "quad_unit",
    title: "Quad Unit Triangle",
    about: "Woop's unit triangle on four at once (SoA quads, 192 B per quad).",
    in_paper: true,
    encode,
    placement,
    prim_binding: BINDING_PRIMS,
    prim_struct: HostStruct {
        size: size_of::<QuadUnit>(),
        offsets: &[
            offset_of!(QuadUnit, m0x),
            offset_of!(QuadUnit, m0y),
            offset_of!(QuadUnit, m0z),
            offset_of!(QuadUnit, n0),
            offset_of!(QuadUnit, m1x),
            offset_of!(QuadUnit, m1y),
            offset_of!(QuadUnit, m1z),
            offset_of!(QuadUnit, n1),
            offset_of!(QuadUnit, m2x),
            offset_of!(QuadUnit, m2y),
            offset_of!(QuadUnit, m2z),
            offset_of!(QuadUnit, n2),
        ],
    },
};

/// GLSL `QuadUnit`: `m{r}{x,y,z}` and `n{r}` hold entry (r, column) of [M | N] for the four
/// triangles, lane k = slot 4q + k (192 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct QuadUnit {
    pub m0x: [f32; 4],
    pub m0y: [f32; 4],
    pub m0z: [f32; 4],
    pub n0: [f32; 4],
    pub m1x: [f32; 4],
    pub m1y: [f32; 4],
    pub m1z: [f32; 4],
    pub n1: [f32; 4],
    pub m2x: [f32; 4],
    pub m2y: [f32; 4],
    pub m2z: [f32; 4],
    pub n2: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<QuadUnit>() == 192);

/// One struct per quad.
fn placement(c: &SceneCounts) -> Vec<BufferPlacement> {
    vec![BufferPlacement::new("quad unit", BINDING_PRIMS, Texel::Rgba32Float, c.quads, size_of::<QuadUnit>())]
}

fn encode(mesh: &Mesh, bvh: &Bvh) -> Encoding {
    let (nodes, quads) = quad_layout(bvh);
    let mut slot_ids = Vec::with_capacity(4 * quads.len());
    let mut unrepresentable = vec![];
    let mut out = Vec::with_capacity(quads.len());
    for q in &quads {
        let mut quad = QuadUnit::default();
        for (k, &p) in q.iter().enumerate() {
            let mut id = slot_id(p);
            let rows = match p {
                PAD_SLOT => PAD_ROWS,
                tri => {
                    let [a, b, c] = mesh.vertices_f64(tri as usize);
                    unit_transform(a, b, c).unwrap_or_else(|| {
                        unrepresentable.push(tri);
                        id = MISS_ID;
                        PAD_ROWS
                    })
                }
            };
            slot_ids.push(id);
            let cols = [
                [&mut quad.m0x, &mut quad.m0y, &mut quad.m0z, &mut quad.n0],
                [&mut quad.m1x, &mut quad.m1y, &mut quad.m1z, &mut quad.n1],
                [&mut quad.m2x, &mut quad.m2y, &mut quad.m2z, &mut quad.n2],
            ];
            for (row, lanes) in rows.iter().zip(cols) {
                for (col, lane) in lanes.into_iter().enumerate() {
                    lane[k] = row[col];
                }
            }
        }
        out.push(quad);
    }
    Encoding {
        nodes,
        slot_ids,
        prims: vec![SceneBuffer {
            name: "quad unit",
            binding: BINDING_PRIMS,
            texel: Texel::Rgba32Float,
            bytes: bytemuck::cast_slice(&out).to_vec(),
        }],
        unrepresentable,
    }
}
