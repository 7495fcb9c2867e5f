//! What a bench reports: a row per kernel or peer and set, the peers' comparison, the text and
//! Markdown tables, and the self-describing rows `compare` and `merge` read.

use std::path::Path;

use serde::Serialize;

use super::plan::{BenchCell, BenchOptions, CellTracer};

use crate::bvh::NodeOrder;
use crate::encoding::{AccessPath, Layout, Method, Traversal};
use crate::error::Result;
use crate::gpu::{AccelStats, Peer};
use crate::rays::order::RayOrder;
use crate::rays::Ray;
use crate::report::{Report, Summary, Table};
use crate::scene::Mesh;
use crate::services::efficiency;
pub use crate::services::efficiency::RooflineEfficiency;
use crate::services::peer_report::{self, PeerComparison};
use crate::services::peers::PeerOutcome;
use crate::services::provenance::Provenance;
use crate::services::rayset::RaySet;
use crate::services::shard::{self, Shard};
use crate::services::validate::mrays_summary;

/// What traced a row's rays: one of our kernels over our BVH, or a peer (the driver's ray
/// query or ray tracing pipeline) over its own structure. Serialises as the method's or the peer's name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum Tracer {
    Method(Method),
    Peer(Peer),
}

impl std::fmt::Display for Tracer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Tracer::Method(m) => m.fmt(f),
            Tracer::Peer(p) => p.fmt(f),
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchRow {
    pub scene: String,
    pub triangles: usize,
    pub ray_set: RaySet,
    pub rays: usize,
    pub method: Tracer,
    /// Our BVH's leaf size; `None` for a peer (the driver's structure is its own).
    pub leaf_size: Option<u32>,
    /// Triangles the BVH's SAH priced as one test (4: quad-aware); `None` for a peer.
    pub sah_group: Option<u32>,
    /// Our encoded scene, or for a driver peer the driver's BLAS + TLAS.
    pub scene_bytes: usize,
    /// How our kernels read the scene (`None` for a peer).
    pub scene_access: Option<AccessPath>,
    /// The BVH node layout our kernel traversed (`None` for a peer).
    pub layout: Option<Layout>,
    /// How our kernel walked the tree (`None` for a peer).
    pub traversal: Option<Traversal>,
    /// The order our kernel's rays were dispatched in (`None` for a peer).
    pub order: Option<RayOrder>,
    /// The order of the layout's nodes in memory (`None` for a peer); left out of the JSON when
    /// it is the built one, so a run without `--node-orders` writes what it wrote before.
    #[serde(skip_serializing_if = "built_order")]
    pub node_order: Option<NodeOrder>,
    /// The host's time to reorder the rays and put the hits back, ms, part of `kernel_ms`
    /// (`None` for a peer, or rays dispatched as given).
    pub reorder_ms: Option<Summary>,
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
    /// `--roofline`: the kernel's fetches per second against the roofline's at its scene's size.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roofline: Option<RooflineEfficiency>,
    /// The hybrid traversal's switch rate: the share of rays that went on alone after the packet
    /// (its stats kernel on the same rays, dispatched in the row's order); `None` for every
    /// other traversal.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub switched: Option<f64>,
}

/// Whether a row's node order is the built one (or it has none): not written.
pub(super) fn built_order(o: &Option<NodeOrder>) -> bool {
    o.is_none_or(|o| o == NodeOrder::DEFAULT)
}

impl BenchRow {
    /// How the peer comparison names our row (the tables give the layout a column).
    pub(super) fn label(&self, method: Method) -> String {
        crate::matrix::KernelLabel {
            method,
            layout: None,
            traversal: self.traversal.unwrap_or_default(),
            node_order: self.node_order.unwrap_or_default(),
            order: self.order.unwrap_or_default(),
            access: self.scene_access.unwrap_or(AccessPath::Texel),
        }
        .to_string()
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    #[serde(flatten)]
    pub provenance: Provenance,
    pub leaf_size: u32,
    /// What the trees and rays were made from (with the provenance's scenes).
    pub recipe: super::plan::BenchRecipe,
    /// Timed runs per measurement (after one warm-up).
    pub repeat: usize,
    pub rows: Vec<BenchRow>,
    /// Per scene and ray set with peers: trilab's best row beside each peer, and the speed target.
    pub peers: Vec<PeerComparison>,
    /// The driver's acceleration structure per scene, for the driver peers' rows.
    pub accel: Vec<(String, AccelStats)>,
    /// One line per driver peer left out: "ray query: unsupported on <device> (<driver>)" where
    /// the device lacks it, "ray tracing pipeline: not run (...)" where the options left it out.
    pub driver_notes: Vec<String>,
    /// Ray sets skipped because they hold no rays (for example `--random-rays 0`).
    pub notes: Vec<String>,
    /// The shard this run took (`--shard I/N`), if any.
    pub shard: Option<Shard>,
    /// Every cell of the whole matrix (all shards; [`plan_cells`]), written as the rows' plan.
    #[serde(skip)]
    pub plan: Vec<crate::rows::Cell>,
}

impl Report for BenchReport {
    fn to_text(&self) -> String {
        self.render(false)
    }
}

impl crate::services::results::Results for BenchReport {
    const STEM: &'static str = "bench";

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        BenchReport::markdown(self)
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        Some(rows(self))
    }

    fn plan(&self) -> Option<crate::rows::Plan> {
        Some(BenchReport::plan(self))
    }
}

impl BenchReport {
    /// Device, driver, host and how the rows were timed.
    pub fn header(&self) -> String {
        let p = &self.provenance;
        let lp = p.lp_num_threads.as_deref().map(|n| format!(", LP_NUM_THREADS={n}")).unwrap_or_default();
        let mut s = format!(
            "device: {} ({}); host: {}{lp}; leaf size {}; median of {} rounds after 1 warm-up, the kernels{} interleaved in every round (GPU timestamps)",
            p.device,
            p.driver,
            p.host.label(),
            self.leaf_size,
            self.repeat,
            if self.peers.is_empty() { "" } else { " and peer programs" }
        );
        if let Some(note) = self.partial() {
            s += &format!("\n{note}");
        }
        s
    }

    /// `partial: shard I/N, X of Y cells ...` for a sharded run, `None` for a whole one.
    pub fn partial(&self) -> Option<String> {
        shard::partial(self.shard, &self.plan, &rows(self), "whole scenes")
    }

    /// The plan of the whole matrix this report belongs to, with its shard.
    pub fn plan(&self) -> crate::rows::Plan {
        crate::rows::Plan {
            command: "bench".into(),
            shard: self.shard,
            cells: self.plan.clone(),
            source: self.provenance.source(),
        }
    }

    /// The tables in Markdown, under the header.
    pub fn markdown(&self) -> String {
        self.render(true)
    }

    /// The header, the tables (in Markdown or as text) and the notes: the text and the
    /// Markdown differ only in how a table is drawn, a capital and the accel table's title.
    fn render(&self, markdown: bool) -> String {
        let table = |t: Table| if markdown { t.to_markdown() } else { t.to_text() };
        let mut s = format!("{}\n\n{}", self.header(), table(self.table()));
        if !self.peers.is_empty() {
            s += &format!(
                "\n{}\n\n{}\n{} target (trilab / peer). {}\n\n{}",
                peer_report::PEER_NOTE,
                table(peer_report::peer_table(&self.peers)),
                if markdown { "Speed" } else { "speed" },
                peer_report::target_note(),
                table(peer_report::target_table(&self.peers))
            );
            for note in peer_report::peer_notes(&self.peers) {
                s += &format!("\n{note}\n");
            }
        }
        if !self.accel.is_empty() {
            let title = match markdown {
                true => "",
                false => "the driver's acceleration structures (ray-query and ray-tracing-pipeline rows):\n\n",
            };
            s += &format!("\n{title}{}", table(self.accel_table()));
        }
        for note in self.driver_notes.iter().chain(&self.notes) {
            s += &format!("\n{note}\n");
        }
        s
    }

    /// Writes the report as JSON and the tables as Markdown where asked, each atomically, and
    /// [`rows`] as `rows.jsonl` beside the JSON file (else beside the Markdown).
    pub fn write(&self, json: Option<&Path>, md: Option<&Path>) -> Result<()> {
        crate::services::results::write(self, json, md).map(drop)
    }

    /// One row per measured cell. The access column appears when rows read their scenes both
    /// ways, the traversal column when a row's traversal is not while-if, the node order column
    /// when a row's nodes are not in the built order, the order and reorder
    /// columns when a row's rays were reordered (`kernel ms` then includes the reordering;
    /// `reorder ms` is that share), the `switched %` column when a row is the hybrid's.
    pub fn table(&self) -> Table {
        let traversals = self.rows.iter().any(|r| r.traversal.is_some_and(|t| t != Traversal::default()));
        let orders = self.rows.iter().any(|r| r.order.is_some_and(|o| o != RayOrder::default()));
        let node_orders = self.rows.iter().any(|r| !built_order(&r.node_order));
        // The access column only where rows read scenes both ways (one path is the header's
        // `--scene-access`, as before lists were taken).
        let access =
            self.rows.iter().filter_map(|r| r.scene_access).collect::<std::collections::BTreeSet<_>>().len() > 1;
        let roofline = self.rows.iter().any(|r| r.roofline.is_some());
        let switched = self.rows.iter().any(|r| r.switched.is_some());
        let mut header = vec!["scene", "rays", "set", "method", "layout"];
        header.extend(access.then_some("access"));
        header.extend(traversals.then_some("traversal"));
        header.extend(node_orders.then_some("node order"));
        header.extend(orders.then_some("order"));
        header.extend(["leaf", "MB", "kernel ms"]);
        header.extend(orders.then_some("reorder ms"));
        header.extend(["Mrays/s", "min..max", "agree %", "Embree"]);
        if roofline {
            header.extend(efficiency::COLUMNS);
        }
        header.extend(switched.then_some("switched %"));
        let mut t = Table::new(header);
        let or_dash = |s: Option<String>| s.unwrap_or_else(|| "-".into());
        for r in &self.rows {
            let mut cells = vec![
                r.scene.clone(),
                r.rays.to_string(),
                r.ray_set.to_string(),
                r.method.to_string(),
                or_dash(r.layout.map(|l| l.to_string())),
            ];
            cells.extend(access.then(|| or_dash(r.scene_access.map(|a| a.name().to_owned()))));
            cells.extend(traversals.then(|| or_dash(r.traversal.map(|t| t.to_string()))));
            cells.extend(node_orders.then(|| or_dash(r.node_order.map(|o| o.to_string()))));
            cells.extend(orders.then(|| or_dash(r.order.map(|o| o.to_string()))));
            cells.extend([
                or_dash(r.leaf_size.map(|l| l.to_string())),
                format!("{:.2}", r.scene_bytes as f64 / 1e6),
                format!("{:.1}", r.kernel_ms.median),
            ]);
            cells.extend(orders.then(|| or_dash(r.reorder_ms.map(|m| format!("{:.1}", m.median)))));
            cells.extend([
                rate(r.mrays_per_s),
                format!("{}..{}", rate(r.mrays_per_s_min), rate(r.mrays_per_s_max)),
                format!("{:.4}", 100.0 * r.agreement),
                or_dash(r.embree_mrays_per_s.map(|e| format!("{e:.2}"))),
            ]);
            if roofline {
                cells.extend(RooflineEfficiency::cells(r.roofline.as_ref()));
            }
            cells.extend(switched.then(|| or_dash(r.switched.map(|s| format!("{:.1}", 100.0 * s)))));
            t.row(cells);
        }
        t
    }

    /// The driver's structures: sizes and build times.
    pub fn accel_table(&self) -> Table {
        let mut t = Table::new([
            "scene",
            "triangles",
            "BLAS bytes",
            "TLAS bytes",
            "scratch bytes",
            "BLAS build ms",
            "TLAS build ms",
            "wall ms",
        ]);
        let ms = |m: Option<f64>| m.map_or_else(|| "-".into(), |m| format!("{m:.2}"));
        for (scene, s) in &self.accel {
            t.row([
                scene.clone(),
                s.triangles.to_string(),
                s.blas_bytes.to_string(),
                s.tlas_bytes.to_string(),
                (s.blas_scratch_bytes + s.tlas_scratch_bytes).to_string(),
                ms(s.blas_build_ms),
                ms(s.tlas_build_ms),
                format!("{:.1}", s.wall_ms),
            ]);
        }
        t
    }
}

pub fn rows(report: &BenchReport) -> Vec<crate::rows::Row> {
    use crate::rows::{Better, Figure, Row};
    let source = report.provenance.source();
    let mut out = vec![];
    for r in &report.rows {
        let tracer = match r.method {
            Tracer::Method(m) => CellTracer::Method {
                method: m,
                layout: r.layout.unwrap_or(Layout::DEFAULT),
                leaf: r.leaf_size.unwrap_or(report.leaf_size),
                sah_group: r.sah_group,
                traversal: r.traversal.unwrap_or_default(),
                node_order: r.node_order.unwrap_or_default(),
                order: r.order.unwrap_or_default(),
                access: r.scene_access.unwrap_or(AccessPath::Texel),
            },
            Tracer::Peer(p) => CellTracer::Peer(p.to_string()),
        };
        let c = BenchCell { scene: r.scene.clone(), set: r.ray_set, rays: Some(r.rays), tracer }.coordinates();
        let speed = Summary { median: r.mrays_per_s, min: r.mrays_per_s_min, max: r.mrays_per_s_max, ..r.kernel_ms };
        out.push(
            Row::new("bench", c, &source)
                .with("mrays_per_s", Figure::timing(speed, "Mrays/s", Better::Higher))
                .with("agreement", Figure::correctness(r.agreement, "fraction", Better::Higher))
                .with("unexplained", Figure::correctness(r.unexplained_disagreements as f64, "rays", Better::Lower))
                .with("invalid", Figure::correctness(r.invalid as f64, "rays", Better::Lower))
                .with("scene_bytes", Figure::count(r.scene_bytes as f64, "bytes")),
        );
        if let Some(e) = &r.roofline {
            let row = out.pop().expect("the row just pushed");
            out.push(e.add_figures(row, r.kernel_ms.runs));
        }
    }
    for p in &report.peers {
        for peer in &p.peers {
            let tracer = CellTracer::Peer(peer.peer.to_string());
            let c = BenchCell { scene: p.scene.clone(), set: p.ray_set, rays: Some(p.rays), tracer }.coordinates();
            let row = match &peer.outcome {
                PeerOutcome::Timed { mrays_per_s, mrays_per_s_min, mrays_per_s_max, trace_ms, agreement, .. } => {
                    let (median, min, max) = (*mrays_per_s, *mrays_per_s_min, *mrays_per_s_max);
                    let speed = Summary { median, min, max, runs: trace_ms.runs };
                    Row::new("bench", c, &source)
                        .with("mrays_per_s", Figure::timing(speed, "Mrays/s", Better::Higher))
                        .with("agreement", Figure::correctness(*agreement, "fraction", Better::Higher))
                }
                PeerOutcome::WrongHits { agreement: Some(a), .. } => {
                    Row::new("bench", c, &source).with("agreement", Figure::correctness(*a, "fraction", Better::Higher))
                }
                PeerOutcome::WrongHits { agreement: None, .. } | PeerOutcome::Skipped { .. } => continue,
            };
            out.push(row);
        }
    }
    // A non-finite figure has no JSON number; such a figure is left out, not written as null.
    for r in &mut out {
        r.figures.retain(|_, f| f.median.is_finite() && f.min.is_finite() && f.max.is_finite());
    }
    out
}

/// Mrays/s with two decimals, or three significant digits below 1 (lavapipe's ray query runs at
/// a few thousand rays per second).
pub(super) fn rate(x: f64) -> String {
    if x >= 1.0 || x == 0.0 || !x.is_finite() {
        format!("{x:.2}")
    } else {
        let decimals = (2.0 - x.log10().floor()).clamp(2.0, 9.0) as usize;
        format!("{x:.decimals$}")
    }
}

/// One table row; `o` is `None` for a peer (no leaf size or SAH grouping); `footprint` is the
/// scene's GPU bytes and the access path it was read through.
#[allow(clippy::too_many_arguments)]
pub(super) fn row(
    scene: &str,
    mesh: &Mesh,
    set: RaySet,
    rays: &[Ray],
    method: Tracer,
    o: Option<&BenchOptions>,
    footprint: (usize, Option<AccessPath>),
    ms: Summary,
    agreement: &crate::agreement::Agreement,
) -> BenchRow {
    let mr = mrays_summary(rays.len(), ms);
    BenchRow {
        scene: scene.to_owned(),
        triangles: mesh.triangle_count(),
        ray_set: set,
        rays: rays.len(),
        method,
        leaf_size: o.map(|o| o.build.max_leaf_size),
        sah_group: o.map(|o| o.build.sah_group),
        scene_bytes: footprint.0,
        scene_access: footprint.1,
        layout: o.map(|_| Layout::DEFAULT),
        traversal: o.map(|_| Traversal::DEFAULT),
        order: o.map(|_| RayOrder::DEFAULT),
        node_order: o.map(|_| NodeOrder::DEFAULT),
        reorder_ms: None,
        kernel_ms: ms,
        mrays_per_s: mr.median,
        mrays_per_s_min: mr.min,
        mrays_per_s_max: mr.max,
        agreement: agreement.fraction(),
        unexplained_disagreements: agreement.unexplained,
        invalid: agreement.invalid.len(),
        embree_mrays_per_s: None,
        roofline: None,
        switched: None,
    }
}
