//! What a bench measures: its options (scenes, methods, layouts, traversals, access paths, node
//! and ray orders, sizes, peers) with their defaults, the kernels they expand to, and the plan of
//! cells a run fills.

use std::path::PathBuf;

use crate::bvh::{BuildOptions, NodeOrder};
use crate::encoding::{AccessPath, Layout, Method, Traversal};
use crate::error::Result;
use crate::gpu::Peer;
use crate::matrix::{Experiment, KernelAxes};
use crate::rays::order::RayOrder;
use crate::services::peers::{EmbreeApi, TinybvhLayout};
use crate::services::rayset::{RaySet, RaySetSizes};
use crate::services::shard::{Shard, Split};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub scenes: Vec<PathBuf>,
    /// The kernel axes crossed: methods, layouts, traversals, access paths, node orders and ray
    /// orders (`matrix`: an empty axis is its default alone). Each method is timed on each
    /// layout with each traversal that has a kernel for it (a combination without one is left
    /// out with a note); several access paths, node orders and ray orders are timed side by
    /// side (a reordering's host time, the sort and putting the hits back, is part of its
    /// kernel time).
    pub axes: KernelAxes,
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
    /// Its calls, each its own peer (empty: [`EmbreeApi::DEFAULT`]); only with `embree`.
    pub embree_apis: Vec<EmbreeApi>,
    /// The tinybvh peer program (`tinybvh_rays`), run on the same ray files.
    pub tinybvh: Option<PathBuf>,
    /// Its layouts (empty: [`TinybvhLayout::DEFAULT`]).
    pub tinybvh_layouts: Vec<TinybvhLayout>,
    pub batch_rays: usize,
    /// Add the driver's ray query as a peer row where the device has it.
    pub ray_query: bool,
    /// Add the driver's ray tracing pipeline as a peer row where the device has it.
    pub ray_tracing_pipeline: bool,
    /// Run only this shard's scenes ([`BenchOptions::split`]): a scene is the unit, so its
    /// methods, layouts and peers stay interleaved side by side in one run.
    pub shard: Option<Shard>,
    /// `--roofline`: per scene, the traversal roofline (`services::roofline`, these settings; its
    /// sizes and paths are the scene's) at the scene's bytes on each access path its kernels
    /// read, and per kernel row its [`RooflineEfficiency`].
    pub roofline: Option<crate::services::roofline::RooflineOptions>,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            scenes: vec![],
            axes: KernelAxes { methods: Method::ALL.to_vec(), ..Default::default() },
            build: BuildOptions::new(crate::defaults::LEAF_SIZE),
            warmup: 1,
            repeat: crate::defaults::REPEAT,
            sizes: RaySetSizes::default(),
            rays_dir: None,
            embree: None,
            embree_apis: vec![],
            tinybvh: None,
            tinybvh_layouts: vec![],
            batch_rays: crate::defaults::BATCH_RAYS,
            ray_query: true,
            ray_tracing_pipeline: true,
            shard: None,
            roofline: None,
        }
    }
}

/// Every cell of the whole bench matrix (all shards): the matrix's cells
/// ([`BenchOptions::experiment`]) as [`BenchCell`]s, and per scene and set the peers, with the
/// coordinates [`rows`] gives them except `rays`: a set's ray count is measured, not chosen (the
/// diffuse set's depends on the primary hits), so a plan names a cell by scene, set and
/// method/layout/leaf or peer, and a row fills it when it agrees on those
/// ([`crate::rows::plan_matches`]). `driver`: the driver peers the run has (ray query, the ray
/// tracing pipeline); `peers`: the peer programs that passed their probe.
pub fn plan_cells(o: &BenchOptions, driver: &[Peer], peers: &[String]) -> Vec<crate::rows::Cell> {
    let experiment = o.experiment();
    let cells = experiment.cells();
    let peers: Vec<String> = driver.iter().map(Peer::to_string).chain(peers.iter().cloned()).collect();
    let mut out = vec![];
    // Per scene and set, the matrix's kernels, then the peers (who run where no kernel does).
    for group in experiment.groups() {
        for &set in &experiment.sets {
            let here = cells.iter().filter(|c| c.group == group && c.set == Some(set));
            out.extend(here.filter_map(|c| BenchCell::of(c, &o.build)).map(|c| c.coordinates()));
            let scene = group.scene_name().unwrap_or_default();
            for peer in &peers {
                let tracer = CellTracer::Peer(peer.clone());
                out.push(BenchCell { scene: scene.clone(), set, rays: None, tracer }.coordinates());
            }
        }
    }
    out
}

impl BenchOptions {
    /// The experiment's axes: the scenes, the one leaf size of `build`, the ray sets the sizes
    /// leave non-empty (every set where `rays_dir` gives the rays), the kernel axes.
    pub fn experiment(&self) -> Experiment {
        let sets = <RaySet as crate::named::Named>::ALL
            .iter()
            .copied()
            .filter(|&set| self.rays_dir.is_some() || !self.sizes.why_empty(set).starts_with("--"))
            .collect();
        Experiment {
            scenes: self.scenes.clone(),
            leaf_sizes: vec![self.build.max_leaf_size],
            sets,
            kernels: self.axes.clone(),
        }
    }

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

    /// Whether the options ask for the driver peer `peer` (`--ray-query`,
    /// `--ray-tracing-pipeline`).
    pub fn wants(&self, peer: Peer) -> bool {
        match peer {
            Peer::RayQuery => self.ray_query,
            Peer::RayTracingPipeline => self.ray_tracing_pipeline,
        }
    }
}

/// What a bench run made its trees and rays from, written into `bench.json` (`recipe`) so that
/// one of its cells can be made again elsewhere (`compare --repro`): the scenes are the run's
/// own list, these are the rest.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BenchRecipe {
    pub build: BuildOptions,
    pub sizes: RaySetSizes,
    /// The folder the sets were read from (`--rays-dir`), or `None`: generated from `sizes`.
    pub rays_dir: Option<PathBuf>,
}

impl BenchOptions {
    /// What this run makes its trees and rays from.
    pub fn recipe(&self) -> BenchRecipe {
        BenchRecipe { build: self.build, sizes: self.sizes, rays_dir: self.rays_dir.clone() }
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
    /// A matrix cell of a bench built with `build`; none for a cell without a ray set (a bench
    /// measures per set). `auto` names no path in the plan (coordinates never name texel): the
    /// row names the one the scene took.
    pub fn of(c: &crate::matrix::Cell, build: &BuildOptions) -> Option<BenchCell> {
        let set = c.set?;
        let k = c.kernel;
        let tracer = CellTracer::Method {
            method: k.method,
            layout: k.layout,
            leaf: c.group.leaf,
            sah_group: Some(build.sah_group),
            traversal: k.traversal,
            node_order: k.node_order,
            order: c.order,
            access: k.planned_path().unwrap_or(AccessPath::Texel),
        };
        Some(BenchCell { scene: c.group.scene_name().unwrap_or_default(), set, rays: None, tracer })
    }

    /// The cell whose [`coordinates`](BenchCell::coordinates) are `c`, or what in them no bench
    /// cell has (an unknown coordinate, a value that does not parse).
    pub fn parse(c: &crate::rows::Cell) -> std::result::Result<BenchCell, String> {
        use std::str::FromStr;
        let get = |k: &str| c.get(k).ok_or_else(|| format!("no `{k}`"));
        fn value<T: FromStr>(k: &str, v: &str) -> std::result::Result<T, String> {
            v.parse().map_err(|_| format!("`{k}={v}` does not parse"))
        }
        let known = [
            "scene",
            "set",
            "rays",
            "method",
            "layout",
            "leaf",
            "sah_group",
            "traversal",
            "node_order",
            "order",
            "access",
            "peer",
        ];
        if let Some(k) = c.keys().find(|k| !known.contains(&k.as_str())) {
            return Err(format!("`{k}` is no bench coordinate"));
        }
        let set = get("set")?;
        let set = set.parse::<RaySet>().map_err(|e| format!("`set={set}`: {e}"))?;
        let rays = c.get("rays").map(|r| value::<usize>("rays", r)).transpose()?;
        let tracer = match c.get("peer") {
            Some(p) => CellTracer::Peer(p.clone()),
            None => {
                let opt = |k: &str| c.get(k).map(String::as_str);
                let access = match opt("access") {
                    None => AccessPath::Texel,
                    Some(a) => {
                        *AccessPath::ALL.iter().find(|p| p.name() == a).ok_or(format!("`access={a}` does not parse"))?
                    }
                };
                CellTracer::Method {
                    method: get("method")?.parse().map_err(|e| format!("`method`: {e}"))?,
                    layout: get("layout")?.parse().map_err(|e| format!("`layout`: {e}"))?,
                    leaf: value("leaf", get("leaf")?)?,
                    sah_group: opt("sah_group").map(|g| value("sah_group", g)).transpose()?,
                    traversal: opt("traversal").map_or(Ok(Traversal::default()), |t| value("traversal", t))?,
                    node_order: opt("node_order").map_or(Ok(NodeOrder::default()), |n| value("node_order", n))?,
                    order: opt("order").map_or(Ok(RayOrder::default()), |o| value("order", o))?,
                    access,
                }
            }
        };
        Ok(BenchCell { scene: get("scene")?.clone(), set, rays, tracer })
    }

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
