//! A node array as the orders see it ([`NodeTree`]): each node's child group and visit
//! probability, for any layout, and the orders' walks over it.

use std::collections::VecDeque;

use super::{NodeOrder, TREELET_BYTES};
use crate::bvh::{Aabb, BvhNode, CwNode, WideNode};

/// What a visit of a node reads from the node buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fetch {
    /// Its children's nodes (bvh2: the parent's `left_or_first` names the pair whose boxes are
    /// tested).
    Children,
    /// The node itself (the wide layouts: the children's boxes are in the parent).
    Node,
}

/// A node array as the orders see it: per node, the nodes directly below it (one run of
/// consecutive indices), and the chance a ray visits it.
#[derive(Clone, Debug)]
pub struct NodeTree {
    /// Node `i`'s child group: `(first, len)`, `len` 0 for none.
    pub(super) kids: Vec<(u32, u32)>,
    /// Surface area of node `i`'s box (the SAH's visit probability, up to a constant).
    pub(super) area: Vec<f64>,
    /// Bytes per node in the buffer.
    pub node_bytes: usize,
    pub fetch: Fetch,
}

impl NodeTree {
    /// The binary nodes ([`BvhNode`], as `Bvh::nodes` or an encoding's): an inner node's group is
    /// its two children.
    pub fn binary(nodes: &[BvhNode]) -> NodeTree {
        NodeTree {
            kids: nodes.iter().map(|n| if n.is_leaf() { (0, 0) } else { (n.left_or_first, 2) }).collect(),
            area: nodes.iter().map(|n| n.aabb().area()).collect(),
            node_bytes: std::mem::size_of::<BvhNode>(),
            fetch: Fetch::Children,
        }
    }

    /// Wide nodes (root at 0, `bounds` the root's box): a node's group is its inner children,
    /// or an error where they are not consecutive in slot order.
    pub fn wide<const N: usize>(nodes: &[WideNode<N>], bounds: &Aabb) -> Result<NodeTree, String> {
        let mut t = NodeTree {
            kids: vec![(0, 0); nodes.len()],
            area: vec![0.0; nodes.len()],
            node_bytes: std::mem::size_of::<WideNode<N>>(),
            fetch: Fetch::Node,
        };
        if let Some(a) = t.area.first_mut() {
            *a = bounds.area();
        }
        for (i, n) in nodes.iter().enumerate() {
            let mut group: Option<(u32, u32)> = None;
            for s in (0..n.children()).filter(|&s| !n.is_leaf(s)) {
                let (first, len) = group.unwrap_or((n.child[s], 0));
                if n.child[s] != first + len || n.child[s] as usize >= nodes.len() {
                    return Err(format!("node {i}'s inner children are not consecutive in slot order"));
                }
                t.area[n.child[s] as usize] = n.child_box(s).area();
                group = Some((first, len + 1));
            }
            t.kids[i] = group.unwrap_or((0, 0));
        }
        Ok(t)
    }

    /// Compressed wide nodes: a node's group is its inner children from `child_base`.
    pub fn cwbvh(nodes: &[CwNode], bounds: &Aabb) -> NodeTree {
        let mut t = NodeTree {
            kids: vec![(0, 0); nodes.len()],
            area: vec![0.0; nodes.len()],
            node_bytes: std::mem::size_of::<CwNode>(),
            fetch: Fetch::Node,
        };
        if let Some(a) = t.area.first_mut() {
            *a = bounds.area();
        }
        for (i, n) in nodes.iter().enumerate() {
            let inner = n.imask.count_ones();
            if inner > 0 {
                t.kids[i] = (n.child_base, inner);
            }
            for s in (0..8).filter(|&s| n.is_inner(s)) {
                t.area[n.inner_child(s) as usize] = n.child_box(s).area();
            }
        }
        t
    }

    /// Nodes in the array.
    pub fn len(&self) -> usize {
        self.kids.len()
    }

    pub fn is_empty(&self) -> bool {
        self.kids.is_empty()
    }

    /// Node `i`'s child group, `(first, len)`.
    pub fn kids(&self, i: usize) -> (u32, u32) {
        self.kids[i]
    }

    pub(super) fn group(&self, (first, len): (u32, u32)) -> std::ops::Range<usize> {
        first as usize..(first + len) as usize
    }

    /// Every node's depth (root 0).
    pub fn depths(&self) -> Vec<u32> {
        let mut d = vec![0; self.len()];
        for i in self.depth_first() {
            for c in self.group(self.kids[i as usize]) {
                d[c] = d[i as usize] + 1;
            }
        }
        d
    }

    /// The nodes in depth-first pre-order of their child groups, first child first.
    pub(super) fn depth_first(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.len());
        if self.is_empty() {
            return out;
        }
        let mut stack = vec![(0u32, 1u32)];
        while let Some(g) = stack.pop() {
            let r = self.group(g);
            out.extend(r.clone().map(|i| i as u32));
            for i in r.rev() {
                if self.kids[i].1 > 0 {
                    stack.push(self.kids[i]);
                }
            }
        }
        out
    }

    fn breadth_first(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.len());
        if self.is_empty() {
            return out;
        }
        let mut queue = VecDeque::from([(0u32, 1u32)]);
        while let Some(g) = queue.pop_front() {
            for i in self.group(g) {
                out.push(i as u32);
                if self.kids[i].1 > 0 {
                    queue.push_back(self.kids[i]);
                }
            }
        }
        out
    }

    /// The nodes in `order`, as old indices: entry `k` is the node placed at `k`.
    pub fn placement(&self, order: NodeOrder) -> Vec<u32> {
        match order {
            NodeOrder::Built => (0..self.len() as u32).collect(),
            NodeOrder::DepthFirst => self.depth_first(),
            NodeOrder::BreadthFirst => self.breadth_first(),
            NodeOrder::Treelets => self.treelets(TREELET_BYTES).concat(),
        }
    }

    /// Every node's index in `order` (entry `i`: the new index of node `i`); `None` for
    /// [`NodeOrder::Built`], or an error where the groups do not cover the array once (a node
    /// below two parents or below none: not a tree these orders can move).
    pub fn permutation(&self, order: NodeOrder) -> Result<Option<Vec<u32>>, String> {
        if order == NodeOrder::Built {
            return Ok(None);
        }
        let placed = self.placement(order);
        let mut new = vec![u32::MAX; self.len()];
        for (k, &i) in placed.iter().enumerate() {
            if std::mem::replace(&mut new[i as usize], k as u32) != u32::MAX {
                return Err(format!("node {i} is in two child groups; the {order} order needs a tree"));
            }
        }
        if let Some(i) = new.iter().position(|&k| k == u32::MAX) {
            return Err(format!("node {i} is in no child group below the root; the {order} order needs a tree"));
        }
        Ok(Some(new))
    }
}
