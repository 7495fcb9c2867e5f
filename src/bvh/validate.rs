//! What every layout's validator ([`Bvh::validate`], [`WideBvh::validate`],
//! [`CwBvh::validate`]) checks the same way, written once:
//! - a tree built from a binary one has nodes and that tree's `prim_ids` ([`built_from`]);
//! - every leaf holds 1..=max leaf size slots of `prim_ids`, each in range, and no slot is in two
//!   leaves ([`Leaves::take`]); after the walk, every slot is in a leaf ([`Leaves::all_taken`])
//!   and a wide or compressed tree's leaves are exactly the binary tree's leaf ranges
//!   ([`Leaves::same_as`]);
//! - every node is reached from the root ([`all_reached`]);
//! - a leaf's box contains its triangles ([`holds_triangles`]; the compressed tree checks its
//!   decoded boxes against the triangles' union instead).
//!
//! Each returns the first violation as a message that names the place (`at`: `node 3`,
//! `node 3 slot 5`).
//!
//! [`WideBvh::validate`]: crate::bvh::WideBvh::validate
//! [`CwBvh::validate`]: crate::bvh::CwBvh::validate

use std::fmt::Display;
use std::ops::Range;

use super::{Aabb, Bvh, PAD_SLOT};
use crate::scene::Mesh;

/// The first checks of a tree built from `bvh` (a wide or compressed one, of `nodes` nodes):
/// it has nodes, and its `prim_ids` are the binary tree's.
pub(super) fn built_from(nodes: usize, prim_ids: &[u32], bvh: &Bvh) -> Result<(), String> {
    if nodes == 0 {
        return Err("no nodes".into());
    }
    if prim_ids != bvh.prim_ids {
        return Err("prim_ids differ from the binary tree's".into());
    }
    Ok(())
}

/// After a walk from the root: `reached` says, node by node, whether the walk reached it.
pub(super) fn all_reached(reached: impl IntoIterator<Item = bool>) -> Result<(), String> {
    match reached.into_iter().position(|r| !r) {
        Some(i) => Err(format!("node {i} is not reachable from the root")),
        None => Ok(()),
    }
}

/// Whether the leaf box `b` (at `at`) contains each of the triangles `ids` (padding skipped).
pub(super) fn holds_triangles(at: impl Display, b: &Aabb, ids: &[u32], mesh: &Mesh) -> Result<(), String> {
    for &id in ids {
        if id != PAD_SLOT && !b.contains(&Aabb::from_points(&mesh.vertices(id as usize))) {
            return Err(format!("{at}: leaf box does not contain triangle {id}"));
        }
    }
    Ok(())
}

/// The leaves a validator's walk has met, as slots of `prim_ids`.
pub(super) struct Leaves {
    /// Per slot: in a leaf already.
    seen: Vec<bool>,
    /// `(first, count)` of every leaf, in the order met.
    ranges: Vec<(u32, u32)>,
}

impl Leaves {
    /// None met yet, over `slots` slots of `prim_ids`.
    pub(super) fn new(slots: usize) -> Leaves {
        Leaves { seen: vec![false; slots], ranges: vec![] }
    }

    /// A leaf of `count` slots from `first`, at `at`: it holds 1..=`max_leaf_size`, every slot
    /// in range and in no leaf met before. Returns its slots.
    pub(super) fn take(
        &mut self,
        at: impl Display,
        first: u32,
        count: u32,
        max_leaf_size: u32,
    ) -> Result<Range<usize>, String> {
        if count == 0 || count > max_leaf_size {
            return Err(format!("{at}: leaf holds {count}, not 1..={max_leaf_size}"));
        }
        for slot in first..first.saturating_add(count) {
            let Some(flag) = self.seen.get_mut(slot as usize) else {
                return Err(format!("{at}: leaf slot {slot} out of range"));
            };
            if std::mem::replace(flag, true) {
                return Err(format!("prim slot {slot} in two leaves"));
            }
        }
        self.ranges.push((first, count));
        Ok(first as usize..(first + count) as usize)
    }

    /// After the walk: every slot is in a leaf.
    pub(super) fn all_taken(&self) -> Result<(), String> {
        match self.seen.iter().position(|&x| !x) {
            Some(s) => Err(format!("prim slot {s} in no leaf")),
            None => Ok(()),
        }
    }

    /// After the walk: the leaves are exactly `bvh`'s (the same `(first, count)` ranges), as a
    /// tree collapsed or compressed from it must have.
    pub(super) fn same_as(mut self, bvh: &Bvh) -> Result<(), String> {
        let mut binary: Vec<(u32, u32)> =
            bvh.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.left_or_first, n.count)).collect();
        binary.sort_unstable();
        self.ranges.sort_unstable();
        if self.ranges != binary {
            return Err("leaf ranges differ from the binary tree's".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{BuildOptions, BvhNode};

    #[test]
    fn a_leaf_s_slots_are_checked_and_taken_once() {
        let mut l = Leaves::new(6);
        assert_eq!(l.take("node 1", 0, 2, 4), Ok(0..2));
        assert_eq!(l.take("node 2", 2, 5, 4).unwrap_err(), "node 2: leaf holds 5, not 1..=4");
        assert_eq!(l.take("node 2", 2, 0, 4).unwrap_err(), "node 2: leaf holds 0, not 1..=4");
        assert_eq!(l.take("node 3", 5, 2, 4).unwrap_err(), "node 3: leaf slot 6 out of range");
        assert_eq!(l.take("node 4", 1, 2, 4).unwrap_err(), "prim slot 1 in two leaves");
        // A slot between two leaves is in none.
        let mut l = Leaves::new(6);
        l.take("node 1", 0, 2, 4).unwrap();
        l.take("node 2", 3, 3, 4).unwrap();
        assert_eq!(l.all_taken().unwrap_err(), "prim slot 2 in no leaf");
        let mut l = Leaves::new(3);
        l.take("a", 1, 2, 4).unwrap();
        l.take("b", 0, 1, 4).unwrap();
        l.all_taken().unwrap();
        // The binary tree's leaves in another order are the same leaves; other ranges are not.
        let leaf = |first, count| BvhNode { left_or_first: first, count, ..BvhNode::default() };
        let bvh = |leaves: Vec<BvhNode>| Bvh {
            nodes: [vec![BvhNode::default()], leaves].concat(),
            prim_ids: vec![0, 1, 2],
            options: BuildOptions::new(4),
            build_seconds: 0.0,
            build_threads: 1,
            degenerate_excluded: 0,
        };
        let same = |l: &Leaves, b: Bvh| Leaves { seen: l.seen.clone(), ranges: l.ranges.clone() }.same_as(&b);
        same(&l, bvh(vec![leaf(0, 1), leaf(1, 2)])).unwrap();
        assert!(same(&l, bvh(vec![leaf(0, 2), leaf(2, 1)])).unwrap_err().contains("leaf ranges differ"));
    }

    #[test]
    fn unreached_nodes_and_stray_triangles_are_named() {
        assert_eq!(all_reached([true, true, false, false]).unwrap_err(), "node 2 is not reachable from the root");
        all_reached([true]).unwrap();
        let mesh = Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let unit = Aabb { min: glam::Vec3::ZERO, max: glam::Vec3::ONE };
        holds_triangles("node 0", &unit, &[0, PAD_SLOT], &mesh).unwrap();
        assert_eq!(
            holds_triangles("node 0", &unit, &[0, 1], &mesh).unwrap_err(),
            "node 0: leaf box does not contain triangle 1"
        );
    }
}
