//! What the builder is asked for: the leaf size, when a node becomes a leaf, the split finder
//! and the SAH's costs ([`BuildOptions`]), and the limits every tree obeys.

use crate::named::named_enum;

/// Deepest leaf allowed (root at depth 0). The traversal pushes at most one node per level, so
/// its stack of `STACK_SIZE` entries never overflows.
pub const MAX_DEPTH: u32 = crate::shared::STACK_SIZE;

/// Largest supported `max_leaf_size`.
pub const MAX_LEAF_SIZE: u32 = 16;

/// The triangles per leaf Shumskiy & Parshin study (their Tables 1-4).
pub const PAPER_LEAF_SIZES: [u32; 6] = [1, 2, 3, 4, 8, 16];

#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Builder {
    /// Binned SAH with this many bins per axis.
    Binned { bins: u32 },
    /// Full-sweep SAH: every split position along every axis.
    Sweep,
}

impl Default for Builder {
    fn default() -> Self {
        Builder::Binned { bins: 32 }
    }
}

impl std::fmt::Display for Builder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Builder::Binned { bins } => write!(f, "binned SAH ({bins} bins)"),
            Builder::Sweep => write!(f, "full-sweep SAH"),
        }
    }
}

named_enum! {
    /// When a node becomes a leaf.
    #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
    #[serde(rename_all = "kebab-case")]
    pub enum LeafPolicy: "leaf policy" {
        /// The paper's: a node with at most `max_leaf_size` triangles is a leaf, so leaves hold
        /// close to that many ("try to fill BVH with four triangles per node", sec. 3.1); SAH
        /// chooses the split planes above that.
        Fill = "fill" (default),
        /// SAH decides: a node is a leaf when that is cheaper than its best split (or it holds one
        /// triangle); `max_leaf_size` is only an upper bound.
        Sah = "sah",
    }
}

#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BuildOptions {
    /// Most triangles in one leaf (1..=16).
    pub max_leaf_size: u32,
    pub leaf_policy: LeafPolicy,
    pub builder: Builder,
    /// SAH cost of one traversal step, relative to `cost_intersect`.
    pub cost_traversal: f32,
    /// SAH cost of one ray-triangle test (of one group, when `sah_group` > 1).
    pub cost_intersect: f32,
    /// Triangles the intersector tests at once: 1, or 4 for the Quad methods. The SAH prices a
    /// leaf of n triangles at ceil(n / sah_group) tests, as tinybvh and madmann91/bvh price
    /// SIMD leaves, so splits that fill whole quads are preferred. 1 is the classic SAH.
    pub sah_group: u32,
}

impl BuildOptions {
    /// Intersection tests for a leaf of `n` triangles: ceil(n / sah_group).
    pub fn tests(&self, n: usize) -> f64 {
        n.div_ceil(self.sah_group.max(1) as usize) as f64
    }

    /// Refuses options the builder cannot honour, naming the option: a leaf size outside
    /// 1..=16, or a SAH grouping outside 1..=16 (what `Bvh::build` asserts).
    pub fn check(&self) -> crate::error::Result<()> {
        let usage = |m: String| Err(crate::error::Error::Usage(m));
        if !(1..=MAX_LEAF_SIZE).contains(&self.max_leaf_size) {
            return usage(format!("--leaf-size {}: must be 1..={MAX_LEAF_SIZE}", self.max_leaf_size));
        }
        if !(1..=MAX_LEAF_SIZE).contains(&self.sah_group) {
            return usage(format!(
                "--sah-group {}: must be 1..={MAX_LEAF_SIZE} (4 prices leaves in quads)",
                self.sah_group
            ));
        }
        Ok(())
    }

    /// Serialises the options as every report and option record names them, `leaf_size`,
    /// `leaf_policy`, `sah_group` (the builder and the costs are the defaults there); a struct
    /// holding the options writes them among its own fields with
    /// `#[serde(flatten, serialize_with = "BuildOptions::serialize_fields")]`.
    pub fn serialize_fields<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut st = s.serialize_struct("BuildOptions", 3)?;
        st.serialize_field("leaf_size", &self.max_leaf_size)?;
        st.serialize_field("leaf_policy", &self.leaf_policy)?;
        st.serialize_field("sah_group", &self.sah_group)?;
        st.end()
    }

    pub fn new(max_leaf_size: u32) -> Self {
        BuildOptions {
            max_leaf_size,
            leaf_policy: LeafPolicy::default(),
            builder: Builder::default(),
            cost_traversal: 1.0,
            cost_intersect: 1.0,
            sah_group: 1,
        }
    }
}
