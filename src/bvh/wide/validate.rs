//! A wide tree's invariants ([`WideBvh::validate`]), against the binary tree it was collapsed
//! from.

use super::{WideBvh, EMPTY_BOX};
use crate::bvh::validate::{all_reached, built_from, holds_triangles, Leaves};
use crate::bvh::Bvh;
use crate::scene::Mesh;

impl<const N: usize> WideBvh<N> {
    /// Checks the invariants every consumer relies on, against the binary tree it was collapsed
    /// from and the mesh; returns the first violation. Every node is reached exactly once from
    /// the root, by an index larger than its parent's; occupied slots come first, a node has at
    /// least two children (one, a leaf, only for a one-leaf tree); each child box contains the
    /// boxes its node stores (so every box contains its whole subtree) or, for a leaf, its
    /// triangles; leaves hold 1..=max leaf size triangles and are exactly the binary tree's
    /// leaf ranges, every slot of `prim_ids` in exactly one leaf; empty slots carry
    /// [`EMPTY_CHILD`](super::EMPTY_CHILD), count 0 and [`EMPTY_BOX`]. The checks every layout
    /// shares are `bvh::validate`'s.
    pub fn validate(&self, bvh: &Bvh, mesh: &Mesh) -> Result<(), String> {
        built_from(self.nodes.len(), &self.prim_ids, bvh)?;
        if self.bounds != bvh.nodes[0].aabb() {
            return Err("root bounds differ from the binary root's".into());
        }
        let one_leaf_tree = bvh.nodes[0].is_leaf();
        let mut reached = vec![false; self.nodes.len()];
        let mut leaves = Leaves::new(self.prim_ids.len());
        let mut stack = vec![(0usize, self.bounds)];
        while let Some((i, parent_box)) = stack.pop() {
            if std::mem::replace(&mut reached[i], true) {
                return Err(format!("node {i} reached twice"));
            }
            let n = &self.nodes[i];
            let k = n.children();
            if let Some(s) = (k..N).find(|&s| !n.is_empty_slot(s)) {
                return Err(format!("node {i} slot {s} is occupied after an empty slot"));
            }
            for s in k..N {
                let b = n.child_box(s);
                if b.min != EMPTY_BOX.min || b.max != EMPTY_BOX.max {
                    return Err(format!("node {i} empty slot {s} has box {b:?}, not the inverted one"));
                }
            }
            let min_children = if one_leaf_tree { 1 } else { 2 };
            if k < min_children {
                return Err(format!("node {i} has {k} children"));
            }
            for s in 0..k {
                let b = n.child_box(s);
                // A padding-only leaf (an all-degenerate scene) has an empty box.
                let padding_leaf = n.is_leaf(s) && b.is_empty();
                if !parent_box.contains(&b) && !padding_leaf {
                    return Err(format!("node {i}: the box of child slot {s} is not inside the node's box"));
                }
                if n.is_leaf(s) {
                    let at = format!("node {i} slot {s}");
                    let slots = leaves.take(&at, n.child[s], n.count[s], self.max_leaf_size)?;
                    holds_triangles(&at, &b, &self.prim_ids[slots], mesh)?;
                } else {
                    let c = n.child[s] as usize;
                    if c >= self.nodes.len() || c <= i {
                        return Err(format!("node {i} slot {s}: bad child index {c}"));
                    }
                    stack.push((c, b));
                }
            }
        }
        all_reached(reached)?;
        leaves.all_taken()?;
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
        let w = WideBvh::<4>::collapse(&bvh);
        let expect = refuses(&w, |c| c.validate(&bvh, &mesh));
        // An inner child's box shrunk: its node's boxes stick out.
        let (ni, si) = (0..w.nodes.len())
            .flat_map(|i| (0..4).map(move |s| (i, s)))
            .find(|&(i, s)| !w.nodes[i].is_empty_slot(s) && !w.nodes[i].is_leaf(s))
            .unwrap();
        expect(&|c| c.nodes[ni].max_x[si] -= 0.25, "is not inside the node's box");
        // A leaf's box shrunk.
        let (nl, sl) = (0..w.nodes.len())
            .flat_map(|i| (0..4).map(move |s| (i, s)))
            .find(|&(i, s)| w.nodes[i].count[s] >= 2)
            .unwrap();
        expect(&|c| c.nodes[nl].min_y[sl] += 0.25, "leaf box does not contain");
        expect(&|c| c.nodes[nl].count[sl] = 17, "leaf holds 17");
        expect(&|c| c.nodes[nl].count[sl] -= 1, "in no leaf");
        expect(&|c| c.nodes[nl].child[sl] = c.nodes[nl].child[(sl + 1) % c.nodes[nl].children()], "leaf");
        // An empty slot before an occupied one.
        let ne = (0..w.nodes.len()).find(|&i| w.nodes[i].children() < 4).unwrap();
        expect(
            &|c| {
                let n = &mut c.nodes[ne];
                let k = n.children();
                n.child.swap(0, k);
                n.count.swap(0, k);
            },
            "occupied after an empty slot",
        );
        expect(&|c| c.nodes[ne].max_z[3] = 0.0, "not the inverted one");
        expect(&|c| c.nodes[ni].child[si] = ni as u32, "bad child index");
        expect(&|c| c.prim_ids.swap(0, 1), "prim_ids differ");
    }
}
