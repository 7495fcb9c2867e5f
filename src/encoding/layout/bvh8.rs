//! 8-wide nodes: the SAH tree collapsed with Ylitie, Karras & Laine's dynamic programme (HPG
//! 2017, sec. 3.1; `bvh::Collapse::Sah`) into 256-byte structure-of-arrays nodes
//! (`bvh::Bvh8Node`); `glsl/layout/bvh8.glsl` tests a node's occupied children per step, sorts
//! the hit ones near to far and pushes all but the nearest.

use super::{inner_nodes, wide_locality, wide_nodes, LayoutSpec};
use crate::bvh::Bvh8Node;
use crate::shared::BVH8_STACK_SIZE;

pub(super) const LAYOUT: LayoutSpec = LayoutSpec {
    name: "bvh8",
    title: "BVH8",
    about: "The SAH tree collapsed into 8-wide 256-byte nodes, child boxes in the parent.",
    width: 8,
    node_bytes: std::mem::size_of::<Bvh8Node>(),
    buffer: "bvh8 nodes",
    build: Some(wide_nodes::<8>),
    locality: Some(wide_locality::<8>),
    placement_bytes: |c| inner_nodes(c) * std::mem::size_of::<Bvh8Node>() as u64,
    stack_size: BVH8_STACK_SIZE,
};
