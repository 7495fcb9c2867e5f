//! `trilab render`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use clap::Args;
use trilab::analyze::MethodChoice;
use trilab::error::{Error, Result};
use trilab::render::session::{self, RenderRequest};
use trilab::render::KernelChoice;

use super::choice::{choice, method_choice, method_help};
use super::{note, scene_help, BuildArgs, GpuArgs, JsonArg};

/// Path-trace a scene: linear RGBA EXR, a tone-mapped sRGB PNG and a JSON sidecar.
#[derive(Args)]
pub struct RenderArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    #[arg(long, value_name = "M", default_value = "mt", value_parser = method_choice(), hide_possible_values = true,
          help = method_help("Intersection method:"))]
    method: MethodChoice,
    #[command(flatten)]
    bvh: BuildArgs,
    /// Image width in pixels.
    #[arg(long, value_name = "W", default_value_t = 800)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, value_name = "H", default_value_t = 600)]
    height: u32,
    /// Samples per pixel.
    #[arg(long, value_name = "N", default_value_t = 500)]
    spp: u32,
    /// Most scattering events per path.
    #[arg(long, value_name = "N", default_value_t = 16)]
    max_depth: u32,
    /// Russian roulette from this many scattering events on.
    #[arg(long, value_name = "N", default_value_t = 3)]
    rr_depth: u32,
    /// Random seed of the sample sequence.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u32,
    /// `eye_x,eye_y,eye_z,target_x,target_y,target_z,up_x,up_y,up_z,fov_y_degrees`; default: frames
    /// the scene as the ray generators do.
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<String>,
    /// Constant environment radiance `r,g,b` (or one value).
    #[arg(long, default_value = "1")]
    env: String,
    /// PNG exposure in stops (the EXR is not scaled).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    exposure: f32,
    /// `specialised`: only the BSDFs the scene uses; `general`: the all-BSDF kernel.
    #[arg(long, value_parser = choice::<KernelChoice>(), default_value_t = KernelChoice::Specialised)]
    kernel: KernelChoice,
    /// Wall-clock target per GPU submit, milliseconds (keeps each submit far from a watchdog).
    #[arg(long, default_value_t = 250.0)]
    submit_ms: f64,
    /// Output OpenEXR file; the PNG and JSON are written beside it (same stem).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Write the image so far (EXR, PNG, JSON with `"checkpoint": true`) every this many
    /// seconds, so a killed process still leaves one; 0 turns checkpoints off.
    #[arg(long, default_value_t = 300.0)]
    checkpoint_secs: f64,
    #[command(flatten)]
    json: JsonArg,
    #[command(flatten)]
    gpu: GpuArgs,
}

/// `--camera`/`--env`: comma-separated finite numbers, as many as one of `n`.
fn parse_floats(what: &str, s: &str, n: &[usize]) -> Result<Vec<f32>> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| Error::Usage(format!("--{what} `{s}`: {e}")))?;
    if !n.contains(&v.len()) || v.iter().any(|x| !x.is_finite()) {
        return Err(Error::Usage(format!("--{what} `{s}`: expected {n:?} finite comma-separated numbers")));
    }
    Ok(v)
}

pub fn run(a: RenderArgs) -> Result<()> {
    let env = parse_floats("env", &a.env, &[1, 3])?;
    let camera = match &a.camera {
        Some(c) => Some(<[f32; 10]>::try_from(parse_floats("camera", c, &[10])?).expect("ten numbers")),
        None => None,
    };
    let req = RenderRequest {
        scene: a.scene,
        out: a.out,
        method: a.method,
        build: a.bvh.options(),
        width: a.width,
        height: a.height,
        spp: a.spp,
        max_depth: a.max_depth,
        rr_depth: a.rr_depth,
        seed: a.seed,
        camera,
        env: if env.len() == 1 { [env[0]; 3] } else { [env[0], env[1], env[2]] },
        exposure: a.exposure,
        kernel: a.kernel,
        submit_ms: a.submit_ms,
        checkpoint_secs: a.checkpoint_secs,
    };
    let ctx = a.gpu.context()?;
    // Ctrl-C: the render finishes the pass in flight, then writes what has accumulated.
    let interrupted = Arc::new(AtomicBool::new(false));
    let flag = interrupted.clone();
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)) {
        note(&format!("warning: cannot catch Ctrl-C ({e}); interrupting will not save the partial image"));
    }
    let bar = if a.quiet { indicatif::ProgressBar::hidden() } else { indicatif::ProgressBar::new(u64::from(req.spp)) };
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:40}] {pos}/{len} spp  {msg}  ETA {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let pixels = f64::from(req.width) * f64::from(req.height);
    let report = session::run(
        &ctx,
        &req,
        &interrupted,
        &mut |p| {
            bar.set_position(u64::from(p.spp_done));
            bar.set_message(format!("{:.3} Msamples/s", f64::from(p.spp_done) * pixels / p.seconds * 1e-6));
        },
        &mut |m| bar.suspend(|| note(m)),
    );
    bar.finish_and_clear();
    let report = report?;
    a.json.print(&report);
    if report.interrupted {
        // Saved; now exit as an interrupted process does (128 + SIGINT), like `study`.
        drop(ctx);
        super::exit_interrupted();
    }
    Ok(())
}
