//! `trilab profile`: driver-level profiling of the ray-casting kernels, one section per tool the
//! device offers, each feature-detected and reported as unsupported (or not applicable) where
//! absent, never emulated:
//!
//! 1. per-dispatch kernel time from GPU timestamps (median, min, max after warm-up), and with
//!    `--roofline` each kernel's share of the traversal roofline (`services::efficiency`);
//! 2. pipeline statistics: compute-shader invocations of a dispatch, beside the count launched;
//! 3. shader-clock ticks per ray (raycast.comp's `clock` variant, [`clock`]): statistics per
//!    ray set and heat maps of the primary rays;
//! 4. pipeline executable statistics (`VK_KHR_pipeline_executable_properties`, [`executable`]);
//! 5. a subgroup-size sweep (`VK_EXT_subgroup_size_control`, [`sweep`]);
//! 6. a workgroup-size sweep (raycast.comp's workgroup size is a specialisation constant);
//! 7. LP_NUM_THREADS scaling on lavapipe ([`threads`]);
//! 8. driver statistics of the profiled kernels: lavapipe's machine code ([`driver_stats`]),
//!    or "not available on this driver".
//!
//! [`write`] also writes `rows.jsonl` ([`rows`]): command `profile` for the timings and pipeline
//! statistics, `driver-stats` for the driver statistics (the rows `trilab driver-stats` writes).
//!
//! Every result's hits are checked against the f64 reference before its time or count is
//! reported; the variants (clock, subgroup and workgroup sizes) must also give hits bitwise
//! identical to the default kernel's.

pub mod clock;
pub mod markdown;
pub mod sweep;
pub mod threads;

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bvh::BuildOptions;
use crate::encoding::{AccessPath, Layout, Method, Raycast};
use crate::error::{Error, Result};
use crate::gpu::{Context, DeviceInfo, EnabledFeatures, Kernel, PipelineOptions, RaycastOptions, Statistic};
use crate::pipeline::{DeviceScene, HostScene};
use crate::rays::{Hit, Ray};
use crate::reference::RefHit;
use crate::report::Summary;
use crate::scene::{load_obj, Mesh};
use crate::services::efficiency::{self, RooflineEfficiency};
use crate::services::rayset::{ray_sets, RaySet, RaySetSizes};
use crate::services::roofline::RooflineReport;
use crate::services::validate::{interleaved, mrays_per_s as mrays, mrays_summary, Interleaved, Job};
use crate::shared::SPEC_ID_WORKGROUP_SIZE;

pub use crate::gpu::executable::ExecutableStatistic;
pub use crate::services::driver_stats::dispatch::{dispatch_once, SingleDispatch};
pub use clock::{CycleStats, HeatScale};
pub use threads::ThreadMeasurement;

use crate::gpu::executable;
use crate::matrix::{KernelAxes, KernelCell};
pub use crate::rays::differing_hits;
pub use crate::report::Status;
use crate::services::driver_stats;
/// Fraction of rays that must agree with the f64 reference (as `trilab bench` requires).
pub use crate::services::validate::MIN_AGREEMENT;

#[derive(Clone, Debug)]
pub struct ProfileOptions {
    pub scene: PathBuf,
    pub methods: Vec<Method>,
    pub build: BuildOptions,
    /// The node layout every kernel traverses (its `*_<layout>` variants).
    pub layout: Layout,
    /// The ray sets' sizes (the primary rays' camera image is the heat maps' size).
    pub sizes: RaySetSizes,
    pub warmup: usize,
    pub repeat: usize,
    /// The ray set the subgroup- and workgroup-size sweeps time.
    pub sweep_set: RaySet,
    pub workgroup_sizes: Vec<u32>,
    /// LP_NUM_THREADS values; empty: 1..=host cores.
    pub thread_counts: Vec<usize>,
    /// The trilab executable the LP_NUM_THREADS section runs (`None`: the section is skipped).
    pub exe: Option<PathBuf>,
    /// The command line that asked for the profile (recorded in profile.md).
    pub command: String,
    /// The trilab executable the driver-statistics section runs under GALLIVM_DEBUG=asm
    /// (`None`: the section is skipped).
    pub driver_stats: Option<driver_stats::CollectOptions>,
    /// `--roofline`: the traversal roofline (these settings; its sizes and path are the scene's)
    /// at the scene's bytes on its access path, and per timing row its [`RooflineEfficiency`].
    pub roofline: Option<crate::services::roofline::RooflineOptions>,
}

impl Default for ProfileOptions {
    fn default() -> Self {
        ProfileOptions {
            scene: PathBuf::from("bunny"),
            methods: Method::ALL.to_vec(),
            build: BuildOptions::new(crate::defaults::LEAF_SIZE),
            layout: Layout::DEFAULT,
            sizes: RaySetSizes { diffuse_per_hit: 2, random_rays: 250_000, ..RaySetSizes::default() },
            warmup: 1,
            repeat: crate::defaults::REPEAT,
            sweep_set: RaySet::Random,
            workgroup_sizes: vec![32, 64, 128, 256],
            thread_counts: vec![],
            exe: None,
            command: "trilab profile".into(),
            driver_stats: None,
            roofline: None,
        }
    }
}

impl ProfileOptions {
    /// The kernel cells profiled: each method on the one layout, in the order asked
    /// (`crate::matrix`: the registry's filter).
    pub fn kernels(&self) -> Vec<KernelCell> {
        KernelAxes { methods: self.methods.clone(), layouts: vec![self.layout], ..Default::default() }.kernels()
    }
}

/// Device, driver and Mesa version, carried by every row.
#[derive(Clone, Debug, Serialize)]
pub struct DeviceTag {
    pub device: String,
    pub driver: String,
    pub mesa_version: Option<String>,
}

impl DeviceTag {
    pub fn of(info: &DeviceInfo) -> DeviceTag {
        DeviceTag { device: info.name.clone(), driver: info.driver_label(), mesa_version: info.mesa_version.clone() }
    }
}

/// One profile section: whether it could be measured, a note saying why not or what limited
/// it, and its rows.
#[derive(Clone, Debug, Serialize)]
pub struct Section<T> {
    pub status: Status,
    pub note: String,
    pub rows: Vec<T>,
}

impl<T> Section<T> {
    fn new(status: Status, note: impl Into<String>) -> Section<T> {
        Section { status, note: note.into(), rows: vec![] }
    }
}

/// A row of any section: the device tag, then the row's own fields.
#[derive(Clone, Debug, Serialize)]
pub struct Row<T> {
    #[serde(flatten)]
    pub tag: DeviceTag,
    pub method: Method,
    #[serde(flatten)]
    pub data: T,
}

impl<T> Row<T> {
    pub fn new(info: &DeviceInfo, method: Method, data: T) -> Row<T> {
        Row { tag: DeviceTag::of(info), method, data }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Timing {
    pub ray_set: RaySet,
    /// How the kernel read the scene.
    pub scene_access: AccessPath,
    pub rays: usize,
    /// Dispatches per run (each its own submit with its own timestamp pair).
    pub dispatches: usize,
    /// Per-run kernel time, milliseconds (GPU timestamps).
    pub kernel_ms: Summary,
    pub mrays_per_s: f64,
    pub agreement: f64,
    /// `--roofline`: the kernel's fetches per second against the roofline's at its scene's size.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roofline: Option<RooflineEfficiency>,
}

#[derive(Clone, Debug, Serialize)]
pub struct Invocations {
    pub ray_set: RaySet,
    pub rays: usize,
    pub local_size: u32,
    pub workgroups: u32,
    /// ceil(rays / local size) x local size.
    pub dispatched: u64,
    /// COMPUTE_SHADER_INVOCATIONS of the same dispatch.
    pub compute_shader_invocations: u64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Cycles {
    pub ray_set: RaySet,
    pub rays: usize,
    pub ticks: CycleStats,
    /// Rays whose hit differs (bitwise) from the default `closest` kernel's.
    pub hits_differing_from_closest: usize,
    pub agreement: f64,
    /// File name of the heat map (primary rays only).
    pub heat_map: Option<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct SizeTiming {
    pub ray_set: RaySet,
    pub rays: usize,
    pub subgroup_size: Option<u32>,
    pub local_size: u32,
    pub kernel_ms: Summary,
    pub mrays_per_s: f64,
    pub agreement: f64,
    /// Rays whose hit differs (bitwise) from the default kernel's.
    pub hits_differing_from_default: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct ProfileReport {
    #[serde(flatten)]
    pub tag: DeviceTag,
    /// The command line that asked for it.
    pub command: String,
    pub driver_id: String,
    pub host_cpus: usize,
    /// LP_NUM_THREADS of the profiling process itself (sections 1-6).
    pub lp_num_threads: Option<String>,
    /// `/proc/loadavg` before and after (Linux): other work on the host skews every timing.
    pub host_load_before: Option<String>,
    pub host_load_after: Option<String>,
    pub scene: String,
    pub triangles: usize,
    pub leaf_size: u32,
    pub layout: Layout,
    pub warmup: usize,
    pub repeat: usize,
    pub width: u32,
    pub height: u32,
    /// (set, rays)
    pub ray_sets: Vec<(RaySet, usize)>,
    pub sweep_set: RaySet,
    pub default_local_size: u32,
    pub timestamps: Section<Row<Timing>>,
    pub pipeline_statistics: Section<Row<Invocations>>,
    pub shader_clock: Section<Row<Cycles>>,
    pub heat_scale: Option<HeatScale>,
    pub executable_properties: Section<Row<ExecutableStatistic>>,
    pub subgroup_sizes: Section<Row<SizeTiming>>,
    pub workgroup_sizes: Section<Row<SizeTiming>>,
    pub lp_num_threads_scaling: Section<Row<ThreadMeasurement>>,
    /// What the driver compiled each profiled kernel (raycast closest per method) to.
    pub driver_statistics: Section<driver_stats::KernelStats>,
    /// Where and when (the rows' source).
    pub provenance: crate::services::provenance::Provenance,
}

impl ProfileReport {
    /// The sections the driver could not measure (unsupported or not applicable), each with its
    /// title and the note saying why, in the report's order; skipped sections (asked away by an
    /// option) are not among them.
    pub fn not_measured(&self) -> Vec<(&'static str, Status, &str)> {
        let all = [
            ("Per-dispatch kernel time", self.timestamps.status, self.timestamps.note.as_str()),
            ("Pipeline statistics", self.pipeline_statistics.status, &self.pipeline_statistics.note),
            ("Shader clock", self.shader_clock.status, &self.shader_clock.note),
            ("Pipeline executable properties", self.executable_properties.status, &self.executable_properties.note),
            ("Subgroup-size sweep", self.subgroup_sizes.status, &self.subgroup_sizes.note),
            ("Workgroup-size sweep", self.workgroup_sizes.status, &self.workgroup_sizes.note),
            ("LP_NUM_THREADS scaling", self.lp_num_threads_scaling.status, &self.lp_num_threads_scaling.note),
            ("Driver statistics", self.driver_statistics.status, &self.driver_statistics.note),
        ];
        all.into_iter().filter(|(_, st, _)| matches!(st, Status::Unsupported | Status::NotApplicable)).collect()
    }
}

/// Checks hits against the f64 reference ([`crate::services::validate::validate_hits`]); an error
/// (so nothing gets reported) if they disagree. Returns the fraction agreeing.
fn validated(mesh: &Mesh, rays: &[Ray], hits: &[Hit], reference: &[RefHit], what: &str) -> Result<f64> {
    crate::services::validate::validate_hits(mesh, rays, hits, reference)
        .map(|a| a.fraction())
        .map_err(|e| Error::Usage(format!("{what}: {e}")))
}

/// The 1, 5 and 15-minute load averages, where the host reports them.
fn load_average() -> Option<String> {
    let text = std::fs::read_to_string("/proc/loadavg").ok()?;
    Some(text.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
}

/// The sections measured per method (1-6), each with its status and note.
struct Sections {
    timestamps: Section<Row<Timing>>,
    pipeline_statistics: Section<Row<Invocations>>,
    shader_clock: Section<Row<Cycles>>,
    executable_properties: Section<Row<ExecutableStatistic>>,
    subgroup_sizes: Section<Row<SizeTiming>>,
    workgroup_sizes: Section<Row<SizeTiming>>,
    /// Subgroup sizes to sweep (empty where the sweep is unsupported) and workgroup sizes.
    subgroup_plan: Vec<u32>,
    workgroup_plan: Vec<u32>,
}

impl Sections {
    /// Which tools the device offers, and what each section will measure.
    fn new(ctx: &Context, o: &ProfileOptions) -> Sections {
        let info = ctx.info();
        let en = ctx.enabled();
        // Each statistic where the device has it (gpu::Capabilities), else the reason it has not.
        let caps = ctx.capabilities();
        fn pick<T>(can: std::result::Result<(), crate::gpu::Unsupported>, yes: &str) -> Section<T> {
            match can {
                Ok(()) => Section::new(Status::Measured, yes),
                Err(u) => Section::new(Status::Unsupported, u.why),
            }
        }
        let (subgroup_plan, subgroup_sizes) = match sweep::subgroup_sizes(info, en, crate::shared::WORKGROUP_SIZE) {
            Ok((sizes, note)) => (sizes, Section::new(Status::Measured, note)),
            Err(why) => (vec![], Section::new(Status::Unsupported, why)),
        };
        let (workgroup_plan, wg_note) = sweep::workgroup_sizes(info, &o.workgroup_sizes);
        let timestamps = match caps.statistic(Statistic::Timestamps) {
            Ok(()) => Section::new(Status::Measured, "kernel time between timestamps around each dispatch"),
            Err(u) => Section::new(Status::Unsupported, format!("{}: host wall time instead", u.why)),
        };
        Sections {
            timestamps,
            pipeline_statistics: pick(
                caps.statistic(Statistic::PipelineStatistics),
                "VK_QUERY_TYPE_PIPELINE_STATISTICS, COMPUTE_SHADER_INVOCATIONS, one dispatch",
            ),
            shader_clock: pick(
                caps.statistic(Statistic::ShaderClock),
                "subgroup-scope clock (VK_KHR_shader_clock, clock2x32ARB) read before and after the trace; \
                 lanes in lock-step share one reading, so a ray's ticks are its subgroup's",
            ),
            executable_properties: pick(
                caps.statistic(Statistic::ExecutableStatistics),
                "pipelines created with CAPTURE_STATISTICS; this code path is untested on lavapipe (which lacks the \
                 extension)",
            ),
            subgroup_sizes,
            workgroup_sizes: Section::new(Status::Measured, wg_note),
            subgroup_plan,
            workgroup_plan,
        }
    }
}

/// One method's profile: its scene on the device, the ray sets and their reference hits.
struct MethodRun<'a, P: FnMut(&str)> {
    ctx: &'a Context,
    info: &'a DeviceInfo,
    en: EnabledFeatures,
    name: &'a str,
    mesh: &'a Mesh,
    scene: DeviceScene,
    sets: &'a [(RaySet, Vec<Ray>)],
    refs: &'a [Vec<RefHit>],
    sweep_idx: usize,
    ropts: RaycastOptions,
    /// Section 1's timings of this method on every set, measured beforehand with every method's
    /// rounds interleaved (`validate::interleaved`); `per_set` takes them.
    timed: Vec<Interleaved>,
    /// `--roofline`: the roofline at the scene's bytes, for each timing's efficiency.
    roofline: Option<&'a RooflineReport>,
    progress: &'a mut P,
}

impl<P: FnMut(&str)> MethodRun<'_, P> {
    fn method(&self) -> Method {
        self.scene.method
    }

    /// Sections 1-3 on every ray set; returns the sweep set's hits and the primary rays' ticks.
    fn per_set(&mut self, s: &mut Sections) -> Result<(Vec<Hit>, Option<Vec<u32>>)> {
        let (method, info) = (self.method(), self.info);
        let closest = self.scene.kernel(self.ctx, Raycast::Closest)?;
        let clock_kernel = if self.en.shader_clock { Some(self.scene.kernel(self.ctx, Raycast::Clock)?) } else { None };
        let (mut sweep_hits, mut primary_cycles) = (vec![], None);
        let timed = std::mem::take(&mut self.timed);
        for (si, ((set, rays), res)) in self.sets.iter().zip(timed).enumerate() {
            let (set, refs) = (*set, &self.refs[si]);
            let what = format!("{} {set} {method}", self.name);
            let (agreement, ms) = (res.agreement.fraction(), res.kernel_ms);
            (self.progress)(&format!("{what}: {:.2} ms ({:.2} Mrays/s)", ms.median, mrays(rays.len(), ms.median)));
            let timing = Timing {
                ray_set: set,
                scene_access: self.scene.access,
                rays: rays.len(),
                dispatches: res.batches,
                kernel_ms: ms,
                mrays_per_s: mrays(rays.len(), ms.median),
                agreement,
                roofline: self.efficiency(rays, ms)?,
            };
            s.timestamps.rows.push(Row::new(info, method, timing));
            if self.en.pipeline_statistics_query {
                let d = dispatch_once(self.ctx, &closest, &self.scene, rays, true)?;
                validated(self.mesh, rays, &d.hits, refs, &format!("{what} (pipeline statistics)"))?;
                let inv = Invocations {
                    ray_set: set,
                    rays: rays.len(),
                    local_size: d.local_size,
                    workgroups: d.workgroups,
                    dispatched: d.dispatched_invocations(),
                    compute_shader_invocations: d.compute_shader_invocations.unwrap_or(0),
                };
                s.pipeline_statistics.rows.push(Row::new(info, method, inv));
            }
            if let Some(k) = &clock_kernel {
                let (cycles, row) = self.clocked(k, set, rays, refs, &res.hits, &what)?;
                s.shader_clock.rows.push(Row::new(info, method, row));
                if set == RaySet::Primary {
                    primary_cycles = Some(cycles);
                }
            }
            if si == self.sweep_idx {
                sweep_hits = res.hits;
            }
        }
        Ok((sweep_hits, primary_cycles))
    }

    /// `--roofline`: the kernel's traversal counts on `rays` against the roofline at its Mrays/s
    /// (from `ms`); `None` without the flag, or where the kernel or roofline has no figure.
    fn efficiency(&self, rays: &[Ray], ms: Summary) -> Result<Option<RooflineEfficiency>> {
        let Some(roof) = self.roofline else { return Ok(None) };
        let counts = efficiency::fetch_counts(self.ctx, &self.scene, rays, None, self.ropts.batch_rays)?;
        let lanes = self.ctx.info().subgroup_size;
        Ok(counts
            .and_then(|c| efficiency::efficiency(&self.scene, roof, mrays_summary(rays.len(), ms), &c, lanes, None)))
    }

    /// Section 3 on one set: ticks per ray from the `clock` variant, whose hits must equal the
    /// default kernel's.
    fn clocked(
        &mut self,
        k: &Kernel,
        set: RaySet,
        rays: &[Ray],
        refs: &[RefHit],
        closest_hits: &[Hit],
        what: &str,
    ) -> Result<(Vec<u32>, Cycles)> {
        let d = dispatch_once(self.ctx, k, &self.scene, rays, false)?;
        let agreement = validated(self.mesh, rays, &d.hits, refs, &format!("{what} (clock)"))?;
        let cycles = d.cycles.expect("the clock variant binds the cycles buffer");
        let ticks = CycleStats::of(&cycles).expect("at least one ray");
        (self.progress)(&format!(
            "{what}: ticks per ray mean {:.0}, median {:.0}, p99 {:.0}",
            ticks.mean, ticks.median, ticks.p99
        ));
        let row = Cycles {
            ray_set: set,
            rays: rays.len(),
            ticks,
            hits_differing_from_closest: differing_hits(&d.hits, closest_hits),
            agreement,
            heat_map: None,
        };
        Ok((cycles, row))
    }

    /// One timed run of the sweep set with a pipeline made for the subgroup or workgroup sweep.
    fn timed(&mut self, kernel: &Kernel, subgroup_size: Option<u32>, sweep_hits: &[Hit]) -> Result<SizeTiming> {
        let (set, rays) = &self.sets[self.sweep_idx];
        let local = kernel.layout.local_size.0;
        let what = format!("{} {set} {} ({}, workgroup {local})", self.name, self.method(), kernel.name);
        let res = self.scene.cast_with(self.ctx, kernel, rays, &self.ropts)?;
        let agreement = validated(self.mesh, rays, &res.hits, &self.refs[self.sweep_idx], &what)?;
        let ms = res.time_ms()?;
        let label = subgroup_size.map(|s| format!(", subgroup {s}")).unwrap_or_default();
        (self.progress)(&format!("{what}{label}: {:.2} ms", ms.median));
        Ok(SizeTiming {
            ray_set: *set,
            rays: rays.len(),
            subgroup_size,
            local_size: local,
            kernel_ms: ms,
            mrays_per_s: mrays(rays.len(), ms.median),
            agreement,
            hits_differing_from_default: differing_hits(&res.hits, sweep_hits),
        })
    }

    /// Sections 4-6: executable statistics and the subgroup- and workgroup-size sweeps.
    fn pipelines(&mut self, s: &mut Sections, sweep_hits: &[Hit]) -> Result<()> {
        let (method, info) = (self.method(), self.info);
        let src = self.scene.kernel_source(Raycast::Closest)?;
        if self.en.pipeline_executable_properties {
            let opts = PipelineOptions { capture_statistics: true, ..Default::default() };
            let k = self.ctx.create_kernel_with(src, &opts)?;
            let stats = executable::executable_statistics(self.ctx, &k)?;
            s.executable_properties.rows.extend(stats.into_iter().map(|d| Row::new(info, method, d)));
        }
        for size in s.subgroup_plan.clone() {
            let opts = PipelineOptions { required_subgroup_size: Some(size), ..Default::default() };
            let k = self.ctx.create_kernel_with(src, &opts)?;
            let row = self.timed(&k, Some(size), sweep_hits)?;
            s.subgroup_sizes.rows.push(Row::new(info, method, row));
        }
        for size in s.workgroup_plan.clone() {
            let k = self.ctx.create_kernel_specialized(src, &[(SPEC_ID_WORKGROUP_SIZE, size)])?;
            let row = self.timed(&k, None, sweep_hits)?;
            s.workgroup_sizes.rows.push(Row::new(info, method, row));
        }
        Ok(())
    }
}

/// Runs every section. Heat maps are written to `out_dir` when given (file names in the
/// report); `progress` gets one line per step.
pub fn run(
    ctx: &Context,
    o: &ProfileOptions,
    out_dir: Option<&Path>,
    mut progress: impl FnMut(&str),
) -> Result<ProfileReport> {
    o.sizes.require_all()?;
    o.sizes.check_memory()?;
    let cells = o.kernels();
    if cells.len() != o.methods.len() {
        let has: Vec<Method> = cells.iter().map(|c| c.method).collect();
        let missing: Vec<String> = o.methods.iter().filter(|m| !has.contains(m)).map(|m| m.to_string()).collect();
        return Err(crate::error::Error::Usage(format!(
            "profile --layout {}: no ray-casting kernel for {}",
            o.layout,
            missing.join(", ")
        )));
    }
    let info = ctx.info();
    let host_load_before = load_average();
    let name = crate::scene::scene_name(&o.scene);
    let mesh = load_obj(&o.scene)?;
    let host = HostScene::build(&name, &mesh, &o.build)?;
    let reference = host.reference();
    let (sets, refs, sweep_idx) = profile_ray_sets(o, &name, &mesh, &reference, &mut progress)?;
    let mut s = Sections::new(ctx, o);
    let mut primary_cycles: Vec<(Method, Vec<u32>)> = vec![];
    let mut profiled_kernels = vec![];
    // Section 1 first, every method's rounds on every set interleaved, so that a burst of other
    // work on the host lands on all of them alike; the other sections per method after it.
    let scenes: Vec<DeviceScene> = cells.iter().map(|c| host.upload(ctx, &c.request())).collect::<Result<_>>()?;
    let kernels = scenes.iter().map(|s| s.kernel(ctx, Raycast::Closest)).collect::<Result<Vec<_>>>()?;
    // The roofline at the scenes' bytes on their access paths, before any timing.
    let roofline = match &o.roofline {
        Some(ro) => Some(efficiency::scene_roofline(ctx, &scenes, ro, &mut progress)?),
        None => None,
    };
    let ropts = RaycastOptions { warmup: o.warmup, repeat: o.repeat.max(1), ..Default::default() };
    let mut section1 =
        interleaved_timestamps(ctx, o, &name, &mesh, (&scenes, &kernels), (&sets, &refs), &ropts)?.into_iter();
    for (&method, scene) in o.methods.iter().zip(scenes) {
        let _span = crate::timeline::span_with("section", || format!("{method}: clocks, pipeline statistics, sizes"));
        let mut m = MethodRun {
            ctx,
            info,
            en: *ctx.enabled(),
            name: &name,
            mesh: &mesh,
            scene,
            sets: &sets,
            refs: &refs,
            sweep_idx,
            ropts: ropts.clone(),
            timed: section1.by_ref().take(sets.len()).collect(),
            roofline: roofline.as_ref(),
            progress: &mut progress,
        };
        debug_assert_eq!(m.method(), method);
        profiled_kernels.push(m.scene.kernel_source(Raycast::Closest)?);
        let (sweep_hits, cycles) = m.per_set(&mut s)?;
        primary_cycles.extend(cycles.map(|c| (method, c)));
        m.pipelines(&mut s, &sweep_hits)?;
    }
    let heat_scale = HeatScale::of(&primary_cycles.iter().map(|(_, c)| c.as_slice()).collect::<Vec<_>>(), 1.0, 99.0);
    if let (Some(dir), Some(scale)) = (out_dir, &heat_scale) {
        write_heat_maps(dir, scale, &primary_cycles, &host.name, o, &mut s)?;
    }
    let lp_scaling = threads_section(ctx, o, &sets, &mut progress)?;
    let driver_statistics = driver_stats_section(ctx, o, &profiled_kernels, &mut progress)?;
    Ok(ProfileReport {
        tag: DeviceTag::of(info),
        command: o.command.clone(),
        driver_id: info.driver_id.clone(),
        host_cpus: std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        lp_num_threads: std::env::var("LP_NUM_THREADS").ok(),
        host_load_before,
        host_load_after: load_average(),
        scene: name,
        triangles: mesh.triangle_count(),
        leaf_size: o.build.max_leaf_size,
        layout: o.layout,
        warmup: o.warmup,
        repeat: o.repeat.max(1),
        width: o.sizes.width,
        height: o.sizes.height,
        ray_sets: sets.iter().map(|(n, r)| (*n, r.len())).collect(),
        sweep_set: o.sweep_set,
        default_local_size: crate::shared::WORKGROUP_SIZE,
        timestamps: s.timestamps,
        pipeline_statistics: s.pipeline_statistics,
        shader_clock: s.shader_clock,
        heat_scale,
        executable_properties: s.executable_properties,
        subgroup_sizes: s.subgroup_sizes,
        workgroup_sizes: s.workgroup_sizes,
        lp_num_threads_scaling: lp_scaling,
        driver_statistics,
        provenance: crate::services::provenance::Provenance::of(ctx),
    })
}

/// The scene's ray sets, their f64 reference hits and the sweep set's index, announced in one
/// progress line.
#[allow(clippy::type_complexity)]
fn profile_ray_sets(
    o: &ProfileOptions,
    name: &str,
    mesh: &Mesh,
    reference: &crate::reference::Reference,
    progress: &mut impl FnMut(&str),
) -> Result<(Vec<(RaySet, Vec<Ray>)>, Vec<Vec<RefHit>>, usize)> {
    let sets = ray_sets(mesh, name, reference, &o.sizes, None)?;
    let refs: Vec<Vec<RefHit>> = sets.iter().map(|(_, r)| reference.trace_all(r, false)).collect();
    let sweep_idx = sets.iter().position(|(s, _)| *s == o.sweep_set).expect("every ray set is made");
    progress(&format!(
        "{name}: {} triangles; rays: {}",
        mesh.triangle_count(),
        sets.iter().map(|(n, r)| format!("{n} {}", r.len())).collect::<Vec<_>>().join(", ")
    ));
    Ok((sets, refs, sweep_idx))
}

/// Section 1: the timestamps of every method's rounds on every set, interleaved so that a burst
/// of other work on the host lands on all of them alike; per method, then per set.
#[allow(clippy::type_complexity)]
fn interleaved_timestamps(
    ctx: &Context,
    o: &ProfileOptions,
    name: &str,
    mesh: &Mesh,
    (scenes, kernels): (&[DeviceScene], &[std::sync::Arc<Kernel>]),
    (sets, refs): (&[(RaySet, Vec<Ray>)], &[Vec<RefHit>]),
    ropts: &RaycastOptions,
) -> Result<Vec<Interleaved>> {
    let jobs: Vec<Job> = scenes
        .iter()
        .zip(kernels)
        .flat_map(|(scene, kernel)| {
            sets.iter().zip(refs).map(move |((_, rays), ref_hits)| Job {
                scene,
                kernel,
                rays,
                ref_hits,
                order: crate::rays::order::RayOrder::Given,
            })
        })
        .collect();
    let timing = crate::timeline::span("section", "timestamps: every method's rounds interleaved");
    let section1 = interleaved(ctx, mesh, &jobs, ropts.warmup, ropts.repeat, ropts.batch_rays).map_err(|(i, e)| {
        let (method, (set, _)) = (o.methods[i / sets.len()], &sets[i % sets.len()]);
        Error::Usage(format!("{name} {set} {method}: {e}"))
    })?;
    drop(jobs);
    drop(timing);
    Ok(section1)
}

/// Section 3's heat maps: one PNG per method of its primary rays' shader-clock ticks, all on
/// one scale, each named in the method's primary-set rows.
fn write_heat_maps(
    dir: &Path,
    scale: &HeatScale,
    primary_cycles: &[(Method, Vec<u32>)],
    scene: &str,
    o: &ProfileOptions,
    s: &mut Sections,
) -> Result<()> {
    for (method, cycles) in primary_cycles {
        let file = format!("heatmap-{method}.png");
        let title = format!("{method}: shader-clock ticks per primary ray, {scene}");
        let png = clock::heat_map_png(cycles, o.sizes.width, o.sizes.height, scale, &title)?;
        crate::io::write_atomic(&dir.join(&file), &png)?;
        for r in s.shader_clock.rows.iter_mut().filter(|r| r.method == *method && r.data.ray_set == RaySet::Primary) {
            r.data.heat_map = Some(file.clone());
        }
    }
    Ok(())
}

/// Section 8: the driver statistics of the kernels the timings ran (each method's closest-hit
/// kernel on the profile's layout and its scene's access path).
fn driver_stats_section(
    ctx: &Context,
    o: &ProfileOptions,
    kernels: &[&'static crate::kernels::KernelSource],
    progress: &mut impl FnMut(&str),
) -> Result<Section<driver_stats::KernelStats>> {
    let _span = crate::timeline::span("section", "driver statistics (child processes)");
    let Some(co) = &o.driver_stats else {
        return Ok(Section::new(Status::Skipped, "skipped (--no-driver-stats)"));
    };
    progress(&format!("driver statistics of {} kernels", kernels.len()));
    let r = driver_stats::collect(ctx, kernels, co)?;
    Ok(Section { status: r.status, note: r.note, rows: r.kernels })
}

/// A profile cell: one method's closest-hit ray-casting kernel on one ray set of the profiled
/// scene and layout, at the default launch or at one swept setting.
#[derive(Clone, Debug, PartialEq)]
pub struct ProfileCell {
    pub scene: String,
    pub set: RaySet,
    pub method: Method,
    pub layout: Layout,
    pub swept: Option<Swept>,
}

/// The launch setting a profile sweep changed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Swept {
    /// The required subgroup size (0: the driver's choice).
    SubgroupSize(u32),
    /// The workgroup's local size.
    LocalSize(u32),
    /// lavapipe's `LP_NUM_THREADS`.
    Threads(usize),
}

impl ProfileCell {
    /// The cell's coordinates, as `rows.jsonl` names them: the kernel is always `raycast`'s
    /// `closest` variant, and a swept setting adds its own coordinate.
    pub fn coordinates(&self) -> crate::rows::Cell {
        let mut c = crate::rows::cell([
            ("scene", self.scene.clone()),
            ("set", self.set.to_string()),
            ("method", self.method.to_string()),
            ("layout", self.layout.to_string()),
            ("kernel", "raycast".into()),
            ("variant", "closest".into()),
        ]);
        let (key, value) = match self.swept {
            None => return c,
            Some(Swept::SubgroupSize(n)) => ("subgroup_size", n as usize),
            Some(Swept::LocalSize(n)) => ("local_size", n as usize),
            Some(Swept::Threads(n)) => ("threads", n),
        };
        c.insert(key.into(), value.to_string());
        c
    }
}

/// The profile's rows: timings (with the pipeline statistics' invocations as a count) per
/// method and ray set, the subgroup/workgroup sweeps and LP_NUM_THREADS runs (command
/// `profile`, [`ProfileCell`]), and the driver statistics (command [`driver_stats::COMMAND`]).
/// The shader-clock ticks are a distribution over rays of one run, not rounds, and are left out.
pub fn rows(r: &ProfileReport) -> Vec<crate::rows::Row> {
    use crate::rows::{Better, Figure, Row as R};
    let source = r.provenance.source();
    let base = |method: Method, set: RaySet, swept: Option<Swept>| {
        ProfileCell { scene: r.scene.clone(), set, method, layout: r.layout, swept }.coordinates()
    };
    let mrays = |rays: usize, ms: &Summary| mrays_summary(rays, *ms);
    let mut out = vec![];
    for t in &r.timestamps.rows {
        let d = &t.data;
        let mut row = R::new("profile", base(t.method, d.ray_set, None), &source)
            .with("kernel_ms", Figure::timing(d.kernel_ms, "ms", Better::Lower))
            .with("mrays_per_s", Figure::timing(mrays(d.rays, &d.kernel_ms), "Mrays/s", Better::Higher))
            .with("agreement", Figure::correctness(d.agreement, "fraction", Better::Higher));
        if let Some(inv) =
            r.pipeline_statistics.rows.iter().find(|i| i.method == t.method && i.data.ray_set == d.ray_set)
        {
            row = row.with(
                "compute_shader_invocations",
                Figure::count(inv.data.compute_shader_invocations as f64, "invocations"),
            );
        }
        if let Some(e) = &d.roofline {
            row = e.add_figures(row, d.kernel_ms.runs);
        }
        out.push(row);
    }
    let subgroups = r.subgroup_sizes.rows.iter().map(|t| (t, Swept::SubgroupSize(t.data.subgroup_size.unwrap_or(0))));
    let locals = r.workgroup_sizes.rows.iter().map(|t| (t, Swept::LocalSize(t.data.local_size)));
    for (t, swept) in subgroups.chain(locals) {
        let d = &t.data;
        out.push(
            R::new("profile", base(t.method, d.ray_set, Some(swept)), &source)
                .with("kernel_ms", Figure::timing(d.kernel_ms, "ms", Better::Lower))
                .with("mrays_per_s", Figure::timing(mrays(d.rays, &d.kernel_ms), "Mrays/s", Better::Higher))
                .with("agreement", Figure::correctness(d.agreement, "fraction", Better::Higher)),
        );
    }
    for t in &r.lp_num_threads_scaling.rows {
        let d = &t.data;
        let set: RaySet = match d.ray_set.parse() {
            Ok(s) => s,
            Err(_) => continue,
        };
        out.push(
            R::new("profile", base(t.method, set, Some(Swept::Threads(d.threads))), &source)
                .with("kernel_ms", Figure::timing(d.kernel_ms, "ms", Better::Lower))
                .with("agreement", Figure::correctness(d.agreement, "fraction", Better::Higher)),
        );
    }
    let ds = driver_stats::DriverStatsReport {
        provenance: r.provenance.clone(),
        status: r.driver_statistics.status,
        note: r.driver_statistics.note.clone(),
        kernels: r.driver_statistics.rows.clone(),
        targets: vec![],
    };
    out.extend(driver_stats::rows(&ds));
    out
}

fn threads_section(
    ctx: &Context,
    o: &ProfileOptions,
    sets: &[(RaySet, Vec<Ray>)],
    progress: &mut impl FnMut(&str),
) -> Result<Section<Row<ThreadMeasurement>>> {
    let _span = crate::timeline::span("section", "LP_NUM_THREADS: trilab bench per thread count (child processes)");
    let info = ctx.info();
    if let Err(u) = ctx.capabilities().statistic(Statistic::ThreadCount) {
        return Ok(Section::new(Status::NotApplicable, format!("{}: {}", u.what, u.why)));
    }
    let Some(exe) = &o.exe else {
        return Ok(Section::new(Status::Skipped, "skipped (no trilab executable given to run per thread count)"));
    };
    let dir = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    let stem = crate::scene::scene_name(&o.scene);
    for (set, rays) in sets {
        crate::rays::write_rays(&dir.path().join(format!("{stem}.{set}.rays")), rays)?;
    }
    let counts = if o.thread_counts.is_empty() { threads::default_counts() } else { o.thread_counts.clone() };
    let run = threads::BenchRun {
        exe,
        scene: &o.scene,
        rays_dir: dir.path(),
        methods: &o.methods,
        leaf_size: o.build.max_leaf_size,
        layout: o.layout,
        repeat: o.repeat.max(1),
        device_index: info.index,
    };
    let mut section = Section::new(
        Status::Measured,
        format!(
            "`trilab bench` run per LP_NUM_THREADS value on the same ray files ({} host CPUs); it validates every result",
            std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
        ),
    );
    for n in counts {
        progress(&format!("LP_NUM_THREADS={n}: running `trilab bench`"));
        let _span = crate::timeline::span_with("child", || format!("child: trilab bench with LP_NUM_THREADS={n}"));
        for m in threads::bench_with_threads(&run, n)? {
            let method: Method = o
                .methods
                .iter()
                .copied()
                .find(|x| x.to_string() == m.method)
                .ok_or_else(|| Error::Usage(format!("bench reported an unknown method {}", m.method)))?;
            section.rows.push(Row::new(info, method, m));
        }
    }
    Ok(section)
}
impl crate::report::Report for ProfileReport {
    /// profile.md.
    fn to_text(&self) -> String {
        markdown::render(self, &self.command)
    }
}

/// No plan: a profile is not sharded.
impl crate::services::results::Results for ProfileReport {
    const STEM: &'static str = "profile";

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        crate::report::Report::to_text(self)
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        Some(rows(self))
    }
}

/// Writes profile.json and profile.md into `dir` (created if needed), each atomically; the
/// heat maps are already there ([`run`] wrote them).
pub fn write(report: &ProfileReport, dir: &Path) -> Result<Vec<PathBuf>> {
    crate::services::results::write_folder(dir, report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_profile_cell_names_its_kernel_and_the_setting_a_sweep_changed() {
        let c = ProfileCell {
            scene: "bunny".into(),
            set: RaySet::Diffuse,
            method: Method::QuadUnit,
            layout: Layout::Bvh4,
            swept: None,
        };
        let base = [
            ("kernel", "raycast"),
            ("layout", "bvh4"),
            ("method", "quad-unit"),
            ("scene", "bunny"),
            ("set", "diffuse"),
            ("variant", "closest"),
        ];
        let pairs = |c: &crate::rows::Cell| c.iter().map(|(k, v)| (k.to_owned(), v.to_owned())).collect::<Vec<_>>();
        let with = |extra: Option<(&str, &str)>| pairs(&crate::rows::cell(base.iter().copied().chain(extra)));
        assert_eq!(pairs(&c.coordinates()), with(None));
        let swept = |s: Swept| pairs(&ProfileCell { swept: Some(s), ..c.clone() }.coordinates());
        assert_eq!(swept(Swept::SubgroupSize(16)), with(Some(("subgroup_size", "16"))));
        assert_eq!(swept(Swept::LocalSize(64)), with(Some(("local_size", "64"))));
        assert_eq!(swept(Swept::Threads(2)), with(Some(("threads", "2"))));
    }
}
