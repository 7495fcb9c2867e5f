//! Compressed 8-wide nodes (Ylitie, Karras & Laine, HPG 2017): the SAH 8-wide collapse
//! (`bvh::Collapse::Sah`) compressed into 80-byte nodes whose child boxes are quantized to 8
//! bits per plane on a power-of-two grid, slots in octant order, plus a leaf table of the
//! encoding's `(first << 5) | count` entries (`bvh::cwbvh`, which also documents the format and
//! the outward rounding); `glsl/layout/cwbvh.glsl` walks it with the paper's hit-mask node
//! groups.

use super::{inner_nodes, LayoutNodes, LayoutSpec};
use crate::bvh::cwbvh::CW_NODE_TEXELS;
use crate::bvh::{Aabb, Locality};
use crate::bvh::{BuildOptions, BvhNode, CwBvh, CwNode, NodeOrder, NodeTree, SlotOrder};
use crate::shared::CWBVH_STACK_SIZE;

fn build(binary: &[BvhNode], o: &BuildOptions, order: NodeOrder) -> Result<LayoutNodes, String> {
    let mut cw = CwBvh::from_binary_nodes(binary, o, SlotOrder::Greedy)?;
    order.reorder_cwbvh(&mut cw)?;
    Ok(LayoutNodes {
        bytes: bytemuck::cast_slice(&cw.words()).to_vec(),
        nodes: cw.nodes.len(),
        stack_bound: cw.stack_bound(),
        sah_cost: cw.sah_cost(o),
    })
}

/// The locality of a built buffer: its nodes come first (the leaf table after them).
fn locality(built: &LayoutNodes, bounds: &Aabb) -> Result<Locality, String> {
    let size = std::mem::size_of::<CwNode>();
    let bytes = built.bytes.get(..built.nodes * size).ok_or("a cwbvh buffer shorter than its nodes")?;
    let nodes: Vec<CwNode> = bytes.chunks_exact(size).map(bytemuck::pod_read_unaligned).collect();
    Ok(NodeTree::cwbvh(&nodes, bounds).locality())
}

pub(super) const LAYOUT: LayoutSpec = LayoutSpec {
    name: "cwbvh",
    title: "CWBVH",
    about:
        "Ylitie et al.'s compressed 8-wide BVH: 80-byte nodes, 8-bit child planes, octant-ordered hit-mask traversal.",
    width: 8,
    node_bytes: std::mem::size_of::<CwNode>(),
    buffer: "cwbvh nodes",
    build: Some(build),
    locality: Some(locality),
    // The nodes, then one 4-byte leaf-table entry per binary leaf (at most half the binary
    // nodes, rounded up), padded to a whole texel.
    placement_bytes: |c| {
        let words = inner_nodes(c) * 4 * CW_NODE_TEXELS as u64 + c.nodes.div_ceil(2);
        words.div_ceil(4) * 16
    },
    stack_size: CWBVH_STACK_SIZE,
};
