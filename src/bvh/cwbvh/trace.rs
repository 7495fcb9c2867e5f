//! The CPU traversal of a compressed tree ([`CwBvh::trace`]): the paper's octant-ordered node
//! groups with hit masks, as the kernel (`glsl/layout/cwbvh.glsl`) walks them.

use super::{CwBvh, CW_WIDTH, INNER_BIT0};
use crate::bvh::hit::WideHit;
use crate::bvh::walk::{Walk, WideSteps};
use crate::rays::Ray;
use crate::shared::{leaf_entry_count, leaf_entry_first};

impl CwBvh {
    /// Closest hit (`any = false`; ties to the lower triangle id: [`crate::bvh::hit`]) or the
    /// first hit found, with the work it took, walking the compressed tree as the kernel does
    /// (module docs): the box test is [`slab_f64`] on the decoded boxes, `intersect(id, tmax)`
    /// the triangle test (the f64 reference's in the tests). The box test, the leaf loop and the
    /// result are the walk every CPU traversal shares (`bvh::walk`). Needs `prim_ids` (a tree
    /// from [`CwBvh::build`]).
    ///
    /// [`slab_f64`]: crate::bvh::slab::slab_f64
    pub fn trace(
        &self,
        ray: &Ray,
        any: bool,
        mut intersect: impl FnMut(u32, f64) -> Option<(f64, f64, f64)>,
    ) -> (WideHit, WideSteps) {
        let mut walk = Walk::new(ray, any);
        let octant = (ray.dir[0] < 0.0) as u32 | ((ray.dir[1] < 0.0) as u32) << 1 | ((ray.dir[2] < 0.0) as u32) << 2;
        let oct_inv = 7 ^ octant;
        // Node groups: (child_base, hits); the root group names node 0 alone.
        let mut stack: Vec<(u32, u32)> = Vec::with_capacity(32);
        let mut group = (0u32, 1u32 << 31);
        loop {
            if group.1 & 0xff00_0000 == 0 {
                match stack.pop() {
                    Some(g) => group = g,
                    None => break,
                }
            }
            // The next child: highest hit bit.
            let bit = 31 - group.1.leading_zeros();
            group.1 &= !(1 << bit);
            let slot = (bit - INNER_BIT0) ^ oct_inv;
            let imask = group.1 & 0xff;
            let index = group.0 + (imask & ((1u32 << slot) - 1)).count_ones();
            if group.1 & 0xff00_0000 != 0 {
                stack.push(group);
                walk.steps.stack_peak = walk.steps.stack_peak.max(stack.len() as u32);
            }
            walk.steps.nodes += 1;
            let n = &self.nodes[index as usize];
            let mut hits = 0u32;
            for s in 0..CW_WIDTH {
                let meta = n.meta[s] as u32;
                if meta == 0 {
                    continue;
                }
                walk.steps.boxes += 1;
                if walk.enters(&n.child_box(s)).is_some() {
                    let inner = meta & 0b11000 == 0b11000;
                    let bit = if inner { (meta & 31) ^ oct_inv } else { meta & 31 };
                    hits |= (meta >> 5) << bit;
                }
            }
            group = (n.child_base, (hits & 0xff00_0000) | n.imask as u32);
            // The leaf group, at once.
            let mut leaf_bits = hits & 0x00ff_ffff;
            while leaf_bits != 0 {
                let rank = leaf_bits.trailing_zeros();
                leaf_bits &= leaf_bits - 1;
                let entry = self.leaf(n, rank);
                let (first, count) = (leaf_entry_first(entry), leaf_entry_count(entry));
                let slots = &self.prim_ids[first as usize..(first + count) as usize];
                if walk.leaf(slots, &mut intersect) {
                    return walk.end();
                }
            }
        }
        walk.end()
    }
}
