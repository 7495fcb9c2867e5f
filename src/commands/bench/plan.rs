//! What a bench measures: its options (scenes, methods, layouts, traversals, access paths, node
//! and ray orders, sizes, peers) with their defaults, the kernels they expand to, and the plan of
//! cells a run fills.

use std::path::PathBuf;

use crate::bvh::{BuildOptions, NodeOrder};
use crate::encoding::{AccessPath, Layout, Method, Raycast, SceneAccess, Traversal};
use crate::error::Result;
use crate::gpu::Peer;
use crate::rays::order::RayOrder;
use crate::services::peers::TinybvhLayout;
use crate::services::rayset::{RaySet, RaySetSizes};
use crate::services::shard::{Shard, Split};

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
    /// `--roofline`: per scene, the traversal roofline (`services::roofline`, these settings; its
    /// sizes and paths are the scene's) at the scene's bytes on each access path its kernels
    /// read, and per kernel row its [`RooflineEfficiency`].
    pub roofline: Option<crate::services::roofline::RooflineOptions>,
}

/// A list option's values, or its default alone when the list is empty (every axis of a bench
/// run: layout, traversal, access, node order and ray order default to the one the kernels had
/// before the axis existed).
pub(super) fn or_default<T: Clone + Default>(v: &[T]) -> Vec<T> {
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
