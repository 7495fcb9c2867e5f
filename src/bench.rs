//! The ray-casting benchmark (`trilab bench`, `cargo bench`): primary, diffuse and random ray
//! sets on each scene, every method, each result validated against the f64 reference before
//! its speed is reported (as tinybvh's speed test does), optionally beside Embree on the same
//! ray files in the same run.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use serde::Serialize;

use crate::bvh::{BuildOptions, Bvh, LeafPolicy};
use crate::compare::compare_closest;
use crate::encoding::Method;
use crate::error::{Error, Result};
use crate::gpu::{raycast, Context, GpuScene, RaycastOptions, Summary};
use crate::rays::{self, Camera, Ray};
use crate::reference::Reference;
use crate::report::Table;
use crate::scene::{load_obj, Mesh};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub scenes: Vec<PathBuf>,
    pub methods: Vec<Method>,
    pub leaf_size: u32,
    pub leaf_policy: LeafPolicy,
    /// `BuildOptions::sah_group`: 4 prices leaves in quads.
    pub sah_group: u32,
    pub warmup: usize,
    pub repeat: usize,
    pub width: u32,
    pub height: u32,
    pub diffuse_per_hit: u32,
    pub random_rays: usize,
    pub seed: u64,
    /// Read `<scene>.{primary,diffuse,random}.rays` from here instead of generating (for
    /// example the peer's held-out sets from ../shared/peers/make_rays.sh).
    pub rays_dir: Option<PathBuf>,
    /// The Embree peer program (`embree_rays`), run on the same ray files.
    pub embree: Option<PathBuf>,
    pub batch_rays: usize,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            scenes: vec![],
            methods: Method::ALL.to_vec(),
            leaf_size: 4,
            leaf_policy: LeafPolicy::Fill,
            sah_group: 1,
            warmup: 1,
            repeat: 5,
            width: 800,
            height: 600,
            diffuse_per_hit: 8,
            random_rays: 1_000_000,
            seed: 7,
            rays_dir: None,
            embree: None,
            batch_rays: 1 << 20,
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub scene: String,
    pub triangles: usize,
    pub ray_set: String,
    pub rays: usize,
    pub method: Method,
    pub leaf_size: u32,
    /// Triangles the BVH's SAH priced as one test (4: quad-aware).
    pub sah_group: u32,
    pub scene_bytes: usize,
    /// Kernel time (GPU timestamps), milliseconds.
    pub kernel_ms: Summary,
    /// Rays per second at the median, min and max kernel time, millions.
    pub mrays_per_s: f64,
    pub mrays_per_s_min: f64,
    pub mrays_per_s_max: f64,
    /// Fraction of rays agreeing with the f64 reference.
    pub agreement: f64,
    pub unexplained_disagreements: usize,
    pub invalid: usize,
    pub embree_mrays_per_s: Option<f64>,
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub device: String,
    pub driver: String,
    pub mesa_version: Option<String>,
    pub lp_num_threads: Option<String>,
    pub host_cpus: usize,
    pub rows: Vec<BenchRow>,
    /// (scene, ray set, Embree Mrays/s, best trilab Mrays/s, ratio)
    pub embree: Vec<(String, String, f64, f64, f64)>,
}

impl BenchReport {
    pub fn table(&self) -> Table {
        let mut t = Table::new([
            "scene",
            "rays",
            "set",
            "method",
            "leaf",
            "MB",
            "kernel ms",
            "Mrays/s",
            "min..max",
            "agree %",
            "Embree",
        ]);
        for r in &self.rows {
            t.row([
                r.scene.clone(),
                r.rays.to_string(),
                r.ray_set.clone(),
                r.method.to_string(),
                r.leaf_size.to_string(),
                format!("{:.2}", r.scene_bytes as f64 / 1e6),
                format!("{:.1}", r.kernel_ms.median),
                format!("{:.2}", r.mrays_per_s),
                format!("{:.2}..{:.2}", r.mrays_per_s_min, r.mrays_per_s_max),
                format!("{:.4}", 100.0 * r.agreement),
                r.embree_mrays_per_s.map(|e| format!("{e:.2}")).unwrap_or_else(|| "-".into()),
            ]);
        }
        t
    }

    pub fn embree_table(&self) -> Table {
        let mut t = Table::new(["scene", "set", "Embree Mrays/s", "best trilab Mrays/s", "trilab / Embree"]);
        for (s, set, e, b, ratio) in &self.embree {
            t.row([s.clone(), set.clone(), format!("{e:.2}"), format!("{b:.2}"), format!("{ratio:.2}")]);
        }
        t
    }
}

/// The three ray sets for a scene: generated (diffuse bounces from the f64 reference over
/// `reference`), or read from `rays_dir`.
pub fn ray_sets(mesh: &Mesh, name: &str, reference: &Reference, o: &BenchOptions) -> Result<Vec<(String, Vec<Ray>)>> {
    if let Some(dir) = &o.rays_dir {
        return ["primary", "diffuse", "random"]
            .iter()
            .map(|set| Ok((set.to_string(), rays::read_rays(&dir.join(format!("{name}.{set}.rays")))?)))
            .collect();
    }
    let bounds = mesh.bounds();
    let primary = rays::primary_rays(&Camera::framing(&bounds), o.width, o.height);
    let diffuse = rays::diffuse_rays(mesh, reference, &primary, o.diffuse_per_hit, o.seed);
    let random = rays::random_rays(&bounds, o.random_rays, o.seed);
    Ok(vec![("primary".into(), primary), ("diffuse".into(), diffuse), ("random".into(), random)])
}

/// Runs the Embree peer on a ray file; returns its best Mrays/s.
fn run_embree(bin: &Path, scene: &Path, rays: &Path, out: &Path, repeat: usize) -> Result<f64> {
    let output = Command::new(bin)
        .arg("trace")
        .arg(scene)
        .arg(rays)
        .arg(out)
        .arg(repeat.max(1).to_string())
        .output()
        .map_err(|e| Error::io(bin, e))?;
    let text = String::from_utf8_lossy(&output.stdout);
    if !output.status.success() {
        return Err(Error::Usage(format!(
            "{} failed: {}{}",
            bin.display(),
            text,
            String::from_utf8_lossy(&output.stderr)
        )));
    }
    text.split_whitespace()
        .find_map(|w| w.strip_prefix("mrays_per_s=").and_then(|v| v.parse().ok()))
        .ok_or_else(|| Error::Usage(format!("cannot read Mrays/s from {}: {text}", bin.display())))
}

/// Compares GPU hits with the f64 reference; an error (never a reported speed) when fewer than
/// 99.99 % agree, any disagreement is unexplained (not an edge, vertex or tie case) or any hit is
/// invalid.
pub fn validate_hits(
    mesh: &Mesh,
    rays: &[Ray],
    hits: &[crate::rays::Hit],
    ref_hits: &[crate::reference::RefHit],
) -> Result<crate::compare::Agreement> {
    let agreement = compare_closest(mesh, rays, hits, ref_hits);
    if !agreement.passes(0.9999) {
        return Err(Error::Usage(format!(
            "results disagree with the f64 reference ({}); not reporting a speed",
            agreement.summary()
        )));
    }
    Ok(agreement)
}

/// Mrays/s from a kernel-time summary: the median run's rate, and min/max from the slowest and
/// fastest runs.
pub fn mrays_summary(rays: usize, ms: Summary) -> Summary {
    let mr = |ms: f64| rays as f64 / (ms * 1e-3) / 1e6;
    Summary { median: mr(ms.median), min: mr(ms.max), max: mr(ms.min), runs: ms.runs }
}

/// One validated ray-casting measurement.
#[derive(Clone, Debug)]
pub struct RayMeasure {
    /// GPU kernel time per run (or host wall time where the queue has no timestamps), ms.
    pub kernel_ms: Summary,
    /// Mrays/s at the median, slowest and fastest run (so `min` comes from `kernel_ms.max`).
    pub mrays_per_s: Summary,
    pub agreement: crate::compare::Agreement,
    pub hits: Vec<crate::rays::Hit>,
}

/// Casts `rays` (`opts.warmup` untimed runs, then `opts.repeat` timed ones) and validates the
/// hits against the f64 reference before the time counts: fewer than 99.99 % agreeing rays, an
/// unexplained disagreement or an invalid hit is an error, never a reported speed.
pub fn measure_rays(
    ctx: &Context,
    kernel: &crate::gpu::Kernel,
    scene: &GpuScene,
    mesh: &Mesh,
    rays: &[Ray],
    ref_hits: &[crate::reference::RefHit],
    opts: &RaycastOptions,
) -> Result<RayMeasure> {
    let res = raycast(ctx, kernel, scene, rays, opts)?;
    let agreement = validate_hits(mesh, rays, &res.hits, ref_hits)?;
    let ms = res.time_ms();
    let mrays_per_s = mrays_summary(rays.len(), ms);
    Ok(RayMeasure { kernel_ms: ms, mrays_per_s, agreement, hits: res.hits })
}

pub fn run(ctx: &Context, o: &BenchOptions, mut progress: impl FnMut(&str)) -> Result<BenchReport> {
    let info = ctx.info();
    let mut report = BenchReport {
        device: info.name.clone(),
        driver: info.driver_label(),
        mesa_version: info.mesa_version.clone(),
        lp_num_threads: std::env::var("LP_NUM_THREADS").ok(),
        host_cpus: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        rows: vec![],
        embree: vec![],
    };
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let kernels: Vec<_> =
        o.methods.iter().map(|&m| ctx.create_kernel(crate::kernels::raycast(m, false))).collect::<Result<_>>()?;
    for scene_path in &o.scenes {
        let name = scene_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let mesh = load_obj(scene_path)?;
        progress(&format!("{name}: {} triangles; making ray sets", mesh.triangle_count()));
        let t = Instant::now();
        let bvh = Bvh::build(
            &mesh,
            &BuildOptions { leaf_policy: o.leaf_policy, sah_group: o.sah_group, ..BuildOptions::new(o.leaf_size) },
        );
        let reference = Reference::new(&mesh, &bvh);
        let sets = ray_sets(&mesh, &name, &reference, o)?;
        progress(&format!("{name}: ray sets ready in {:.1} s", t.elapsed().as_secs_f64()));
        let scenes: Vec<GpuScene> =
            o.methods.iter().map(|m| GpuScene::upload(ctx, &m.encode(&mesh, &bvh))).collect::<Result<_>>()?;
        for (set, rays) in &sets {
            let ref_hits = reference.trace_all(rays, false);
            let mut best: f64 = 0.0;
            for ((method, kernel), gscene) in o.methods.iter().zip(&kernels).zip(&scenes) {
                let opts = RaycastOptions { warmup: o.warmup, repeat: o.repeat, batch_rays: o.batch_rays };
                let m = measure_rays(ctx, kernel, gscene, &mesh, rays, &ref_hits, &opts)
                    .map_err(|e| Error::Usage(format!("{name} {set} {method}: {e}")))?;
                let (ms, mr, agreement) = (m.kernel_ms, m.mrays_per_s, m.agreement);
                progress(&format!(
                    "{name} {set} {method}: {:.2} Mrays/s ({:.1} ms), {}",
                    mr.median,
                    ms.median,
                    agreement.summary()
                ));
                best = best.max(mr.median);
                report.rows.push(BenchRow {
                    scene: name.clone(),
                    triangles: mesh.triangle_count(),
                    ray_set: set.clone(),
                    rays: rays.len(),
                    method: *method,
                    leaf_size: o.leaf_size,
                    sah_group: o.sah_group,
                    scene_bytes: gscene.bytes,
                    kernel_ms: ms,
                    mrays_per_s: mr.median,
                    mrays_per_s_min: mr.min,
                    mrays_per_s_max: mr.max,
                    agreement: agreement.fraction(),
                    unexplained_disagreements: agreement.unexplained,
                    invalid: agreement.invalid.len(),
                    embree_mrays_per_s: None,
                });
            }
            if let Some(bin) = &o.embree {
                let rays_file = tmp.path().join(format!("{name}.{set}.rays"));
                rays::write_rays(&rays_file, rays)?;
                let e = run_embree(bin, scene_path, &rays_file, &tmp.path().join("embree.hits"), o.repeat.max(3))?;
                progress(&format!("{name} {set} Embree: {e:.2} Mrays/s; best trilab / Embree = {:.2}", best / e));
                for r in report.rows.iter_mut().filter(|r| r.scene == name && &r.ray_set == set) {
                    r.embree_mrays_per_s = Some(e);
                }
                report.embree.push((name.clone(), set.clone(), e, best, best / e));
            }
        }
    }
    Ok(report)
}
