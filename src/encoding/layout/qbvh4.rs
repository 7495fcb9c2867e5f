//! Quantized 4-wide nodes: the bvh4 tree (the SAH collapse, `bvh::Collapse::Sah`) with each
//! node's child boxes quantized to 8 bits per plane on a power-of-two grid (`bvh::qbvh4`, which
//! documents the 64-byte node; the grid arithmetic is cwbvh's, `bvh::quantize`);
//! `glsl/layout/qbvh4.glsl` decodes a node's four boxes and runs bvh4's step on them.

use super::{inner_nodes, LayoutNodes, LayoutSpec};
use crate::bvh::qbvh4::{QNode4, Qbvh4};
use crate::bvh::{Aabb, BuildOptions, BvhNode, Collapse, Locality, NodeOrder, NodeTree, WideBvh};
use crate::shared::BVH4_STACK_SIZE;

fn build(binary: &[BvhNode], o: &BuildOptions, order: NodeOrder) -> Result<LayoutNodes, String> {
    let bounds = binary[0].aabb();
    let mut nodes = WideBvh::<4>::collapse_nodes(binary, o, Collapse::Sah);
    order.reorder_wide_as(&mut nodes, &bounds, std::mem::size_of::<QNode4>())?;
    let wide = WideBvh { nodes, bounds, prim_ids: vec![], max_leaf_size: o.max_leaf_size, collapse_seconds: 0.0 };
    let q = Qbvh4::quantize(&wide)?;
    let decoded = q.decoded();
    Ok(LayoutNodes {
        bytes: bytemuck::cast_slice(&q.nodes).to_vec(),
        nodes: q.nodes.len(),
        stack_bound: decoded.stack_bound(),
        sah_cost: decoded.sah_cost(o),
    })
}

/// The locality of a built buffer: bvh4's tree of decoded boxes, at 64 bytes a node.
fn locality(built: &LayoutNodes, bounds: &Aabb) -> Result<Locality, String> {
    let size = std::mem::size_of::<QNode4>();
    let nodes: Vec<_> =
        built.bytes.chunks_exact(size).map(|b| bytemuck::pod_read_unaligned::<QNode4>(b).decoded()).collect();
    let mut tree = NodeTree::wide(&nodes, bounds)?;
    tree.node_bytes = size;
    Ok(tree.locality())
}

pub(super) const LAYOUT: LayoutSpec = LayoutSpec {
    name: "qbvh4",
    title: "QBVH4",
    about: "The bvh4 tree with 8-bit child planes on a per-node grid (cwbvh's quantization at width 4): 64-byte nodes, bvh4's step.",
    width: 4,
    node_bytes: std::mem::size_of::<QNode4>(),
    buffer: "qbvh4 nodes",
    build: Some(build),
    locality: Some(locality),
    placement_bytes: |c| inner_nodes(c) * std::mem::size_of::<QNode4>() as u64,
    stack_size: BVH4_STACK_SIZE,
};
