//! A kernel's efficiency against the traversal roofline (issue 27), what `bench --roofline` and
//! `profile --roofline` add beside each kernel's Mrays/s: the roofline ([`services::roofline`],
//! `trilab roofline`'s pointer chase) measured at each scene's bytes on the access path its
//! kernels read ([`scene_roofline`]), the kernel's node and triangle fetches per ray from its
//! `stats` variant on the same rays ([`fetch_counts`]), and the one over the other
//! ([`efficiency`]). One place, so both commands compute, show and write the same figures.
//!
//! [`services::roofline`]: crate::services::roofline

use serde::Serialize;

use crate::encoding::Raycast;
use crate::error::Result;
use crate::gpu::roofline::RooflineAccess;
use crate::gpu::traversal_stats;
use crate::gpu::{Context, RaycastOptions, TraversalCounts, TraversalSummary};
use crate::pipeline::DeviceScene;
use crate::rays::Ray;
use crate::report::Summary;
use crate::services::roofline::{self, RooflineOptions, RooflineReport};

/// A kernel's node and triangle fetches per second against the traversal roofline's node steps
/// per second at its scene's working set (its encoded bytes: nodes, primitives, slot ids) on
/// the access path it reads the scene through. A fetch is a node visited (inner or leaf, any
/// layout's node size) or a triangle tested, from the kernel's `stats` variant on the same rays;
/// the roofline's step is one dependent 32-byte node load with a slab test. So `efficiency` =
/// (nodes + triangles per ray) x Mrays/s / roofline Msteps/s: 1 means the kernel fetches as
/// fast as a pure dependent walk does at that size.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RooflineEfficiency {
    /// Nodes visited per ray, mean (inner and leaf).
    pub nodes_per_ray: f64,
    /// Triangles tested per ray, mean.
    pub triangles_per_ray: f64,
    /// The roofline at the scene's bytes on its access path, Msteps/s (median; interpolated
    /// between the two power-of-two sizes around it).
    pub roofline_msteps_per_s: f64,
    /// Fetches per second over the roofline's steps per second, at the median Mrays/s.
    pub efficiency: f64,
    /// The same at the slowest and fastest rounds.
    pub efficiency_min: f64,
    pub efficiency_max: f64,
    /// Rays in lock-step: the device's subgroup size (lavapipe: one SIMD row of the host CPU).
    pub lanes: u32,
    /// Where the gap to the roofline goes, first part: the share of lane-steps that fetch for a
    /// ray when `lanes` consecutive rays of the dispatch (in the order the kernel got them) run
    /// in lock-step, from the same per-ray counts ([`crate::gpu::traversal_stats::lanes_busy`]:
    /// an upper bound). The roofline's walk keeps every lane busy, so `efficiency /
    /// lanes_busy` is what a busy lane fetches against it; `None` for no fetches.
    pub lanes_busy: Option<f64>,
}

/// The table columns [`RooflineEfficiency::cells`] fills.
pub const COLUMNS: [&str; 4] = ["fetches/ray", "roofline Msteps/s", "of roofline %", "lanes busy %"];

impl RooflineEfficiency {
    /// Nodes and triangles per ray.
    pub fn fetches_per_ray(&self) -> f64 {
        self.nodes_per_ray + self.triangles_per_ray
    }

    /// The [`COLUMNS`] of a row: its figures, or dashes where it has none.
    pub fn cells(e: Option<&RooflineEfficiency>) -> [String; 4] {
        match e {
            Some(e) => [
                format!("{:.1}", e.fetches_per_ray()),
                format!("{:.1}", e.roofline_msteps_per_s),
                format!("{:.1}", 100.0 * e.efficiency),
                e.lanes_busy.map_or("-".into(), |b| format!("{:.0} ({} lanes)", 100.0 * b, e.lanes)),
            ],
            None => ["-".into(), "-".into(), "-".into(), "-".into()],
        }
    }

    /// `row` with the figures `roofline_efficiency` (timing: median and min-max over `runs`
    /// rounds) and `fetches_per_ray` (count).
    pub fn add_figures(&self, row: crate::rows::Row, runs: usize) -> crate::rows::Row {
        use crate::rows::{Better, Figure};
        let eff = Summary { median: self.efficiency, min: self.efficiency_min, max: self.efficiency_max, runs };
        let row = row
            .with("roofline_efficiency", Figure::timing(eff, "fraction", Better::Higher))
            .with("fetches_per_ray", Figure::count(self.fetches_per_ray(), "fetches"));
        match self.lanes_busy {
            Some(b) => row.with("lanes_busy", Figure::count(b, "fraction")),
            None => row,
        }
    }
}

/// The roofline at the bytes of each of `scenes` on the access path it reads ([`roofline::run`]
/// over the two powers of two around each size, interleaved), with `o`'s other settings.
pub fn scene_roofline(
    ctx: &Context,
    scenes: &[DeviceScene],
    o: &RooflineOptions,
    progress: &mut impl FnMut(&str),
) -> Result<RooflineReport> {
    let mut sizes: Vec<u64> = scenes.iter().flat_map(|s| roofline::sizes_around(s.bytes as u64)).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let mut access: Vec<RooflineAccess> = scenes.iter().map(|s| RooflineAccess::of_scene(s.access)).collect();
    access.sort_unstable();
    access.dedup();
    let o = RooflineOptions { sizes, access, ..o.clone() };
    let report = roofline::run(ctx, &o, &mut *progress)?;
    for s in &report.skipped {
        progress(&format!("roofline: {} skipped: {}", roofline::show_size(s.bytes), s.why));
    }
    Ok(report)
}

/// A kernel's traversal counts per ray on `rays`, in the set's order, from its `stats` variant
/// (one untimed cast) with the rays dispatched in `order` (`order[k]`: the set's index of the
/// `k`-th ray dispatched; `None`: as given), which changes the counts only of a traversal whose
/// lanes walk together ([`Traversal::walks_together`]); `None` for a traversal without a `stats`
/// variant (persistent threads).
///
/// [`Traversal::walks_together`]: crate::encoding::Traversal::walks_together
pub fn fetch_counts(
    ctx: &Context,
    scene: &DeviceScene,
    rays: &[Ray],
    order: Option<&[u32]>,
    batch_rays: usize,
) -> Result<Option<Vec<TraversalCounts>>> {
    if scene.kernel_source(Raycast::Stats).is_err() {
        return Ok(None);
    }
    let once = RaycastOptions { warmup: 0, repeat: 1, batch_rays };
    let Some(order) = order else {
        return Ok(Some(scene.cast(ctx, Raycast::Stats, rays, &once)?.traversal.unwrap_or_default()));
    };
    let dispatched = crate::rays::order::permute(order, rays);
    let counts = scene.cast(ctx, Raycast::Stats, &dispatched, &once)?.traversal.unwrap_or_default();
    Ok(Some(crate::rays::order::unpermute(order, &counts)))
}

/// `scene`'s kernel against the roofline: its nodes and triangles per ray (`counts`, per ray in
/// the set's order: [`fetch_counts`]) at its Mrays/s (`mrays`: median, slowest and fastest
/// rounds) over the roofline at the scene's bytes on its access path (`None` where the roofline
/// measured that path at no size); and the lanes those counts keep busy in groups of `lanes`
/// rays, the rays dispatched in `order` (`order[k]`: the set's index of the `k`-th ray
/// dispatched; `None`: as given).
pub fn efficiency(
    scene: &DeviceScene,
    roof: &RooflineReport,
    mrays: Summary,
    counts: &[TraversalCounts],
    lanes: u32,
    order: Option<&[u32]>,
) -> Option<RooflineEfficiency> {
    let steps = roof.at(RooflineAccess::of_scene(scene.access), scene.bytes as u64)?;
    let t = TraversalSummary::of(counts);
    let fetches = t.nodes.mean + t.triangles.mean;
    let of = |mrays: f64| fetches * mrays / steps;
    let dispatched: Vec<TraversalCounts> = match order {
        Some(o) => o.iter().map(|&i| counts[i as usize]).collect(),
        None => counts.to_vec(),
    };
    Some(RooflineEfficiency {
        nodes_per_ray: t.nodes.mean,
        triangles_per_ray: t.triangles.mean,
        roofline_msteps_per_s: steps,
        efficiency: of(mrays.median),
        efficiency_min: of(mrays.min),
        efficiency_max: of(mrays.max),
        lanes,
        lanes_busy: traversal_stats::lanes_busy(&dispatched, lanes as usize, traversal_stats::fetches),
    })
}
