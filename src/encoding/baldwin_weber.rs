//! Baldwin and Weber's layout: per slot, the nine non-trivial coefficients of the affine map from
//! world space to the triangle's barycentric space, plus the index of the map's fixed column
//! (`glsl/intersect/baldwin_weber.glsl`).
//!
//! D. Baldwin, M. Weber, "Fast Ray-Triangle Intersections by Coordinate Transformation", JCGT
//! 5(3), 2016, sec. 2-3. Like Woop's unit triangle (`unit.rs`) the map sends the triangle to
//! (0,0,0), (1,0,0), (0,1,0), but its third basis vector is not the normal n: it is the world
//! axis k on which |n| is largest (the "free vector"). The inverse then has one column known in
//! advance, (0, 0, 1)^T for world coordinate k, so only nine coefficients need storing and the
//! plane row costs two multiplications instead of three.
//!
//! Storage (three rgba32f texels, 48 bytes). With `p' = (p[k], p[k+1], p[k+2])` (indices mod 3:
//! a cyclic permutation, which keeps cross products, so `n' = e1' x e2'` and `n'[0] = n[k]`):
//! - `plane = (n'1/n'0, n'2/n'0, -(n . v0)/n'0, k)`: `w(p) = p'0 + plane.x p'1 + plane.y p'2
//!   + plane.z` is zero on the triangle's plane, and `t = -w(O) / (w(O + D) - w(O))`;
//! - `u_row = (e2'2/n'0, -e2'1/n'0, -(v0 x e2)[k]/n[k], 0)`: `u = u_row.x p'1 + u_row.y p'2 + u_row.z`
//!   at the hit point `p = O + t D`, the barycentric weight of v1;
//! - `v_row = (-e1'2/n'0, e1'1/n'0, (v0 x e1)[k]/n[k], 0)`: `v` likewise, the weight of v2.
//!
//! The fixed column `k` is stored as the float 0.0, 1.0 or 2.0 (exact, and not a denormal bit
//! pattern that a texel fetch might flush); 3.0 marks a slot that is never hit (padding, or a
//! triangle whose map is not representable), which the kernel skips before any arithmetic.
//! Because `|n'0|` is the largest component of n, `plane.x` and `plane.y` lie in [-1, 1].
//! The paper writes out the three cases separately, with the remaining coordinates in the order
//! (y, z), (x, z), (x, y); the cyclic order here, (y, z), (z, x), (x, y), only swaps the y case's
//! two coefficients and lets one code path with a swizzle serve all three cases.

use std::mem::{offset_of, size_of};

use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use super::{slot_layout, BufferPlacement, Encoding, HostStruct, Intersector, SceneBuffer, SceneCounts};
use crate::bvh::{Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_PRIMS, MISS_ID};

pub const INTERSECTOR: Intersector = Intersector {
    name: "baldwin-weber",
    glsl: "baldwin_weber",
    title: "Baldwin-Weber",
    about: "Baldwin & Weber (JCGT 5(3), 2016), the affine map with the normal's largest axis as fixed \
            column: 9 coefficients + the column (48 B per triangle).",
    in_paper: false,
    encode,
    placement,
    prim_binding: BINDING_PRIMS,
    prim_struct: HostStruct {
        size: size_of::<BwTriangle>(),
        offsets: &[offset_of!(BwTriangle, plane), offset_of!(BwTriangle, u_row), offset_of!(BwTriangle, v_row)],
    },
};

/// GLSL `BwTriangle { vec4 plane; vec4 u_row; vec4 v_row; }` (std430: 48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct BwTriangle {
    /// Plane row's coefficients of p'1 and p'2, its constant, and the fixed column k (0, 1, 2).
    pub plane: [f32; 4],
    /// u = `u_row.x p'1 + u_row.y p'2 + u_row.z` (w unused, 0).
    pub u_row: [f32; 4],
    /// v = `v_row.x p'1 + v_row.y p'2 + v_row.z` (w unused, 0).
    pub v_row: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<BwTriangle>() == 48);

/// `plane.w` of a slot the kernel skips (padding or an unrepresentable triangle).
pub const BW_NEVER_HIT: f32 = 3.0;

/// A slot that is never hit: skipped on `plane.w`, and besides u = v = -1 for any finite point.
pub const BW_PAD: BwTriangle =
    BwTriangle { plane: [0.0, 0.0, 0.0, BW_NEVER_HIT], u_row: [0.0, 0.0, -1.0, 0.0], v_row: [0.0, 0.0, -1.0, 0.0] };

/// Baldwin and Weber's map for triangle (a, b, c), computed in f64 and rounded to f32.
/// `None` for a zero-area triangle, or when a coefficient overflows f32 (a needle so thin that
/// 1/n[k] does not fit).
pub fn bw_transform(a: DVec3, b: DVec3, c: DVec3) -> Option<BwTriangle> {
    let e1 = b - a;
    let e2 = c - a;
    let n = e1.cross(e2);
    let abs = n.abs();
    // The free (fixed) column: the axis of n's largest component (the paper's three cases).
    let k = if abs.x >= abs.y && abs.x >= abs.z {
        0
    } else if abs.y >= abs.z {
        1
    } else {
        2
    };
    if n[k] == 0.0 {
        return None;
    }
    let perm = |v: DVec3| DVec3::new(v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
    let (e1p, e2p, np) = (perm(e1), perm(e2), perm(n));
    let inv = 1.0 / np.x;
    let plane = [np.y * inv, np.z * inv, -n.dot(a) * inv, k as f64];
    let u_row = [e2p.z * inv, -e2p.y * inv, -a.cross(e2)[k] * inv, 0.0];
    let v_row = [-e1p.z * inv, e1p.y * inv, a.cross(e1)[k] * inv, 0.0];
    let f = |r: [f64; 4]| r.map(|x| x as f32);
    let t = BwTriangle { plane: f(plane), u_row: f(u_row), v_row: f(v_row) };
    bytemuck::cast_slice::<BwTriangle, f32>(&[t]).iter().all(|x| x.is_finite()).then_some(t)
}

/// One map per slot.
fn placement(c: &SceneCounts) -> Vec<BufferPlacement> {
    vec![BufferPlacement::new("baldwin-weber triangles", BINDING_PRIMS, Texel::Rgba32Float, c.slots, size_of::<BwTriangle>())]
}

fn encode(mesh: &Mesh, bvh: &Bvh) -> Encoding {
    let (nodes, mut slot_ids) = slot_layout(bvh);
    let mut unrepresentable = vec![];
    let tris: Vec<BwTriangle> = bvh
        .prim_ids
        .iter()
        .enumerate()
        .map(|(slot, &p)| match p {
            PAD_SLOT => BW_PAD,
            id => {
                let [a, b, c] = mesh.vertices_f64(id as usize);
                bw_transform(a, b, c).unwrap_or_else(|| {
                    unrepresentable.push(id);
                    slot_ids[slot] = MISS_ID;
                    BW_PAD
                })
            }
        })
        .collect();
    Encoding {
        nodes,
        slot_ids,
        prims: vec![SceneBuffer {
            name: "baldwin-weber triangles",
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

    /// (w, u, v) of world point p, as the kernel computes them (in f64 here).
    fn apply(t: &BwTriangle, p: DVec3) -> [f64; 3] {
        let k = t.plane[3] as usize;
        let q = [p[k], p[(k + 1) % 3], p[(k + 2) % 3]];
        let row = |r: [f32; 4]| r[0] as f64 * q[1] + r[1] as f64 * q[2] + r[2] as f64;
        [q[0] + row(t.plane), row(t.u_row), row(t.v_row)]
    }

    #[test]
    fn maps_vertices_to_the_unit_triangle_for_every_fixed_column() {
        let (a, b, c) = (DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, 2.5, 3.0), DVec3::new(1.5, 5.0, 2.0));
        // Rotating the coordinates moves n's largest component through x, y and z, and a
        // reflection (swapping two axes) flips the orientation.
        let rot = |p: DVec3, r: usize| DVec3::new(p[r % 3], p[(r + 1) % 3], p[(r + 2) % 3]);
        let swap = |p: DVec3| DVec3::new(p.y, p.x, p.z);
        let mut cases = vec![];
        for r in 0..3 {
            for mirrored in [false, true] {
                let f = |p: DVec3| if mirrored { swap(rot(p, r)) } else { rot(p, r) };
                let (a, b, c) = (f(a), f(b), f(c));
                let t = bw_transform(a, b, c).unwrap();
                cases.push(t.plane[3] as usize);
                assert!(t.plane[0].abs() <= 1.0 && t.plane[1].abs() <= 1.0, "{t:?}");
                for (p, want) in [(a, [0.0, 0.0, 0.0]), (b, [0.0, 1.0, 0.0]), (c, [0.0, 0.0, 1.0])] {
                    let got = apply(&t, p);
                    for i in 0..3 {
                        assert!((got[i] - want[i]).abs() < 1e-6, "rotation {r} {mirrored}: {got:?} at {p}");
                    }
                }
                // w moves along the world axis k with slope exactly 1 (the fixed column).
                let k = t.plane[3] as usize;
                let mut off = (a + b + c) / 3.0;
                off[k] += 1.0;
                assert!((apply(&t, off)[0] - 1.0).abs() < 1e-6);
                // And a ray along axis k meets the plane where u, v are the centroid's.
                let got = apply(&t, (a + b + c) / 3.0);
                assert!((got[1] - 1.0 / 3.0).abs() < 1e-6 && (got[2] - 1.0 / 3.0).abs() < 1e-6);
            }
        }
        cases.sort_unstable();
        cases.dedup();
        assert_eq!(cases, [0, 1, 2], "every fixed column is exercised");
    }

    #[test]
    fn degenerate_and_overflowing_triangles_have_no_map() {
        let a = DVec3::ZERO;
        assert!(bw_transform(a, DVec3::X, 2.0 * DVec3::X).is_none(), "collinear");
        assert!(bw_transform(a, a, DVec3::Y).is_none(), "repeated vertex");
        assert!(bw_transform(a, a, a).is_none(), "a point");
        // Edges so short (an f32 subnormal) that the coefficients, about 1/|edge|, overflow f32.
        let tiny = 1e-40;
        assert!(bw_transform(a, DVec3::new(tiny, 0.0, 0.0), DVec3::new(0.0, tiny, 0.0)).is_none());
    }

    #[test]
    fn unrepresentable_triangles_become_never_hit_padding() {
        let pos = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1e-40, 0.0, 0.0], [0.0, 1e-40, 0.0]];
        let mesh = Mesh::from_triangles(pos, vec![[0, 1, 2], [0, 3, 4]]);
        let bvh = Bvh::build(&mesh, &crate::bvh::BuildOptions::new(4));
        let e = encode(&mesh, &bvh);
        let tris: &[BwTriangle] = bytemuck::cast_slice(&e.prims[0].bytes);
        for (slot, &id) in bvh.prim_ids.iter().enumerate() {
            if id == 1 {
                assert_eq!(tris[slot], BW_PAD);
                assert_eq!(e.slot_ids[slot], MISS_ID);
            }
        }
        assert!(bvh.prim_ids.contains(&1), "the tiny triangle has nonzero area, so the BVH keeps it");
        assert_eq!(e.unrepresentable, [1]);
    }
}
