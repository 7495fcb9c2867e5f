//! The path-tracing benchmark: scenes x methods x kernel choice, each configuration rendered
//! once to warm up and then `repeat` times, reporting median / min / max samples per second and
//! rays per second from GPU timestamps. Every render is validated before its speed counts: no
//! dropped (NaN/Inf) samples, and an image mean within 2 % of the Möller–Trumbore render of the
//! same scene (the methods trace the same paths).

use std::path::{Path, PathBuf};

use crate::bvh::BuildOptions;
use crate::encoding::Method;
use crate::error::{Error, Result};
use crate::gpu::Context;
use crate::pipeline::HostScene;
use crate::render::{render, KernelChoice, PathtraceKernel, RenderSettings, RenderTarget};
use crate::report::{Report, Summary, Table};
use crate::scene::{load_obj, BsdfKind};
use crate::services::render_measure::{bench_settings, check_image_mean, summarise_renders};

#[derive(Clone, Debug)]
pub struct RenderBenchOptions {
    pub scenes: Vec<PathBuf>,
    pub methods: Vec<Method>,
    pub kernels: Vec<KernelChoice>,
    pub build: BuildOptions,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    /// Environment radiance; `None`: white, or black for scenes with emitters.
    pub env: Option<[f32; 3]>,
    pub repeat: usize,
}

impl Default for RenderBenchOptions {
    fn default() -> Self {
        RenderBenchOptions {
            scenes: vec![],
            methods: Method::ALL.to_vec(),
            kernels: vec![KernelChoice::Specialised],
            build: BuildOptions::new(crate::defaults::LEAF_SIZE),
            width: 200,
            height: 150,
            spp: 16,
            max_depth: 16,
            env: None,
            repeat: 3,
        }
    }
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderBenchRow {
    pub scene: String,
    pub triangles: usize,
    pub method: Method,
    pub kernel_choice: KernelChoice,
    pub kernel: &'static str,
    pub bsdfs: Vec<&'static str>,
    /// SPIR-V instructions: whole module, and inside function bodies.
    pub spirv_module: u32,
    pub spirv_functions: u32,
    pub msamples_per_s: Summary,
    pub mrays_per_s: Summary,
    pub ms: Summary,
    /// Rays per sample (closest + occlusion).
    pub rays_per_sample: f64,
    pub image_mean: f64,
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderBenchReport {
    pub device: String,
    pub driver: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    pub leaf_size: u32,
    pub timed_on_gpu: bool,
    /// Timed renders per configuration (after one warm-up).
    pub repeat: usize,
    pub rows: Vec<RenderBenchRow>,
}

impl Report for RenderBenchReport {
    fn to_text(&self) -> String {
        format!("{}\n{}", self.header(), self.table().to_text())
    }
}

impl crate::services::results::Results for RenderBenchReport {
    /// `bench.json`, `bench.md` in `--out`, as bench's.
    const STEM: &'static str = "bench";

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        format!("{}\n{}", self.header(), self.table().to_markdown())
    }

    /// None: bench-render writes no rows.
    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        None
    }
}

impl RenderBenchReport {
    /// Device, driver and the settings every row shares.
    pub fn header(&self) -> String {
        format!(
            "device: {} ({})\n{}x{}, {} spp, max depth {}, leaf size {}, median (min-max) of {} renders after a warm-up, {} time\n",
            self.device,
            self.driver,
            self.width,
            self.height,
            self.spp,
            self.max_depth,
            self.leaf_size,
            self.repeat.max(1),
            if self.timed_on_gpu { "GPU timestamp" } else { "wall" }
        )
    }

    /// Writes the report as JSON and the table as Markdown where asked, each atomically.
    pub fn write(&self, json: Option<&Path>, md: Option<&Path>) -> Result<()> {
        crate::services::results::write(self, json, md).map(drop)
    }

    pub fn table(&self) -> Table {
        let mut t = Table::new([
            "scene",
            "method",
            "choice",
            "kernel",
            "BSDFs",
            "SPIR-V (fn)",
            "Msamples/s median (min-max)",
            "Mrays/s median",
            "rays/sample",
        ]);
        for r in &self.rows {
            let s = r.msamples_per_s;
            t.row([
                r.scene.clone(),
                r.method.name().to_owned(),
                match r.kernel_choice {
                    KernelChoice::Specialised => "specialised".to_owned(),
                    KernelChoice::General => "general".to_owned(),
                },
                r.kernel.to_owned(),
                if r.bsdfs.len() == BsdfKind::ALL.len() { "all 7".to_owned() } else { r.bsdfs.join("+") },
                format!("{} ({})", r.spirv_module, r.spirv_functions),
                format!("{:.3} ({:.3}-{:.3})", s.median, s.min, s.max),
                format!("{:.2}", r.mrays_per_s.median),
                format!("{:.2}", r.rays_per_sample),
            ]);
        }
        t
    }
}

pub fn run(ctx: &Context, o: &RenderBenchOptions, mut progress: impl FnMut(&str)) -> Result<RenderBenchReport> {
    let info = ctx.info();
    let mut report = RenderBenchReport {
        device: info.name.clone(),
        driver: info.driver_label(),
        width: o.width,
        height: o.height,
        spp: o.spp,
        max_depth: o.max_depth,
        leaf_size: o.build.max_leaf_size,
        timed_on_gpu: info.timestamp_valid_bits > 0,
        repeat: o.repeat,
        rows: vec![],
    };
    for path in &o.scenes {
        let mesh = load_obj(path)?;
        let name = crate::scene::scene_name(path);
        let host = HostScene::build(&name, &mesh, &o.build)?;
        let settings = bench_settings(&mesh, (o.width, o.height), o.spp, o.max_depth, o.env);
        let mut reference_mean: Option<f64> = None;
        for &method in &o.methods {
            // Every path-trace variant reads the same bindings: one upload serves each choice.
            let mut target =
                RenderTarget::new(ctx, &host, method.into(), KernelChoice::General, settings.pixels(), false)?;
            for &choice in &o.kernels {
                let kernel = PathtraceKernel::choose(method, target.scene.bsdf_mask, choice);
                target.kernel = kernel;
                progress(&format!("{name}: {} ({})", kernel.source.name, kernel.bsdfs().join("+")));
                let warm = RenderSettings { spp: 1, ..settings.clone() };
                render(ctx, &target, &warm, &mut |_| true)?;
                let mut runs = vec![];
                for _ in 0..o.repeat.max(1) {
                    runs.push(render(ctx, &target, &settings, &mut |_| true)?);
                }
                let m = summarise_renders(&runs)
                    .map_err(|e| Error::Usage(format!("{name} {}: {e}", kernel.source.name)))?;
                check_image_mean(m.image_mean, &mut reference_mean)
                    .map_err(|e| Error::Usage(format!("{name} {}: {e}", kernel.source.name)))?;
                let counts = crate::spirv::count(&kernel.source.words())
                    .map_err(|e| Error::Spirv { kernel: kernel.source.name.into(), message: e })?;
                report.rows.push(RenderBenchRow {
                    scene: name.clone(),
                    triangles: mesh.triangle_count(),
                    method,
                    kernel_choice: choice,
                    kernel: kernel.source.name,
                    bsdfs: kernel.bsdfs(),
                    spirv_module: counts.module,
                    spirv_functions: counts.functions,
                    msamples_per_s: m.msamples_per_s,
                    mrays_per_s: m.mrays_per_s,
                    ms: m.ms,
                    rays_per_sample: m.rays_per_sample,
                    image_mean: m.image_mean,
                });
            }
        }
    }
    Ok(report)
}
