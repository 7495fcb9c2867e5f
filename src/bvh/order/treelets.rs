//! The treelets of [`NodeOrder::Treelets`]: Gil & Itai's greedy packing of the tree into pages
//! (the module docs of [`super`]).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::tree::NodeTree;
#[cfg(doc)]
use super::NodeOrder;

/// A place in a priority queue of child groups: the heaviest first, then the earliest in
/// depth-first order.
struct Candidate {
    weight: f64,
    rank: u32,
    group: (u32, u32),
}

impl PartialEq for Candidate {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for Candidate {
    fn cmp(&self, o: &Self) -> Ordering {
        self.weight.total_cmp(&o.weight).then(o.rank.cmp(&self.rank))
    }
}

impl NodeTree {
    /// The treelets of [`NodeOrder::Treelets`] with at most `bytes` of nodes each (a child group
    /// larger than that is a treelet alone), in layout order; each lists its nodes in layout
    /// order (module docs).
    pub fn treelets(&self, bytes: usize) -> Vec<Vec<u32>> {
        let mut out = vec![];
        if self.is_empty() {
            return out;
        }
        let budget = (bytes / self.node_bytes).max(1);
        // Depth-first rank of every node: treelet roots are laid out in it, and it breaks ties.
        let mut rank = vec![0u32; self.len()];
        for (k, &i) in self.depth_first().iter().enumerate() {
            rank[i as usize] = k as u32;
        }
        let mut roots = vec![(0u32, 1u32)];
        while let Some(root) = roots.pop() {
            let (mut taken, mut size) = (vec![], 0);
            let mut heap =
                BinaryHeap::from([Candidate { weight: f64::INFINITY, rank: rank[root.0 as usize], group: root }]);
            let mut frontier = vec![];
            while let Some(c) = heap.pop() {
                if size > 0 && size + c.group.1 as usize > budget {
                    frontier.push(c.group);
                    continue;
                }
                taken.push(c.group);
                size += c.group.1 as usize;
                for i in self.group(c.group) {
                    let g = self.kids[i];
                    if g.1 > 0 {
                        heap.push(Candidate { weight: self.area[i], rank: rank[g.0 as usize], group: g });
                    }
                }
            }
            // Inside the treelet, depth first (a first child's group right after its parent's,
            // as in the depth-first order); the next treelets' roots, the first in depth-first
            // order on top.
            taken.sort_by_key(|g| rank[g.0 as usize]);
            frontier.sort_by_key(|g| std::cmp::Reverse(rank[g.0 as usize]));
            roots.extend(frontier);
            out.push(taken.into_iter().flat_map(|g| self.group(g).map(|i| i as u32)).collect());
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::order::{NodeOrder, TREELET_BYTES};
    use crate::bvh::testing::grid_trees;
    use crate::bvh::{Collapse, WideBvh};

    /// Treelets: within the byte budget (a bigger group alone), connected (every group but the
    /// first hangs below a node of the same treelet), the treelets' roots in depth-first order,
    /// and the order is their concatenation, so each treelet is contiguous.
    #[test]
    fn treelets_are_contiguous_connected_and_within_their_budget() {
        let check = |t: &NodeTree, bytes: usize, what: &str| {
            let treelets = t.treelets(bytes);
            let mut parent = vec![u32::MAX; t.len()];
            for p in 0..t.len() {
                for c in t.group(t.kids[p]) {
                    parent[c] = p as u32;
                }
            }
            let mut treelet_of = vec![usize::MAX; t.len()];
            for (k, tl) in treelets.iter().enumerate() {
                tl.iter().for_each(|&i| treelet_of[i as usize] = k);
            }
            let dfs: Vec<u32> = t.depth_first();
            let mut rank = vec![0; t.len()];
            dfs.iter().enumerate().for_each(|(k, &i)| rank[i as usize] = k);
            let mut last_root = None;
            for (k, tl) in treelets.iter().enumerate() {
                let root = tl[0] as usize;
                let group = if root == 0 { 1 } else { t.kids[parent[root] as usize].1 as usize };
                assert!(
                    tl.len() * t.node_bytes <= bytes || tl.len() == group,
                    "{what}: treelet {k} holds {} nodes",
                    tl.len()
                );
                for &i in &tl[group..] {
                    let p = parent[i as usize];
                    assert_eq!(treelet_of[p as usize], k, "{what}: treelet {k} is connected");
                }
                assert!(last_root.is_none_or(|r| r < rank[root]), "{what}: treelet roots in depth-first order");
                last_root = Some(rank[root]);
            }
            if bytes == TREELET_BYTES {
                assert_eq!(
                    treelets.concat(),
                    t.placement(NodeOrder::Treelets),
                    "{what}: the order is the treelets one after another"
                );
            }
            treelets.len()
        };
        for bvh in grid_trees() {
            let t = NodeTree::binary(&bvh.nodes);
            for bytes in [64, 256, TREELET_BYTES] {
                let n = check(&t, bytes, "bvh2");
                assert!(n >= t.len() * t.node_bytes / bytes, "bvh2 {bytes}: {n} treelets");
            }
            let w = WideBvh::<8>::collapse_with(&bvh, Collapse::Sah);
            check(&NodeTree::wide(&w.nodes, &w.bounds).unwrap(), 1024, "bvh8");
        }
    }
}
