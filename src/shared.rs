//! The host/kernel contract: the constants `glsl/shared.glsl` defines (bindings, sizes, ids;
//! build.rs turns every `#define NAME <integer>` there into a `pub const NAME: u32` here, so the
//! two cannot drift apart) and the texel formats the kernels read scene buffers as
//! (`glsl/types.glsl`).

include!(concat!(env!("OUT_DIR"), "/shared_consts.rs"));

/// `LEAF_ENTRY(first, count)` of `glsl/shared.glsl`: the packed entry the traversals keep of a
/// node (their stacks hold these) and the cwbvh leaf table's entries. `count` is a leaf's
/// triangles or units (0: an inner node), at most [`LEAF_ENTRY_MAX_COUNT`]; `first` is below
/// [`LEAF_ENTRY_FIRST_LIMIT`].
pub const fn leaf_entry(first: u32, count: u32) -> u32 {
    (first << LEAF_ENTRY_COUNT_BITS) | count
}

/// `LEAF_ENTRY_FIRST(e)`: the first slot, unit or child of a packed entry.
pub const fn leaf_entry_first(e: u32) -> u32 {
    e >> LEAF_ENTRY_COUNT_BITS
}

/// `LEAF_ENTRY_COUNT(e)`: the count of a packed entry.
pub const fn leaf_entry_count(e: u32) -> u32 {
    e & LEAF_ENTRY_MAX_COUNT
}

/// Largest count a packed entry holds.
pub const LEAF_ENTRY_MAX_COUNT: u32 = (1 << LEAF_ENTRY_COUNT_BITS) - 1;
/// Firsts a packed entry holds: `0..LEAF_ENTRY_FIRST_LIMIT`.
pub const LEAF_ENTRY_FIRST_LIMIT: u64 = 1 << (32 - LEAF_ENTRY_COUNT_BITS);

/// How the kernels read a scene buffer: as texels of this format (`glsl/types.glsl`); named by
/// the GLSL image format in files (a repro's `cell.json`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Texel {
    /// 16 bytes, four u32 (`rgba32ui`).
    #[serde(rename = "rgba32ui")]
    Rgba32Uint,
    /// 16 bytes, four f32 (`rgba32f`).
    #[serde(rename = "rgba32f")]
    Rgba32Float,
    /// 4 bytes, one u32 (`r32ui`).
    #[serde(rename = "r32ui")]
    R32Uint,
}

impl Texel {
    /// The GLSL image format (`rgba32ui`), as files name it.
    pub fn name(self) -> &'static str {
        match self {
            Texel::Rgba32Uint => "rgba32ui",
            Texel::Rgba32Float => "rgba32f",
            Texel::R32Uint => "r32ui",
        }
    }

    pub fn size(self) -> usize {
        match self {
            Texel::Rgba32Uint | Texel::Rgba32Float => 16,
            Texel::R32Uint => 4,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packed_entry_is_first_times_32_plus_count() {
        // The kernels' format (5 count bits), written out: 7 * 32 + 3 = 227.
        assert_eq!(LEAF_ENTRY_COUNT_BITS, 5);
        assert_eq!(leaf_entry(7, 3), 227);
        assert_eq!((leaf_entry_first(227), leaf_entry_count(227)), (7, 3));
        assert_eq!((LEAF_ENTRY_MAX_COUNT, LEAF_ENTRY_FIRST_LIMIT), (31, 1 << 27));
        let top = leaf_entry((LEAF_ENTRY_FIRST_LIMIT - 1) as u32, LEAF_ENTRY_MAX_COUNT);
        assert_eq!(top, u32::MAX);
    }
}
