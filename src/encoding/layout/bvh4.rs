//! 4-wide nodes: the SAH tree collapsed with Ylitie, Karras & Laine's dynamic programme (HPG
//! 2017, sec. 3.1; `bvh::Collapse::Sah`) into 128-byte structure-of-arrays nodes
//! (`bvh::Bvh4Node`), the children's boxes in the parent; `glsl/layout/bvh4.glsl` tests a node's
//! occupied children per step and visits them near to far.

use super::{inner_nodes, wide_locality, wide_nodes, LayoutSpec};
use crate::bvh::Bvh4Node;
use crate::shared::BVH4_STACK_SIZE;

pub(super) const LAYOUT: LayoutSpec = LayoutSpec {
    name: "bvh4",
    title: "BVH4",
    about: "The SAH tree collapsed into 4-wide 128-byte nodes, child boxes in the parent.",
    width: 4,
    node_bytes: std::mem::size_of::<Bvh4Node>(),
    buffer: "bvh4 nodes",
    build: Some(wide_nodes::<4>),
    locality: Some(wide_locality::<4>),
    placement_bytes: |c| inner_nodes(c) * std::mem::size_of::<Bvh4Node>() as u64,
    stack_size: BVH4_STACK_SIZE,
};
