//! The ray-casting benchmark (`trilab bench`, `cargo bench`): primary, diffuse and random ray
//! sets on each scene, every method, each result validated against the f64 reference before
//! its speed is reported (as tinybvh's speed test does), optionally beside the peers (Embree,
//! tinybvh: `harness::peers`) on the same ray files in the same run, each validated the same way.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use crate::agreement::compare_closest;
use crate::bvh::{BuildOptions, NodeOrder};
use crate::encoding::{AccessPath, Layout, Method, Raycast, SceneAccess, Traversal};
use crate::error::{Error, Result};
use crate::gpu::{AccelStats, AccelStructure, Context, Peer, PeerTracer, RaycastOptions};
use crate::harness::efficiency;
pub use crate::harness::efficiency::RooflineEfficiency;
use crate::harness::peer_report::{self, PeerComparison, TrilabBest};
use crate::harness::peers::{self, PeerKind, PeerOutcome, PeerResult, PeerRound, PeerSet, TinybvhLayout};
use crate::harness::provenance::Provenance;
use crate::harness::rayset::{ray_sets, RaySet, RaySetSizes};
use crate::harness::shard::{self, Shard, Split};
use crate::harness::validate::{interleaved_with, mrays_summary, Job, RoundJob};
use crate::pipeline::{DeviceScene, HostScene, SceneRequest};
use crate::rays::order::RayOrder;
use crate::rays::{self, Ray};
use crate::reference::RefHit;
use crate::report::{Report, Summary, Table};
use crate::scene::{load_obj, Mesh};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub scenes: Vec<PathBuf>,
    pub methods: Vec<Method>,
    /// The BVH every method's encoding shares.
    pub build: BuildOptions,
    pub warmup: usize,
    pub repeat: usize,
    /// The ray sets' sizes.
    pub sizes: RaySetSizes,
    /// Read `<scene>.{primary,diffuse,random}.rays` from here instead of generating (for
    /// example the peer's held-out sets from ../shared/peers/make_rays.sh).
    pub rays_dir: Option<PathBuf>,
    /// The Embree peer program (`embree_rays`), run on the same ray files.
    pub embree: Option<PathBuf>,
    /// The tinybvh peer program (`tinybvh_rays`), run on the same ray files.
    pub tinybvh: Option<PathBuf>,
    /// Its layouts (empty: [`TinybvhLayout::DEFAULT`]).
    pub tinybvh_layouts: Vec<TinybvhLayout>,
    pub batch_rays: usize,
    /// Add the driver's ray query as a peer row where the device has it.
    pub ray_query: bool,
    /// Add the driver's ray tracing pipeline as a peer row where the device has it.
    pub ray_tracing_pipeline: bool,
    /// How the kernels read each scene (`encoding::plan`; `auto`: texel buffers when they fit);
    /// several are timed side by side (texel and address: what the address path costs).
    pub scene_access: Vec<SceneAccess>,
    /// BVH node layouts, each method timed on each, side by side in one run (default: bvh2).
    pub layouts: Vec<Layout>,
    /// Traversals, each method and layout timed with each that has a kernel for it (default:
    /// while-if); a combination without a kernel is left out with a note.
    pub traversals: Vec<Traversal>,
    /// The orders each set is dispatched in (default: as given), side by side: a reordering's
    /// host time (the sort, and putting the hits back) is part of its kernel time.
    pub orders: Vec<RayOrder>,
    /// The node orders each layout's buffer is laid out in (`bvh::order`; default: as built),
    /// each one more set of scenes timed side by side with the others.
    pub node_orders: Vec<NodeOrder>,
    /// Run only this shard's scenes ([`BenchOptions::split`]): a scene is the unit, so its
    /// methods, layouts and peers stay interleaved side by side in one run.
    pub shard: Option<Shard>,
    /// `--roofline`: per scene, the traversal roofline (`harness::roofline`, these settings; its
    /// sizes and paths are the scene's) at the scene's bytes on each access path its kernels
    /// read, and per kernel row its [`RooflineEfficiency`].
    pub roofline: Option<crate::harness::roofline::RooflineOptions>,
}

/// A list option's values, or its default alone when the list is empty (every axis of a bench
/// run: layout, traversal, access, node order and ray order default to the one the kernels had
/// before the axis existed).
fn or_default<T: Clone + Default>(v: &[T]) -> Vec<T> {
    if v.is_empty() {
        vec![T::default()]
    } else {
        v.to_vec()
    }
}

/// The path a kernel for `access` is looked up on before the scene is planned: `auto` takes the
/// texel path wherever the scene fits one binding.
pub fn path_of(access: SceneAccess) -> AccessPath {
    match access {
        SceneAccess::Address => AccessPath::Address,
        SceneAccess::Storage => AccessPath::Storage,
        SceneAccess::Auto | SceneAccess::Texel => AccessPath::Texel,
    }
}

/// Wall-clock target of one submit of a driver peer (its batch is sized to it,
/// [`PeerTracer::batch_for`]).
const PEER_SUBMIT_MS: f64 = 500.0;

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            scenes: vec![],
            methods: Method::ALL.to_vec(),
            build: BuildOptions::new(crate::defaults::LEAF_SIZE),
            warmup: 1,
            repeat: crate::defaults::REPEAT,
            sizes: RaySetSizes::default(),
            rays_dir: None,
            embree: None,
            tinybvh: None,
            tinybvh_layouts: vec![],
            batch_rays: crate::defaults::BATCH_RAYS,
            ray_query: true,
            ray_tracing_pipeline: true,
            scene_access: vec![SceneAccess::DEFAULT],
            layouts: vec![Layout::DEFAULT],
            traversals: vec![Traversal::DEFAULT],
            orders: vec![RayOrder::DEFAULT],
            node_orders: vec![NodeOrder::DEFAULT],
            shard: None,
            roofline: None,
        }
    }
}

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
}

/// Whether a row's node order is the built one (or it has none): not written.
fn built_order(o: &Option<NodeOrder>) -> bool {
    o.is_none_or(|o| o == NodeOrder::DEFAULT)
}

/// A kernel's name: the method, then its layout (where given and not bvh2: progress lines; the
/// tables give the layout a column), traversal, node order, ray order and access path where
/// they are not the defaults (`quad-unit bvh4 while-while treelets nodes octant-origin address`).
fn kernel_label(
    method: Method,
    layout: Option<Layout>,
    traversal: Traversal,
    node_order: NodeOrder,
    order: RayOrder,
    access: AccessPath,
) -> String {
    let mut s = method.to_string();
    if let Some(l) = layout.filter(|&l| l != Layout::DEFAULT) {
        s += &format!(" {l}");
    }
    if traversal != Traversal::default() {
        s += &format!(" {traversal}");
    }
    if node_order != NodeOrder::default() {
        s += &format!(" {node_order} nodes");
    }
    if order != RayOrder::default() {
        s += &format!(" {order}");
    }
    if access != AccessPath::Texel {
        s += &format!(" {}", access.name());
    }
    s
}

impl BenchRow {
    /// How the peer comparison names our row ([`kernel_label`]).
    fn label(&self, method: Method) -> String {
        let access = self.scene_access.unwrap_or(AccessPath::Texel);
        let (t, n, o) = (self.traversal, self.node_order, self.order);
        kernel_label(method, None, t.unwrap_or_default(), n.unwrap_or_default(), o.unwrap_or_default(), access)
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    #[serde(flatten)]
    pub provenance: Provenance,
    pub leaf_size: u32,
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

impl crate::harness::results::Results for BenchReport {
    const STEM: &'static str = "bench";

    fn markdown(&self, _: &[crate::harness::plots::Plot]) -> String {
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
                "\n{}\n\n{}\n{} target (trilab / peer):\n\n{}",
                peer_report::PEER_NOTE,
                table(peer_report::peer_table(&self.peers)),
                if markdown { "Speed" } else { "speed" },
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
        crate::harness::results::write(self, json, md).map(drop)
    }

    /// One row per measured cell. The access column appears when rows read their scenes both
    /// ways, the traversal column when a row's traversal is not while-if, the node order column
    /// when a row's nodes are not in the built order, the order and reorder
    /// columns when a row's rays were reordered (`kernel ms` then includes the reordering;
    /// `reorder ms` is that share).
    pub fn table(&self) -> Table {
        let traversals = self.rows.iter().any(|r| r.traversal.is_some_and(|t| t != Traversal::default()));
        let orders = self.rows.iter().any(|r| r.order.is_some_and(|o| o != RayOrder::default()));
        let node_orders = self.rows.iter().any(|r| !built_order(&r.node_order));
        // The access column only where rows read scenes both ways (one path is the header's
        // `--scene-access`, as before lists were taken).
        let access =
            self.rows.iter().filter_map(|r| r.scene_access).collect::<std::collections::BTreeSet<_>>().len() > 1;
        let roofline = self.rows.iter().any(|r| r.roofline.is_some());
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

/// The report as result rows (`rows.jsonl`, what `trilab compare` reads): one row per table
/// row, cell `scene`, `set`, `rays` and either `method`, `layout`, `leaf` (our kernels) or `peer`
/// (the driver's ray query, Embree, tinybvh); figures `mrays_per_s` (timing, with min-max over
/// the rounds), `agreement`, `unexplained`, `invalid` (correctness) and `scene_bytes` (count).
/// A peer program's `mrays_per_s` is over the same rounds as the kernels' (one trace a round).
/// One bench cell: what its plan entry and its row are both made from, so the two cannot
/// spell a coordinate differently. `rays` is measured (a diffuse set's size depends on the
/// scene's hits): the plan leaves it out, a row carries it.
#[derive(Clone, Debug, PartialEq)]
pub struct BenchCell {
    pub scene: String,
    pub set: RaySet,
    pub rays: Option<usize>,
    pub tracer: CellTracer,
}

/// Who traced a bench cell's rays.
#[derive(Clone, Debug, PartialEq)]
pub enum CellTracer {
    /// One of trilab's kernels; `sah_group` only when it is not 1, the traversal, the node
    /// order and the ray order only when they are not the defaults (while-if, as built, as
    /// given). The access path is named only when it is the address path.
    Method {
        method: Method,
        layout: Layout,
        leaf: u32,
        sah_group: Option<u32>,
        traversal: Traversal,
        node_order: NodeOrder,
        order: RayOrder,
        access: AccessPath,
    },
    /// A peer, by its name (the driver's ray query, Embree, tinybvh's kernels).
    Peer(String),
}

impl BenchCell {
    /// The cell's coordinates, as `rows.jsonl` names them.
    pub fn coordinates(&self) -> crate::rows::Cell {
        let mut c = crate::rows::cell([("scene", self.scene.clone()), ("set", self.set.to_string())]);
        if let Some(rays) = self.rays {
            c.insert("rays".into(), rays.to_string());
        }
        match &self.tracer {
            CellTracer::Method { method, layout, leaf, sah_group, traversal, node_order, order, access } => {
                c.insert("method".into(), method.to_string());
                c.insert("layout".into(), layout.to_string());
                c.insert("leaf".into(), leaf.to_string());
                if let Some(g) = sah_group.filter(|&g| g != 1) {
                    c.insert("sah_group".into(), g.to_string());
                }
                if *traversal != Traversal::default() {
                    c.insert("traversal".into(), traversal.to_string());
                }
                if *node_order != NodeOrder::default() {
                    c.insert("node_order".into(), node_order.to_string());
                }
                if *order != RayOrder::default() {
                    c.insert("order".into(), order.to_string());
                }
                if *access != AccessPath::Texel {
                    c.insert("access".into(), access.name().into());
                }
            }
            CellTracer::Peer(p) => {
                c.insert("peer".into(), p.clone());
            }
        }
        c
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
fn rate(x: f64) -> String {
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
fn row(
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
    }
}

/// Every cell of the whole bench matrix (all shards), with the coordinates [`rows`] gives them
/// except `rays`: a set's ray count is measured, not chosen (the diffuse set's depends on the
/// primary hits), so a plan names a cell by scene, set and method/layout/leaf or peer, and a row
/// fills it when it agrees on those ([`crate::rows::plan_matches`]). A set the options leave empty
/// (`--random-rays 0`) is not planned; `driver`: the driver peers the run has (ray query, the ray
/// tracing pipeline); `peers`: the peer programs that passed their probe.
pub fn plan_cells(o: &BenchOptions, driver: &[Peer], peers: &[String]) -> Vec<crate::rows::Cell> {
    let sizes = o.sizes;
    let sets: Vec<RaySet> = <RaySet as crate::named::Named>::ALL
        .iter()
        .copied()
        .filter(|&set| o.rays_dir.is_some() || !sizes.why_empty(set).starts_with("--"))
        .collect();
    let mut cells = vec![];
    for scene in &o.scenes {
        let name = crate::scene::scene_name(scene);
        for set in &sets {
            for (m, l, t, a) in o.kernels() {
                for node_order in o.node_orders() {
                    for &order in &o.orders() {
                        let tracer = CellTracer::Method {
                            method: m,
                            layout: l,
                            leaf: o.build.max_leaf_size,
                            sah_group: Some(o.build.sah_group),
                            traversal: t,
                            node_order,
                            order,
                            access: path_of(a),
                        };
                        cells.push(BenchCell { scene: name.clone(), set: *set, rays: None, tracer }.coordinates());
                    }
                }
            }
            let peers = driver.iter().map(Peer::to_string).chain(peers.iter().cloned());
            for peer in peers {
                let tracer = CellTracer::Peer(peer);
                cells.push(BenchCell { scene: name.clone(), set: *set, rays: None, tracer }.coordinates());
            }
        }
    }
    cells
}

impl BenchOptions {
    /// The matrix as its shards split it: a shard takes whole scenes.
    pub fn split(&self) -> Split {
        Split::new(self.shard, self.scenes.len(), 1)
    }

    /// Refuses more shards than scenes, naming `--shard`, before any work.
    pub fn check_shard(&self) -> Result<()> {
        self.split().check(&format!(
            "a bench shard takes whole scenes (each scene's methods, layouts and peers interleaved in one run) and \
             this run has {} scene(s)",
            self.scenes.len()
        ))
    }

    /// Every (method, layout, traversal, access) timed: the options' combinations that have a
    /// closest-hit kernel (`auto` is checked as the texel path, which it takes wherever a scene
    /// fits one binding; a traversal's support does not depend on the method:
    /// `encoding::variants`' test holds it).
    pub fn kernels(&self) -> Vec<(Method, Layout, Traversal, SceneAccess)> {
        let mut out = vec![];
        for &m in &self.methods {
            for (l, t, a) in self.combinations() {
                if m.traversal_kernel(Raycast::Closest, path_of(a), l, t).is_ok() {
                    out.push((m, l, t, a));
                }
            }
        }
        out
    }

    /// Every layout x traversal x access asked for, defaults where a list is empty.
    fn combinations(&self) -> Vec<(Layout, Traversal, SceneAccess)> {
        let (traversals, access) = (or_default(&self.traversals), or_default(&self.scene_access));
        let mut out = vec![];
        for l in or_default(&self.layouts) {
            for &t in &traversals {
                for &a in &access {
                    out.push((l, t, a));
                }
            }
        }
        out
    }

    /// The traversal x layout x access combinations asked for that have no kernel, one note each.
    pub fn kernel_notes(&self) -> Vec<String> {
        let Some(&m) = self.methods.first() else { return vec![] };
        self.combinations()
            .into_iter()
            .filter(|&(l, t, a)| m.traversal_kernel(Raycast::Closest, path_of(a), l, t).is_err())
            .map(|(l, t, a)| {
                format!(
                    "{t} traversal on {l} ({} path): not run, no kernel ({t} has: {})",
                    path_of(a).name(),
                    crate::encoding::traversal_support(t)
                )
            })
            .collect()
    }

    /// The node orders, the built one alone when none was asked for.
    pub fn node_orders(&self) -> Vec<NodeOrder> {
        or_default(&self.node_orders)
    }

    /// The ray orders, the default alone when none was asked for.
    pub fn orders(&self) -> Vec<RayOrder> {
        or_default(&self.orders)
    }

    /// Whether the options ask for the driver peer `peer` (`--ray-query`,
    /// `--ray-tracing-pipeline`).
    pub fn wants(&self, peer: Peer) -> bool {
        match peer {
            Peer::RayQuery => self.ray_query,
            Peer::RayTracingPipeline => self.ray_tracing_pipeline,
        }
    }
}

/// `o` with what this device cannot run left out, one note each (`gpu::Capabilities`): methods
/// whose kernels need a feature it lacks (f64 without shaderFloat64), traversals it cannot run
/// (coop without subgroup operations), access paths it lacks (address without shaderInt64). A
/// support matrix is per axis (the tests of `encoding::variants` hold that), so leaving out an
/// axis's item leaves out exactly the cells that need it. An error when an axis keeps nothing.
pub fn for_device(ctx: &Context, o: &BenchOptions, notes: &mut Vec<String>) -> Result<BenchOptions> {
    use crate::gpu::Capabilities;
    let caps = ctx.capabilities();
    let mut o = o.clone();
    o.methods = caps.keep("methods", &o.methods, Capabilities::method, notes)?;
    o.traversals = caps.keep("traversals", &or_default(&o.traversals), Capabilities::traversal, notes)?;
    o.scene_access = caps.keep(
        "scene access paths",
        &or_default(&o.scene_access),
        |c, a| match a {
            SceneAccess::Auto => Ok(()),
            a => c.access(path_of(a)),
        },
        notes,
    )?;
    Ok(o)
}

pub fn run(ctx: &Context, o: &BenchOptions, mut progress: impl FnMut(&str)) -> Result<BenchReport> {
    o.sizes.check_memory()?;
    let mut device_notes = vec![];
    let o = &for_device(ctx, o, &mut device_notes)?;
    for note in &device_notes {
        progress(note);
    }
    let mut report = BenchReport {
        provenance: Provenance::of(ctx),
        leaf_size: o.build.max_leaf_size,
        repeat: o.repeat,
        rows: vec![],
        peers: vec![],
        accel: vec![],
        driver_notes: vec![],
        notes: device_notes,
        shard: o.shard,
        plan: vec![],
    };
    o.check_shard()?;
    let tmp = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
    // The peers first: a missing program, a garbage line or no OpenCL is found before any work.
    if let Some(p) = &o.embree {
        peers::check_program("--embree", p)?;
    }
    if let Some(p) = &o.tinybvh {
        peers::check_program("--tinybvh", p)?;
    }
    let programs = peers::programs(o.embree.as_deref(), o.tinybvh.as_deref(), &o.tinybvh_layouts);
    if !programs.is_empty() {
        progress(&format!("checking {} peer(s) on a small scene", programs.len()));
    }
    let mut peer_notes = vec![];
    let programs = peers::probe(&programs, tmp.path(), &mut peer_notes)?;
    for note in peer_notes {
        progress(&note);
        report.notes.push(note);
    }
    // The driver's peers: each traced where asked for and the device has it, else a note.
    let mut driver: Vec<PeerTracer> = vec![];
    for &peer in <Peer as crate::named::Named>::ALL {
        let note = if !o.wants(peer) {
            format!("{}: not run (--{peer} off, or auto on a CPU device)", peer.feature())
        } else if let Err(u) = ctx.capabilities().peer(peer) {
            let note = u.to_string();
            progress(&note);
            note
        } else {
            driver.push(PeerTracer::new(ctx, peer, false)?);
            continue;
        };
        report.driver_notes.push(note);
    }
    let peer_names: Vec<String> = programs.iter().map(|p| p.kind.to_string()).collect();
    let driver_peers: Vec<Peer> = driver.iter().map(PeerTracer::peer).collect();
    report.plan = plan_cells(o, &driver_peers, &peer_names);
    for note in o.kernel_notes() {
        progress(&note);
        report.notes.push(note);
    }
    for (scene_index, scene_path) in o.scenes.iter().enumerate() {
        if !o.split().runs(scene_index, 0) {
            continue;
        }
        let name = crate::scene::scene_name(scene_path);
        let mesh = load_obj(scene_path)?;
        // The peers read the scene as we loaded it (same triangles, same ids, any scene spec).
        let scene_obj = tmp.path().join(format!("scene{scene_index}.obj"));
        if !programs.is_empty() {
            peers::write_obj(&mesh, &scene_obj)?;
        }
        progress(&format!("{name}: {} triangles; making ray sets", mesh.triangle_count()));
        let t = Instant::now();
        let host = HostScene::build(&name, &mesh, &o.build)?;
        let reference = host.reference();
        let mut sets = ray_sets(&mesh, &name, &reference, &o.sizes, o.rays_dir.as_deref())?;
        // An empty set has no speed: it is skipped with a note, and the other sets still run.
        sets.retain(|(set, rays)| {
            if rays.is_empty() {
                let note = format!("{name} {set}: skipped, no rays ({})", o.sizes.why_empty(*set));
                progress(&note);
                report.notes.push(note);
            }
            !rays.is_empty()
        });
        progress(&format!("{name}: ray sets ready in {:.1} s", t.elapsed().as_secs_f64()));
        // Each method's plan picks its access path before encoding (and fails clearly if the
        // scene cannot fit); its kernels read the scene through that path. Each node order is
        // one more scene of every kernel.
        // A kernel the device cannot run on this scene (a traversal without a kernel on the path
        // the scene needs here) is left out with its reason; the others run.
        let mut scenes: Vec<DeviceScene> = vec![];
        let requests = o.kernels().into_iter().flat_map(|(m, l, t, a)| {
            o.node_orders()
                .into_iter()
                .map(move |n| SceneRequest::new(m).access(a).layout(l).traversal(t).node_order(n))
        });
        for req in requests {
            match host.upload(ctx, &req) {
                Ok(s) => scenes.push(s),
                Err(Error::Unsupported(why)) => {
                    let note = format!("{name}: {why}; left out");
                    if !report.notes.contains(&note) {
                        progress(&note);
                        report.notes.push(note);
                    }
                }
                Err(e) => return Err(e),
            }
        }
        if scenes.is_empty() {
            return Err(Error::Unsupported(format!(
                "{name}: none of the kernels asked for can run on this scene here: {}",
                report.notes.join("; ")
            )));
        }
        let accel = match driver.is_empty() {
            false => {
                let a = AccelStructure::build(ctx, &mesh)?;
                progress(&accel_line(&name, &a.stats));
                report.accel.push((name.clone(), a.stats));
                Some(a)
            }
            true => None,
        };
        let kernels = scenes.iter().map(|s| s.kernel(ctx, Raycast::Closest)).collect::<Result<Vec<_>>>()?;
        // The roofline at every scene's bytes on its access path, before any timing.
        let roofline = match &o.roofline {
            Some(ro) => Some(efficiency::scene_roofline(ctx, &scenes, ro, &mut progress)?),
            None => None,
        };
        // Every set's reference before any timing: the f64 traversal fills every core (and
        // rayon's threads linger), which would slow whichever kernel ran next.
        let ref_hits: Vec<Vec<RefHit>> = sets.iter().map(|(_, rays)| reference.trace_all(rays, false)).collect();
        for ((set, rays), ref_hits) in sets.iter().zip(&ref_hits) {
            let set = *set;
            let mut best: f64 = 0.0;
            let label = |scene: &DeviceScene, order: RayOrder| {
                let (m, l, t, n) = (scene.method, Some(scene.layout), scene.traversal, scene.node_order);
                kernel_label(m, l, t, n, order, scene.access)
            };
            let jobs: Vec<Job> = scenes
                .iter()
                .zip(&kernels)
                .flat_map(|(scene, kernel)| o.orders().into_iter().map(move |order| (scene, kernel, order)))
                .map(|(scene, kernel, order)| Job { scene, kernel, rays, ref_hits, order })
                .collect();
            // The peer programs run in the same rounds, each once a round beside every kernel.
            let rays_file = tmp.path().join(format!("scene{scene_index}.{set}.rays"));
            if !programs.is_empty() {
                rays::write_rays(&rays_file, rays)?;
            }
            let peer_set = PeerSet { scene_obj: &scene_obj, rays_file: &rays_file, mesh: &mesh, rays, ref_hits };
            let mut peer_rounds: Vec<PeerRound> = (programs.iter().enumerate())
                .map(|(k, p)| PeerRound::new(p, &peer_set, tmp.path().join(format!("peer{k}.hits"))))
                .collect();
            let mut others: Vec<&mut dyn RoundJob> = peer_rounds.iter_mut().map(|p| p as &mut dyn RoundJob).collect();
            let measured = interleaved_with(ctx, &mesh, &jobs, &mut others, o.warmup, o.repeat, o.batch_rays).map_err(
                |(i, e)| match jobs.get(i) {
                    Some(j) => Error::Usage(format!("{name} {set} {}: {e}", label(j.scene, j.order))),
                    None => Error::Usage(format!("{name} {set}: {e}")),
                },
            )?;
            drop(others);
            let results: Vec<PeerResult> = peer_rounds.into_iter().map(PeerRound::finish).collect();
            // Each kernel's traversal counts on this set, cast once however many ray orders it ran
            // in and whatever its nodes' order (the walk does not depend on either:
            // tests/node_orders_gpu.rs), on the first scene of that kernel.
            let mut counts: Vec<Option<Option<Vec<crate::gpu::TraversalCounts>>>> = vec![None; scenes.len()];
            // The order each ray order dispatched the rays in, sorted once for every kernel's
            // lanes busy (which rays share a subgroup).
            let orders = o.orders();
            let mut dispatched: Vec<Option<Option<Vec<u32>>>> = vec![None; orders.len()];
            for (job, m) in jobs.iter().zip(measured) {
                let (scene, order) = (job.scene, job.order);
                let (ms, agreement) = (m.kernel_ms, m.agreement);
                let mr = mrays_summary(rays.len(), ms);
                progress(&format!(
                    "{name} {set} {}: {:.2} Mrays/s ({:.1} ms), {}",
                    label(scene, order),
                    mr.median,
                    ms.median,
                    agreement.summary()
                ));
                best = best.max(mr.median);
                let tracer = Tracer::Method(scene.method);
                let bytes = (scene.bytes, Some(scene.access));
                let mut r = row(&name, &mesh, set, rays, tracer, Some(o), bytes, ms, &agreement);
                r.layout = Some(scene.layout);
                r.traversal = Some(scene.traversal);
                r.node_order = Some(scene.node_order);
                r.order = Some(order);
                r.reorder_ms = (order != RayOrder::Given).then_some(m.reorder_ms);
                if let Some(roof) = &roofline {
                    let kernel = |s: &DeviceScene| (s.method, s.layout, s.traversal, s.access);
                    let i = scenes
                        .iter()
                        .position(|s| kernel(s) == kernel(scene))
                        .expect("a job's scene is one of the scenes");
                    let c = match &counts[i] {
                        Some(c) => c,
                        None => counts[i].insert(efficiency::fetch_counts(ctx, &scenes[i], rays, o.batch_rays)?),
                    };
                    // The lanes a subgroup's rays keep busy depend on which rays share it: the
                    // order the kernel got them in (the sort is deterministic).
                    let k = orders.iter().position(|&x| x == order).expect("a job's order is one of the orders");
                    let d = dispatched[k].get_or_insert_with(|| order.permutation(rays));
                    let lanes = ctx.info().subgroup_size;
                    r.roofline =
                        c.as_deref().and_then(|c| efficiency::efficiency(scene, roof, mr, c, lanes, d.as_deref()));
                }
                report.rows.push(r);
            }
            // Every driver peer over the scene's one structure (built whenever there is a peer).
            for (tracer, accel) in driver.iter().filter_map(|t| Some((t, accel.as_ref()?))) {
                // The driver's answer may differ on edge rays: report the agreement, refuse only
                // impossible values (NaN, ids out of range, t outside the interval).
                let peer = tracer.peer();
                let batch = tracer.batch_for(ctx, accel, rays, PEER_SUBMIT_MS, o.batch_rays)?;
                let opts = RaycastOptions { warmup: o.warmup, repeat: o.repeat, batch_rays: batch };
                let res = tracer.cast(ctx, accel, rays, &opts)?;
                let agreement = compare_closest(&mesh, rays, &res.hits, ref_hits);
                let ms = res.time_ms()?;
                progress(&format!(
                    "{name} {set} {peer}: {} Mrays/s ({:.1} ms, {} rays per submit), {}",
                    rate(crate::harness::validate::mrays_per_s(rays.len(), ms.median)),
                    ms.median,
                    batch,
                    agreement.summary()
                ));
                if !agreement.invalid.is_empty() {
                    return Err(Error::Usage(format!(
                        "{name} {set} {peer}: {} invalid results, e.g. ray {}: {}; not reporting a speed",
                        agreement.invalid.len(),
                        agreement.invalid[0].0,
                        agreement.invalid[0].1
                    )));
                }
                let bytes = (accel.stats.blas_bytes + accel.stats.tlas_bytes) as usize;
                report.rows.push(row(&name, &mesh, set, rays, Tracer::Peer(peer), None, (bytes, None), ms, &agreement));
            }
            if !programs.is_empty() {
                for r in &results {
                    progress(&format!("{name} {set} {}", r.progress(best)));
                }
                if let Some(e) = results.iter().find(|r| r.peer == PeerKind::Embree).and_then(|r| r.mrays_per_s()) {
                    for r in report.rows.iter_mut().filter(|r| r.scene == name && r.ray_set == set) {
                        r.embree_mrays_per_s = Some(e);
                    }
                }
                let mine = report.rows.iter().filter(|r| r.scene == name && r.ray_set == set);
                let best = TrilabBest::fastest(mine.filter_map(|r| match r.method {
                    Tracer::Method(m) => Some((r.label(m), r.layout, r.mrays_per_s)),
                    Tracer::Peer(_) => None, // the driver's ray tracing is not ours
                }));
                report.peers.push(PeerComparison::new(&name, set, rays.len(), best, results));
            }
        }
    }
    Ok(report)
}

/// The progress line of the driver's acceleration structure.
fn accel_line(name: &str, s: &AccelStats) -> String {
    format!(
        "{name}: driver BLAS {} B + TLAS {} B, built in {}",
        s.blas_bytes,
        s.tlas_bytes,
        s.blas_build_ms
            .zip(s.tlas_build_ms)
            .map_or_else(|| format!("{:.1} ms (wall)", s.wall_ms), |(b, t)| format!("{b:.2} + {t:.2} ms (GPU)"))
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bench_cell_plans_and_rows_with_the_same_coordinates() {
        let method = |sah_group, traversal, order| CellTracer::Method {
            method: Method::Mt,
            layout: Layout::Bvh4,
            leaf: 4,
            sah_group: Some(sah_group),
            traversal,
            node_order: NodeOrder::Built,
            order,
            access: AccessPath::Texel,
        };
        let tracer = method(1, Traversal::WhileIf, RayOrder::Given);
        let planned = BenchCell { scene: "bunny".into(), set: RaySet::Diffuse, rays: None, tracer };
        let measured = BenchCell { rays: Some(9794), ..planned.clone() };
        let want = [("layout", "bvh4"), ("leaf", "4"), ("method", "mt"), ("scene", "bunny"), ("set", "diffuse")];
        let plan = planned.coordinates();
        assert_eq!(plan.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect::<Vec<_>>(), want);
        // The row adds only what is measured, so the plan finds it.
        let row = measured.coordinates();
        assert_eq!(row.get("rays").map(String::as_str), Some("9794"));
        assert!(crate::rows::plan_matches(&plan, &row));
        // A SAH group of 1 is the default and unnamed; another is a coordinate of both.
        let grouped = method(4, Traversal::WhileIf, RayOrder::Given);
        let g = BenchCell { tracer: grouped, ..planned.clone() }.coordinates();
        assert_eq!(g.get("sah_group").map(String::as_str), Some("4"));
        assert!(!crate::rows::plan_matches(&g, &row));
        // So are a traversal other than while-if and a ray order other than the given one.
        let ww =
            BenchCell { tracer: method(1, Traversal::WhileWhile, RayOrder::Given), ..planned.clone() }.coordinates();
        assert_eq!(ww.get("traversal").map(String::as_str), Some("while-while"));
        assert!(!crate::rows::plan_matches(&ww, &row) && !ww.contains_key("order"));
        let sorted = BenchCell { tracer: method(1, Traversal::WhileIf, RayOrder::OctantOrigin), ..planned.clone() }
            .coordinates();
        assert_eq!(sorted.get("order").map(String::as_str), Some("octant-origin"));
        assert!(!crate::rows::plan_matches(&sorted, &row) && !sorted.contains_key("traversal"));
        // And a node order other than the built one.
        let treelets = CellTracer::Method {
            method: Method::Mt,
            layout: Layout::Bvh4,
            leaf: 4,
            sah_group: Some(1),
            traversal: Traversal::WhileIf,
            node_order: NodeOrder::Treelets,
            order: RayOrder::Given,
            access: AccessPath::Texel,
        };
        let t = BenchCell { tracer: treelets, ..planned.clone() }.coordinates();
        assert_eq!(t.get("node_order").map(String::as_str), Some("treelets"));
        assert!(!crate::rows::plan_matches(&t, &row) && !row.contains_key("node_order"));
        let address = CellTracer::Method {
            method: Method::Mt,
            layout: Layout::Bvh4,
            leaf: 4,
            sah_group: Some(1),
            traversal: Traversal::WhileIf,
            node_order: NodeOrder::Built,
            order: RayOrder::Given,
            access: AccessPath::Address,
        };
        let a = BenchCell { tracer: address, ..planned.clone() }.coordinates();
        assert_eq!(a.get("access").map(String::as_str), Some("address"));
        assert!(!crate::rows::plan_matches(&a, &row) && !row.contains_key("access"));
        let peer = BenchCell { tracer: CellTracer::Peer("embree".into()), ..planned }.coordinates();
        assert_eq!(peer.get("peer").map(String::as_str), Some("embree"));
        assert!(!peer.contains_key("method") && !peer.contains_key("leaf"));
    }

    /// A report as `run` would make it: two kernel rows, the two driver peers, an Embree peer.
    fn report() -> BenchReport {
        let provenance = Provenance {
            device: "llvmpipe (LLVM 15.0.7, 256 bits)".into(),
            driver: "Mesa 25.0.7".into(),
            mesa_version: Some("25.0.7".into()),
            commit: "abc123".into(),
            date: "2025-01-01T00:00:00Z".into(),
            host: crate::host::Host { cpu_model: "test CPU".into(), cpus: 2, ..Default::default() },
            lp_num_threads: None,
            timed_on_gpu: true,
            settings: [("subgroup_size".to_owned(), "8".to_owned())].into(),
            scenes: vec![],
            spirv_compiler: "test compiler",
            driver_package: None,
        };
        let row = |method: Tracer, layout: Option<Layout>, ms: Summary, agreement: f64| {
            let mr = crate::harness::validate::mrays_summary(48_000, ms);
            BenchRow {
                scene: "bunny".into(),
                triangles: 69_451,
                ray_set: RaySet::Diffuse,
                rays: 48_000,
                method,
                leaf_size: layout.map(|_| 4),
                sah_group: layout.map(|_| 1),
                scene_bytes: 3_000_000 + (ms.median * 1000.0) as usize,
                scene_access: layout.map(|_| AccessPath::Texel),
                layout,
                traversal: layout.map(|_| Traversal::WhileIf),
                order: layout.map(|_| RayOrder::Given),
                node_order: layout.map(|_| NodeOrder::Built),
                reorder_ms: None,
                kernel_ms: ms,
                mrays_per_s: mr.median,
                mrays_per_s_min: mr.min,
                mrays_per_s_max: mr.max,
                agreement,
                unexplained_disagreements: 3,
                invalid: 0,
                embree_mrays_per_s: None,
                roofline: None,
            }
        };
        let s = |median: f64, min: f64, max: f64| Summary { median, min, max, runs: 5 };
        let rows = vec![
            row(Tracer::Method(Method::Mt), Some(Layout::Bvh2), s(10.0, 9.0, 12.0), 0.9999),
            row(Tracer::Method(Method::Mt), Some(Layout::Bvh4), s(7.0, 6.5, 7.5), 0.9998),
            row(Tracer::Peer(Peer::RayQuery), None, s(900.0, 880.0, 950.0), 0.9990),
            row(Tracer::Peer(Peer::RayTracingPipeline), None, s(800.0, 790.0, 850.0), 0.9990),
        ];
        let embree = crate::harness::peers::PeerResult {
            peer: PeerKind::Embree,
            outcome: PeerOutcome::Timed {
                mrays_per_s: 21.5,
                mrays_per_s_min: 20.0,
                mrays_per_s_max: 22.0,
                trace_ms: Summary { median: 48_000.0 / 21.5e3, min: 48_000.0 / 22e3, max: 48_000.0 / 20e3, runs: 5 },
                build_ms: None,
                threads: Some(2),
                agreement: 0.99995,
            },
        };
        let best = TrilabBest::fastest([("mt".to_owned(), Some(Layout::Bvh4), rows[1].mrays_per_s)]);
        let peers = vec![PeerComparison::new("bunny", RaySet::Diffuse, 48_000, best, vec![embree])];
        BenchReport {
            provenance,
            leaf_size: 4,
            repeat: 5,
            rows,
            peers,
            accel: vec![],
            driver_notes: vec![],
            notes: vec![],
            shard: None,
            plan: vec![],
        }
    }

    #[test]
    fn every_row_fills_one_planned_cell_peers_included() {
        let o = BenchOptions {
            scenes: vec![PathBuf::from("bunny")],
            methods: vec![Method::Mt],
            layouts: vec![Layout::Bvh2, Layout::Bvh4],
            ..BenchOptions::default()
        };
        let plan = plan_cells(&o, &[Peer::RayQuery, Peer::RayTracingPipeline], &[PeerKind::Embree.to_string()]);
        // 3 sets x (2 layouts + the two driver rows + Embree).
        assert_eq!(plan.len(), 3 * 5);
        let rows = rows(&report());
        assert_eq!(rows.len(), 5);
        let mut filled = vec![];
        for r in &rows {
            let fits: Vec<&crate::rows::Cell> = plan.iter().filter(|c| crate::rows::plan_matches(c, &r.cell)).collect();
            assert_eq!(fits.len(), 1, "{} fills {fits:?}", r.key());
            filled.push(fits[0].clone());
        }
        filled.dedup();
        assert_eq!(filled.len(), 5, "each row its own planned cell");
        assert!(filled.iter().all(|c| c["set"] == "diffuse"));
        // Without the ray query and peers, and with an empty random set, they are not planned.
        let o = BenchOptions { sizes: RaySetSizes { random_rays: 0, ..o.sizes }, ..o };
        let plan = plan_cells(&o, &[], &[]);
        assert_eq!(plan.len(), 2 * 2);
        assert!(plan.iter().all(|c| c.contains_key("method") && c["set"] != "random"));
    }

    #[test]
    fn a_bench_shard_takes_whole_scenes_and_no_more_shards_than_scenes() {
        let shard = |s: &str| Some(s.parse::<Shard>().unwrap());
        let o = BenchOptions {
            scenes: ["a", "b", "c"].map(PathBuf::from).to_vec(),
            shard: shard("2/2"),
            ..Default::default()
        };
        assert!(o.check_shard().is_ok());
        assert_eq!((0..3).map(|i| o.split().runs(i, 0)).collect::<Vec<_>>(), [false, true, false]);
        let e = BenchOptions { shard: shard("4/4"), ..o }.check_shard().unwrap_err().to_string();
        assert!(e.contains("--shard 4/4") && e.contains("3 scene(s)"), "{e}");
    }

    #[test]
    fn rows_carry_every_table_row_and_peer_with_its_figures() {
        let report = report();
        let rows = rows(&report);
        // The report as bench.json has it: the independent path to each figure.
        let json = serde_json::to_value(&report).unwrap();
        let table = json["rows"].as_array().unwrap();
        assert_eq!(rows.len(), table.len() + 1, "every table row and the Embree peer");
        for t in table {
            let row = rows
                .iter()
                .find(|r| {
                    let method = t["method"].as_str().unwrap();
                    r.cell.get("method").or(r.cell.get("peer")).map(String::as_str) == Some(method)
                        && r.cell.get("layout").map(String::as_str) == t["layout"].as_str()
                })
                .unwrap_or_else(|| panic!("no row for {t}"));
            assert_eq!(row.command, "bench");
            assert_eq!(row.cell["scene"], t["scene"].as_str().unwrap());
            assert_eq!(row.cell["set"], t["ray_set"].as_str().unwrap());
            assert_eq!(row.cell["rays"], t["rays"].to_string());
            let f = &row.figures["mrays_per_s"];
            assert_eq!(f.class, crate::rows::Class::Timing);
            assert_eq!(
                (f.median, f.min, f.max),
                (
                    t["mrays_per_s"].as_f64().unwrap(),
                    t["mrays_per_s_min"].as_f64().unwrap(),
                    t["mrays_per_s_max"].as_f64().unwrap()
                )
            );
            assert!(f.min < f.median && f.median < f.max, "a spread from the rounds");
            assert_eq!(f.runs as u64, t["kernel_ms"]["runs"].as_u64().unwrap());
            assert_eq!(row.figures["agreement"].median, t["agreement"].as_f64().unwrap());
            assert_eq!(row.figures["agreement"].class, crate::rows::Class::Correctness);
            assert_eq!(row.figures["unexplained"].median, t["unexplained_disagreements"].as_f64().unwrap());
            assert_eq!(row.figures["scene_bytes"].median, t["scene_bytes"].as_f64().unwrap());
            assert_eq!(row.figures["scene_bytes"].class, crate::rows::Class::Count);
            assert_eq!(row.source.device, json["device"].as_str().unwrap());
            assert_eq!(row.source.settings["subgroup_size"], "8");
        }
        let peer = &json["peers"][0]["peers"][0];
        let e = rows.iter().find(|r| r.cell.get("peer").map(String::as_str) == peer["peer"].as_str()).unwrap();
        assert_eq!(e.figures["mrays_per_s"].median, peer["mrays_per_s"].as_f64().unwrap());
        let f = &e.figures["mrays_per_s"];
        assert_eq!((f.min, f.max, f.runs), (20.0, 22.0, 5), "a peer's rounds, as trilab's rows have them");
        assert_eq!(e.figures["agreement"].median, peer["agreement"].as_f64().unwrap());
        // The rows survive their file format, and the cells are unique.
        let text = crate::rows::to_jsonl(None, &rows);
        let back = crate::rows::parse(Path::new("rows.jsonl"), &text).unwrap();
        assert_eq!(back.rows, rows);
        let keys: std::collections::BTreeSet<String> = rows.iter().map(|r| r.key()).collect();
        assert_eq!(keys.len(), rows.len());
    }

    /// The node order column only where a row's nodes are not in the built order; the JSON
    /// names a row's node order only then too.
    #[test]
    fn the_node_order_column_appears_only_when_an_order_is_not_the_built_one() {
        let mut r = report();
        let before = r.table().to_text();
        assert!(!before.contains("node order"));
        assert!(serde_json::to_value(&r).unwrap()["rows"][0].get("node_order").is_none());
        r.rows[1].node_order = Some(NodeOrder::Treelets);
        let text = r.table().to_text();
        assert!(text.contains("node order") && text.contains("treelets"), "{text}");
        assert_eq!(serde_json::to_value(&r).unwrap()["rows"][1]["node_order"], "treelets");
        assert!(r.rows[1].label(Method::Mt).contains("treelets"));
    }

    #[test]
    fn rates_keep_three_significant_digits_below_one() {
        assert_eq!(super::rate(3.667), "3.67");
        assert_eq!(super::rate(0.25), "0.250");
        assert_eq!(super::rate(0.002688), "0.00269");
    }
}
