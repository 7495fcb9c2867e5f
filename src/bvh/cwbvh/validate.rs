//! A compressed tree's invariants ([`CwBvh::validate`]), against the binary tree it was built
//! from.

use super::{CwBvh, CW_WIDTH, INNER_BIT0, META_EMPTY};
use crate::bvh::quantize::check_contains;
use crate::bvh::validate::{all_reached, built_from, Leaves};
use crate::bvh::{Aabb, Bvh, PAD_SLOT};
use crate::scene::Mesh;
use crate::shared::{leaf_entry_count, leaf_entry_first};

impl CwBvh {
    /// Checks the invariants the kernel relies on, against the binary tree it was built from
    /// and the mesh; returns the first violation. Every node is reached exactly once from the
    /// root, by an index larger than its parent's; the inner children of a node are
    /// `child_base..` in slot order and its leaves `leaf_base..` in slot order; every meta byte
    /// is empty, inner (`0b001_11sss` with `sss` = the slot, matching `imask`) or a leaf of the
    /// right rank; every grid's exponent is normal; every decoded child box contains every
    /// triangle under it (both decode variants, [`decode_plane`](super::decode_plane)); the
    /// leaves are exactly the binary tree's leaf ranges. The checks every layout shares are
    /// `bvh::validate`'s.
    pub fn validate(&self, bvh: &Bvh, mesh: &Mesh) -> Result<(), String> {
        built_from(self.nodes.len(), &self.prim_ids, bvh)?;
        // The true box of every node's subtree, from the triangles up.
        let tri_box = |first: u32, count: u32| -> Result<Aabb, String> {
            let mut b = Aabb::EMPTY;
            for slot in first..first.saturating_add(count) {
                let Some(&id) = self.prim_ids.get(slot as usize) else {
                    return Err(format!("leaf slot {slot} out of range"));
                };
                if id != PAD_SLOT {
                    b.grow(&Aabb::from_points(&mesh.vertices(id as usize)));
                }
            }
            Ok(b)
        };
        let mut parent = vec![usize::MAX; self.nodes.len()];
        let mut order = vec![];
        let mut leaves = Leaves::new(self.prim_ids.len());
        let mut stack = vec![0usize];
        parent[0] = 0;
        while let Some(i) = stack.pop() {
            order.push(i);
            let n = &self.nodes[i];
            if n.e.iter().any(|&e| e == 0 || e == 255) {
                return Err(format!("node {i}: exponent {:?} is not a normal scale", n.e));
            }
            let (mut inner, mut rank) = (0u32, 0u8);
            for s in 0..CW_WIDTH {
                let m = n.meta[s];
                if m == META_EMPTY {
                    if n.is_inner(s) {
                        return Err(format!("node {i} slot {s}: empty but set in imask"));
                    }
                    continue;
                }
                if m >> 5 != 1 {
                    return Err(format!("node {i} slot {s}: meta {m:#010b} is not one unit"));
                }
                if n.is_inner(s) {
                    if m & 31 != INNER_BIT0 as u8 + s as u8 {
                        return Err(format!("node {i} slot {s}: inner meta {m:#010b} does not name its slot"));
                    }
                    let c = n.child_base as usize + inner as usize;
                    if n.inner_child(s) as usize != c || c >= self.nodes.len() || c <= i {
                        return Err(format!("node {i} slot {s}: bad child index {c}"));
                    }
                    if parent[c] != usize::MAX {
                        return Err(format!("node {c} reached twice"));
                    }
                    parent[c] = i;
                    inner += 1;
                    stack.push(c);
                } else {
                    if m & 31 != rank {
                        return Err(format!("node {i} slot {s}: leaf rank {} where {rank} was due", m & 31));
                    }
                    let w = n.leaf_base as usize + rank as usize;
                    if w < self.table_word() || w - self.table_word() >= self.leaves.len() {
                        return Err(format!("node {i} slot {s}: leaf word {w} outside the table"));
                    }
                    rank += 1;
                    let e = self.leaf(n, m as u32 & 31);
                    let (first, count) = (leaf_entry_first(e), leaf_entry_count(e));
                    leaves.take(format!("node {i} slot {s}"), first, count, self.max_leaf_size)?;
                }
            }
        }
        all_reached(parent.iter().map(|&p| p != usize::MAX))?;
        leaves.all_taken()?;
        // Containment, children before parents.
        let mut under = vec![Aabb::EMPTY; self.nodes.len()];
        for &i in order.iter().rev() {
            let n = &self.nodes[i];
            let mut all = Aabb::EMPTY;
            for s in (0..CW_WIDTH).filter(|&s| n.is_present(s)) {
                let truth = if n.is_inner(s) {
                    under[n.inner_child(s) as usize]
                } else {
                    let e = self.leaf(n, (n.meta[s] & 31) as u32);
                    tri_box(leaf_entry_first(e), leaf_entry_count(e))?
                };
                if !truth.is_empty() {
                    check_contains(&n.grid(), n.planes(s), &truth).map_err(|e| format!("node {i} slot {s}: {e}"))?;
                    all.grow(&truth);
                }
            }
            under[i] = all;
        }
        leaves.same_as(bvh)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::testing::{grid_tree, refuses};

    #[test]
    fn corruption_is_caught() {
        let (mesh, bvh) = grid_tree();
        let cw = CwBvh::build(&bvh).unwrap();
        let expect = refuses(&cw, |c| c.validate(&bvh, &mesh));
        let (ni, si) = (0..cw.nodes.len())
            .flat_map(|i| (0..8).map(move |s| (i, s)))
            .find(|&(i, s)| cw.nodes[i].is_present(s) && !cw.nodes[i].is_inner(s) && cw.nodes[i].q_hi_x[s] > 0)
            .unwrap();
        expect(&|c| c.nodes[ni].q_hi_x[si] -= 1, "decoded max");
        expect(&|c| c.nodes[ni].q_lo_y[si] += 1, "decoded min");
        expect(&|c| c.nodes[ni].p[2] += 1.0, "decoded");
        expect(&|c| c.nodes[ni].e[0] = 0, "normal scale");
        expect(&|c| c.nodes[ni].meta[si] ^= 0b1000_0000, "one unit");
        let inner = (0..8).find(|&s| cw.nodes[0].is_inner(s)).unwrap();
        expect(&|c| c.nodes[0].meta[inner] ^= 1, "does not name its slot");
        expect(&|c| c.nodes[0].child_base = 0, "bad child index");
        expect(&|c| c.nodes[0].child_base += 1, "not reachable");
        expect(&|c| c.leaves[0] += 1, "leaf");
        expect(&|c| c.prim_ids.swap(0, 1), "prim_ids differ");
    }
}
