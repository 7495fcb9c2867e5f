//! Timing renders the same way everywhere (the render benchmark, the study, `ab`'s worker): a
//! benchmark's render settings, the check that every method's image agrees with the scene's
//! first render, and the summary of timed renders that refuses a speed for a broken image.

use crate::error::{Error, Result};
use crate::render::{RenderResult, RenderSettings};
use crate::report::Summary;
use crate::scene::Mesh;

/// A benchmark's render settings for `mesh`: the paper's camera and path settings at `size`,
/// `spp` and `max_depth`; a white environment, or black for scenes with emitters, unless `env`
/// is given.
pub fn bench_settings(
    mesh: &Mesh,
    size: (u32, u32),
    spp: u32,
    max_depth: u32,
    env: Option<[f32; 3]>,
) -> RenderSettings {
    let emissive = mesh.materials.iter().any(|m| m.is_emissive());
    RenderSettings {
        width: size.0,
        height: size.1,
        spp,
        max_depth,
        env: env.unwrap_or(if emissive { [0.0; 3] } else { [1.0; 3] }),
        ..RenderSettings::paper(mesh)
    }
}

/// Every method (and leaf size) traces the same paths through the same scene, so their image
/// means must agree: checks `mean` against the first one seen for the scene (kept in `first`)
/// to within 2 %.
pub fn check_image_mean(mean: f64, first: &mut Option<f64>) -> std::result::Result<(), String> {
    let base = *first.get_or_insert(mean);
    if (mean - base).abs() > 0.02 * base.abs().max(1e-6) {
        return Err(format!("image mean {mean} differs from the scene's first render ({base}) by more than 2 %"));
    }
    Ok(())
}

/// Timed renders of one configuration, summarised and checked.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderMeasure {
    pub msamples_per_s: Summary,
    pub mrays_per_s: Summary,
    /// GPU time per render (host wall time where there are no timestamps), ms.
    pub ms: Summary,
    /// Rays per sample (closest + occlusion).
    pub rays_per_sample: f64,
    /// Mean of the last render's RGB.
    pub image_mean: f64,
}

/// Summarises timed renders of one configuration; an error when any sample was NaN/Inf (dropped)
/// or the image mean is not finite, so a broken kernel never reports a speed.
pub fn summarise_renders(runs: &[RenderResult]) -> Result<RenderMeasure> {
    let last = runs.last().ok_or_else(|| Error::Usage("no timed renders".into()))?;
    let mean = image_mean(last);
    let bad = runs.iter().map(|r| r.dropped_samples).sum::<u64>();
    if bad > 0 || !mean.is_finite() {
        return Err(Error::Usage(format!("{bad} NaN/Inf samples (image mean {mean})")));
    }
    let rate = |f: &dyn Fn(&RenderResult) -> f64| Summary::of(&runs.iter().map(f).collect::<Vec<_>>()).unwrap();
    Ok(RenderMeasure {
        msamples_per_s: rate(&|r| r.samples_per_second() * 1e-6),
        mrays_per_s: rate(&|r| r.mrays_per_second()),
        ms: rate(&|r| r.seconds() * 1e3),
        rays_per_sample: (last.closest_rays + last.shadow_rays) as f64 / last.samples() as f64,
        image_mean: mean,
    })
}

pub fn image_mean(r: &RenderResult) -> f64 {
    let img = r.image();
    img.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>() / (3 * img.len()) as f64
}
