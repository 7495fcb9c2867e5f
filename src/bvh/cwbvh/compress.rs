//! The compressed tree built from a binary one ([`CwBvh::build_with`]): the SAH collapse into
//! 8-wide nodes, each node's children assigned to slots in octant order, their boxes quantized
//! on the node's grid, leaves written to the leaf table.

use std::time::Instant;

use bytemuck::Zeroable;
use glam::Vec3;

use super::slots::{assign_slots, slot_costs};
use super::{CwBvh, CwNode, SlotOrder, CW_NODE_WORDS, INNER_BIT0, META_PRESENT};
use crate::bvh::quantize::quantize_boxes;
use crate::bvh::{Aabb, BuildOptions, Bvh, BvhNode, Collapse, WideBvh, WideNode};
use crate::shared::{self, LEAF_ENTRY_FIRST_LIMIT, LEAF_ENTRY_MAX_COUNT};

/// A leaf-table entry (`crate::shared::leaf_entry`), or why it cannot hold the leaf: more than
/// 2^27 units, or 32 and more in one leaf (the binary tree's limit is 16).
fn leaf_entry(first: u32, count: u32) -> Result<u32, String> {
    if u64::from(first) >= LEAF_ENTRY_FIRST_LIMIT || count == 0 || count > LEAF_ENTRY_MAX_COUNT {
        return Err(format!("a leaf of {count} units from unit {first} does not fit a leaf-table entry"));
    }
    Ok(shared::leaf_entry(first, count))
}

/// One child being laid out: its true box and what it is.
#[derive(Clone, Copy)]
enum Kid {
    /// A wide node's index.
    Inner(usize, Aabb),
    /// `(first_unit, count)`.
    Leaf(u32, u32, Aabb),
}

impl Kid {
    fn bounds(&self) -> Aabb {
        match *self {
            Kid::Inner(_, b) | Kid::Leaf(_, _, b) => b,
        }
    }
}

/// Quantizes `kids` (in their slots) against the grid of their union; fills `p`, `e` and the
/// planes of `node`.
fn quantize_node(node: &mut CwNode, kids: &[(usize, Kid)]) -> Result<(), String> {
    let boxes: Vec<Aabb> = kids.iter().map(|(_, k)| k.bounds()).collect();
    let (grid, planes) = quantize_boxes(&boxes)?;
    (node.p, node.e) = (grid.p, grid.e);
    for (&(s, _), &q) in kids.iter().zip(&planes) {
        node.set_q(s, q);
    }
    Ok(())
}

impl CwBvh {
    /// The binary tree collapsed ([`Collapse::Sah`]) and compressed, slots in
    /// [`SlotOrder::Greedy`] order.
    pub fn build(bvh: &Bvh) -> Result<CwBvh, String> {
        Self::build_with(bvh, SlotOrder::Greedy)
    }

    pub fn build_with(bvh: &Bvh, order: SlotOrder) -> Result<CwBvh, String> {
        let t0 = Instant::now();
        let mut cw = Self::from_binary_nodes(&bvh.nodes, &bvh.options, order)?;
        cw.prim_ids = bvh.prim_ids.clone();
        cw.build_seconds = t0.elapsed().as_secs_f64();
        Ok(cw)
    }

    /// The compressed tree of a binary node array (as [`WideBvh::collapse_nodes`] takes it:
    /// an encoding's nodes give leaves in the encoding's units). `prim_ids` is left empty.
    pub fn from_binary_nodes(binary: &[BvhNode], o: &BuildOptions, order: SlotOrder) -> Result<CwBvh, String> {
        let t0 = Instant::now();
        let wide = WideBvh::<8>::collapse_nodes(binary, o, Collapse::Sah);
        let mut cw = Self::from_wide(&wide, binary[0].aabb(), order)?;
        cw.max_leaf_size = o.max_leaf_size;
        cw.build_seconds = t0.elapsed().as_secs_f64();
        Ok(cw)
    }

    /// Compresses 8-wide nodes (root at 0; `bounds` the root's box).
    pub fn from_wide(wide: &[WideNode<8>], bounds: Aabb, order: SlotOrder) -> Result<CwBvh, String> {
        let t0 = Instant::now();
        let mut nodes = vec![CwNode::zeroed()];
        let mut leaves: Vec<u32> = vec![];
        // (compressed node to fill, wide node it comes from)
        let mut work = std::collections::VecDeque::from([(0usize, 0usize)]);
        while let Some((ci, wi)) = work.pop_front() {
            let w = &wide[wi];
            let kids: Vec<Kid> = (0..w.children())
                .map(|s| {
                    let b = w.child_box(s);
                    if w.is_leaf(s) {
                        Kid::Leaf(w.child[s], w.count[s], b)
                    } else {
                        Kid::Inner(w.child[s] as usize, b)
                    }
                })
                .collect();
            let mut union = Aabb::EMPTY;
            kids.iter().filter(|k| !k.bounds().is_empty()).for_each(|k| union.grow(&k.bounds()));
            let centre = if union.is_empty() { Vec3::ZERO } else { union.center() };
            let centres: Vec<Vec3> =
                kids.iter().map(|k| if k.bounds().is_empty() { centre } else { k.bounds().center() }).collect();
            let slots = assign_slots(order, &slot_costs(centre, &centres));
            let mut placed: Vec<(usize, Kid)> = slots.iter().copied().zip(kids.iter().copied()).collect();
            placed.sort_by_key(|&(s, _)| s);
            let mut node = CwNode::zeroed();
            node.child_base = nodes.len() as u32;
            node.leaf_base = leaves.len() as u32;
            let mut rank = 0u8;
            for &(s, kid) in &placed {
                match kid {
                    Kid::Inner(child, _) => {
                        node.imask |= 1 << s;
                        node.meta[s] = META_PRESENT | (INNER_BIT0 as u8 + s as u8);
                        work.push_back((nodes.len(), child));
                        nodes.push(CwNode::zeroed());
                    }
                    Kid::Leaf(first, count, _) => {
                        node.meta[s] = META_PRESENT | rank;
                        rank += 1;
                        leaves.push(leaf_entry(first, count)?);
                    }
                }
            }
            quantize_node(&mut node, &placed)?;
            nodes[ci] = node;
        }
        let table = (nodes.len() * CW_NODE_WORDS) as u64;
        if table + leaves.len() as u64 > u32::MAX as u64 {
            return Err(format!("{} nodes and {} leaves overflow 32-bit word indices", nodes.len(), leaves.len()));
        }
        for n in &mut nodes {
            n.leaf_base += table as u32;
        }
        Ok(CwBvh {
            nodes,
            leaves,
            bounds,
            prim_ids: vec![],
            max_leaf_size: 0,
            slot_order: order,
            build_seconds: t0.elapsed().as_secs_f64(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::testing::grid;
    use crate::rays::Ray;
    use crate::scene::Mesh;

    #[test]
    fn grid_tree_is_valid_for_every_slot_order() {
        let mesh = grid(3000);
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            for how in [SlotOrder::Greedy, SlotOrder::Exact, SlotOrder::Plain] {
                let cw = CwBvh::build_with(&bvh, how).unwrap();
                cw.validate(&bvh, &mesh).unwrap_or_else(|e| panic!("leaf {leaf} {how:?}: {e}"));
                let w8 = WideBvh::<8>::collapse(&bvh);
                assert_eq!(cw.nodes.len(), w8.nodes.len());
                assert_eq!(cw.leaves.len(), w8.stats(&bvh.options).leaves);
            }
        }
    }

    #[test]
    fn one_leaf_and_all_degenerate_trees() {
        let mesh = grid(3);
        let bvh = Bvh::build(&mesh, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &mesh).unwrap();
        assert_eq!((cw.nodes.len(), cw.leaves.len(), cw.leaves[0] & 31), (1, 1, 3));
        assert_eq!(cw.stack_bound(), 0);
        let deg = Mesh::from_triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], vec![[0, 1, 1]]);
        let bvh = Bvh::build(&deg, &BuildOptions::new(4));
        let cw = CwBvh::build(&bvh).unwrap();
        cw.validate(&bvh, &deg).unwrap();
        let r = Ray::new([0.5, 0.0, -1.0], [0.0, 0.0, 1.0]);
        assert!(!cw.trace(&r, false, |_, _| Some((1.0, 0.0, 0.0))).0.is_hit(), "padding is never tested");
    }
}
