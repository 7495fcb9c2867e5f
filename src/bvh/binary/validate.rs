//! The binary tree's invariants ([`Bvh::validate`]).

use super::Bvh;
use crate::bvh::validate::{holds_triangles, Leaves};
use crate::bvh::{MAX_DEPTH, PAD_SLOT};
use crate::scene::Mesh;

impl Bvh {
    /// Checks the structural invariants every consumer relies on; returns the first violation.
    /// No leaf deeper than [`MAX_DEPTH`]; every leaf holds 1..=max leaf size slots of
    /// `prim_ids` (each in exactly one leaf) and its box contains their triangles; an inner
    /// node's children come after it and lie inside its box; the leaves hold exactly the
    /// mesh's non-degenerate triangles.
    pub fn validate(&self, mesh: &Mesh) -> Result<(), String> {
        let mut leaves = Leaves::new(self.prim_ids.len());
        let mut err = None;
        self.visit(|i, d| {
            if err.is_some() {
                return;
            }
            let n = &self.nodes[i];
            let checked = if d > MAX_DEPTH {
                Err(format!("node {i} at depth {d} > {MAX_DEPTH}"))
            } else if n.is_leaf() {
                let at = format!("node {i}");
                leaves
                    .take(&at, n.left_or_first, n.count, self.options.max_leaf_size)
                    .and_then(|slots| holds_triangles(&at, &n.aabb(), &self.prim_ids[slots], mesh))
            } else {
                let l = n.left_or_first as usize;
                if l + 1 >= self.nodes.len() || l <= i {
                    Err(format!("node {i} has bad children {l}"))
                } else if !n.aabb().contains(&self.nodes[l].aabb()) || !n.aabb().contains(&self.nodes[l + 1].aabb()) {
                    Err(format!("node {i} box does not contain its children"))
                } else {
                    Ok(())
                }
            };
            err = checked.err();
        });
        if let Some(e) = err {
            return Err(e);
        }
        leaves.all_taken()?;
        let mut ids: Vec<u32> = self.prim_ids.iter().copied().filter(|&p| p != PAD_SLOT).collect();
        ids.sort_unstable();
        let expected: Vec<u32> =
            (0..mesh.triangle_count() as u32).filter(|&i| !mesh.is_degenerate(i as usize)).collect();
        if ids != expected {
            return Err("leaves do not hold exactly the non-degenerate triangles".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use crate::bvh::testing::{grid_tree, refuses};

    /// Each corruption is caught and named (so the checks can fail).
    #[test]
    fn corruption_is_caught() {
        let (mesh, bvh) = grid_tree();
        let expect = refuses(&bvh, |c| c.validate(&mesh));
        // Leaves in the order the walk meets them (which is also their slots' order).
        let mut met = vec![];
        bvh.visit(|i, _| {
            if bvh.nodes[i].is_leaf() {
                met.push(i);
            }
        });
        let (a, b) = (met[0], met[1]);
        let leaf = *met.iter().find(|&&i| bvh.nodes[i].count >= 2).unwrap();
        let inner = (1..bvh.nodes.len()).find(|&i| !bvh.nodes[i].is_leaf()).unwrap();
        expect(&|c| c.nodes[leaf].count = 5, "leaf holds 5, not 1..=4");
        expect(&|c| c.nodes[leaf].count -= 1, "in no leaf");
        expect(&|c| c.nodes[b].left_or_first = c.nodes[a].left_or_first, "in two leaves");
        expect(&|c| c.nodes[leaf].left_or_first = c.prim_ids.len() as u32 - 1, "out of range");
        expect(&|c| c.nodes[leaf].min[1] += 0.25, "leaf box does not contain");
        expect(&|c| c.nodes[inner].max[0] -= 0.25, "does not contain its children");
        let f = bvh.nodes[leaf].left_or_first as usize;
        expect(&|c| c.prim_ids[f] = c.prim_ids[f + 1], "non-degenerate triangles");
    }
}
