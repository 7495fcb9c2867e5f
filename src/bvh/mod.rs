//! Bounding volume hierarchy: top-down SAH build into the paper's 32-byte nodes, the wide and
//! compressed layouts collapsed from it, and their CPU traversals.
//!
//! One folder per tree, one file per concept:
//! - `Aabb` (from `scene`): boxes.
//! - [`binary`]: the built tree ([`Bvh`]), its 32-byte node shared with the kernels
//!   ([`BvhNode`]), its statistics ([`BvhStats`]: nodes, depth, leaf-size histogram, SAH cost,
//!   build time, and with the mesh the end-point overlap, [`epo`]) and its invariants.
//! - [`sah`]: the binned and full-sweep SAH builder with a depth bound, serial and parallel.
//! - [`wide`]: the binary tree collapsed into 4- and 8-wide nodes (child boxes in the parent),
//!   their SAH cost, invariants and CPU traversal (issue 15 groundwork).
//! - [`cwbvh`]: the 8-wide tree compressed into Ylitie et al.'s 80-byte nodes (quantized
//!   child boxes, octant-ordered slots), its invariants and its hit-mask traversal on the CPU.
//! - [`qbvh4`]: the 4-wide tree with its child boxes quantized as cwbvh's (64-byte nodes), its
//!   invariants and its CPU model (bvh4's walk over the decoded boxes); [`quantize`]: the grid
//!   arithmetic both quantized layouts share.
//! - [`order`]: the tree's node order in memory (as built, depth first, breadth first, treelets),
//!   applied to any layout's node array by renaming child indices, and the locality of a
//!   descent (issue 27).
//!
//! Written once for every layout:
//! - [`hit`]: the CPU traversals' hit and the rule for two hits at the same distance (the lower
//!   triangle id; not the kernels' rule, the module says why);
//! - `walk`: one ray's walk through a CPU traversal (its box test, the leaf loop, the work it
//!   counts, [`WideSteps`]); [`slab`]: the box tests;
//! - `validate`: what every layout's validator checks the same way (each leaf's slots,
//!   the tree against the binary one it was built from).

pub mod binary;
pub mod cwbvh;
pub mod epo;
pub mod hit;
pub mod order;
pub mod qbvh4;
pub mod quantize;
pub mod sah;
pub mod slab;
#[cfg(test)]
mod testing;
mod validate;
mod walk;
pub mod wide;

pub use crate::scene::Aabb;
pub use binary::{Bvh, BvhNode, BvhStats};
pub use cwbvh::{CwBvh, CwNode, CwStats, SlotOrder};
pub use hit::WideHit;
pub use order::{Locality, NodeOrder, NodeTree};
pub use sah::{BuildOptions, Builder, LeafPolicy, MAX_DEPTH, MAX_LEAF_SIZE, PAPER_LEAF_SIZES};
pub use walk::WideSteps;
pub use wide::{Bvh4, Bvh4Node, Bvh8, Bvh8Node, Collapse, Wide2Node, WideBvh, WideNode, WideStats};

/// Marks a padding slot in [`Bvh::prim_ids`]: a degenerate triangle that can never be hit.
pub const PAD_SLOT: u32 = u32::MAX;
