//! Host side of the BSDFs in `glsl/bsdf/`: the GPU probe that runs the kernels' own dispatcher
//! (`glsl/bsdf_probe.comp`), the statistics that test it (a chi-square goodness-of-fit test of
//! sampled directions against the pdf, in the style of pbrt-v4's and Mitsuba 3's BSDF tests),
//! and f64 references for the delta BSDFs (mirror reflection, refraction, dielectric Fresnel).

use std::f64::consts::PI;
use std::mem::size_of;

use ash::vk;
use gpu_allocator::MemoryLocation;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use crate::error::Result;
use crate::gpu::{Context, Kernel, Resource, TexelBuffer};
use crate::scene::GpuMaterial;
use crate::shared::Texel;
use crate::shared::{BINDING_BSDF_PROBE_IN, BINDING_BSDF_PROBE_OUT, BINDING_MATERIALS, WORKGROUP_SIZE};

/// `struct ProbeIn` in `glsl/bsdf_probe.comp` (std430, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ProbeIn {
    /// Outgoing direction, local shading frame, unit length.
    pub wo: [f32; 3],
    /// Index into the materials given to [`Probe::new`].
    pub material: u32,
    /// [`MODE_SAMPLE`]: the three uniforms `u`; [`MODE_EVAL`]: `wi`.
    pub v: [f32; 3],
    pub pad: u32,
}

/// `struct ProbeOut` in `glsl/bsdf_probe.comp` (std430, 48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ProbeOut {
    /// Sample: the sampled direction; eval: the `wi` given.
    pub wi: [f32; 3],
    /// Sample: `BsdfSample.pdf`; eval: `bsdf_pdf(wo, wi)`.
    pub pdf: f32,
    /// Sample: `BsdfSample.weight`; eval: 0.
    pub weight: [f32; 3],
    /// [`FLAG_OK`], [`FLAG_DELTA`], [`FLAG_DELTA_KIND`].
    pub flags: u32,
    /// `bsdf_eval(wo, wi)`.
    pub f: [f32; 3],
    /// `bsdf_pdf(wo, wi)`.
    pub eval_pdf: f32,
}

/// `Push` in `glsl/bsdf_probe.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ProbePush {
    pub mode: u32,
    pub count: u32,
}

const _: () = assert!(size_of::<ProbeIn>() == 32);
const _: () = assert!(size_of::<ProbeOut>() == 48);
const _: () = assert!(size_of::<ProbePush>() == 8);

/// Probe mode: `bsdf_sample` with `v` as the uniforms.
pub const MODE_SAMPLE: u32 = 0;
/// Probe mode: `bsdf_eval` and `bsdf_pdf` at `wi = v`.
pub const MODE_EVAL: u32 = 1;
/// `bsdf_sample` returned true.
pub const FLAG_OK: u32 = 1;
/// `BsdfSample.delta`.
pub const FLAG_DELTA: u32 = 2;
/// `bsdf_is_delta(material.kind)`.
pub const FLAG_DELTA_KIND: u32 = 4;

/// Invocations per dispatch (well under every device's maxComputeWorkGroupCount of 65535 groups).
const CHUNK: usize = 1 << 20;

/// The BSDF probe kernel with a set of materials uploaded.
pub struct Probe<'a> {
    ctx: &'a Context,
    kernel: Kernel,
    materials: TexelBuffer,
}

impl<'a> Probe<'a> {
    /// The probe with every BSDF kind compiled in.
    pub fn new(ctx: &'a Context, materials: &[GpuMaterial]) -> Result<Probe<'a>> {
        Probe::with_variant(ctx, materials, "main")
    }

    /// The probe's `variant` (`bsdf_probe.comp`: `main`, every kind; `lambert`, BSDF_MASK = 1).
    pub fn with_variant(ctx: &'a Context, materials: &[GpuMaterial], variant: &str) -> Result<Probe<'a>> {
        let src = crate::kernels::find("bsdf_probe", crate::kernels::NO_INTERSECTOR, variant)
            .ok_or_else(|| crate::error::Error::Usage(format!("bsdf_probe has no variant `{variant}`")))?;
        let kernel = ctx.create_kernel(src)?;
        let materials =
            ctx.upload_texels("bsdf probe materials", bytemuck::cast_slice(materials), Texel::Rgba32Float)?;
        Ok(Probe { ctx, kernel, materials })
    }

    /// Runs the probe over `inputs` in `mode` and returns one output per input.
    pub fn run(&self, mode: u32, inputs: &[ProbeIn]) -> Result<Vec<ProbeOut>> {
        let mut out = Vec::with_capacity(inputs.len());
        for chunk in inputs.chunks(CHUNK) {
            let input =
                self.ctx.upload("bsdf probe in", bytemuck::cast_slice(chunk), vk::BufferUsageFlags::STORAGE_BUFFER)?;
            let bytes = (chunk.len() * size_of::<ProbeOut>()) as u64;
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
            let output = self.ctx.create_buffer("bsdf probe out", bytes, usage, MemoryLocation::GpuOnly)?;
            let resources = [
                (BINDING_MATERIALS, Resource::Texels(&self.materials)),
                (BINDING_BSDF_PROBE_IN, Resource::whole(&input)),
                (BINDING_BSDF_PROBE_OUT, Resource::whole(&output)),
            ];
            let push = ProbePush { mode, count: chunk.len() as u32 };
            let groups = (chunk.len() as u32).div_ceil(WORKGROUP_SIZE);
            self.ctx.dispatch(&self.kernel, &resources, bytemuck::bytes_of(&push), groups)?;
            let got = self.ctx.download(&output, bytes)?;
            out.extend_from_slice(bytemuck::cast_slice::<u8, ProbeOut>(&got));
        }
        Ok(out)
    }

    /// `bsdf_sample(material, wo, u)` for every `u`.
    pub fn sample(&self, material: u32, wo: [f32; 3], u: &[[f32; 3]]) -> Result<Vec<ProbeOut>> {
        let inputs: Vec<ProbeIn> = u.iter().map(|&v| ProbeIn { wo, material, v, pad: 0 }).collect();
        self.run(MODE_SAMPLE, &inputs)
    }

    /// `bsdf_eval` and `bsdf_pdf(material, wo, wi)` for every `wi`.
    pub fn eval(&self, material: u32, wo: [f32; 3], wi: &[[f32; 3]]) -> Result<Vec<ProbeOut>> {
        let inputs: Vec<ProbeIn> = wi.iter().map(|&v| ProbeIn { wo, material, v, pad: 0 }).collect();
        self.run(MODE_EVAL, &inputs)
    }
}

/// A unit direction from spherical angles (radians) in the local frame (normal +z).
pub fn direction(theta: f64, phi: f64) -> [f64; 3] {
    [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]
}

pub fn to_f32(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// The sphere cut into `z_bins` equal slices of cos(theta) in [-1, 1] times `phi_bins` equal
/// slices of phi in [0, 2 pi): cells of equal solid angle, as in pbrt-v4's and Mitsuba 3's
/// chi-square tests. `z_bins` must be even so that the horizon is a cell edge (the pdf of an
/// opaque BSDF jumps there).
#[derive(Clone, Copy, Debug)]
pub struct SphereGrid {
    pub z_bins: usize,
    pub phi_bins: usize,
}

impl SphereGrid {
    pub fn cells(&self) -> usize {
        self.z_bins * self.phi_bins
    }

    /// The cell holding direction `w` (need not be normalised exactly).
    pub fn cell(&self, w: [f32; 3]) -> usize {
        let z = (w[2] as f64).clamp(-1.0, 1.0);
        let i = (((z + 1.0) * 0.5 * self.z_bins as f64) as usize).min(self.z_bins - 1);
        let mut phi = (w[1] as f64).atan2(w[0] as f64);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let j = ((phi / (2.0 * PI) * self.phi_bins as f64) as usize).min(self.phi_bins - 1);
        i * self.phi_bins + j
    }

    /// How many of `wi` fall in each cell.
    pub fn histogram<'w>(&self, wi: impl IntoIterator<Item = &'w [f32; 3]>) -> Vec<f64> {
        let mut h = vec![0.0; self.cells()];
        for w in wi {
            h[self.cell(*w)] += 1.0;
        }
        h
    }

    /// Quadrature nodes for integrating a function of direction over every cell: composite
    /// Simpson with `z_sub` and `phi_sub` (even) intervals per cell along theta and phi,
    /// dω = sin θ dθ dφ. Each cell is integrated in theta, not cos(theta): a lobe off the pole is
    /// smooth in theta but goes like sqrt(1 - cos θ) at the pole, which would cost Simpson its
    /// order in the polar cells. Returns the nodes' directions and, per node, (cell, weight).
    pub fn quadrature(&self, z_sub: usize, phi_sub: usize) -> Quadrature {
        assert!(z_sub.is_multiple_of(2) && phi_sub.is_multiple_of(2), "Simpson needs an even number of intervals");
        let nphi = self.phi_bins * phi_sub;
        let dphi = 2.0 * PI / nphi as f64;
        let simpson = |k: usize, sub: usize| -> f64 {
            match k % sub {
                0 => 1.0,
                r if r % 2 == 1 => 4.0,
                _ => 2.0,
            }
        };
        let mut dirs = Vec::with_capacity(self.z_bins * (z_sub + 1) * (nphi + 1));
        let mut weights = Vec::with_capacity(dirs.capacity());
        for i in 0..self.z_bins {
            let z_lo = -1.0 + 2.0 * i as f64 / self.z_bins as f64;
            let z_hi = -1.0 + 2.0 * (i + 1) as f64 / self.z_bins as f64;
            let (theta_a, theta_b) = (z_hi.clamp(-1.0, 1.0).acos(), z_lo.clamp(-1.0, 1.0).acos());
            let h = (theta_b - theta_a) / z_sub as f64;
            for k in 0..=z_sub {
                let theta = theta_a + k as f64 * h;
                let wz = simpson(k, z_sub) * h / 3.0 * theta.sin();
                // The pdf of an opaque BSDF jumps at the horizon, a cell edge: a node there takes
                // the limit from inside its cell (and cos(pi/2) = 6e-17 must not count as above).
                let z = match k {
                    0 if z_hi == 0.0 => -HORIZON_NUDGE,
                    k if k == z_sub && z_lo == 0.0 => HORIZON_NUDGE,
                    _ => theta.cos(),
                };
                let r = (1.0 - z * z).max(0.0).sqrt();
                for l in 0..=nphi {
                    let phi = l as f64 * dphi;
                    dirs.push(to_f32([r * phi.cos(), r * phi.sin(), z]));
                    // A node on a phi edge belongs to both neighbouring cells, weight 1 in each.
                    let mut w = Vec::with_capacity(2);
                    if l > 0 {
                        let j = (l - 1) / phi_sub;
                        w.push(((i * self.phi_bins + j) as u32, wz * simpson(l - j * phi_sub, phi_sub) * dphi / 3.0));
                    }
                    if l < nphi && l.is_multiple_of(phi_sub) {
                        let j = l / phi_sub;
                        w.push(((i * self.phi_bins + j) as u32, wz * dphi / 3.0));
                    }
                    weights.push(w);
                }
            }
        }
        Quadrature { cells: self.cells(), dirs, weights }
    }
}

/// How far above or below the horizon [`SphereGrid::quadrature`] evaluates its nodes on it.
const HORIZON_NUDGE: f64 = 1e-6;

/// Nodes and weights from [`SphereGrid::quadrature`].
pub struct Quadrature {
    cells: usize,
    pub dirs: Vec<[f32; 3]>,
    /// Per node: (cell, weight) for each cell whose closure holds the node.
    pub weights: Vec<Vec<(u32, f64)>>,
}

impl Quadrature {
    /// The integral of `values` (one per node) over every cell.
    pub fn integrate(&self, values: impl IntoIterator<Item = f64>) -> Vec<f64> {
        let mut out = vec![0.0; self.cells];
        for (v, w) in values.into_iter().zip(&self.weights) {
            for &(c, wt) in w {
                out[c as usize] += v * wt;
            }
        }
        out
    }
}

/// The outcome of [`chi_square`].
#[derive(Clone, Debug)]
pub struct ChiSquare {
    pub statistic: f64,
    pub dof: usize,
    /// Probability of a statistic at least this large if the samples follow the pdf.
    pub p_value: f64,
    /// Cells merged because their expected count was below the minimum.
    pub pooled_cells: usize,
    /// Samples found in cells where the pdf integrates to exactly 0 (beyond a tolerance of
    /// 1e-5 of the samples, pbrt-v4's rule, this alone fails the test: p = 0).
    pub samples_where_pdf_is_zero: f64,
}

/// Pearson's chi-square goodness-of-fit test of `observed` counts against `expected` counts
/// (the pdf's integral over each cell times the number of samples drawn), as pbrt-v4's
/// `Chi2Test`: cells with expected count below `min_expected` are pooled (in increasing order
/// of expected count, until the pool reaches it), the p-value comes from the chi-square
/// distribution with (cells - 1) degrees of freedom.
pub fn chi_square(observed: &[f64], expected: &[f64], min_expected: f64) -> ChiSquare {
    assert_eq!(observed.len(), expected.len());
    let total: f64 = observed.iter().sum();
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut stat, mut cells, mut pooled_cells) = (0.0, 0usize, 0usize);
    let (mut pool_obs, mut pool_exp) = (0.0, 0.0);
    let mut zero = 0.0;
    for i in order {
        let (o, e) = (observed[i], expected[i]);
        if e <= 0.0 {
            zero += o;
        } else if e < min_expected || (pool_exp > 0.0 && pool_exp < min_expected) {
            pool_obs += o;
            pool_exp += e;
            pooled_cells += 1;
        } else {
            stat += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pool_exp > 0.0 {
        stat += (pool_obs - pool_exp) * (pool_obs - pool_exp) / pool_exp;
        cells += 1;
    }
    let dof = cells.saturating_sub(1).max(1);
    let mut p_value = ChiSquared::new(dof as f64).expect("dof >= 1").sf(stat);
    if zero > 1e-5 * total.max(1.0) {
        p_value = 0.0;
    }
    ChiSquare { statistic: stat, dof, p_value, pooled_cells, samples_where_pdf_is_zero: zero }
}

/// Šidák's correction: the per-test significance level that keeps the probability of one or
/// more false rejections among `tests` independent tests at `alpha`: 1 - (1 - alpha)^(1/tests).
pub fn sidak_threshold(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests as f64)
}

/// Mean and standard error of the mean of `x`.
pub fn mean_and_error(x: impl IntoIterator<Item = f64>) -> (f64, f64) {
    let (mut n, mut s, mut s2) = (0.0, 0.0, 0.0);
    for v in x {
        n += 1.0;
        s += v;
        s2 += v * v;
    }
    if n == 0.0 {
        return (0.0, 0.0);
    }
    let mean = s / n;
    let var = (s2 / n - mean * mean).max(0.0);
    (mean, (var / n).sqrt())
}

/// f64 reference: mirror reflection of `wo` about the normal +z (either side).
pub fn reflect(wo: [f64; 3]) -> [f64; 3] {
    [-wo[0], -wo[1], wo[2]]
}

/// f64 reference: exact unpolarised Fresnel reflectance of a smooth dielectric for light
/// arriving at `cos_i > 0` on the side of index eta_i, with `eta` = eta_t / eta_i (pbrt-v3
/// section 8.2.1). 1 under total internal reflection.
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// f64 reference: `wo` refracted through the interface z = 0 (Snell's law), with `eta` =
/// eta_t / eta_i the index on the far side relative to `wo`'s side; `None` under total internal
/// reflection. The result points away from the surface on the other side.
pub fn refract(wo: [f64; 3], eta: f64) -> Option<[f64; 3]> {
    let cos_i = wo[2].abs();
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some([-wo[0] / eta, -wo[1] / eta, -cos_t * wo[2].signum()])
}

/// What `glass.glsl` does for `wo`, in f64: (probability of reflection, reflected direction,
/// refracted direction or `None` under total internal reflection). wo.z > 0 is outside (the
/// ray enters, eta = ior), wo.z < 0 inside (eta = 1 / ior). The weights are Ks for reflection
/// and Kd for refraction, with no 1 / eta^2 factor (see glass.glsl).
pub fn glass_reference(wo: [f64; 3], ior: f64) -> (f64, [f64; 3], Option<[f64; 3]>) {
    let eta = if wo[2] > 0.0 { ior } else { 1.0 / ior };
    (fresnel_dielectric(wo[2].abs(), eta), reflect(wo), refract(wo, eta))
}

/// The angle between two directions (radians), robust near 0.
pub fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let (na, nb) = (norm(a), norm(b));
    let a = a.map(|x| x / na);
    let b = b.map(|x| x / nb);
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let s = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    2.0 * norm(d).atan2(norm(s))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadrature_integrates_cells_of_equal_solid_angle() {
        let g = SphereGrid { z_bins: 4, phi_bins: 6 };
        let q = g.quadrature(16, 2);
        let ones = q.integrate(q.dirs.iter().map(|_| 1.0));
        for c in &ones {
            assert!((c - 4.0 * PI / 24.0).abs() < 1e-6, "{c}");
        }
        let z2: f64 = q.integrate(q.dirs.iter().map(|d| (d[2] as f64).powi(2))).iter().sum();
        assert!((z2 - 4.0 * PI / 3.0).abs() < 1e-4, "{z2}");
    }

    #[test]
    fn chi_square_accepts_exact_counts_and_rejects_wrong_ones() {
        let e = vec![100.0; 50];
        assert!(chi_square(&e, &e, 5.0).p_value > 0.99);
        let mut o = e.clone();
        o[0] = 200.0;
        o[1] = 0.0;
        assert!(chi_square(&o, &e, 5.0).p_value < 1e-10);
        let mut z = e.clone();
        z.push(0.0);
        let mut oz = e.clone();
        oz.push(10.0);
        assert_eq!(chi_square(&oz, &z, 5.0).p_value, 0.0);
    }

    #[test]
    fn fresnel_reference_known_values() {
        // Normal incidence: ((n - 1) / (n + 1))^2 = 0.04 for n = 1.5, from either side.
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
        assert!((fresnel_dielectric(1.0, 1.0 / 1.5) - 0.04).abs() < 1e-12);
        // Beyond the critical angle asin(1 / 1.5) inside: total internal reflection.
        assert_eq!(fresnel_dielectric((45f64).to_radians().cos(), 1.0 / 1.5), 1.0);
        assert!(refract(direction(45f64.to_radians(), 0.0).map(|x| x * 1.0), 1.0 / 1.5).is_none());
        // Snell: sin_t = sin_i / eta.
        let t = refract(direction(30f64.to_radians(), 1.0), 1.5).unwrap();
        let sin_t = (t[0] * t[0] + t[1] * t[1]).sqrt();
        assert!((sin_t - 0.5 / 1.5).abs() < 1e-12 && t[2] < 0.0);
    }
}
