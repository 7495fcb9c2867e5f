//! The BSDFs of `glsl/bsdf/`, run on the GPU through the dispatcher the path tracer calls
//! (`glsl/bsdf_probe.comp` -> `bsdf.glsl`), tested statistically:
//! - sampling against the pdf: a chi-square goodness-of-fit test per case (10^6 samples,
//!   20 x 40 equal-solid-angle cells, expected counts from Simpson quadrature of `bsdf_pdf`),
//!   Sidak-corrected over every case so that a correct implementation fails with probability
//!   below ALPHA = 1% in all;
//! - `bsdf_pdf` integrates to at most 1; the sample's pdf and weight agree with `bsdf_pdf` and
//!   `bsdf_eval * cos / pdf` at the sampled direction;
//! - the estimator is unbiased (mean weight = the quadrature of f cos) and the white furnace
//!   holds (mean weight <= 1 for albedos summing to <= 1; exactly 1 for a white Lambert);
//! - reciprocity and two-sidedness of the opaque BSDFs;
//! - glass and mirror against the f64 references in `trilab::render::bsdf`;
//! - and that the chi-square test can fail: it must reject samples tested against a wrong pdf.

mod common;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use trilab::render::bsdf::{
    angle_between, chi_square, direction, glass_reference, mean_and_error, reflect, sidak_threshold, to_f32, Probe,
    ProbeOut, Quadrature, SphereGrid, FLAG_DELTA, FLAG_DELTA_KIND, FLAG_OK,
};
use trilab::scene::{BsdfKind, GpuMaterial};

const SAMPLES: usize = 1_000_000;
const ALPHA: f64 = 0.01;
const GRID: SphereGrid = SphereGrid { z_bins: 20, phi_bins: 40 };
/// Simpson intervals per cell: 32 along cos(theta) (a cos^1000 lobe near the pole is a steep
/// polynomial in cos(theta)), 16 along phi.
const Z_SUB: usize = 32;
const PHI_SUB: usize = 16;
/// Wall-clock limit of each GPU test.
const TIMEOUT_S: u64 = 300;

/// One tested configuration: a material and an outgoing direction.
#[derive(Clone, Debug)]
struct Case {
    label: String,
    material: GpuMaterial,
    theta_o: f64,
    phi_o: f64,
    /// White Lambert: the furnace must give exactly 1.
    unit_albedo: bool,
}

impl Case {
    fn wo(&self) -> [f64; 3] {
        direction(self.theta_o.to_radians(), self.phi_o.to_radians())
    }

    fn describe(&self) -> String {
        format!("{} at theta_o {} deg, phi_o {} deg", self.label, self.theta_o, self.phi_o)
    }
}

fn material(kind: BsdfKind, kd: f32, ks: f32, exponent: f32, exponent_v: f32, sigma: f32) -> GpuMaterial {
    GpuMaterial { diffuse: [kd; 3], specular: [ks; 3], exponent, exponent_v, sigma, ..GpuMaterial::new(kind) }
}

/// (label, material, anisotropic) for every non-delta parameter set tested.
fn parameter_sets() -> Vec<(String, GpuMaterial, bool)> {
    use BsdfKind::*;
    let mut sets = vec![
        ("lambert kd 1".to_owned(), material(Lambert, 1.0, 0.0, 1.0, 1.0, 0.0), false),
        ("oren-nayar kd 1 sigma 0".to_owned(), material(OrenNayar, 1.0, 0.0, 1.0, 1.0, 0.0), false),
        ("oren-nayar kd 1 sigma 0.5".to_owned(), material(OrenNayar, 1.0, 0.0, 1.0, 1.0, 0.5), false),
    ];
    for kind in [Phong, BlinnPhong] {
        for (kd, ks, n) in [(0.5, 0.5, 1.0), (0.2, 0.8, 20.0), (0.0, 1.0, 200.0)] {
            sets.push((format!("{kind} kd {kd} ks {ks} n {n}"), material(kind, kd, ks, n, n, 0.0), false));
        }
    }
    for (rd, rs, nu, nv) in [(0.5, 0.05, 10.0, 10.0), (0.3, 0.3, 100.0, 10.0), (0.0, 0.9, 1000.0, 20.0)] {
        sets.push((
            format!("ashikhmin-shirley Rd {rd} Rs {rs} nu {nu} nv {nv}"),
            material(AshikhminShirley, rd, rs, nu, nv, 0.0),
            nu != nv,
        ));
    }
    sets
}

/// Every chi-square case: three incoming elevations, and two azimuths when anisotropic.
fn cases() -> Vec<Case> {
    let mut out = vec![];
    for (label, m, aniso) in parameter_sets() {
        let phis: &[f64] = if aniso { &[30.0, 120.0] } else { &[0.0] };
        for theta_o in [10.0, 45.0, 80.0] {
            for &phi_o in phis {
                out.push(Case {
                    unit_albedo: label == "lambert kd 1",
                    label: label.clone(),
                    material: m,
                    theta_o,
                    phi_o,
                });
            }
        }
    }
    out
}

/// The per-test significance level: Sidak over every chi-square case in this file.
fn threshold() -> f64 {
    sidak_threshold(ALPHA, cases().len())
}

fn uniforms(n: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..n).map(|_| [rng.random::<f32>(), rng.random::<f32>(), rng.random::<f32>()]).collect()
}

fn rel_close(a: f64, b: f64, rel: f64, abs: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + abs
}

/// Per cell, the integral of `bsdf_pdf`; and the quadrature of f cos (the directional albedo,
/// per channel) over the hemisphere around wo.
fn pdf_cells(probe: &Probe, quad: &Quadrature, index: u32, wo: [f32; 3]) -> (Vec<f64>, [f64; 3]) {
    let ev = probe.eval(index, wo, &quad.dirs).unwrap();
    let cells = quad.integrate(ev.iter().map(|o| o.pdf as f64));
    let mut albedo = [0.0; 3];
    for (c, a) in albedo.iter_mut().enumerate() {
        *a = quad.integrate(ev.iter().map(|o| o.f[c] as f64 * (o.wi[2] as f64).abs())).iter().sum();
    }
    (cells, albedo)
}

/// Runs every check on one case; returns what failed.
fn check_case(probe: &Probe, quad: &Quadrature, index: u32, case: &Case, seed: u64) -> Vec<String> {
    let what = case.describe();
    let mut fails = vec![];
    let wo = to_f32(case.wo());
    let samples = probe.sample(index, wo, &uniforms(SAMPLES, seed)).unwrap();

    // Per-sample consistency.
    let (mut worst_pdf, mut worst_weight, mut bad) = (0.0f64, 0.0f64, 0usize);
    for s in samples.iter().filter(|s| s.flags & FLAG_OK != 0) {
        let len = s.wi.iter().map(|x| (*x as f64).powi(2)).sum::<f64>().sqrt();
        if s.flags & (FLAG_DELTA | FLAG_DELTA_KIND) != 0 || s.wi[2] <= 0.0 || (len - 1.0).abs() > 1e-4 || s.pdf <= 0.0 {
            bad += 1;
            continue;
        }
        let (pdf, eval_pdf) = (s.pdf as f64, s.eval_pdf as f64);
        worst_pdf = worst_pdf.max((pdf - eval_pdf).abs() / pdf.max(eval_pdf));
        for c in 0..3 {
            let want = s.f[c] as f64 * s.wi[2] as f64 / eval_pdf;
            let got = s.weight[c] as f64;
            worst_weight = worst_weight.max((got - want).abs() / (got.abs().max(want.abs()) + 1e-6));
        }
    }
    if bad > 0 {
        fails
            .push(format!("{what}: {bad} accepted samples are flagged delta, below the horizon, not unit or pdf <= 0"));
    }
    if worst_pdf > 1e-4 {
        fails.push(format!("{what}: sample pdf and bsdf_pdf at the sampled wi differ by {worst_pdf:e} (relative)"));
    }
    if worst_weight > 1e-4 {
        fails.push(format!("{what}: sample weight and f cos / pdf differ by {worst_weight:e} (relative)"));
    }

    // Chi-square of the sampled directions against the pdf.
    let observed = GRID.histogram(samples.iter().filter(|s| s.flags & FLAG_OK != 0).map(|s| &s.wi));
    let (cells, albedo) = pdf_cells(probe, quad, index, wo);
    let expected: Vec<f64> = cells.iter().map(|p| p * SAMPLES as f64).collect();
    let chi = chi_square(&observed, &expected, 5.0);
    let t = threshold();
    if chi.p_value < t {
        fails.push(format!(
            "{what}: chi-square rejects sampling against the pdf: statistic {:.1}, dof {}, p {:e} < {t:e} \
             ({} cells pooled, {} samples where the pdf is 0)",
            chi.statistic, chi.dof, chi.p_value, chi.pooled_cells, chi.samples_where_pdf_is_zero
        ));
    }

    // The pdf integrates to at most 1 (less where sampled directions below the horizon are lost).
    let total: f64 = cells.iter().sum();
    if total > 1.0 + 1e-3 {
        fails.push(format!("{what}: the pdf integrates to {total:.5} > 1"));
    }
    let accepted = observed.iter().sum::<f64>() / SAMPLES as f64;
    // The accepted fraction is a binomial estimate of that integral.
    let bound = 5.0 * (total.min(1.0) * (1.0 - total.min(1.0)) / SAMPLES as f64).sqrt() + 1e-3;
    if (accepted - total).abs() > bound {
        fails.push(format!("{what}: {accepted:.5} of the samples accepted, the pdf integrates to {total:.5}"));
    }

    // Unbiased and energy conserving: mean weight (0 for absorbed samples) per channel.
    for (c, &albedo) in albedo.iter().enumerate() {
        let (mean, se) =
            mean_and_error(samples.iter().map(|s| if s.flags & FLAG_OK != 0 { s.weight[c] as f64 } else { 0.0 }));
        // Noise: 5 standard errors; quadrature: 0.2% of the albedo.
        let noise = 5.0 * se + 2e-3 * albedo;
        if (mean - albedo).abs() > noise {
            fails.push(format!(
                "{what}: channel {c}: mean weight {mean:.5} +- {se:.1e} but the quadrature of f cos is {albedo:.5}"
            ));
        }
        // 1e-5: f32 rounding of f cos / pdf.
        if mean > 1.0 + 5.0 * se + 1e-5 {
            fails.push(format!("{what}: channel {c}: white furnace gives {mean:.5} +- {se:.1e} > 1"));
        }
        if case.unit_albedo && (mean - 1.0).abs() > 1e-4 {
            fails.push(format!("{what}: channel {c}: white Lambert furnace gives {mean:.6}, not 1 within 1e-4"));
        }
    }
    fails
}

fn run_kind(kinds: &[BsdfKind]) {
    let kinds = kinds.to_vec();
    let fails = common::with_gpu(TIMEOUT_S, move |ctx| {
        let all = cases();
        let mine: Vec<(usize, Case)> =
            all.into_iter().enumerate().filter(|(_, c)| kinds.iter().any(|k| k.code() == c.material.kind)).collect();
        assert!(!mine.is_empty(), "no cases for {kinds:?}");
        let materials: Vec<GpuMaterial> = mine.iter().map(|(_, c)| c.material).collect();
        let probe = Probe::new(ctx, &materials).unwrap();
        let quad = GRID.quadrature(Z_SUB, PHI_SUB);
        let mut fails = vec![];
        for (i, (global, case)) in mine.iter().enumerate() {
            fails.extend(check_case(&probe, &quad, i as u32, case, 1000 + *global as u64));
        }
        fails
    });
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

#[test]
fn lambert_and_oren_nayar_sample_their_pdf_and_conserve_energy() {
    run_kind(&[BsdfKind::Lambert, BsdfKind::OrenNayar]);
}

#[test]
fn phong_samples_its_pdf_and_conserves_energy() {
    run_kind(&[BsdfKind::Phong]);
}

#[test]
fn blinn_phong_samples_its_pdf_and_conserves_energy() {
    run_kind(&[BsdfKind::BlinnPhong]);
}

#[test]
fn ashikhmin_shirley_samples_its_pdf_and_conserves_energy() {
    run_kind(&[BsdfKind::AshikhminShirley]);
}

/// The chi-square test is not vacuous: samples of one BSDF tested against another's pdf (a
/// Phong lobe against Lambert's; an anisotropic lobe against the same lobe turned 90 degrees)
/// are rejected at the same corrected level.
#[test]
fn chi_square_rejects_a_wrong_pdf() {
    let phong = material(BsdfKind::Phong, 0.2, 0.8, 20.0, 20.0, 0.0);
    let lambert = material(BsdfKind::Lambert, 1.0, 0.0, 1.0, 1.0, 0.0);
    let aniso = material(BsdfKind::AshikhminShirley, 0.0, 0.5, 100.0, 10.0, 0.0);
    let turned = material(BsdfKind::AshikhminShirley, 0.0, 0.5, 10.0, 100.0, 0.0);
    let p_values = common::with_gpu(TIMEOUT_S, move |ctx| {
        let probe = Probe::new(ctx, &[phong, lambert, aniso, turned]).unwrap();
        let quad = GRID.quadrature(Z_SUB, PHI_SUB);
        let mut out = vec![];
        for (sampled, tested, what) in
            [(0u32, 1u32, "phong samples vs the lambert pdf"), (2, 3, "AS nu 100 nv 10 vs nu 10 nv 100")]
        {
            let wo = to_f32(direction(45f64.to_radians(), 0.0));
            let s = probe.sample(sampled, wo, &uniforms(SAMPLES, 7)).unwrap();
            let observed = GRID.histogram(s.iter().filter(|s| s.flags & FLAG_OK != 0).map(|s| &s.wi));
            let (cells, _) = pdf_cells(&probe, &quad, tested, wo);
            let expected: Vec<f64> = cells.iter().map(|p| p * SAMPLES as f64).collect();
            out.push((what, chi_square(&observed, &expected, 5.0).p_value));
        }
        out
    });
    for (what, p) in p_values {
        assert!(p < threshold(), "{what}: the chi-square test should reject, p = {p:e} >= {:e}", threshold());
    }
}

/// (wo, wi).
type Pair = ([f64; 3], [f64; 3]);

/// f(wo, wi) = f(wi, wo) for the opaque BSDFs (all of them are reciprocal), and two-sidedness:
/// flipping both directions' z changes nothing, while wi on the other side of the surface
/// from wo gives f = pdf = 0.
#[test]
fn opaque_bsdfs_are_reciprocal_and_two_sided() {
    let sets = parameter_sets();
    let materials: Vec<GpuMaterial> = sets.iter().map(|s| s.1).collect();
    let labels: Vec<String> = sets.iter().map(|s| s.0.clone()).collect();
    let fails = common::with_gpu(TIMEOUT_S, move |ctx| {
        let probe = Probe::new(ctx, &materials).unwrap();
        let mut rng = Pcg64::seed_from_u64(3);
        let mut fails = vec![];
        let random_dir = |rng: &mut Pcg64| {
            let z: f64 = rng.random_range(0.02..1.0);
            direction(z.acos(), rng.random_range(0.0..2.0 * std::f64::consts::PI))
        };
        for (m, label) in labels.iter().enumerate() {
            if fails.len() > 40 {
                break;
            }
            let pairs: Vec<Pair> = (0..2000).map(|_| (random_dir(&mut rng), random_dir(&mut rng))).collect();
            let run = |f: &dyn Fn(&Pair) -> Pair| -> Vec<ProbeOut> {
                let inputs: Vec<trilab::render::bsdf::ProbeIn> = pairs
                    .iter()
                    .map(|p| {
                        let (wo, wi) = f(p);
                        trilab::render::bsdf::ProbeIn { wo: to_f32(wo), material: m as u32, v: to_f32(wi), pad: 0 }
                    })
                    .collect();
                probe.run(trilab::render::bsdf::MODE_EVAL, &inputs).unwrap()
            };
            let flip = |v: [f64; 3]| [v[0], v[1], -v[2]];
            let fwd = run(&|&(o, i)| (o, i));
            let rev = run(&|&(o, i)| (i, o));
            let both_flipped = run(&|&(o, i)| (flip(o), flip(i)));
            let across = run(&|&(o, i)| (o, flip(i)));
            for (k, (wo, wi)) in pairs.iter().enumerate() {
                for c in 0..3 {
                    let (a, b, d) = (fwd[k].f[c] as f64, rev[k].f[c] as f64, both_flipped[k].f[c] as f64);
                    if !rel_close(a, b, 1e-4, 1e-6) {
                        fails.push(format!("{label}: f(wo, wi) = {a} but f(wi, wo) = {b}, wo {wo:?}, wi {wi:?}"));
                    }
                    if !rel_close(a, d, 1e-6, 0.0) {
                        fails.push(format!(
                            "{label}: f = {a} on the front, {d} with both z flipped, wo {wo:?}, wi {wi:?}"
                        ));
                    }
                }
                if !rel_close(fwd[k].pdf as f64, both_flipped[k].pdf as f64, 1e-6, 0.0) {
                    fails.push(format!("{label}: pdf changes when both z are flipped, wo {wo:?}, wi {wi:?}"));
                }
                if across[k].f != [0.0; 3] || across[k].pdf != 0.0 {
                    fails.push(format!("{label}: f or pdf nonzero with wi across the surface, wo {wo:?}, wi {wi:?}"));
                }
                if fwd[k].f.iter().any(|x| !(x.is_finite() && *x >= 0.0)) || fwd[k].pdf.is_nan() || fwd[k].pdf < 0.0 {
                    fails.push(format!("{label}: f {:?} pdf {} at wo {wo:?}, wi {wi:?}", fwd[k].f, fwd[k].pdf));
                }
            }
        }
        fails
    });
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

/// Glass against the f64 reference: the reflected and refracted directions, the fraction of
/// reflections (Fresnel, within a binomial bound), the returned pdf (F or 1 - F) and weights
/// (Ks, Kd: no 1/eta^2), total internal reflection beyond the critical angle, from both sides;
/// bsdf_eval and bsdf_pdf are 0 for a delta BSDF.
#[test]
fn glass_matches_the_fresnel_reference() {
    const N: usize = 200_000;
    let iors = [1.5f32, 1.33, 2.4];
    let materials: Vec<GpuMaterial> = iors
        .iter()
        .map(|&ior| GpuMaterial {
            diffuse: [0.9, 0.8, 0.7],
            specular: [0.6, 0.5, 0.4],
            ior,
            ..GpuMaterial::new(BsdfKind::Glass)
        })
        .collect();
    let fails = common::with_gpu(TIMEOUT_S, move |ctx| {
        let probe = Probe::new(ctx, &materials).unwrap();
        let mut fails = vec![];
        for (m, mat) in materials.iter().enumerate() {
            let ior = mat.ior as f64;
            for theta in [0.0f64, 10.0, 30.0, 40.0, 41.0, 45.0, 60.0, 80.0, 89.0] {
                for inside in [false, true] {
                    let mut wo = direction(theta.to_radians(), 0.7);
                    if inside {
                        wo[2] = -wo[2];
                    }
                    let what =
                        format!("glass ior {ior} wo theta {theta} deg {}", if inside { "inside" } else { "outside" });
                    let (fresnel, r, t) = glass_reference(wo, ior);
                    let out = probe.sample(m as u32, to_f32(wo), &uniforms(N, 11 + m as u64)).unwrap();
                    let mut reflected = 0usize;
                    let mut worst_angle = 0.0f64;
                    for s in &out {
                        if s.flags & FLAG_OK == 0 || s.flags & FLAG_DELTA == 0 || s.flags & FLAG_DELTA_KIND == 0 {
                            fails.push(format!("{what}: sample not ok or not flagged delta: {s:?}"));
                            break;
                        }
                        if s.f != [0.0; 3] || s.eval_pdf != 0.0 {
                            fails.push(format!("{what}: bsdf_eval/bsdf_pdf of a delta BSDF are not 0: {s:?}"));
                            break;
                        }
                        let wi = s.wi.map(|x| x as f64);
                        let is_reflection = wi[2].signum() == wo[2].signum();
                        let (want_dir, want_pdf, want_weight) = if is_reflection {
                            reflected += 1;
                            (r, fresnel, mat.specular)
                        } else {
                            match t {
                                Some(t) => (t, 1.0 - fresnel, mat.diffuse),
                                None => {
                                    fails.push(format!("{what}: refracted under total internal reflection"));
                                    break;
                                }
                            }
                        };
                        worst_angle = worst_angle.max(angle_between(wi, want_dir));
                        if (s.pdf as f64 - want_pdf).abs() > 1e-5 || s.weight != want_weight {
                            fails.push(format!(
                                "{what}: pdf {} weight {:?}, want {want_pdf} and {want_weight:?}",
                                s.pdf, s.weight
                            ));
                            break;
                        }
                    }
                    if worst_angle > 1e-5 {
                        fails.push(format!("{what}: direction off the reference by {worst_angle:e} rad"));
                    }
                    let frac = reflected as f64 / N as f64;
                    let bound = 5.0 * (fresnel * (1.0 - fresnel) / N as f64).sqrt() + 1e-5;
                    if (frac - fresnel).abs() > bound {
                        fails.push(format!(
                            "{what}: {frac:.5} reflected, Fresnel says {fresnel:.5} (bound {bound:.1e})"
                        ));
                    }
                    if t.is_none() && reflected != N {
                        fails.push(format!("{what}: beyond the critical angle but {} refracted", N - reflected));
                    }
                    if inside && theta > (1.0 / ior).asin().to_degrees() + 1e-3 && t.is_some() {
                        fails.push(format!("{what}: the reference misses total internal reflection"));
                    }
                }
            }
        }
        fails
    });
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

/// Mirror: wi is the exact reflection on either side, pdf 1, weight Ks; eval and pdf are 0.
#[test]
fn mirror_reflects_exactly() {
    let mirror = GpuMaterial { specular: [0.9, 0.5, 0.2], ..GpuMaterial::new(BsdfKind::Mirror) };
    let fails = common::with_gpu(TIMEOUT_S, move |ctx| {
        let probe = Probe::new(ctx, &[mirror]).unwrap();
        let mut fails = vec![];
        for theta in [0.0f64, 30.0, 60.0, 89.0, 91.0, 150.0, 180.0] {
            let wo = direction(theta.to_radians(), 2.0);
            let out = probe.sample(0, to_f32(wo), &uniforms(1000, 5)).unwrap();
            for s in &out {
                let err = angle_between(s.wi.map(|x| x as f64), reflect(wo));
                if s.flags != FLAG_OK | FLAG_DELTA | FLAG_DELTA_KIND
                    || err > 1e-6
                    || s.pdf != 1.0
                    || s.weight != mirror.specular
                    || s.f != [0.0; 3]
                    || s.eval_pdf != 0.0
                {
                    fails.push(format!("mirror at theta_o {theta} deg: {s:?}, reflection off by {err:e} rad"));
                    break;
                }
            }
        }
        fails
    });
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}

/// BSDF_MASK: a kernel compiled with Lambert only still runs Lambert, and every other kind
/// (and an unknown kind) evaluates to 0 and never samples.
#[test]
fn kinds_left_out_of_bsdf_mask_are_black() {
    let mut materials: Vec<GpuMaterial> = BsdfKind::ALL.iter().map(|&k| GpuMaterial::new(k)).collect();
    materials.push(GpuMaterial { kind: 99, ..GpuMaterial::new(BsdfKind::Lambert) });
    let fails = common::with_gpu(TIMEOUT_S, move |ctx| {
        let probe = Probe::with_variant(ctx, &materials, "lambert").unwrap();
        let wo = to_f32(direction(0.5, 1.0));
        let wi = [to_f32(direction(0.3, 2.0))];
        let mut fails = vec![];
        for (m, mat) in materials.iter().enumerate() {
            let name =
                BsdfKind::ALL.iter().find(|k| k.code() == mat.kind).map_or("unknown kind".into(), |k| k.to_string());
            let s = probe.sample(m as u32, wo, &uniforms(64, 1)).unwrap();
            let e = probe.eval(m as u32, wo, &wi).unwrap();
            let ok = s.iter().filter(|s| s.flags & FLAG_OK != 0).count();
            if mat.kind == BsdfKind::Lambert.code() {
                if ok != 64 || e[0].f[0] <= 0.0 || e[0].pdf <= 0.0 {
                    fails.push(format!("{name} (compiled in): {ok}/64 samples, f {:?}, pdf {}", e[0].f, e[0].pdf));
                }
            } else if ok != 0 || e[0].f != [0.0; 3] || e[0].pdf != 0.0 {
                fails.push(format!("{name} (left out): {ok}/64 samples, f {:?}, pdf {}", e[0].f, e[0].pdf));
            }
        }
        fails
    });
    assert!(fails.is_empty(), "{} failure(s):\n{}", fails.len(), fails.join("\n"));
}
