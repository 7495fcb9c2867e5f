//! Woop's unit triangle (S. Woop, J. Schmittler, P. Slusallek, "RPU: A Programmable Ray
//! Processing Unit for Realtime Ray Tracing", SIGGRAPH 2005), one triangle at a time
//! (`glsl/intersect/unit.glsl`). Layout: per slot, the affine map from world space to the space
//! where the triangle is (0,0,0), (1,0,0), (0,1,0).

use std::mem::{offset_of, size_of};

use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use super::{slot_layout, BufferPlacement, Encoding, HostStruct, Intersector, SceneBuffer, SceneCounts};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_PRIMS};

pub const INTERSECTOR: Intersector = Intersector {
    name: "unit",
    glsl: "unit",
    title: "Unit Triangle",
    about: "Woop's unit triangle, one at a time (48-byte affine map per triangle).",
    in_paper: true,
    encode,
    placement,
    prim_binding: BINDING_PRIMS,
    prim_struct: HostStruct {
        size: size_of::<UnitTriangle>(),
        offsets: &[offset_of!(UnitTriangle, row0), offset_of!(UnitTriangle, row1), offset_of!(UnitTriangle, row2)],
    },
};

/// GLSL `UnitTriangle { vec4 row0, row1, row2; }`: rows of [M | N] (48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct UnitTriangle {
    pub row0: [f32; 4],
    pub row1: [f32; 4],
    pub row2: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<UnitTriangle>() == 48);

/// Rows of a padding triangle: D'z is exactly zero for every ray (rejected by `dz != 0`),
/// and u = -1 besides.
pub(super) const PAD_ROWS: [[f32; 4]; 3] = [[0.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, -1.0], [0.0, 0.0, 0.0, 1.0]];

/// The rows of T(x) = M x + N taking triangle (a, b, c) to the unit triangle, computed in f64
/// (Woop 2004): with e1 = b - a, e2 = c - a, n = e1 x e2, M = [e1 e2 n]^-1, whose rows are
/// (e2 x n, n x e1, n) / |n|^2, and N = -M a. Then u = row0 . (p,1), v = row1 . (p,1) are the
/// barycentric weights of b and c, and row2 . (p,1) is the signed distance from the plane in
/// units of 1/|n|. `None` for a zero-area triangle or when a row overflows f32.
pub fn unit_transform(a: DVec3, b: DVec3, c: DVec3) -> Option<[[f32; 4]; 3]> {
    let e1 = b - a;
    let e2 = c - a;
    let n = e1.cross(e2);
    let det = n.length_squared();
    if det == 0.0 {
        return None;
    }
    let rows = [e2.cross(n) / det, n.cross(e1) / det, n / det];
    let out = rows.map(|r| [r.x as f32, r.y as f32, r.z as f32, (-r.dot(a)) as f32]);
    out.iter().flatten().all(|x| x.is_finite()).then_some(out)
}

/// One map per slot.
fn placement(c: &SceneCounts) -> Vec<BufferPlacement> {
    vec![BufferPlacement::new("unit triangles", BINDING_PRIMS, Texel::Rgba32Float, c.slots, size_of::<UnitTriangle>())]
}

fn encode(mesh: &Mesh, bvh: &Bvh) -> Encoding {
    let (nodes, mut slot_ids) = slot_layout(bvh);
    let mut unrepresentable = vec![];
    let tris: Vec<UnitTriangle> = bvh
        .prim_ids
        .iter()
        .enumerate()
        .map(|(slot, &p)| {
            let rows = match p {
                PAD_SLOT => PAD_ROWS,
                id => {
                    let [a, b, c] = mesh.vertices_f64(id as usize);
                    unit_transform(a, b, c).unwrap_or_else(|| {
                        unrepresentable.push(id);
                        slot_ids[slot] = crate::shared::MISS_ID;
                        PAD_ROWS
                    })
                }
            };
            UnitTriangle { row0: rows[0], row1: rows[1], row2: rows[2] }
        })
        .collect();
    Encoding {
        nodes,
        slot_ids,
        prims: vec![SceneBuffer {
            name: "unit triangles",
            binding: BINDING_PRIMS,
            texel: Texel::Rgba32Float,
            bytes: bytemuck::cast_slice(&tris).to_vec(),
        }],
        unrepresentable,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(row: [f32; 4], p: DVec3) -> f64 {
        row[0] as f64 * p.x + row[1] as f64 * p.y + row[2] as f64 * p.z + row[3] as f64
    }

    #[test]
    fn maps_vertices_to_the_unit_triangle() {
        let (a, b, c) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, 2.5, 3.0), DVec3::new(1.5, 5.0, 2.0));
        let m = unit_transform(a, b, c).unwrap();
        for (p, want) in [(a, [0.0, 0.0, 0.0]), (b, [1.0, 0.0, 0.0]), (c, [0.0, 1.0, 0.0])] {
            for r in 0..3 {
                assert!((apply(m[r], p) - want[r]).abs() < 1e-6, "row {r} at {p}: {}", apply(m[r], p));
            }
        }
        // A point off the plane has a nonzero third coordinate.
        let off = (a + b + c) / 3.0 + (b - a).cross(c - a);
        assert!((apply(m[2], off) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn degenerate_has_no_map() {
        let a = DVec3::ZERO;
        assert!(unit_transform(a, DVec3::X, 2.0 * DVec3::X).is_none());
        assert!(unit_transform(a, a, DVec3::Y).is_none());
    }
}
