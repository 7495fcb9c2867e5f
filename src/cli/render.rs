//! `trilab render`.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::sync::Arc;

use clap::Args;
use trilab::conditioning::MethodChoice;
use trilab::encoding::Layout;
use trilab::error::{Error, Result};
use trilab::render::session::{self, RenderRequest};
use trilab::render::{EnvSpec, KernelChoice};

use super::camera::CameraArg;

use super::choice::{choice, method_choice, method_help};
use super::{note, scene_help, signals, BuildArgs, GpuArgs, JsonArg};

/// Path-trace a scene: linear RGBA EXR, a tone-mapped sRGB PNG and a JSON sidecar.
#[derive(Args)]
pub struct RenderArgs {
    #[arg(long, value_name = "S", help = scene_help!())]
    scene: PathBuf,
    #[arg(long, value_name = "M", default_value = trilab::defaults::METHOD, value_parser = method_choice(), hide_possible_values = true,
          help = method_help("Intersection method:"))]
    method: MethodChoice,
    /// BVH node layout the path tracer traverses (`trilab methods` lists them).
    #[arg(long, value_parser = choice::<Layout>(), default_value_t = Layout::DEFAULT)]
    layout: Layout,
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
    #[command(flatten)]
    camera: CameraArg,
    /// `sky`: a sky gradient over a ground with a sun, sampled by next-event estimation (the
    /// default for scenes without emitters); or a constant radiance `v` or `r,g,b` (`0`: none,
    /// the default for scenes with emitters).
    #[arg(long, allow_hyphen_values = true)]
    env: Option<EnvSpec>,
    /// Direction towards the sun of `--env sky`, `x,y,z` (y up; default -0.45,0.75,0.5: high on
    /// the left of the default front view).
    #[arg(long, allow_hyphen_values = true)]
    sun_dir: Option<String>,
    /// PNG exposure in stops, -100 to 100 (the EXR is not scaled).
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_hyphen_values = true, value_parser = exposure)]
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

/// `--exposure`: a finite number of stops that 2^EV scales by in f32 (refused here, before
/// any work: `nan` gave a black PNG).
fn exposure(s: &str) -> std::result::Result<f32, String> {
    let ev: f32 = s.trim().parse().map_err(|e| format!("`{s}`: {e}"))?;
    session::check_exposure(ev)?;
    Ok(ev)
}

/// `--sun-dir`: comma-separated finite numbers, as many as one of `n`.
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
    let sun_dir = match &a.sun_dir {
        Some(d) => {
            let v = parse_floats("sun-dir", d, &[3])?;
            Some([v[0], v[1], v[2]])
        }
        None => None,
    };
    let req = RenderRequest {
        scene: a.scene,
        out: a.out,
        method: a.method,
        layout: a.layout,
        build: a.bvh.options(),
        width: a.width,
        height: a.height,
        spp: a.spp,
        max_depth: a.max_depth,
        rr_depth: a.rr_depth,
        seed: a.seed,
        camera: a.camera.camera,
        env: a.env,
        sun_dir,
        exposure: a.exposure,
        kernel: a.kernel,
        submit_ms: a.submit_ms,
        checkpoint_secs: a.checkpoint_secs,
    };
    let ctx = a.gpu.context()?;
    // Ctrl-C, SIGTERM (`timeout`, CI runners, containers) or SIGHUP: the render finishes the
    // pass in flight, then writes what has accumulated. A second signal ends it at once (the
    // last checkpoint stays).
    let interrupted = Arc::new(AtomicBool::new(false));
    let stop_signal = Arc::new(AtomicI32::new(0));
    let (flag, first) = (interrupted.clone(), stop_signal.clone());
    let handler = signals::on_stop(move |signal| {
        if flag.swap(true, Ordering::SeqCst) {
            note(&format!(
                "{} again: stopping without saving the passes since the last checkpoint",
                signals::name(signal)
            ));
            signals::exit_now(signal);
        }
        first.store(signal, Ordering::SeqCst);
    });
    if let Err(e) = handler {
        note(&format!(
            "warning: cannot catch Ctrl-C or SIGTERM ({e}); stopping the render will not save the partial image"
        ));
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
        // Saved; now exit as a process the signal ended does (128 + its number: 130, 143, 129).
        drop(ctx);
        super::exit_interrupted(stop_signal.load(Ordering::SeqCst));
    }
    Ok(())
}
