//! How close in memory the nodes a descent reads are ([`Locality`]), for any layout's node
//! array in any order.

use serde::Serialize;

use super::tree::{Fetch, NodeTree};

/// Bytes of a cache line and of a page, for [`Locality`].
pub const LINE_BYTES: usize = 64;
pub const PAGE_BYTES: usize = 4096;

/// How close in memory the nodes a descent reads are: over every step from a node to one of
/// its children, weighted by how often a ray takes it (the child's surface area), the 64-byte
/// lines and 4 KiB pages the child's visit reads that its parent's visit did not. A model of one
/// root-to-leaf path, cheap and the same for every layout (what a visit reads: [`Fetch`]); it
/// counts no reuse between the paths of one ray or between rays, and not cwbvh's leaf table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Locality {
    /// New 64-byte lines per step, mean.
    pub lines_per_step: f64,
    /// New 4 KiB pages per step, mean (the share of steps that leave the parent's pages).
    pub pages_per_step: f64,
}

impl NodeTree {
    /// The bytes a visit of node `i` reads (an empty range for a binary leaf).
    fn fetched(&self, i: usize) -> std::ops::Range<usize> {
        let r = match self.fetch {
            Fetch::Node => i..i + 1,
            Fetch::Children => self.group(self.kids[i]),
        };
        r.start * self.node_bytes..r.end * self.node_bytes
    }

    /// [`Locality`] of the array as it is (apply an order first to measure it).
    pub fn locality(&self) -> Locality {
        // Units of `unit` bytes in `a` and not in `b`.
        fn fresh(a: &std::ops::Range<usize>, b: &std::ops::Range<usize>, unit: usize) -> usize {
            if a.is_empty() {
                return 0;
            }
            let (a0, a1) = (a.start / unit, (a.end - 1) / unit);
            let all = a1 - a0 + 1;
            if b.is_empty() {
                return all;
            }
            let (b0, b1) = (b.start / unit, (b.end - 1) / unit);
            let overlap = (a1.min(b1) + 1).saturating_sub(a0.max(b0));
            all - overlap
        }
        let (mut w, mut lines, mut pages) = (0.0, 0.0, 0.0);
        for p in 0..self.len() {
            let from = self.fetched(p);
            for c in self.group(self.kids[p]) {
                let to = self.fetched(c);
                if to.is_empty() {
                    continue;
                }
                let a = self.area[c];
                w += a;
                lines += a * fresh(&to, &from, LINE_BYTES) as f64;
                pages += a * fresh(&to, &from, PAGE_BYTES) as f64;
            }
        }
        if w > 0.0 {
            Locality { lines_per_step: lines / w, pages_per_step: pages / w }
        } else {
            Locality::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::bvh::order::{NodeOrder, NodeTree};
    use crate::bvh::testing::grid;
    use crate::bvh::{BuildOptions, Bvh};

    /// Locality: treelets leave the parent's page on fewer steps than breadth first; bvh2's
    /// child pairs straddle two lines (the root alone at 0 puts every pair at an odd index).
    #[test]
    fn treelets_leave_pages_less_than_breadth_first() {
        let bvh = Bvh::build(&grid(20_000), &BuildOptions::new(1));
        let l = |order: NodeOrder| {
            let mut nodes = bvh.nodes.clone();
            order.reorder_binary(&mut nodes).unwrap();
            NodeTree::binary(&nodes).locality()
        };
        let (bfs, tl) = (l(NodeOrder::BreadthFirst), l(NodeOrder::Treelets));
        assert!(tl.pages_per_step < 0.5 * bfs.pages_per_step, "treelets {tl:?}, breadth first {bfs:?}");
        // A pair straddles two lines; depth first inside the treelet shares one with the parent's
        // pair on a first child's step.
        assert!(tl.lines_per_step > 1.2 && tl.lines_per_step < bfs.lines_per_step, "{tl:?}");
        eprintln!("depth first {:?}\nbreadth first {bfs:?}\ntreelets {tl:?}", l(NodeOrder::DepthFirst));
    }
}
