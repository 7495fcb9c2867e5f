//! `trilab steps`: the traversal work per ray from the CPU mirror of the kernels' loop
//! (`traversal`), and what SIMD lock-step costs at each width; with a device, each method's
//! `stats` kernel's own counts beside the mirror's, and how many rays they differ on.

use std::path::PathBuf;

use serde::ser::{Serialize, SerializeStruct, Serializer};

use crate::bvh::BuildOptions;
use crate::encoding::{AccessPath, Method, Raycast};
use crate::error::{Error, Result};
use crate::gpu::{Context, RaycastOptions, TraversalCounts, TraversalSummary};
use crate::pipeline::{HostScene, SceneRequest};
use crate::rays::{self, Ray};
use crate::report::{Report, Table};
use crate::scene::load_obj;
use crate::traversal::{ray_steps_with, step_stats, StepStats};

/// What to count.
#[derive(Clone, Debug)]
pub struct StepsRequest {
    pub scene: PathBuf,
    pub rays: PathBuf,
    pub build: BuildOptions,
    /// SIMD widths to model.
    pub widths: Vec<usize>,
    /// The methods whose `stats` kernels to run (`None`: the CPU mirror only; empty: every
    /// method the device runs).
    pub gpu_methods: Option<Vec<Method>>,
}

/// One method's kernel counts.
#[derive(Clone, Debug)]
pub struct GpuSteps {
    pub method: Method,
    /// How the kernel read the scene.
    pub access: AccessPath,
    pub summary: TraversalSummary,
    /// Rays whose (inner, leaves, triangles) differ from the CPU mirror's.
    pub rays_differing_from_cpu: usize,
}

/// The report: per width, the mirror's statistics; and the kernels' counts when asked. As JSON,
/// the list of widths, or with kernels `{cpu, cpu_summary, gpu}`.
#[derive(Clone, Debug)]
pub struct StepsReport {
    pub build: BuildOptions,
    pub cpu: Vec<StepStats>,
    /// The mirror's own summary and each method's kernel counts.
    pub gpu: Option<(TraversalSummary, Vec<GpuSteps>)>,
    /// What the CLI should tell the user (the ray file's sidecar names another scene).
    pub warnings: Vec<String>,
}

impl Serialize for GpuSteps {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let mut st = s.serialize_struct("GpuSteps", 4)?;
        st.serialize_field("method", &self.method)?;
        st.serialize_field("access", &self.access)?;
        st.serialize_field("summary", &self.summary)?;
        st.serialize_field("rays_differing_from_cpu", &self.rays_differing_from_cpu)?;
        st.end()
    }
}

impl Serialize for StepsReport {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match &self.gpu {
            None => s.collect_seq(&self.cpu),
            Some((cpu_summary, rows)) => {
                let mut st = s.serialize_struct("StepsReport", 3)?;
                st.serialize_field("cpu", &self.cpu)?;
                st.serialize_field("cpu_summary", cpu_summary)?;
                st.serialize_field("gpu", rows)?;
                st.end()
            }
        }
    }
}

/// Counts the traversal of `req.rays` through `req.scene`; `ctx` is needed only for the kernels.
pub fn run(ctx: Option<&Context>, req: &StepsRequest) -> Result<StepsReport> {
    req.build.check()?;
    if req.widths.contains(&0) {
        return Err(Error::Usage("--widths: a SIMD width must be at least 1".into()));
    }
    let mesh = load_obj(&req.scene)?;
    let rays = rays::read_rays(&req.rays)?;
    rays::check_reach(&req.rays, &rays, &mesh.bounds())?;
    let warnings =
        rays::check_sidecar(&req.rays, rays.len(), &crate::scene::scene_name(&req.scene), &mesh).into_iter().collect();
    let host = HostScene::build(crate::scene::scene_name(&req.scene), &mesh, &req.build)?;
    let cpu = req.widths.iter().map(|&w| step_stats(&mesh, &host.bvh, &rays, w)).collect();
    let gpu = match (&req.gpu_methods, ctx) {
        (None, _) => None,
        (Some(methods), Some(ctx)) => Some(gpu_steps(ctx, &host, &rays, methods)?),
        (Some(_), None) => return Err(Error::Usage("steps: the kernels' counts need a device".into())),
    };
    Ok(StepsReport { build: req.build, cpu, gpu, warnings })
}

/// Each method's `stats` kernel beside the CPU mirror (the conservative mirror for methods that
/// traverse conservatively).
fn gpu_steps(
    ctx: &Context,
    host: &HostScene,
    rays: &[Ray],
    methods: &[Method],
) -> Result<(TraversalSummary, Vec<GpuSteps>)> {
    let mirror = |conservative| -> Vec<TraversalCounts> {
        ray_steps_with(host.mesh, &host.bvh, rays, conservative)
            .iter()
            .map(|s| TraversalCounts {
                inner: s.inner,
                leaves: s.leaves,
                triangles: s.triangles,
                slots: 0,
                boxes: 2 * s.inner + 1,
                alone: 0,
            })
            .collect()
    };
    let (cpu, cpu_conservative) = (mirror(false), mirror(true));
    let methods =
        if methods.is_empty() { crate::conditioning::available_methods(&ctx.capabilities()) } else { methods.to_vec() };
    let mut rows = vec![];
    for m in methods {
        let scene = host.upload(ctx, &SceneRequest::new(m))?;
        let once = RaycastOptions { warmup: 0, repeat: 1, ..Default::default() };
        let counts =
            scene.cast(ctx, Raycast::Stats, rays, &once)?.traversal.expect("a stats kernel returns its counts");
        let reference = if m.conservative_traversal() { &cpu_conservative } else { &cpu };
        let differing = counts
            .iter()
            .zip(reference)
            .filter(|(g, c)| (g.inner, g.leaves, g.triangles) != (c.inner, c.leaves, c.triangles))
            .count();
        let summary = TraversalSummary::of(&counts);
        rows.push(GpuSteps { method: m, access: scene.access, summary, rays_differing_from_cpu: differing });
    }
    Ok((TraversalSummary::of(&cpu), rows))
}

impl Report for StepsReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let s0 = &self.cpu[0];
        let mut s = format!(
            "{} rays, leaf size {} ({}); per ray alone: {:.2} iterations ({:.2} inner, {:.2} leaf), {:.2} triangle tests\n",
            s0.rays,
            self.build.max_leaf_size,
            self.build.leaf_policy,
            s0.iterations,
            s0.inner,
            s0.leaves,
            s0.triangles
        );
        let mut t = Table::new([
            "SIMD width",
            "iterations/ray",
            "x alone",
            "inner code/ray",
            "leaf code/ray",
            "triangle slots/ray",
        ]);
        for st in &self.cpu {
            t.row([
                st.width.to_string(),
                format!("{:.2}", st.simd_iterations),
                format!("{:.2}", st.lockstep_overhead()),
                format!("{:.2}", st.simd_inner),
                format!("{:.2}", st.simd_leaf),
                format!("{:.2}", st.simd_triangles),
            ]);
        }
        s += &t.to_text();
        if let Some((cpu, rows)) = &self.gpu {
            s += "\nper ray, GPU stats kernels beside the CPU mirror (nodes = inner + leaf iterations; slots include quad padding):\n";
            s += &gpu_table(cpu, rows).to_text();
        }
        s
    }
}

fn gpu_table(cpu: &TraversalSummary, rows: &[GpuSteps]) -> Table {
    let mut t = Table::new([
        "source",
        "nodes mean",
        "nodes max",
        "inner mean",
        "leaf mean",
        "triangles mean",
        "triangles max",
        "slots mean",
        "slots max",
        "rays differing",
    ]);
    let row = |name: String, s: &TraversalSummary, slots: bool, differing: String| {
        [
            name,
            format!("{:.2}", s.nodes.mean),
            s.nodes.max.to_string(),
            format!("{:.2}", s.inner.mean),
            format!("{:.2}", s.leaves.mean),
            format!("{:.2}", s.triangles.mean),
            s.triangles.max.to_string(),
            if slots { format!("{:.2}", s.slots.mean) } else { "-".into() },
            if slots { s.slots.max.to_string() } else { "-".into() },
            differing,
        ]
    };
    t.row(row("CPU mirror".into(), cpu, false, "-".into()));
    for r in rows {
        t.row(row(format!("GPU {}", r.method), &r.summary, true, r.rays_differing_from_cpu.to_string()));
    }
    t
}
