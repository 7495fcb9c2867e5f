//! Wide BVHs (issue 15 groundwork, CPU side): the binary SAH tree collapsed into nodes of `N`
//! children (`N` = 4 or 8; 2 gives the binary tree in the same layout, for comparisons), each
//! node holding its children's boxes.
//!
//! # How the tree is collapsed
//!
//! Two ways ([`Collapse`]), both top down from the binary root, both keeping the leaves:
//! - [`Collapse::Sah`] (the default): Ylitie, Karras & Laine, "Efficient Incoherent Ray
//!   Traversal on GPUs Through Compressed Wide BVHs" (HPG 2017), sec. 4.1: a dynamic program
//!   over the binary tree finds, for every binary node and every number of slots `j <= N`, the
//!   cheapest way to cover its subtree with `j` child slots, each slot a leaf or a new wide
//!   node; the wide tree is the one of least [`WideBvh::sah_cost`] among all collapses that
//!   keep the leaves (see `SahPlan`). Unlike the paper, leaves are never merged (so the
//!   encodings' leaf ranges stay valid) and the price is our SAH's, not the paper's per-slot
//!   one. O(N²) per binary node.
//! - [`Collapse::Greedy`]: as tinybvh's `MBVH<M>::ConvertFrom` (tiny_bvh.h, the peer in
//!   `../shared/peers/tinybvh/`) and Wald, Benthin & Boulos, "Getting Rid of Packets" (IEEE RT
//!   2008, sec. 3) collapse a binary tree: a wide node starts from the two children of a
//!   binary inner node and repeatedly *opens* the inner child with the largest surface area
//!   (ties: the first in slot order), replacing it by its two children, until it has `N`
//!   children or only leaves are left; each inner child then becomes a wide node of its own.
//!   (tinybvh puts the second grandchild in the last slot; here both take the opened child's
//!   place, so slots keep the binary tree's left-to-right order.) On a balanced tree this
//!   fills the top levels and leaves half-empty nodes at the bottom: bunny, leaf 4, N = 8 uses
//!   4.6 of 8 slots per node (22.0 node bytes per triangle) against the SAH collapse's 6.0
//!   (15.5 bytes); on a 3,000-triangle grid its 8-wide tree has more nodes than its 4-wide one.
//!
//! Leaves are never split or merged: every leaf of the wide tree is a leaf of the binary tree
//! with the same `(first, count)` range of [`Bvh::prim_ids`](crate::bvh::Bvh::prim_ids), so every encoding's per-slot
//! triangle order stays valid and leaf sizes obey the binary tree's limits
//! ([`WideBvh::validate`] checks both). A binary tree whose root is a leaf (one leaf in all)
//! becomes one wide node with one leaf child.
//!
//! # Node layout ([`WideNode`], `#[repr(C)]`, 32·N bytes, all fields 4 bytes, no padding)
//!
//! | bytes (N = 4) | bytes (N = 8) | field | meaning per child slot i |
//! |---|---|---|---|
//! | 0..16    | 0..32    | `min_x[N]` | child box |
//! | 16..32   | 32..64   | `min_y[N]` | |
//! | 32..48   | 64..96   | `min_z[N]` | |
//! | 48..64   | 96..128  | `max_x[N]` | |
//! | 64..80   | 128..160 | `max_y[N]` | |
//! | 80..96   | 160..192 | `max_z[N]` | |
//! | 96..112  | 192..224 | `child[N]` | inner: node index; leaf: first slot of `prim_ids`; empty: [`EMPTY_CHILD`] |
//! | 112..128 | 224..256 | `count[N]` | inner: 0; leaf: triangles (1..=max leaf size); empty: 0 |
//!
//! So a 4-wide node is 8 `vec4`/`uvec4` texels (one per field: the slab test of all four
//! children for one plane is one texel load) and an 8-wide node 16 texels, two per field.
//!
//! Empty slots come after the occupied ones (a kernel may stop at the first `EMPTY_CHILD`)
//! and have the inverted box `min = +inf, max = -inf`. A slab test that picks the near and far
//! plane by the sign of the ray direction (near = `min` where the direction is positive, `max`
//! where it is negative, as Embree and tinybvh's BVH4/8 do) never hits that box, whatever the
//! ray ([`slab_ordered`], tested for every octant and zero components). The min/max-swapping
//! test of `glsl/box.glsl`'s `hit_box` does NOT miss it (on each axis the swap turns
//! `(+inf, -inf)` into an unbounded interval), so a kernel with that test must check the slot.
//!
//! The root's own box is [`WideBvh::bounds`] (the binary root's); node 0 is the root. The inner
//! children of one node occupy consecutive node indices (allocated together), in slot order.
//!
//! # Files
//!
//! The node and the tree are here; [`collapse`](WideBvh::collapse_with) is in `collapse.rs`,
//! the SAH costs, sizes and stack bound ([`WideStats`]) in `stats.rs`, the CPU traversal
//! ([`WideBvh::trace`]) in `trace.rs`, the invariants ([`WideBvh::validate`]) in `validate.rs`.
//! The leaf loop, the slab tests, the hit and its tie-break rule are every layout's
//! (`bvh::walk`, [`bvh::slab`](crate::bvh::slab), [`bvh::hit`](crate::bvh::hit)).

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::{Aabb, PAD_SLOT};

mod collapse;
mod stats;
mod trace;
mod validate;

pub use super::hit::WideHit;
pub use super::slab::{slab_f64, slab_ordered};
pub use super::walk::WideSteps;
pub use collapse::Collapse;
pub use stats::WideStats;

/// `child[i]` of an empty slot.
pub const EMPTY_CHILD: u32 = u32::MAX;

/// A node of `N` children, child boxes stored structure-of-arrays (see the module docs for the
/// byte layout). `N` must be 2..=8.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WideNode<const N: usize> {
    pub min_x: [f32; N],
    pub min_y: [f32; N],
    pub min_z: [f32; N],
    pub max_x: [f32; N],
    pub max_y: [f32; N],
    pub max_z: [f32; N],
    pub child: [u32; N],
    pub count: [u32; N],
}

// SAFETY: `WideNode<N>` is `#[repr(C)]` and made only of `[f32; N]` and `[u32; N]` arrays:
// every field has size 4·N and alignment 4, so there is no padding anywhere, every bit pattern
// is a valid value, and the all-zero pattern is too. That is all `Zeroable` and `Pod` require
// (`#[derive(Pod)]` does not accept const-generic structs, hence the manual impls).
unsafe impl<const N: usize> Zeroable for WideNode<N> {}
// SAFETY: as above.
unsafe impl<const N: usize> Pod for WideNode<N> {}

/// The binary tree in the wide layout: 64 bytes, both children's boxes in the parent, like
/// Aila & Laine's node (whose fields are ordered per child, not per plane). Not the bvh2
/// layout's node: that is [`crate::bvh::BvhNode`], 32 bytes, one box per node.
pub type Wide2Node = WideNode<2>;
/// 4 children, 128 bytes.
pub type Bvh4Node = WideNode<4>;
/// 8 children, 256 bytes.
pub type Bvh8Node = WideNode<8>;

const _: () = assert!(std::mem::size_of::<Wide2Node>() == 64);
const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::size_of::<Bvh8Node>() == 256);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 4 && std::mem::align_of::<Bvh8Node>() == 4);

/// The box of an empty slot: inverted, so that no ray hits it ([`slab_ordered`]).
pub const EMPTY_BOX: Aabb = Aabb::EMPTY;

impl<const N: usize> WideNode<N> {
    /// Refuses widths the traversal's fixed stack and the layout docs do not cover.
    const WIDTH_OK: () = assert!(N >= 2 && N <= 8, "wide nodes have 2..=8 children");

    /// Every slot empty.
    pub const EMPTY: Self = WideNode {
        min_x: [f32::INFINITY; N],
        min_y: [f32::INFINITY; N],
        min_z: [f32::INFINITY; N],
        max_x: [f32::NEG_INFINITY; N],
        max_y: [f32::NEG_INFINITY; N],
        max_z: [f32::NEG_INFINITY; N],
        child: [EMPTY_CHILD; N],
        count: [0; N],
    };

    pub fn child_box(&self, i: usize) -> Aabb {
        Aabb {
            min: Vec3::new(self.min_x[i], self.min_y[i], self.min_z[i]),
            max: Vec3::new(self.max_x[i], self.max_y[i], self.max_z[i]),
        }
    }

    pub fn set_child_box(&mut self, i: usize, b: &Aabb) {
        [self.min_x[i], self.min_y[i], self.min_z[i]] = b.min.to_array();
        [self.max_x[i], self.max_y[i], self.max_z[i]] = b.max.to_array();
    }

    pub fn is_empty_slot(&self, i: usize) -> bool {
        self.child[i] == EMPTY_CHILD && self.count[i] == 0
    }

    pub fn is_leaf(&self, i: usize) -> bool {
        self.count[i] > 0
    }

    /// Occupied slots (they come first).
    pub fn children(&self) -> usize {
        (0..N).take_while(|&i| !self.is_empty_slot(i)).count()
    }
}

/// A wide tree over the same leaves (and the same `prim_ids`) as the binary tree it came from.
#[derive(Clone, Debug)]
pub struct WideBvh<const N: usize> {
    /// Root at 0.
    pub nodes: Vec<WideNode<N>>,
    /// The root's box (the binary root's).
    pub bounds: Aabb,
    /// Leaf slot -> triangle id: a copy of the binary tree's
    /// [`Bvh::prim_ids`](crate::bvh::Bvh::prim_ids).
    pub prim_ids: Vec<u32>,
    /// The binary tree's leaf size limit.
    pub max_leaf_size: u32,
    pub collapse_seconds: f64,
}

pub type Bvh4 = WideBvh<4>;
pub type Bvh8 = WideBvh<8>;

impl<const N: usize> WideBvh<N> {
    /// Triangles in the hierarchy (padding not counted).
    pub fn triangle_count(&self) -> usize {
        self.prim_ids.iter().filter(|&&p| p != PAD_SLOT).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_slots_are_missed_by_the_ordered_slab_test_in_every_octant() {
        let comps = [-1.0f32, -1e-3, 0.0, 1e-3, 1.0];
        let mut n = 0;
        for x in comps {
            for y in comps {
                for z in comps {
                    let dir = Vec3::new(x, y, z);
                    if dir == Vec3::ZERO {
                        continue;
                    }
                    // make_trace_ray()'s guard against zero components.
                    let safe = Vec3::select(dir.cmplt(Vec3::ZERO), -Vec3::ONE, Vec3::ONE)
                        * dir.abs().max(Vec3::splat(f32::MIN_POSITIVE));
                    for origin in [Vec3::ZERO, Vec3::splat(1e30), Vec3::new(-3.0, 5.0, 1e-20)] {
                        let inv = Vec3::ONE / safe;
                        assert_eq!(slab_ordered(origin, inv, &EMPTY_BOX, 0.0, f32::INFINITY), None, "{dir} {origin}");
                        let (o, d) = (origin.as_dvec3().to_array(), dir.as_dvec3().to_array());
                        assert_eq!(slab_f64(o, d, &EMPTY_BOX, 0.0, f64::INFINITY), None, "{dir} {origin}");
                        // A real box on the ray is hit by both.
                        let b = Aabb { min: origin + dir - 0.5, max: origin + dir + 0.5 };
                        if origin == Vec3::ZERO {
                            assert!(slab_ordered(origin, inv, &b, 0.0, f32::INFINITY).is_some());
                            assert!(slab_f64(o, d, &b, 0.0, f64::INFINITY).is_some());
                        }
                        n += 1;
                    }
                }
            }
        }
        assert_eq!(n, 124 * 3);
        // The swapping test (box.glsl's hit_box) does hit it: why kernels must not use it
        // on empty slots without checking them.
        let (o, inv) = (Vec3::ZERO, Vec3::ONE);
        let (t0, t1) = ((EMPTY_BOX.min - o) * inv, (EMPTY_BOX.max - o) * inv);
        assert!(t0.min(t1).max_element() <= t0.max(t1).min_element());
    }
}
