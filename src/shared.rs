//! The host/kernel contract: the constants `glsl/shared.glsl` defines (bindings, sizes, ids;
//! build.rs turns every `#define NAME <integer>` there into a `pub const NAME: u32` here, so the
//! two cannot drift apart) and the texel formats the kernels read scene buffers as
//! (`glsl/types.glsl`).

include!(concat!(env!("OUT_DIR"), "/shared_consts.rs"));

/// How the kernels read a scene buffer: as texels of this format (`glsl/types.glsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Texel {
    /// 16 bytes, four u32 (`rgba32ui`).
    Rgba32Uint,
    /// 16 bytes, four f32 (`rgba32f`).
    Rgba32Float,
    /// 4 bytes, one u32 (`r32ui`).
    R32Uint,
}

impl Texel {
    pub fn size(self) -> usize {
        match self {
            Texel::Rgba32Uint | Texel::Rgba32Float => 16,
            Texel::R32Uint => 4,
        }
    }
}
