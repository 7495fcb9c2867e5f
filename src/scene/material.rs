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
//! Anything else that changes appearance gets a warning naming the MTL file, the line, the
//! material and the key, and is ignored: textures (`map_*`, `bump`, `disp`, `decal`, `refl`,
//! `norm`, with any options), partial transparency (`d` or `Tr` below 1 on an opaque BSDF),
//! `illum 10`, the PBR extension's keys, unknown keys and unknown `trilab_bsdf` parameters.
//! Colours reach [`Material::from_mtl`] as three numbers: `super::mtl` writes out the spec's
//! one-number and `xyz` forms before tobj reads them (docs/obj-mtl.md lists every statement).
//!
//! ## Values
//!
//! The rule table is docs/formats.md's "MTL values": every number must be finite; a negative
//! `Kd`, `Ks`, `Tf` or `Ke`, a negative `Ns`, `Ke` above [`MAX_EMISSION`], `d` or `Tr` outside
//! 0 to 1 and a glass's `Ni` outside [`IOR_RANGE`] are refused (file, line, material, key);
//! an albedo above 1 and an exponent above [`MAX_EXPONENT`] that the BSDF reads are clamped with
//! a warning.

use std::collections::HashMap;
use std::path::Path;

use crate::error::{Error, Result};
use crate::shared;

/// The line of each key in one `newmtl` block of an MTL file (the last one, whose value tobj
/// keeps), for messages.
pub type MtlLines = HashMap<String, usize>;

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

    /// Maps one tobj material (read from `mtl`; `lines` gives the line of each of its keys)
    /// onto a BSDF, pushing a warning for everything that is ignored, unsupported or clamped,
    /// and refusing values that cannot be meant, by the rules of the module documentation.
    pub fn from_mtl(m: &tobj::Material, mtl: &Path, lines: &MtlLines, warnings: &mut Vec<String>) -> Result<Material> {
        // The material of a `newmtl` without a name (Blender 2.61) is named "" and called so.
        let name =
            if m.name == super::text::NO_NAME { String::new() } else { super::text::shown(&m.name).into_owned() };
        let mut msgs = Messages { mtl, lines, label: label(&m.name), warnings };
        let extra = ExtraStatements::read(m, &mut msgs);
        check_colours(m, extra.tf, &msgs)?;
        check_scalars(m, extra.tr, &msgs)?;
        if let Some(t) = extra.tr.filter(|&t| t != 0.0) {
            msgs.warn("Tr", format!("{t}: partial transparency is not supported; rendered opaque"));
        }
        warn_textures(m, &mut msgs);
        let kind = choose_bsdf(m, &extra.explicit, &mut msgs);
        if !kind.is_delta() && m.dissolve.is_some_and(|d| d < 1.0) {
            msgs.warn("d", format!("{}: partial transparency is not supported; rendered opaque", m.dissolve.unwrap()));
        }
        let params = match &extra.explicit {
            Some((_, params)) => BsdfParams::read(kind, params, &mut msgs)?,
            None => BsdfParams::default(),
        };
        let gpu = gpu_material(m, kind, extra.tf, &params, &mut msgs)?;
        if matches!(kind, BsdfKind::Phong | BsdfKind::BlinnPhong)
            && (0..3).any(|c| gpu.diffuse[c] + gpu.specular[c] > 1.0)
        {
            msgs.warn("Ks", "Kd + Ks exceeds 1 in some channel: the BSDF reflects more than it receives".into());
        }
        Ok(Material { name, kind, gpu })
    }
}

/// Where [`Material::from_mtl`]'s messages point: the MTL file, the line of each key, the
/// material as messages call it; warnings go onto the caller's list.
struct Messages<'a> {
    mtl: &'a Path,
    lines: &'a MtlLines,
    label: String,
    warnings: &'a mut Vec<String>,
}

impl Messages<'_> {
    /// A warning that `key` of this material `problem`.
    fn warn(&mut self, key: &str, problem: String) {
        let place = match self.lines.get(key) {
            Some(line) => format!("{}:{line}", self.mtl.display()),
            None => self.mtl.display().to_string(),
        };
        self.warnings.push(format!("{place}: {}: `{key}` {problem}", self.label));
    }

    /// The error refusing `key` of this material for `problem`.
    fn refuse(&self, key: &str, problem: String) -> Error {
        Error::bad_input(self.mtl, self.lines.get(key).copied(), format!("{}: `{key}` {problem}", self.label))
    }

    /// An albedo the BSDF reads, each channel clamped to 1 (warned about).
    fn albedo(&mut self, key: &str, c: [f32; 3]) -> [f32; 3] {
        if c.iter().any(|&x| x > 1.0) {
            self.warn(
                key,
                format!(
                    "{}: above 1 in some channel, a surface that reflects more light than it receives; clamped to 1",
                    c.map(num).join(" ")
                ),
            );
        }
        c.map(|x| x.min(1.0))
    }

    /// A specular exponent the BSDF reads, clamped to [`MAX_EXPONENT`] (warned about).
    fn clamp_exponent(&mut self, key: &str, shown: &str, v: f32) -> f32 {
        if v > MAX_EXPONENT {
            self.warn(
                key,
                format!("{shown}: above {MAX_EXPONENT:e}, which f32 directions cannot resolve; clamped to it"),
            );
        }
        v.min(MAX_EXPONENT)
    }
}

/// The statements tobj leaves in `unknown_param` that trilab reads (`Tf`, `Tr`, `trilab_bsdf`);
/// every other one is warned about and ignored.
struct ExtraStatements {
    tf: Option<[f32; 3]>,
    tr: Option<f32>,
    /// `trilab_bsdf`: the BSDF named and its parameters as written.
    explicit: Option<(BsdfKind, String)>,
}

impl ExtraStatements {
    /// Reads them in key order, warning about each statement ignored.
    fn read(m: &tobj::Material, msgs: &mut Messages) -> ExtraStatements {
        let mut extra = ExtraStatements { tf: None, tr: None, explicit: None };
        let mut keys: Vec<(&String, &String)> = m.unknown_param.iter().collect();
        keys.sort();
        for (k, v) in keys {
            match k.as_str() {
                "Tf" => match parse_rgb(v) {
                    Some(c) => extra.tf = Some(c),
                    None => msgs.warn("Tf", format!("`{v}` is not a colour (one or three numbers); ignored")),
                },
                "trilab_bsdf" => {
                    let mut words = v.split_whitespace();
                    match words.next().map(str::parse::<BsdfKind>) {
                        Some(Ok(kind)) => extra.explicit = Some((kind, words.collect::<Vec<_>>().join(" "))),
                        Some(Err(e)) => msgs.warn("trilab_bsdf", format!("{e}; using illum instead")),
                        None => msgs.warn("trilab_bsdf", "names no BSDF; using illum instead".into()),
                    }
                }
                "Tr" => match v.trim().parse::<f32>() {
                    Ok(t) => extra.tr = Some(t),
                    Err(_) => msgs.warn("Tr", format!("`{v}` is not a number; ignored")),
                },
                other if is_texture_statement(other) => {
                    msgs.warn(other, format!("{}: textures are not supported; ignored", super::text::shown(v)))
                }
                // tinyobjloader reads `Kt` as `Tf`; the spec has no `Kt`.
                "Kt" => msgs
                    .warn("Kt", "is not an MTL statement (tinyobjloader reads it as `Tf`; write `Tf`); ignored".into()),
                pbr @ ("Pr" | "Pm" | "Ps" | "Pc" | "Pcr" | "aniso" | "anisor") => {
                    msgs.warn(pbr, "(a PBR extension) is not supported; ignored".into())
                }
                other => msgs.warn(other, "is not supported; ignored".into()),
            }
        }
        extra
    }
}

/// Refuses a colour that cannot be meant, whichever BSDF reads it (docs/formats.md): not
/// finite, a negative reflectance or radiance, or more radiance than [`MAX_EMISSION`].
fn check_colours(m: &tobj::Material, tf: Option<[f32; 3]>, msgs: &Messages) -> Result<()> {
    for (key, colour) in [("Ka", m.ambient), ("Kd", m.diffuse), ("Ks", m.specular), ("Ke", m.emissive), ("Tf", tf)] {
        let Some(c) = colour else { continue };
        let shown = c.map(num).join(" ");
        if c.iter().any(|x| !x.is_finite()) {
            return Err(msgs.refuse(key, format!("{shown}: every MTL number must be finite")));
        }
        if key != "Ka" && c.iter().any(|&x| x < 0.0) {
            let what = if key == "Ke" { "radiance" } else { "reflectance" };
            return Err(msgs.refuse(key, format!("{shown}: a {what} cannot be negative")));
        }
        if key == "Ke" && c.iter().any(|&x| x > MAX_EMISSION) {
            return Err(msgs.refuse(
                key,
                format!("{shown}: above {MAX_EMISSION:e}, the most emitted radiance the image's f32 sums hold"),
            ));
        }
    }
    Ok(())
}

/// Refuses a scalar that cannot be meant, whichever BSDF reads it (docs/formats.md): not
/// finite, a negative `Ns`, a `d` or `Tr` outside 0 to 1.
fn check_scalars(m: &tobj::Material, tr: Option<f32>, msgs: &Messages) -> Result<()> {
    for (key, value) in [("Ns", m.shininess), ("Ni", m.optical_density), ("d", m.dissolve), ("Tr", tr)] {
        let Some(v) = value else { continue };
        if !v.is_finite() {
            return Err(msgs.refuse(key, format!("{}: every MTL number must be finite", num(v))));
        }
        match key {
            "Ns" if v < 0.0 => {
                return Err(msgs.refuse(key, format!("{}: a specular exponent cannot be negative", num(v))))
            }
            "d" | "Tr" if !(0.0..=1.0).contains(&v) => {
                return Err(
                    msgs.refuse(key, format!("{}: a fraction (0 to 1) of opacity or transparency is needed", num(v)))
                )
            }
            _ => {}
        }
    }
    Ok(())
}

/// Warns about each texture tobj read into its own field (the others are in `unknown_param`).
fn warn_textures(m: &tobj::Material, msgs: &mut Messages) {
    for (key, tex) in [
        ("map_Ka", &m.ambient_texture),
        ("map_Kd", &m.diffuse_texture),
        ("map_Ks", &m.specular_texture),
        ("map_Bump", &m.normal_texture),
        ("map_Ns", &m.shininess_texture),
        ("map_d", &m.dissolve_texture),
    ] {
        if let Some(t) = tex {
            msgs.warn(key, format!("{}: textures are not supported; ignored", super::text::shown(t)));
        }
    }
}

/// The BSDF: `trilab_bsdf`'s where given, else `illum`'s (a black or absent `Ks` makes
/// Blinn-Phong Lambert); an `illum` trilab does not render is Lambert, warned about.
fn choose_bsdf(m: &tobj::Material, explicit: &Option<(BsdfKind, String)>, msgs: &mut Messages) -> BsdfKind {
    let black = |c: Option<[f32; 3]>| c.is_none_or(|c| c.iter().all(|&x| x == 0.0));
    match (explicit, m.illumination_model) {
        (Some((k, _)), _) => *k,
        (None, Some(0 | 1)) => BsdfKind::Lambert,
        (None, Some(2) | None) if black(m.specular) => BsdfKind::Lambert,
        (None, Some(2) | None) => BsdfKind::BlinnPhong,
        (None, Some(3 | 5 | 8)) => BsdfKind::Mirror,
        (None, Some(4 | 6 | 7 | 9)) => BsdfKind::Glass,
        (None, Some(i)) => {
            msgs.warn("illum", format!("{i} is not supported; rendered as Lambert (Kd)"));
            BsdfKind::Lambert
        }
    }
}

/// `trilab_bsdf`'s parameters that apply to the BSDF, each with the parameter as written.
#[derive(Default)]
struct BsdfParams<'p> {
    /// `exponent=` (Phong, Blinn-Phong, Ashikhmin-Shirley) or `nu=` (Ashikhmin-Shirley).
    exponent_u: Option<(&'p str, f32)>,
    /// `nv=` (Ashikhmin-Shirley).
    exponent_v: Option<(&'p str, f32)>,
    /// `sigma=` (Oren-Nayar).
    sigma: Option<(&'p str, f32)>,
    /// `ior=` (glass).
    ior: Option<(&'p str, f32)>,
}

impl<'p> BsdfParams<'p> {
    /// Reads `name=number ...` for `kind`: numbers as every MTL number; a parameter that is not
    /// name=number or does not apply to `kind` is warned about and ignored.
    fn read(kind: BsdfKind, params: &'p str, msgs: &mut Messages) -> Result<BsdfParams<'p>> {
        let mut out = BsdfParams::default();
        for p in params.split_whitespace() {
            let parsed = p.split_once('=').and_then(|(k, v)| Some((k, v.parse::<f32>().ok()?)));
            let Some((param, value)) = parsed else {
                msgs.warn("trilab_bsdf", format!("parameter `{p}` is not name=number; ignored"));
                continue;
            };
            if !value.is_finite() {
                return Err(msgs.refuse("trilab_bsdf", format!("parameter `{p}`: every MTL number must be finite")));
            }
            let slot = match (kind, param) {
                (BsdfKind::Phong | BsdfKind::BlinnPhong, "exponent")
                | (BsdfKind::AshikhminShirley, "exponent" | "nu") => &mut out.exponent_u,
                (BsdfKind::AshikhminShirley, "nv") => &mut out.exponent_v,
                (BsdfKind::OrenNayar, "sigma") => &mut out.sigma,
                (BsdfKind::Glass, "ior") => &mut out.ior,
                _ => {
                    msgs.warn("trilab_bsdf", format!("parameter `{p}` does not apply to {kind}; ignored"));
                    continue;
                }
            };
            if value < 0.0 {
                return Err(msgs.refuse("trilab_bsdf", format!("parameter `{p}` cannot be negative")));
            }
            if param == "ior" && !IOR_RANGE.contains(&value) {
                return Err(msgs.refuse("trilab_bsdf", format!("parameter `{p}`: {}", ior_problem(value))));
            }
            *slot = Some((p, value));
        }
        Ok(out)
    }
}

/// What the BSDF of `kind` reads, clamped to what it can render (each clamp warned about).
fn gpu_material(
    m: &tobj::Material,
    kind: BsdfKind,
    tf: Option<[f32; 3]>,
    params: &BsdfParams,
    msgs: &mut Messages,
) -> Result<GpuMaterial> {
    let ks = m.specular;
    let mut gpu = GpuMaterial::new(kind);
    gpu.emission = m.emissive.unwrap_or([0.0; 3]);
    match kind {
        BsdfKind::Lambert | BsdfKind::OrenNayar => {
            gpu.diffuse = msgs.albedo("Kd", m.diffuse.unwrap_or([0.8; 3]));
            gpu.specular = [0.0; 3];
            gpu.sigma = params.sigma.map_or(0.0, |s| s.1);
        }
        BsdfKind::Phong | BsdfKind::BlinnPhong | BsdfKind::AshikhminShirley => {
            gpu.diffuse = msgs.albedo("Kd", m.diffuse.unwrap_or([0.8; 3]));
            gpu.specular = msgs.albedo("Ks", ks.unwrap_or([0.0; 3]));
            // Ns gives what no parameter does (nv of Ashikhmin-Shirley defaults to Ns, not nu).
            let ns = m.shininess.unwrap_or(1.0);
            let ns_read =
                params.exponent_u.is_none() || (kind == BsdfKind::AshikhminShirley && params.exponent_v.is_none());
            let ns = if ns_read { msgs.clamp_exponent("Ns", &num(ns), ns) } else { ns.min(MAX_EXPONENT) };
            let mut given = |e: Option<(&str, f32)>| {
                e.map_or(ns, |(p, v)| msgs.clamp_exponent("trilab_bsdf", &format!("parameter `{p}`"), v))
            };
            gpu.exponent = given(params.exponent_u);
            gpu.exponent_v = given(params.exponent_v);
        }
        BsdfKind::Glass => {
            gpu.diffuse = msgs.albedo("Tf", tf.unwrap_or([1.0; 3]));
            gpu.specular = msgs.albedo("Ks", ks.filter(|c| c.iter().any(|&x| x > 0.0)).unwrap_or([1.0; 3]));
            gpu.ior = match params.ior {
                Some((_, v)) => v,
                None => {
                    let ni = m.optical_density.unwrap_or(1.5);
                    if !IOR_RANGE.contains(&ni) {
                        return Err(msgs.refuse("Ni", ior_problem(ni)));
                    }
                    ni
                }
            };
        }
        BsdfKind::Mirror => {
            gpu.diffuse = [0.0; 3];
            gpu.specular = msgs.albedo("Ks", ks.filter(|c| c.iter().any(|&x| x > 0.0)).unwrap_or([1.0; 3]));
        }
    }
    Ok(gpu)
}

/// How messages call the material named `name` as tobj holds it: the material of a `newmtl`
/// without a name is called unnamed.
pub(super) fn label(name: &str) -> String {
    if name == super::text::NO_NAME {
        "unnamed material (`newmtl` without a name)".to_owned()
    } else {
        format!("material `{}`", super::text::shown(name))
    }
}

/// Whether an MTL statement names a texture (or sets how textures are read: `map_aat`): the
/// spec's `map_*`, `bump`, `disp`, `decal` and `refl`, and the PBR extension's `norm` and
/// `map_*` keys. Trilab renders no textures, so each is ignored with a warning, whatever
/// options and file name it holds.
pub(super) fn is_texture_statement(key: &str) -> bool {
    key.starts_with("map_") || matches!(key, "bump" | "disp" | "decal" | "refl" | "norm")
}

/// The most emitted radiance (`Ke`, per channel): at any sample count the image's f32 sums of
/// such radiance stay finite.
pub const MAX_EMISSION: f32 = 1e20;

/// The largest specular exponent (`Ns`, `exponent=`, `nu=`, `nv=`): the lobe of cos^1e6 is
/// about 0.08 degrees wide, a few f32 steps of a direction near the normal; a larger exponent
/// is clamped to it (it already renders as a mirror).
pub const MAX_EXPONENT: f32 = 1e6;

/// Indices of refraction a glass accepts (`Ni`, `ior=`): every real material's, inside
/// relative to outside (germanium's 4 and its inverse), with margin; outside it the f32
/// Fresnel and Snell arithmetic breaks down (0 or less: the glass vanished).
pub const IOR_RANGE: std::ops::RangeInclusive<f32> = 0.1..=10.0;

fn ior_problem(v: f32) -> String {
    format!("{}: a glass needs an index of refraction from {} to {}", num(v), IOR_RANGE.start(), IOR_RANGE.end())
}

/// A number as messages show it: as written for everyday sizes, in exponent form otherwise
/// (`1e30`, not thirty-one digits).
fn num(x: f32) -> String {
    if x != 0.0 && x.is_finite() && !(1e-4..1e7).contains(&x.abs()) {
        format!("{x:e}")
    } else {
        x.to_string()
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
