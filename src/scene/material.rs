//! Materials: what the path tracer's BSDFs read, and how MTL maps onto it.
//!
//! ## MTL mapping
//!
//! | MTL | meaning in trilab |
//! |---|---|
//! | `illum 0`, `illum 1` | Lambert, albedo `Kd` |
//! | `illum 2` | Blinn-Phong (`Kd`, `Ks`, exponent `Ns`); Lambert when `Ks` is black or absent |
//! | `illum 3`, `5`, `8` | perfect mirror tinted by `Ks` (white when absent) |
//! | `illum 4`, `6`, `7`, `9` | glass: index `Ni` (1.5 when absent), reflection tint `Ks`, transmission tint `Tf` (white when absent) |
//! | no `illum` | Lambert (`Kd`), or Blinn-Phong when `Ks` is not black |
//! | `Ke` | emitted radiance, any BSDF; one-sided (front face = counter-clockwise vertex order) |
//! | `Ka` | ignored (a path tracer has no ambient term) |
//! | `trilab_bsdf <kind> [name=value ...]` | chooses the BSDF explicitly, overriding `illum` (below) |
//!
//! `trilab_bsdf` kinds are `lambert`, `oren-nayar`, `phong` (modified, energy-normalised),
//! `blinn-phong`, `ashikhmin-shirley`, `glass` and `mirror`; colours still come from `Kd`, `Ks`,
//! `Tf` and `Ke`, scalars from `Ns` and `Ni` unless given as parameters: `exponent=` (Phong,
//! Blinn-Phong; Ashikhmin-Shirley nu), `nu=`, `nv=` (Ashikhmin-Shirley), `sigma=` (Oren-Nayar,
//! radians), `ior=` (glass). Example: `trilab_bsdf ashikhmin-shirley nu=200 nv=20`.
//!
//! Anything else that changes appearance gets a warning naming the MTL file, the material and
//! the key, and is ignored: textures (`map_*`, `bump`), partial transparency (`d` or `Tr` below
//! 1 on an opaque BSDF), `illum 10`, unknown keys and unknown `trilab_bsdf` parameters.

use std::path::Path;

use crate::shared;

/// The seven BSDFs, one GLSL file each in `glsl/bsdf/`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
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

    /// The kinds whose bit is set in `mask`, in `ALL` order.
    pub fn in_mask(mask: u32) -> impl Iterator<Item = BsdfKind> {
        BsdfKind::ALL.into_iter().filter(move |k| mask & k.bit() != 0)
    }
}

impl std::fmt::Display for BsdfKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for BsdfKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        BsdfKind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| {
            format!(
                "unknown BSDF `{s}` (known: {})",
                BsdfKind::ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", ")
            )
        })
    }
}

/// A scene material: its name and what the kernels read.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub kind: BsdfKind,
    pub gpu: GpuMaterial,
}

impl Default for Material {
    /// Grey Lambert (albedo 0.8), for triangles without a material.
    fn default() -> Self {
        Material::lambert("default", [0.8; 3])
    }
}

impl Material {
    pub fn lambert(name: &str, albedo: [f32; 3]) -> Material {
        let mut gpu = GpuMaterial::new(BsdfKind::Lambert);
        gpu.diffuse = albedo;
        gpu.specular = [0.0; 3];
        Material { name: name.into(), kind: BsdfKind::Lambert, gpu }
    }

    pub fn is_emissive(&self) -> bool {
        self.gpu.emission.iter().any(|&e| e > 0.0)
    }

    /// Maps one tobj material (read from `mtl`) onto a BSDF, pushing a warning for everything
    /// that is ignored or unsupported (see the module documentation).
    pub fn from_mtl(m: &tobj::Material, mtl: &Path, warnings: &mut Vec<String>) -> Material {
        let mut warn = |key: &str, problem: String| {
            warnings.push(format!("{}: material `{}`: `{key}` {problem}", mtl.display(), m.name));
        };
        let black = |c: Option<[f32; 3]>| c.is_none_or(|c| c.iter().all(|&x| x == 0.0));
        let mut tf = [1.0f32; 3];
        let mut explicit: Option<(BsdfKind, String)> = None;
        let mut keys: Vec<(&String, &String)> = m.unknown_param.iter().collect();
        keys.sort();
        for (k, v) in keys {
            match k.as_str() {
                "Tf" => match parse_rgb(v) {
                    Some(c) => tf = c,
                    None => warn("Tf", format!("`{v}` is not a colour (one or three numbers); ignored")),
                },
                "trilab_bsdf" => {
                    let mut words = v.split_whitespace();
                    match words.next().map(str::parse::<BsdfKind>) {
                        Some(Ok(kind)) => explicit = Some((kind, words.collect::<Vec<_>>().join(" "))),
                        Some(Err(e)) => warn("trilab_bsdf", format!("{e}; using illum instead")),
                        None => warn("trilab_bsdf", "names no BSDF; using illum instead".into()),
                    }
                }
                "Tr" => {
                    if v.trim().parse::<f32>() != Ok(0.0) {
                        warn("Tr", format!("{v}: partial transparency is not supported; rendered opaque"));
                    }
                }
                other => warn(other, "is not supported; ignored".into()),
            }
        }
        for (key, tex) in [
            ("map_Ka", &m.ambient_texture),
            ("map_Kd", &m.diffuse_texture),
            ("map_Ks", &m.specular_texture),
            ("map_Bump", &m.normal_texture),
            ("map_Ns", &m.shininess_texture),
            ("map_d", &m.dissolve_texture),
        ] {
            if let Some(t) = tex {
                warn(key, format!("{t}: textures are not supported; ignored"));
            }
        }
        let kd = m.diffuse.unwrap_or([0.8; 3]);
        let ks = m.specular;
        let kind = match (&explicit, m.illumination_model) {
            (Some((k, _)), _) => *k,
            (None, Some(0 | 1)) => BsdfKind::Lambert,
            (None, Some(2) | None) if black(ks) => BsdfKind::Lambert,
            (None, Some(2) | None) => BsdfKind::BlinnPhong,
            (None, Some(3 | 5 | 8)) => BsdfKind::Mirror,
            (None, Some(4 | 6 | 7 | 9)) => BsdfKind::Glass,
            (None, Some(i)) => {
                warn("illum", format!("{i} is not supported; rendered as Lambert (Kd)"));
                BsdfKind::Lambert
            }
        };
        if !kind.is_delta() && m.dissolve.is_some_and(|d| d < 1.0) {
            warn("d", format!("{}: partial transparency is not supported; rendered opaque", m.dissolve.unwrap()));
        }
        let mut gpu = GpuMaterial::new(kind);
        gpu.emission = m.emissive.unwrap_or([0.0; 3]);
        let ns = m.shininess.unwrap_or(1.0).max(0.0);
        match kind {
            BsdfKind::Lambert | BsdfKind::OrenNayar => {
                gpu.diffuse = kd;
                gpu.specular = [0.0; 3];
            }
            BsdfKind::Phong | BsdfKind::BlinnPhong | BsdfKind::AshikhminShirley => {
                gpu.diffuse = kd;
                gpu.specular = ks.unwrap_or([0.0; 3]);
                gpu.exponent = ns;
                gpu.exponent_v = ns;
                if kind != BsdfKind::AshikhminShirley && (0..3).any(|c| gpu.diffuse[c] + gpu.specular[c] > 1.0) {
                    warn("Ks", "Kd + Ks exceeds 1 in some channel: the BSDF reflects more than it receives".into());
                }
            }
            BsdfKind::Glass => {
                gpu.diffuse = tf;
                gpu.specular = ks.filter(|c| c.iter().any(|&x| x > 0.0)).unwrap_or([1.0; 3]);
                gpu.ior = m.optical_density.unwrap_or(1.5);
            }
            BsdfKind::Mirror => {
                gpu.diffuse = [0.0; 3];
                gpu.specular = ks.filter(|c| c.iter().any(|&x| x > 0.0)).unwrap_or([1.0; 3]);
            }
        }
        if let Some((_, params)) = &explicit {
            for p in params.split_whitespace() {
                let parsed = p.split_once('=').and_then(|(k, v)| Some((k, v.parse::<f32>().ok()?)));
                let Some((name, value)) = parsed.filter(|(_, v)| v.is_finite()) else {
                    warn("trilab_bsdf", format!("parameter `{p}` is not name=number; ignored"));
                    continue;
                };
                match (kind, name) {
                    (BsdfKind::Phong | BsdfKind::BlinnPhong, "exponent") => gpu.exponent = value.max(0.0),
                    (BsdfKind::AshikhminShirley, "exponent" | "nu") => gpu.exponent = value.max(0.0),
                    (BsdfKind::AshikhminShirley, "nv") => gpu.exponent_v = value.max(0.0),
                    (BsdfKind::OrenNayar, "sigma") => gpu.sigma = value.max(0.0),
                    (BsdfKind::Glass, "ior") if value > 0.0 => gpu.ior = value,
                    _ => warn("trilab_bsdf", format!("parameter `{p}` does not apply to {kind}; ignored")),
                }
            }
        }
        if gpu.emission.iter().any(|&e| e < 0.0) {
            warn("Ke", "has a negative component; clamped to 0".into());
            gpu.emission = gpu.emission.map(|e| e.max(0.0));
        }
        Material { name: m.name.clone(), kind, gpu }
    }
}

/// `r g b` or a single grey value.
fn parse_rgb(v: &str) -> Option<[f32; 3]> {
    let xs: Vec<f32> = v.split_whitespace().map(str::parse).collect::<Result<_, _>>().ok()?;
    match xs.as_slice() {
        [g] => Some([*g; 3]),
        [r, g, b] => Some([*r, *g, *b]),
        _ => None,
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

#[cfg(test)]
mod tests {
    use super::*;

    fn mtl(text: &str) -> (Vec<Material>, Vec<String>) {
        let (mats, _) = tobj::load_mtl_buf(&mut text.as_bytes()).unwrap();
        let mut warnings = vec![];
        let m = mats.iter().map(|m| Material::from_mtl(m, Path::new("x.mtl"), &mut warnings)).collect();
        (m, warnings)
    }

    #[test]
    fn illum_models_map_to_bsdfs() {
        let (m, w) = mtl(
            "newmtl a\nKd 0.5 0.5 0.5\nillum 2\nKs 0 0 0\nnewmtl b\nKd 0.5 0.4 0.3\nKs 0.2 0.2 0.2\nNs 40\nillum 2\n\
             newmtl c\nillum 3\nnewmtl d\nillum 7\nNi 1.33\nTf 0.9 1 1\nnewmtl e\nKd 1 1 1\nKe 4 4 4\n",
        );
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(
            m.iter().map(|m| m.kind).collect::<Vec<_>>(),
            vec![BsdfKind::Lambert, BsdfKind::BlinnPhong, BsdfKind::Mirror, BsdfKind::Glass, BsdfKind::Lambert]
        );
        assert_eq!(m[1].gpu.exponent, 40.0);
        assert_eq!(m[1].gpu.specular, [0.2; 3]);
        assert_eq!(m[2].gpu.specular, [1.0; 3]);
        assert_eq!((m[3].gpu.ior, m[3].gpu.diffuse), (1.33, [0.9, 1.0, 1.0]));
        assert!(m[4].is_emissive() && m[4].gpu.emission == [4.0; 3]);
    }

    #[test]
    fn explicit_bsdf_key_and_parameters() {
        let (m, w) = mtl("newmtl a\nKd 0.3 0.3 0.3\nKs 0.5 0.5 0.5\ntrilab_bsdf ashikhmin-shirley nu=200 nv=20\n\
             newmtl b\ntrilab_bsdf oren-nayar sigma=0.35\nillum 3\n");
        assert!(w.is_empty(), "{w:?}");
        assert_eq!(m[0].kind, BsdfKind::AshikhminShirley);
        assert_eq!((m[0].gpu.exponent, m[0].gpu.exponent_v), (200.0, 20.0));
        assert_eq!(m[1].kind, BsdfKind::OrenNayar);
        assert_eq!(m[1].gpu.sigma, 0.35);
    }

    #[test]
    fn unsupported_requests_warn_with_file_material_and_key() {
        let (m, w) = mtl("newmtl skin\nKd 1 0 0\nmap_Kd skin.png\nd 0.5\nsheen 0.3\nillum 10\n\
             newmtl x\ntrilab_bsdf velvet\nnewmtl y\ntrilab_bsdf glass roughness=0.1\n");
        assert_eq!(m[0].kind, BsdfKind::Lambert);
        let has = |needle: &str| w.iter().any(|l| l.starts_with("x.mtl: material `") && l.contains(needle));
        assert!(has("`skin`: `map_Kd` skin.png: textures are not supported"), "{w:?}");
        assert!(has("`skin`: `d` 0.5: partial transparency"), "{w:?}");
        assert!(has("`skin`: `sheen` is not supported"), "{w:?}");
        assert!(has("`skin`: `illum` 10 is not supported"), "{w:?}");
        assert!(has("`x`: `trilab_bsdf` unknown BSDF `velvet`"), "{w:?}");
        assert!(has("`y`: `trilab_bsdf` parameter `roughness=0.1` does not apply to glass"), "{w:?}");
        assert_eq!(w.len(), 6, "{w:?}");
    }
}
