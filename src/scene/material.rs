//! Materials: what the path tracer's BSDFs read, and how MTL maps onto it.

use crate::gpu::shared;

/// The seven BSDFs, one GLSL file each in `glsl/bsdf/`.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, clap::ValueEnum, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum BsdfKind {
    Lambert,
    OrenNayar,
    Phong,
    BlinnPhong,
    AshikhminShirley,
    Glass,
    Mirror,
}

impl BsdfKind {
    pub const ALL: [BsdfKind; 7] = [
        BsdfKind::Lambert,
        BsdfKind::OrenNayar,
        BsdfKind::Phong,
        BsdfKind::BlinnPhong,
        BsdfKind::AshikhminShirley,
        BsdfKind::Glass,
        BsdfKind::Mirror,
    ];

    /// `Material.kind` in the kernels (`BSDF_*` in `glsl/shared.glsl`).
    pub fn code(self) -> u32 {
        match self {
            BsdfKind::Lambert => shared::BSDF_LAMBERT,
            BsdfKind::OrenNayar => shared::BSDF_OREN_NAYAR,
            BsdfKind::Phong => shared::BSDF_PHONG,
            BsdfKind::BlinnPhong => shared::BSDF_BLINN_PHONG,
            BsdfKind::AshikhminShirley => shared::BSDF_ASHIKHMIN_SHIRLEY,
            BsdfKind::Glass => shared::BSDF_GLASS,
            BsdfKind::Mirror => shared::BSDF_MIRROR,
        }
    }

    /// The name used on the command line, in MTL (`trilab_bsdf`) and for kernel variants.
    pub fn name(self) -> &'static str {
        match self {
            BsdfKind::Lambert => "lambert",
            BsdfKind::OrenNayar => "oren-nayar",
            BsdfKind::Phong => "phong",
            BsdfKind::BlinnPhong => "blinn-phong",
            BsdfKind::AshikhminShirley => "ashikhmin-shirley",
            BsdfKind::Glass => "glass",
            BsdfKind::Mirror => "mirror",
        }
    }

    /// Whether every lobe is a Dirac delta (no `eval`/`pdf`, no light sampling).
    pub fn is_delta(self) -> bool {
        matches!(self, BsdfKind::Glass | BsdfKind::Mirror)
    }

    pub fn bit(self) -> u32 {
        1 << self.code()
    }
}

impl std::fmt::Display for BsdfKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// `struct Material` in `glsl/bsdf/common.glsl`: four rgba32f texels.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuMaterial {
    /// Kd: diffuse albedo; glass: transmission tint.
    pub diffuse: [f32; 3],
    /// `BsdfKind::code()`.
    pub kind: u32,
    /// Ks: specular albedo; mirror and glass: reflection tint.
    pub specular: [f32; 3],
    /// Phong and Blinn-Phong exponent; Ashikhmin-Shirley nu.
    pub exponent: f32,
    /// Ke: emitted radiance.
    pub emission: [f32; 3],
    /// Glass: index of refraction inside relative to outside.
    pub ior: f32,
    /// Ashikhmin-Shirley nv.
    pub exponent_v: f32,
    /// Oren-Nayar sigma, radians.
    pub sigma: f32,
    pub reserved: [f32; 2],
}

const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 64);

impl GpuMaterial {
    /// A material of `kind` with neutral parameters: white albedos, exponent 1, IOR 1.5.
    pub fn new(kind: BsdfKind) -> GpuMaterial {
        GpuMaterial {
            diffuse: [1.0; 3],
            kind: kind.code(),
            specular: [1.0; 3],
            exponent: 1.0,
            emission: [0.0; 3],
            ior: 1.5,
            exponent_v: 1.0,
            sigma: 0.0,
            reserved: [0.0; 2],
        }
    }
}
