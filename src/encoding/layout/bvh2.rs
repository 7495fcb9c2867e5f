//! The paper's binary tree: 32-byte nodes (`bvh::BvhNode`), one node per step of
//! `glsl/traversal/while_if.glsl`'s loop (`glsl/layout/bvh2.glsl`, the default layout) (Shumskiy & Parshin, appendix 8.3; Aila & Laine 2009).

use super::LayoutSpec;
use crate::bvh::BvhNode;
use crate::shared::STACK_SIZE;

pub(super) const LAYOUT: LayoutSpec = LayoutSpec {
    name: "bvh2",
    title: "BVH2",
    about: "The paper's binary tree of 32-byte nodes, while-if traversal (every kernel).",
    width: 2,
    node_bytes: std::mem::size_of::<BvhNode>(),
    buffer: "bvh nodes",
    build: None,
    locality: None,
    placement_bytes: |c| c.nodes * std::mem::size_of::<BvhNode>() as u64,
    stack_size: STACK_SIZE,
};
