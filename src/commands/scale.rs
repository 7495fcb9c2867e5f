//! `trilab scale`: large scenes end to end. Per scene: load (time), BVH build (time, Mtris/s);
//! per method: the GPU memory placement (bytes per buffer and per triangle, path-tracer extras
//! apart), the access path it picks, upload, a timed cast (GPU timestamps: warm-up + repeats,
//! median/min/max Mrays/s), a sample of hits validated against the CPU f64 reference, peak
//! host RSS. Writes scale.csv, scale.json and scale.md (atomically, `io::write_atomic`).
//! `--placement-only` stops after the placement: the bytes-per-triangle table without touching
//! the GPU's memory. Beside it, per scene, every node layout's node buffer as the placement
//! prices it ([`crate::encoding::Placement::with_layout`]): the methods' rows are the binary tree's.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::agreement::compare_closest;
use crate::bvh::BuildOptions;
use crate::encoding::placement::check_rays;
use crate::encoding::{DeviceLimits, Layout, Method, Placement, Raycast, SceneAccess};
use crate::error::{Error, Result};
use crate::gpu::{Context, RaycastOptions};
use crate::named::Named;
use crate::pipeline::{HostScene, ScenePlacement, SceneRequest};
use crate::rays::{random_rays, Ray};
use crate::render::placement::extras_for as pathtrace_extras_for;
use crate::report::Summary;
use crate::services::rayset::RaySet;
use crate::shared::BINDING_NODES;

/// Which rays `trilab scale` casts: random (uniform origins in the scene's sphere towards the
/// box, `rays::random_rays`), diffuse (one bounce from the hits of primary rays through a
/// 1024 x 1024 camera) or primary (a square image of at least `rays` pixels).
pub type RayKind = RaySet;

#[derive(Clone, Debug)]
pub struct ScaleOptions {
    /// Scene specs (paths; whatever `scene::load_obj` accepts).
    pub scenes: Vec<String>,
    pub methods: Vec<Method>,
    pub build: BuildOptions,
    pub rays: usize,
    pub ray_kind: RayKind,
    pub warmup: usize,
    pub repeat: usize,
    /// Hits checked against the f64 reference (evenly spaced over the ray set; all if larger).
    pub validate: usize,
    pub scene_access: SceneAccess,
    pub batch_rays: usize,
    pub seed: u64,
    /// Placement only: no upload, no cast.
    pub placement_only: bool,
}

/// One scene x method.
#[derive(Clone, Debug, Serialize)]
pub struct ScaleRow {
    pub scene: String,
    pub triangles: u64,
    pub method: Method,
    pub leaf_size: u32,
    /// "texel", "address", or the reason it does not fit.
    pub access: String,
    /// (buffer, bytes) as placed.
    pub buffers: Vec<(String, u64)>,
    pub scene_bytes: u64,
    pub bytes_per_triangle: f64,
    /// The path tracer's extra buffers for this scene (shading, lights, materials; no image).
    pub pathtrace_extra_bytes: u64,
    pub pathtrace_extra_bytes_per_triangle: f64,
    pub load_s: f64,
    pub bvh_s: f64,
    pub bvh_mtris_per_s: f64,
    pub upload_s: Option<f64>,
    pub rays: usize,
    /// Mrays/s from the kernel times (median, min, max over the repeats).
    pub mrays_per_s: Option<Summary>,
    pub timed_on_gpu: bool,
    /// GPU bytes in use while casting: the scene, rays, hits.
    pub gpu_bytes: Option<u64>,
    pub validated_rays: usize,
    pub agreement: Option<f64>,
    /// Disagreements not explained by f32 rounding (within 16 ULPs of an edge, or a tie).
    pub unexplained: Option<usize>,
    pub validation_passes: Option<bool>,
    /// Peak resident set of this process so far (VmHWM), bytes.
    pub peak_rss_bytes: Option<u64>,
}

/// One scene's node buffer in one layout, as the memory placement prices it (a bound from counts;
/// the same for every method: leaves are the encoding's units, the nodes are the tree's).
#[derive(Clone, Debug, Serialize)]
pub struct LayoutPlacementRow {
    pub scene: String,
    pub triangles: u64,
    pub layout: Layout,
    pub node_bytes: u64,
    pub node_bytes_per_triangle: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct ScaleReport {
    pub device: String,
    pub driver: String,
    pub limits: DeviceLimits,
    pub ray_kind: RayKind,
    pub rows: Vec<ScaleRow>,
    /// Every layout's node buffer per scene.
    pub layouts: Vec<LayoutPlacementRow>,
}

/// Every layout's placed node buffer for a scene of `counts`.
pub fn layout_placements(scene: &str, counts: &crate::encoding::SceneCounts) -> Vec<LayoutPlacementRow> {
    Layout::ALL
        .iter()
        .map(|&layout| {
            let placement = Placement::of(Method::Mt, counts).with_layout(layout);
            let node_bytes = placement.buffers.iter().filter(|b| b.binding == BINDING_NODES).map(|b| b.bytes).sum();
            LayoutPlacementRow {
                scene: scene.to_owned(),
                triangles: counts.triangles,
                layout,
                node_bytes,
                node_bytes_per_triangle: node_bytes as f64 / counts.triangles.max(1) as f64,
            }
        })
        .collect()
}

/// Peak resident set size (Linux `VmHWM`), where readable.
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The ray set of a scale run, checked as every generated set is ([`crate::rays::check_rays`]).
fn make_rays(host: &HostScene, o: &ScaleOptions) -> Result<Vec<Ray>> {
    let camera = crate::rays::Camera::framing(&host.mesh.bounds());
    let made = match o.ray_kind {
        RaySet::Random => random_rays(&host.mesh.bounds(), o.rays, o.seed),
        RaySet::Diffuse => {
            let primary = crate::rays::primary_rays(&camera, 1024, 1024);
            let per_hit = (o.rays as f64 / primary.len() as f64).ceil().max(1.0) as u32;
            let mut rays = RaySet::diffuse_from(host.mesh, &host.reference(), &primary, per_hit, o.seed);
            rays.truncate(o.rays);
            rays
        }
        RaySet::Primary => {
            let side = (o.rays as f64).sqrt().ceil() as u32;
            let mut rays = crate::rays::primary_rays(&camera, side, side);
            rays.truncate(o.rays);
            rays
        }
    };
    crate::rays::check_rays(&o.ray_kind.to_string(), &host.mesh.bounds(), made)
}

/// Runs the sweep; `progress` gets one line per step.
pub fn run(ctx: &Context, o: &ScaleOptions, progress: impl Fn(&str)) -> Result<ScaleReport> {
    // The ray set and its hits, on the host before they go to the device (none with
    // --placement-only).
    let each = crate::memory::RAY_BYTES + crate::memory::HIT_BYTES;
    let rays = crate::memory::Need::new(format!("--ray-count {}", o.rays), "rays", Some(o.rays as u64), each);
    if !o.placement_only {
        crate::memory::check(&[rays])?;
    }
    let limits = ctx.limits()?;
    let info = ctx.info();
    let mut rows = vec![];
    let mut layouts = vec![];
    for spec in &o.scenes {
        let name = crate::scene::scene_name(Path::new(spec));
        let t = Instant::now();
        let mesh = crate::scene::load_obj(Path::new(spec))?;
        let load_s = t.elapsed().as_secs_f64();
        let triangles = mesh.triangle_count() as u64;
        progress(&format!("{name}: {triangles} triangles loaded in {load_s:.2} s"));
        let host = HostScene::build(&name, &mesh, &o.build)?;
        let bvh_s = host.bvh.build_seconds;
        let bvh_mtris_per_s = triangles as f64 / bvh_s.max(1e-9) / 1e6;
        progress(&format!(
            "{name}: BVH (leaf {}) in {bvh_s:.2} s, {bvh_mtris_per_s:.2} Mtris/s",
            o.build.max_leaf_size
        ));
        layouts.extend(layout_placements(&name, &host.counts()));
        let rays = if o.placement_only { vec![] } else { make_rays(&host, o)? };
        let sample: Vec<usize> = if rays.is_empty() {
            vec![]
        } else {
            let n = o.validate.min(rays.len()).max(1);
            (0..n).map(|i| i * rays.len() / n).collect()
        };
        let sample_rays: Vec<Ray> = sample.iter().map(|&i| rays[i]).collect();
        let reference = (!sample_rays.is_empty()).then(|| host.reference().trace_all(&sample_rays, false));
        for &m in &o.methods {
            let placement = Placement::of(m, &host.counts());
            // The path tracer's own buffers beyond the scene, without an image.
            let extra_bytes: u64 =
                pathtrace_extras_for(&mesh, m, crate::encoding::AccessPath::Texel, &placement.counts, 0)
                    .iter()
                    .map(|(b, _)| b.bytes)
                    .sum();
            let mut row = ScaleRow {
                scene: name.clone(),
                triangles,
                method: m,
                leaf_size: o.build.max_leaf_size,
                access: String::new(),
                buffers: placement.buffers.iter().map(|b| (b.name.to_owned(), b.bytes)).collect(),
                scene_bytes: placement.bytes(),
                bytes_per_triangle: placement.bytes_per_triangle(),
                pathtrace_extra_bytes: extra_bytes,
                pathtrace_extra_bytes_per_triangle: extra_bytes as f64 / triangles.max(1) as f64,
                load_s,
                bvh_s,
                bvh_mtris_per_s,
                upload_s: None,
                rays: rays.len(),
                mrays_per_s: None,
                timed_on_gpu: false,
                gpu_bytes: None,
                validated_rays: 0,
                agreement: None,
                unexplained: None,
                validation_passes: None,
                peak_rss_bytes: None,
            };
            let placed = match host.place_for(m, None, &SceneRequest::new(m).access(o.scene_access), &limits) {
                Ok(p) => p,
                Err(e @ Error::SceneTooLarge(_)) => {
                    progress(&format!("{name} {m}: {e}"));
                    row.access = format!("does not fit: {e}");
                    row.peak_rss_bytes = peak_rss_bytes();
                    rows.push(row);
                    continue;
                }
                Err(e) => return Err(e),
            };
            let access = placed.access;
            row.access = access.name().to_owned();
            if !o.placement_only {
                cast(ctx, placed, &rays, &sample, reference.as_deref(), o, &mut row)?;
                progress(&format!(
                    "{name} {m}: {} path, {:.1} B/tri, {} Mrays/s, validation {}",
                    access.name(),
                    row.bytes_per_triangle,
                    row.mrays_per_s.map_or("-".into(), |s| format!("{:.2}", s.median)),
                    row.agreement.map_or("-".into(), |a| format!("{:.5}", a))
                ));
            }
            row.peak_rss_bytes = peak_rss_bytes();
            rows.push(row);
        }
    }
    Ok(ScaleReport {
        device: info.name.clone(),
        driver: info.driver_label(),
        limits,
        ray_kind: o.ray_kind,
        rows,
        layouts,
    })
}

/// Uploads the placed scene, casts `rays` (timed), and checks the `sample` of them against the
/// f64 `reference` hits.
fn cast(
    ctx: &Context,
    placed: ScenePlacement,
    rays: &[Ray],
    sample: &[usize],
    reference: Option<&[crate::reference::RefHit]>,
    o: &ScaleOptions,
    row: &mut ScaleRow,
) -> Result<()> {
    let ray_bytes = check_rays(rays.len() as u64, false, &placed.limits)?;
    let mesh = placed.mesh();
    let t = Instant::now();
    let scene = placed.upload(ctx)?;
    row.upload_s = Some(t.elapsed().as_secs_f64());
    row.gpu_bytes = Some(scene.bytes as u64 + ray_bytes);
    let opts = RaycastOptions { warmup: o.warmup, repeat: o.repeat.max(1), batch_rays: o.batch_rays };
    let res = scene.cast(ctx, Raycast::Closest, rays, &opts)?;
    let mrays: Vec<f64> = if res.timed_on_gpu() { &res.kernel_ms } else { &res.wall_ms }
        .iter()
        .map(|&ms| crate::services::validate::mrays_per_s(rays.len(), ms))
        .collect();
    row.mrays_per_s = Summary::of(&mrays);
    row.timed_on_gpu = res.timed_on_gpu();
    if let Some(reference) = reference {
        let sample_rays: Vec<Ray> = sample.iter().map(|&i| rays[i]).collect();
        let hits: Vec<_> = sample.iter().map(|&i| res.hits[i]).collect();
        let agreement = compare_closest(mesh, &sample_rays, &hits, reference);
        row.validated_rays = sample.len();
        row.agreement = Some(agreement.fraction());
        row.unexplained = Some(agreement.unexplained);
        // Every disagreement must be explained by rounding. The share of rays that land within
        // rounding of an edge grows as triangles shrink against their coordinates (10M-triangle
        // terrain: edges ~4e-4 at |p| ~ 1), so the agreement floor is 99.9 % here, not the
        // bunny's 99.99 %; the fraction is reported either way.
        row.validation_passes = Some(agreement.passes(0.999));
    }
    Ok(())
}

/// The scenes `trilab scale` takes by default: the full-resolution dragon of ../shared/scenes if
/// it is there, and a 10M-triangle synthetic terrain.
pub fn default_scenes() -> Vec<String> {
    let dragon = Path::new("../shared/scenes/dragon_full_draco11.obj.gz");
    let mut v = vec![];
    if dragon.exists() {
        v.push(dragon.display().to_string());
    }
    v.push("synth:terrain:10M".to_owned());
    v
}

impl ScaleReport {
    /// Every row validated (or placement only).
    pub fn passes(&self) -> bool {
        self.rows.iter().all(|r| r.validation_passes != Some(false))
    }

    /// An error when a cast disagreed with the f64 reference.
    pub fn verdict(&self) -> Result<()> {
        if self.passes() {
            Ok(())
        } else {
            Err(Error::Usage("scale: some casts disagree with the f64 reference (see scale.md)".into()))
        }
    }

    pub fn csv(&self) -> String {
        let mut s = String::from(
            "scene,triangles,method,leaf_size,access,nodes_bytes,slot_ids_bytes,prims_bytes,scene_bytes,\
             bytes_per_triangle,pathtrace_extra_bytes_per_triangle,load_s,bvh_s,bvh_mtris_per_s,upload_s,rays,\
             mrays_median,mrays_min,mrays_max,timed_with,validated_rays,agreement,unexplained,peak_rss_bytes\n",
        );
        let opt = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:.4}"));
        for r in &self.rows {
            let b = |i: usize| r.buffers.get(i).map_or(0, |b| b.1);
            let prims: u64 = r.buffers.iter().skip(2).map(|b| b.1).sum();
            let access = if r.access.starts_with("does not fit") { "does-not-fit" } else { r.access.as_str() };
            s += &format!(
                "{},{},{},{},{},{},{},{},{},{:.2},{:.2},{:.3},{:.3},{:.3},{},{},{},{},{},{},{},{},{},{}\n",
                r.scene,
                r.triangles,
                r.method,
                r.leaf_size,
                access,
                b(0),
                b(1),
                prims,
                r.scene_bytes,
                r.bytes_per_triangle,
                r.pathtrace_extra_bytes_per_triangle,
                r.load_s,
                r.bvh_s,
                r.bvh_mtris_per_s,
                opt(r.upload_s),
                r.rays,
                opt(r.mrays_per_s.map(|s| s.median)),
                opt(r.mrays_per_s.map(|s| s.min)),
                opt(r.mrays_per_s.map(|s| s.max)),
                if r.mrays_per_s.is_none() {
                    ""
                } else if r.timed_on_gpu {
                    "gpu"
                } else {
                    "wall"
                },
                r.validated_rays,
                r.agreement.map_or(String::new(), |a| format!("{a:.6}")),
                r.unexplained.map_or(String::new(), |u| u.to_string()),
                r.peak_rss_bytes.map_or(String::new(), |v| v.to_string()),
            );
        }
        s
    }

    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# trilab scale\n\nDevice: {} ({}). Rays: {:?}. maxTexelBufferElements {}, maxStorageBufferRange {} B.\n\n",
            self.device,
            self.driver,
            self.ray_kind,
            self.limits.max_texel_buffer_elements,
            self.limits.max_storage_buffer_range
        );
        s += "| scene | triangles | method | leaf | access | buffers (bytes) | B/tri | +path tracer B/tri | BVH Mtris/s | Mrays/s (median [min, max]) | validated | peak RSS MiB |\n";
        s += "|---|---:|---|---:|---|---|---:|---:|---:|---|---|---:|\n";
        for r in &self.rows {
            let bufs: Vec<String> = r.buffers.iter().map(|(n, b)| format!("{n} {b}")).collect();
            let access = if r.access.starts_with("does not fit") { "does not fit" } else { r.access.as_str() };
            s += &format!(
                "| {} | {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.2} | {} | {} | {} |\n",
                r.scene,
                r.triangles,
                r.method,
                r.leaf_size,
                access,
                bufs.join(", "),
                r.bytes_per_triangle,
                r.pathtrace_extra_bytes_per_triangle,
                r.bvh_mtris_per_s,
                r.mrays_per_s.map_or("-".into(), |m| format!("{:.2} [{:.2}, {:.2}]", m.median, m.min, m.max)),
                match (r.agreement, r.validation_passes) {
                    (Some(a), Some(p)) => format!(
                        "{} rays, {:.4} % agree, {} unexplained{}",
                        r.validated_rays,
                        100.0 * a,
                        r.unexplained.unwrap_or(0),
                        if p { "" } else { " FAIL" }
                    ),
                    _ => "-".into(),
                },
                r.peak_rss_bytes.map_or("-".into(), |v| format!("{}", v >> 20)),
            );
        }
        if !self.layouts.is_empty() {
            s += "\n## Node bytes per layout\n\nThe node buffer of each layout as the memory placement prices it \
                  (a bound from counts, the same for every method; the rows above are the binary tree's, `bvh2`). \
                  A wide layout replaces `bvh nodes` above by its own buffer.\n\n";
            s += "| scene | triangles | layout | node bytes | node B/tri |\n|---|---:|---|---:|---:|\n";
            for r in &self.layouts {
                s += &format!(
                    "| {} | {} | {} | {} | {:.1} |\n",
                    r.scene, r.triangles, r.layout, r.node_bytes, r.node_bytes_per_triangle
                );
            }
        }
        s
    }

    /// Writes scale.csv, scale.json and scale.md into `dir` (created if needed).
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        crate::services::results::write_folder(dir, self)
    }
}

/// No rows: scale's figures are limits and sizes, not cells to compare.
impl crate::services::results::Results for ScaleReport {
    const STEM: &'static str = "scale";

    const JSON_NEWLINE: bool = true;

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        ScaleReport::markdown(self)
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        None
    }

    fn files(&self) -> Result<Vec<(&'static str, String)>> {
        Ok(vec![("scale.csv", self.csv())])
    }
}
impl crate::report::Report for ScaleReport {
    fn to_text(&self) -> String {
        self.markdown()
    }
}
