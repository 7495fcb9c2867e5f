//! `trilab build-bench`: BVH build speed (Mtris/s) and tree quality (SAH cost, nodes, depth)
//! per scene and thread count, for the parallel binned SAH, the serial loop it must equal, the
//! full sweep (SAH reference, small scenes), and optionally Embree 3's builder run by the
//! benchmark-only peer `benches/peers/embree_build.cpp` on the same triangles.
//!
//! Every tree is priced by [`Bvh::sah_cost`] with the same options (C_trav = 1, C_isect = 1, a
//! leaf of n triangles costs ceil(n / sah_group)), Embree's included: the peer writes the tree
//! it built in trilab's node layout, and it is validated ([`Bvh::validate`]: every triangle in
//! exactly one leaf, boxes containing their triangles and children, depth and leaf-size
//! bounds) before any of its numbers is reported.
//!
//! Beside the builds, each node layout's conversion (`--layouts`, default all of
//! [`Layout::ALL`]): the time to make its node buffer from the binary tree
//! ([`Layout::nodes`], median of the repeats after a warm-up; `bvh2` uploads the binary nodes as
//! they are and converts nothing), its nodes, bytes and bytes per triangle.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::Serialize;

use crate::bvh::{BuildOptions, Builder, Bvh, BvhNode, LeafPolicy, MAX_DEPTH};
use crate::encoding::Layout;
use crate::error::{Error, Result};
use crate::named::Named;
use crate::report::Summary;
use crate::report::Table;
use crate::scene::{load_obj, Mesh};
use crate::services::results;
use crate::services::shard::{self, Shard, Split};

#[derive(Clone, Debug, Serialize)]
pub struct BuildBenchOptions {
    /// OBJ files (`.obj`, `.obj.gz`) or `synth:<kind>:<N>` specs.
    pub scenes: Vec<PathBuf>,
    /// The tree every builder makes (each measurement sets its own builder).
    #[serde(flatten, serialize_with = "BuildOptions::serialize_fields")]
    pub build: BuildOptions,
    /// Thread counts for the parallel builder and Embree.
    pub threads: Vec<usize>,
    /// Timed runs per measurement, after one untimed warm-up.
    pub repeat: usize,
    /// Time the single-threaded reference loop too.
    pub serial: bool,
    /// Build the full-sweep SAH tree (at the largest thread count, once) on scenes with at
    /// most this many triangles.
    pub sweep_max_triangles: usize,
    /// The `embree_build` peer.
    pub embree: Option<PathBuf>,
    /// Node layouts whose node buffer is made from the binary tree and timed.
    pub layouts: Vec<Layout>,
    /// Run only this shard's scenes ([`BuildBenchOptions::split`]).
    pub shard: Option<Shard>,
}

impl Default for BuildBenchOptions {
    fn default() -> Self {
        BuildBenchOptions {
            scenes: vec![],
            build: BuildOptions::new(crate::defaults::LEAF_SIZE),
            threads: vec![std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)],
            repeat: crate::defaults::REPEAT,
            serial: true,
            sweep_max_triangles: 300_000,
            embree: None,
            layouts: Layout::ALL.to_vec(),
            shard: None,
        }
    }
}

/// One measured builder on one scene at one thread count.
#[derive(Clone, Debug, Serialize)]
pub struct BuildRow {
    pub scene: String,
    /// Triangles in the mesh (degenerate ones included: they are read and tested too).
    pub triangles: usize,
    /// `trilab-binned`, `trilab-serial`, `trilab-sweep`, `embree-build` (rtcBuildBVH) or
    /// `embree-commit` (rtcCommitScene, a reference time without a tree).
    pub builder: String,
    pub threads: usize,
    pub seconds: Summary,
    /// Triangles per second / 10^6 at the median time.
    pub mtris_per_s: f64,
    /// SAH cost of the tree with the benchmark's costs; `None` without a tree.
    pub sah_cost: Option<f64>,
    pub nodes: Option<usize>,
    pub leaves: Option<usize>,
    pub depth: Option<u32>,
}

/// Where and from what the figures came.
#[derive(Clone, Debug, Serialize)]
pub struct Provenance {
    pub cpu_model: String,
    /// Logical CPUs available to the process.
    pub cores: usize,
    pub commit: String,
    pub date: String,
    pub embree_version: Option<String>,
}

impl Provenance {
    pub fn here(embree: bool) -> Provenance {
        Provenance {
            cpu_model: crate::host::cpu_model(),
            cores: crate::host::cpus(),
            commit: crate::services::provenance::commit(),
            date: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
            embree_version: embree.then(embree_version).flatten(),
        }
    }
}

fn embree_version() -> Option<String> {
    let out = Command::new("dpkg-query").args(["-W", "-f=${Version}", "libembree3-3"]).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_owned()).filter(|s| !s.is_empty())
}

/// One layout's node buffer made from one scene's binary tree (`trilab-binned`'s).
#[derive(Clone, Debug, Serialize)]
pub struct LayoutRow {
    pub scene: String,
    pub triangles: usize,
    pub layout: Layout,
    /// Seconds to make the node buffer from the binary nodes (`None` for `bvh2`: its nodes are
    /// the binary tree's, nothing is converted).
    pub convert_seconds: Option<Summary>,
    /// The binary tree's build (`trilab-binned`'s median at the last thread count listed), for
    /// scale.
    pub build_seconds: f64,
    pub nodes: usize,
    /// Bytes of the node buffer.
    pub node_bytes: usize,
    pub node_bytes_per_triangle: f64,
    /// The tree's SAH cost as this layout prices it (node cost per node visited).
    pub sah_cost: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct BuildBenchReport {
    pub options: BuildBenchOptions,
    pub provenance: Provenance,
    pub rows: Vec<BuildRow>,
    /// Each layout's node buffer per scene.
    pub layouts: Vec<LayoutRow>,
    /// Every cell of the whole matrix (all shards; [`plan_cells`]), written as the rows' plan.
    #[serde(skip)]
    pub plan: Vec<crate::rows::Cell>,
}

impl BuildBenchOptions {
    fn build_options(&self, builder: Builder) -> BuildOptions {
        BuildOptions { builder, ..self.build }
    }

    /// Refuses what the benchmark cannot run, naming the option, before any work.
    pub fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Usage(m));
        if self.scenes.is_empty() {
            return bad("--scenes: name at least one scene".into());
        }
        self.split().check(&format!(
            "a build-bench shard takes whole scenes and this run has {} scene(s)",
            self.scenes.len()
        ))?;
        self.build.check()?;
        if self.threads.is_empty() {
            return bad("--threads: name at least one thread count".into());
        }
        check_threads(&self.threads)?;
        if self.repeat == 0 {
            return bad("--repeat must be at least 1".into());
        }
        for (i, l) in self.layouts.iter().enumerate() {
            if self.layouts[..i].contains(l) {
                return bad(format!("--layouts: {l} is named twice"));
            }
        }
        if self.embree.is_some() && !self.build.sah_group.is_power_of_two() {
            return bad(format!(
                "--sah-group {}: Embree's SAH block size must be a power of two",
                self.build.sah_group
            ));
        }
        Ok(())
    }
}

impl BuildBenchOptions {
    /// The matrix as its shards split it: a shard takes whole scenes.
    pub fn split(&self) -> Split {
        Split::new(self.shard, self.scenes.len(), 1)
    }
}

/// A build-bench cell: what the plan lists and a row measures, of one scene at the run's tree
/// shape (`leaf`, and `sah_group` when it is not 1).
#[derive(Clone, Debug, PartialEq)]
pub enum BuildCell {
    /// A builder at a thread count (`trilab-binned`, `trilab-serial`, `trilab-sweep`,
    /// `embree-build`, `embree-commit`).
    Build { scene: String, builder: String, threads: usize },
    /// A layout's node buffer converted from the binary tree.
    Convert { scene: String, layout: Layout },
}

impl BuildCell {
    /// The cell's coordinates, as `rows.jsonl` names them.
    pub fn coordinates(&self, build: &BuildOptions) -> crate::rows::Cell {
        use crate::rows::cell;
        let mut c = match self {
            BuildCell::Build { scene, builder, threads } => {
                cell([("scene", scene.clone()), ("builder", builder.clone()), ("threads", threads.to_string())])
            }
            BuildCell::Convert { scene, layout } => cell([("scene", scene.clone()), ("layout", layout.to_string())]),
        };
        c.insert("leaf".into(), build.max_leaf_size.to_string());
        if build.sah_group != 1 {
            c.insert("sah_group".into(), build.sah_group.to_string());
        }
        c
    }
}

/// Every cell of the whole matrix (all shards) with [`BuildBenchReport::rows`]'s coordinates:
/// per scene the binned build at each thread count, the serial build, the sweep (on scenes of at
/// most `--sweep-max` triangles; `triangles`: each scene's count), Embree's build and commit at
/// each thread count, and each layout's conversion.
pub fn plan_cells(o: &BuildBenchOptions, triangles: &[usize]) -> Vec<crate::rows::Cell> {
    let max_threads = o.threads.iter().max().copied().unwrap_or(1);
    let mut cells = vec![];
    // The matrix's groups: each scene at the one leaf size; a build-bench's other axes are its
    // own (builders and thread counts, and the layouts' conversions, which run no kernel).
    let groups = crate::matrix::Experiment {
        scenes: o.scenes.clone(),
        leaf_sizes: vec![o.build.max_leaf_size],
        ..Default::default()
    }
    .groups();
    for (group, &n) in groups.iter().zip(triangles) {
        let name = group.scene_name().unwrap_or_default();
        let mut builds: Vec<(&str, usize)> = o.threads.iter().map(|&t| ("trilab-binned", t)).collect();
        if o.serial {
            builds.push(("trilab-serial", 1));
        }
        if n <= o.sweep_max_triangles {
            builds.push(("trilab-sweep", max_threads));
        }
        if o.embree.is_some() {
            for &t in &o.threads {
                builds.push(("embree-build", t));
                builds.push(("embree-commit", t));
            }
        }
        for (builder, threads) in builds {
            cells.push(BuildCell::Build { scene: name.clone(), builder: builder.into(), threads });
        }
        for &layout in &o.layouts {
            cells.push(BuildCell::Convert { scene: name.clone(), layout });
        }
    }
    cells.iter().map(|c| c.coordinates(&o.build)).collect()
}

/// Threads per logical CPU that `--threads` may ask for ([`max_threads`]).
pub const THREADS_PER_CPU: usize = 4;

/// The fewest threads [`max_threads`] allows on any machine, so a thread ladder such as
/// `1,2,4,8,16` runs on a small one too.
pub const MIN_MAX_THREADS: usize = 64;

/// Most threads `--threads` may ask for here (build threads for `bvh` and `build-bench`,
/// `LP_NUM_THREADS` for `profile`): [`THREADS_PER_CPU`] per logical CPU, and at least
/// [`MIN_MAX_THREADS`]. Threads beyond the CPUs only take turns on them, and rayon's idle workers
/// spin looking for work, which slows the build itself: on 2 CPUs the bunny's full-sweep build
/// took 0.3 to 0.4 s at 2 to 256 threads, 1.0 s at 512 and 6.6 s at 1,024, and `bvh --threads 100000`
/// ran past two minutes.
pub fn max_threads() -> usize {
    let cpus = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    cpus.saturating_mul(THREADS_PER_CPU).max(MIN_MAX_THREADS)
}

/// Refuses a thread count of 0 or over [`max_threads`], naming `--threads`.
pub fn check_threads(threads: &[usize]) -> Result<()> {
    let max = max_threads();
    match threads.iter().find(|&&t| t == 0 || t > max) {
        None => Ok(()),
        Some(t) => {
            let cpus = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
            Err(Error::Usage(format!(
                "--threads {t}: thread counts must be 1..={max} here ({THREADS_PER_CPU} per logical CPU, {cpus} \
                 here, and at least {MIN_MAX_THREADS}): more threads only take turns on the CPUs and slow the \
                 work down"
            )))
        }
    }
}

/// A rayon pool of `threads` threads for a build (`--threads`: 1..=[`max_threads`]).
pub fn pool(threads: usize) -> Result<rayon::ThreadPool> {
    check_threads(&[threads])?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Usage(format!("cannot start a pool of {threads} threads: {e}")))
}

/// Warm-up plus `repeat` builds; the times are the builder's own (`build_seconds`: primitive
/// setup, build and node assembly). Returns the summary and the last tree.
fn time_builds(repeat: usize, mut build: impl FnMut() -> Bvh) -> (Summary, Bvh) {
    let mut bvh = build();
    let mut secs = Vec::with_capacity(repeat);
    for _ in 0..repeat {
        bvh = build();
        secs.push(bvh.build_seconds);
    }
    (Summary::of(&secs).expect("repeat >= 1"), bvh)
}

fn row(scene: &str, triangles: usize, builder: &str, threads: usize, s: Summary, tree: Option<&Bvh>) -> BuildRow {
    // Each tree is priced with its own options' costs: the same for every builder here.
    let stats = tree.map(Bvh::stats);
    BuildRow {
        scene: scene.into(),
        triangles,
        builder: builder.into(),
        threads,
        seconds: s,
        mtris_per_s: triangles as f64 / s.median.max(f64::MIN_POSITIVE) / 1e6,
        sah_cost: stats.as_ref().map(|s| s.sah_cost),
        nodes: stats.as_ref().map(|s| s.nodes),
        leaves: stats.as_ref().map(|s| s.leaves),
        depth: stats.as_ref().map(|s| s.depth),
    }
}

/// Runs the benchmark; `progress` gets one line per measurement.
pub fn run(o: &BuildBenchOptions, mut progress: impl FnMut(&str)) -> Result<BuildBenchReport> {
    o.check()?;
    let provenance = Provenance::here(o.embree.is_some());
    let mut rows = vec![];
    let mut layout_rows = vec![];
    let binned = o.build_options(Builder::default());
    let max_threads = *o.threads.iter().max().expect("checked non-empty");
    let mut triangles = vec![];
    for (scene_index, scene) in o.scenes.iter().enumerate() {
        let name = crate::scene::scene_name(scene);
        let mesh = load_obj(scene)?;
        let n = mesh.triangle_count();
        // Another shard's scene is loaded only for its triangle count: whether it has a sweep row.
        triangles.push(n);
        if !o.split().runs(scene_index, 0) {
            continue;
        }
        progress(&format!("{name}: {n} triangles"));
        let mut first: Option<Bvh> = None;
        for &t in &o.threads {
            let (s, bvh) = pool(t)?.install(|| time_builds(o.repeat, || Bvh::build(&mesh, &binned)));
            match &first {
                None => {
                    bvh.validate(&mesh).map_err(|e| Error::Usage(format!("{name}: invalid tree: {e}")))?;
                    first = Some(bvh.clone());
                }
                Some(f) if !f.same_tree(&bvh) => {
                    return Err(Error::Usage(format!("{name}: the {t}-thread tree differs from the first")));
                }
                Some(_) => {}
            }
            let r = row(&name, n, "trilab-binned", t, s, Some(&bvh));
            progress(&line(&r));
            rows.push(r);
        }
        let first = first.expect("at least one thread count");
        let build_seconds = rows.last().map_or(f64::NAN, |r: &BuildRow| r.seconds.median);
        for &layout in &o.layouts {
            let r = layout_row(&name, n, layout, &first, build_seconds, o.repeat)?;
            progress(&layout_line(&r));
            layout_rows.push(r);
        }
        if o.serial {
            let (s, bvh) = time_builds(o.repeat, || Bvh::build_serial(&mesh, &binned));
            if !first.same_tree(&bvh) {
                return Err(Error::Usage(format!("{name}: the serial tree differs from the parallel one")));
            }
            let r = row(&name, n, "trilab-serial", 1, s, Some(&bvh));
            progress(&line(&r));
            rows.push(r);
        }
        if n <= o.sweep_max_triangles {
            let sweep = o.build_options(Builder::Sweep);
            let bvh = pool(max_threads)?.install(|| Bvh::build(&mesh, &sweep));
            bvh.validate(&mesh).map_err(|e| Error::Usage(format!("{name}: invalid sweep tree: {e}")))?;
            let s = Summary::of(&[bvh.build_seconds]).expect("one run");
            let r = row(&name, n, "trilab-sweep", max_threads, s, Some(&bvh));
            progress(&line(&r));
            rows.push(r);
        }
        if let Some(bin) = &o.embree {
            let dir = tempfile::tempdir().map_err(|e| Error::io(Path::new("temporary directory"), e))?;
            let input = dir.path().join("scene.tlbuild");
            write_input(&input, &mesh, &first)?;
            for &t in &o.threads {
                let tree_path = dir.path().join("tree.tlbvh");
                let run = run_peer(bin, &input, &tree_path, t, o, t == max_threads)?;
                let mut tree = read_tree(&tree_path, &binned, t)?;
                tree.degenerate_excluded = first.degenerate_excluded;
                tree.validate(&mesh).map_err(|e| {
                    Error::Usage(format!("{name}: Embree's tree ({t} threads) is invalid, not reported: {e}"))
                })?;
                let s = Summary::of(&run.build_ms.iter().map(|ms| ms * 1e-3).collect::<Vec<_>>())
                    .ok_or_else(|| Error::Usage(format!("{}: no timed runs", bin.display())))?;
                let r = row(&name, n, "embree-build", t, s, Some(&tree));
                progress(&line(&r));
                rows.push(r);
                if let Some(s) = Summary::of(&run.commit_ms.iter().map(|ms| ms * 1e-3).collect::<Vec<_>>()) {
                    let r = row(&name, n, "embree-commit", t, s, None);
                    progress(&line(&r));
                    rows.push(r);
                }
            }
        }
    }
    let plan = plan_cells(o, &triangles);
    Ok(BuildBenchReport { options: o.clone(), provenance, rows, layouts: layout_rows, plan })
}

/// `layout`'s node buffer made from `bvh`: a warm-up and `repeat` timed conversions.
fn layout_row(
    scene: &str,
    triangles: usize,
    layout: Layout,
    bvh: &Bvh,
    build_seconds: f64,
    repeat: usize,
) -> Result<LayoutRow> {
    let built = layout
        .nodes(&bvh.nodes, &bvh.options)
        .map_err(|e| Error::Usage(format!("scene `{scene}`: the {layout} layout cannot hold its tree: {e}")))?;
    let (convert_seconds, nodes, bytes, sah_cost) = match built {
        None => (None, bvh.nodes.len(), std::mem::size_of_val(&bvh.nodes[..]), bvh.sah_cost(&bvh.options)),
        Some(built) => {
            let secs: Vec<f64> = (0..repeat)
                .map(|_| {
                    let t = std::time::Instant::now();
                    let again = layout.nodes(&bvh.nodes, &bvh.options);
                    let s = t.elapsed().as_secs_f64();
                    let _ = std::hint::black_box(again);
                    s
                })
                .collect();
            (Summary::of(&secs), built.nodes, built.bytes.len(), built.sah_cost)
        }
    };
    Ok(LayoutRow {
        scene: scene.into(),
        triangles,
        layout,
        convert_seconds,
        build_seconds,
        nodes,
        node_bytes: bytes,
        node_bytes_per_triangle: bytes as f64 / triangles.max(1) as f64,
        sah_cost,
    })
}

fn layout_line(r: &LayoutRow) -> String {
    format!(
        "{} layout {}: {}, {} nodes, {:.1} node bytes per triangle",
        r.scene,
        r.layout,
        r.convert_seconds.map_or_else(
            || "the binary nodes as built".into(),
            |s| format!("converted in {:.4} s ({:.4}-{:.4})", s.median, s.min, s.max)
        ),
        r.nodes,
        r.node_bytes_per_triangle
    )
}

fn line(r: &BuildRow) -> String {
    format!(
        "{} {} threads {}: {:.4} s ({:.4}-{:.4}), {:.2} Mtris/s{}",
        r.scene,
        r.builder,
        r.threads,
        r.seconds.median,
        r.seconds.min,
        r.seconds.max,
        r.mtris_per_s,
        r.sah_cost.map(|c| format!(", SAH {c:.2}")).unwrap_or_default()
    )
}

/// The peer's input (format in benches/peers/embree_build.cpp): the mesh, then one build
/// primitive per triangle of the tree (`bvh.prim_ids`: the non-degenerate ones), with the box
/// trilab's builder uses.
pub fn write_input(path: &Path, mesh: &Mesh, bvh: &Bvh) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = std::io::BufWriter::new(file);
    let ids: Vec<u32> = bvh.prim_ids.iter().copied().filter(|&p| p != crate::bvh::PAD_SLOT).collect();
    let mut put = |b: &[u8]| w.write_all(b).map_err(|e| Error::io(path, e));
    put(b"TLBUILD1")?;
    for c in [mesh.positions.len(), mesh.triangle_count(), ids.len()] {
        put(&(c as u64).to_le_bytes())?;
    }
    put(bytemuck::cast_slice(&mesh.positions))?;
    put(bytemuck::cast_slice(&mesh.triangles))?;
    for id in ids {
        let b = crate::scene::Aabb::from_points(&mesh.vertices(id as usize));
        let rec: [u32; 8] = [
            b.min.x.to_bits(),
            b.min.y.to_bits(),
            b.min.z.to_bits(),
            0,
            b.max.x.to_bits(),
            b.max.y.to_bits(),
            b.max.z.to_bits(),
            id,
        ];
        put(bytemuck::cast_slice(&rec))?;
    }
    w.flush().map_err(|e| Error::io(path, e))
}

#[derive(serde::Deserialize)]
struct PeerRun {
    build_ms: Vec<f64>,
    commit_ms: Vec<f64>,
}

fn run_peer(
    bin: &Path,
    input: &Path,
    tree: &Path,
    threads: usize,
    o: &BuildBenchOptions,
    commit: bool,
) -> Result<PeerRun> {
    // Fill: a node of at most leaf_size triangles is a leaf (Embree: minLeafSize = maxLeafSize);
    // SAH: the SAH decides below leaf_size (minLeafSize = 1).
    let min_leaf = match o.build.leaf_policy {
        LeafPolicy::Fill => o.build.max_leaf_size,
        LeafPolicy::Sah => 1,
    };
    let mut cmd = Command::new(bin);
    cmd.arg(input).arg(tree);
    for (k, v) in [
        ("--threads", threads.to_string()),
        ("--repeat", o.repeat.to_string()),
        ("--leaf", o.build.max_leaf_size.to_string()),
        ("--min-leaf", min_leaf.to_string()),
        ("--block", o.build.sah_group.to_string()),
        ("--max-depth", MAX_DEPTH.to_string()),
    ] {
        cmd.arg(k).arg(v);
    }
    if commit {
        cmd.arg("--commit");
    }
    let out = crate::children::output(&mut cmd).map_err(|e| Error::io(bin, e))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    if !out.status.success() {
        return Err(Error::Usage(format!(
            "{} failed ({}): {}{}",
            bin.display(),
            out.status,
            stdout,
            String::from_utf8_lossy(&out.stderr)
        )));
    }
    serde_json::from_str(stdout.trim())
        .map_err(|e| Error::Usage(format!("cannot read {}'s output `{}`: {e}", bin.display(), stdout.trim())))
}

/// Reads the peer's tree (format in benches/peers/embree_build.cpp) as a [`Bvh`] so it is
/// validated and priced by the same code as trilab's trees.
pub fn read_tree(path: &Path, options: &BuildOptions, threads: usize) -> Result<Bvh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bad = |m: &str| Error::bad_input(path, None, m);
    if bytes.len() < 24 || &bytes[..8] != b"TLBVHOUT" {
        return Err(bad("not a TLBVHOUT tree"));
    }
    let count = |i: usize| u64::from_le_bytes(bytes[i..i + 8].try_into().expect("8 bytes")) as usize;
    let (nodes, slots) = (count(8), count(16));
    let expected = nodes.checked_mul(32).and_then(|a| slots.checked_mul(4).and_then(|b| a.checked_add(b)));
    if nodes == 0 || expected.and_then(|e| e.checked_add(24)) != Some(bytes.len()) {
        return Err(bad("node and slot counts do not match the file size"));
    }
    let node_bytes = &bytes[24..24 + 32 * nodes];
    let nodes: Vec<BvhNode> = node_bytes.chunks_exact(32).map(bytemuck::pod_read_unaligned).collect();
    let prim_ids: Vec<u32> = bytes[24 + 32 * nodes.len()..]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    // `Bvh::validate` checks the rest; reject here what would make its walk index out of
    // bounds or visit a node twice (children after their parent, each node one parent's).
    let mut has_parent = vec![false; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if n.count == 0 {
            let l = n.left_or_first as usize;
            if l <= i || l + 1 >= nodes.len() || has_parent[l] || has_parent[l + 1] {
                return Err(bad(&format!("node {i} has bad children {l}")));
            }
            has_parent[l] = true;
            has_parent[l + 1] = true;
        }
        if n.count > 0 && (n.left_or_first as usize).checked_add(n.count as usize).is_none_or(|e| e > prim_ids.len()) {
            return Err(bad(&format!("leaf {i} points past the slots")));
        }
    }
    if prim_ids.contains(&crate::bvh::PAD_SLOT) {
        return Err(bad("a slot holds the padding id"));
    }
    Ok(Bvh { nodes, prim_ids, options: *options, build_seconds: 0.0, build_threads: threads, degenerate_excluded: 0 })
}

impl BuildBenchReport {
    pub fn table(&self) -> Table {
        let mut t = Table::new([
            "scene",
            "triangles",
            "builder",
            "threads",
            "median s",
            "min s",
            "max s",
            "Mtris/s",
            "SAH cost",
            "nodes",
            "leaves",
            "depth",
        ]);
        let opt = |v: Option<String>| v.unwrap_or_else(|| "-".into());
        for r in &self.rows {
            t.row([
                r.scene.clone(),
                r.triangles.to_string(),
                r.builder.clone(),
                r.threads.to_string(),
                format!("{:.4}", r.seconds.median),
                format!("{:.4}", r.seconds.min),
                format!("{:.4}", r.seconds.max),
                format!("{:.2}", r.mtris_per_s),
                opt(r.sah_cost.map(|c| format!("{c:.3}"))),
                opt(r.nodes.map(|n| n.to_string())),
                opt(r.leaves.map(|n| n.to_string())),
                opt(r.depth.map(|n| n.to_string())),
            ]);
        }
        t
    }

    /// One row per scene and layout: conversion time beside the build, nodes, bytes.
    pub fn layouts_table(&self) -> Table {
        let mut t = Table::new([
            "scene",
            "layout",
            "convert median s (min-max)",
            "BVH build s",
            "nodes",
            "node bytes",
            "node B/tri",
            "SAH cost",
        ]);
        for r in &self.layouts {
            t.row([
                r.scene.clone(),
                r.layout.to_string(),
                r.convert_seconds.map_or_else(
                    || "- (binary nodes)".into(),
                    |s| format!("{:.4} ({:.4}-{:.4})", s.median, s.min, s.max),
                ),
                format!("{:.4}", r.build_seconds),
                r.nodes.to_string(),
                r.node_bytes.to_string(),
                format!("{:.1}", r.node_bytes_per_triangle),
                format!("{:.3}", r.sah_cost),
            ]);
        }
        t
    }

    /// `layouts.csv`: one row per scene and layout.
    pub fn layouts_csv(&self) -> Result<String> {
        let header = [
            "scene",
            "triangles",
            "layout",
            "convert_runs",
            "convert_median_s",
            "convert_min_s",
            "convert_max_s",
            "build_s",
            "nodes",
            "node_bytes",
            "node_bytes_per_triangle",
            "sah_cost",
            "leaf_size",
            "commit",
        ];
        let records = self.layouts.iter().map(|r| {
            let c = |f: fn(&Summary) -> f64| r.convert_seconds.as_ref().map(|s| f(s).to_string()).unwrap_or_default();
            [
                r.scene.clone(),
                r.triangles.to_string(),
                r.layout.to_string(),
                r.convert_seconds.map(|s| s.runs.to_string()).unwrap_or_default(),
                c(|s| s.median),
                c(|s| s.min),
                c(|s| s.max),
                r.build_seconds.to_string(),
                r.nodes.to_string(),
                r.node_bytes.to_string(),
                r.node_bytes_per_triangle.to_string(),
                r.sah_cost.to_string(),
                self.options.build.max_leaf_size.to_string(),
                self.provenance.commit.clone(),
            ]
        });
        results::csv("layouts.csv", header, records)
    }

    pub fn csv(&self) -> Result<String> {
        let header = [
            "scene",
            "triangles",
            "builder",
            "threads",
            "runs",
            "median_s",
            "min_s",
            "max_s",
            "mtris_per_s",
            "sah_cost",
            "nodes",
            "leaves",
            "depth",
            "leaf_size",
            "leaf_policy",
            "sah_group",
            "cpu_model",
            "cores",
            "commit",
            "date",
        ];
        let opt = |v: Option<String>| v.unwrap_or_default();
        let (o, p) = (&self.options, &self.provenance);
        let records = self.rows.iter().map(|r| {
            [
                r.scene.clone(),
                r.triangles.to_string(),
                r.builder.clone(),
                r.threads.to_string(),
                r.seconds.runs.to_string(),
                r.seconds.median.to_string(),
                r.seconds.min.to_string(),
                r.seconds.max.to_string(),
                r.mtris_per_s.to_string(),
                opt(r.sah_cost.map(|c| c.to_string())),
                opt(r.nodes.map(|n| n.to_string())),
                opt(r.leaves.map(|n| n.to_string())),
                opt(r.depth.map(|n| n.to_string())),
                o.build.max_leaf_size.to_string(),
                o.build.leaf_policy.to_string(),
                o.build.sah_group.to_string(),
                p.cpu_model.clone(),
                p.cores.to_string(),
                p.commit.clone(),
                p.date.clone(),
            ]
        });
        results::csv("build.csv", header, records)
    }

    pub fn markdown(&self) -> String {
        let (o, p) = (&self.options, &self.provenance);
        let mut s = String::from("# BVH build speed and quality\n\n");
        if let Some(note) = self.partial() {
            s += &format!("**{note}.**\n\n");
        }
        s += &format!(
            "CPU: {} ({} logical CPUs); commit {}; {}{}.\n\n",
            p.cpu_model,
            p.cores,
            p.commit,
            p.date,
            p.embree_version.as_ref().map(|v| format!("; Embree {v}")).unwrap_or_default()
        );
        s += &format!(
            "Leaf size {}, leaf policy {}, SAH group {}; {} timed runs after one warm-up, seconds as median (min-max). \
             SAH cost: C_trav = 1, C_isect = 1, a leaf of n triangles costs ceil(n / {}), areas relative to the root; \
             every tree is priced by the same code (`Bvh::sah_cost`) after `Bvh::validate` accepted it.\n\n",
            o.build.max_leaf_size, o.build.leaf_policy, o.build.sah_group, o.repeat, o.build.sah_group
        );
        s += "- `trilab-binned`: the parallel binned SAH (32 bins) on a rayon pool of `threads`; its time \
              includes primitive setup (degeneracy test, boxes) and node assembly. Its tree is bitwise the same \
              at every thread count (checked here) and equal to `trilab-serial`'s.\n\
              - `trilab-serial`: the same build as one single-threaded loop.\n\
              - `trilab-sweep`: full-sweep SAH (every primitive boundary), one run: the SAH-cost reference.\n\
              - `embree-build`: Embree 3 `rtcBuildBVH`, RTC_BUILD_QUALITY_HIGH, branching factor 2, the same \
              leaf size (minimum leaf size = leaf size under the fill policy, 1 under SAH), SAH block size = \
              SAH group, traversal and intersection cost 1, Embree's own thread pool of `threads`; timed: the \
              `rtcBuildBVH` call alone (primitive boxes given), so trilab's primitive setup is extra work \
              in its row. Without a split callback HIGH is Embree's binned SAH (no spatial splits).\n\
              - `embree-commit`: `rtcCommitScene` of the triangle mesh at RTC_BUILD_QUALITY_HIGH (Embree's \
              BVH4/8 with spatial splits): a reference time only, no tree to price.\n\n";
        s += &self.table().to_markdown();
        if !self.layouts.is_empty() {
            s += "\n## Node layouts\n\n";
            s += "Each layout's node buffer made from the `trilab-binned` tree (`Layout::nodes`: the wide \
                  layouts collapse it with the SAH), timed like the builds (median, min-max of the timed runs \
                  after one warm-up) beside that build's median; `bvh2` uploads the binary nodes as built. \
                  Node bytes per triangle: the node buffer alone (triangle data and slot ids are the method's, \
                  the same on every layout). SAH cost as the layout prices its own tree.\n\n";
            s += &self.layouts_table().to_markdown();
        }
        s
    }

    /// Writes build.csv, layouts.csv, build.json and build.md into `dir` (each atomically).
    pub fn write(&self, dir: &Path) -> Result<()> {
        results::write_folder(dir, self).map(drop)
    }

    /// The plan of the whole matrix this report belongs to, with its shard.
    pub fn plan(&self) -> crate::rows::Plan {
        crate::rows::Plan {
            command: "build-bench".into(),
            shard: self.options.shard,
            cells: self.plan.clone(),
            source: self.source(),
        }
    }

    /// `partial: shard I/N, X of Y cells ...` for a sharded run, `None` for a whole one.
    pub fn partial(&self) -> Option<String> {
        shard::partial(self.options.shard, &self.plan, &self.rows(), "whole scenes")
    }

    /// Where the rows were measured: the host CPU (its model as the device, the logical CPUs as
    /// a setting).
    fn source(&self) -> crate::rows::Source {
        let p = &self.provenance;
        crate::rows::Source {
            device: p.cpu_model.clone(),
            driver: "host CPU (no GPU driver)".into(),
            commit: p.commit.clone(),
            date: p.date.clone(),
            settings: [("host_cpus".to_owned(), p.cores.to_string())].into(),
            host: Some(crate::host::Host::current()),
        }
    }

    /// The report as result rows (`rows.jsonl`, what `trilab compare` reads): per scene,
    /// builder and thread count `build_s` (timing, min-max over the rounds) and the tree's
    /// `sah_cost` and `nodes` (counts); per scene and layout `convert_s` (timing) and the node
    /// buffer's `node_bytes`, `nodes` and `sah_cost` (counts). Measured on the host CPU: the
    /// source's device is the CPU model, its settings the logical CPUs.
    pub fn rows(&self) -> Vec<crate::rows::Row> {
        use crate::rows::{Better, Figure, Row};
        let source = self.source();
        let build = &self.options.build;
        let mut out = vec![];
        for r in &self.rows {
            let c = BuildCell::Build { scene: r.scene.clone(), builder: r.builder.clone(), threads: r.threads }
                .coordinates(build);
            let mut row =
                Row::new("build-bench", c, &source).with("build_s", Figure::timing(r.seconds, "s", Better::Lower));
            if let Some(sah) = r.sah_cost {
                row = row.with("sah_cost", Figure::count(sah, "SAH"));
            }
            if let Some(n) = r.nodes {
                row = row.with("nodes", Figure::count(n as f64, "nodes"));
            }
            out.push(row);
        }
        for l in &self.layouts {
            let c = BuildCell::Convert { scene: l.scene.clone(), layout: l.layout }.coordinates(build);
            let mut row = Row::new("build-bench", c, &source)
                .with("node_bytes", Figure::count(l.node_bytes as f64, "bytes"))
                .with("nodes", Figure::count(l.nodes as f64, "nodes"))
                .with("sah_cost", Figure::count(l.sah_cost, "SAH"));
            if let Some(s) = l.convert_seconds {
                row = row.with("convert_s", Figure::timing(s, "s", Better::Lower));
            }
            out.push(row);
        }
        for r in &mut out {
            r.figures.retain(|_, f| f.median.is_finite() && f.min.is_finite() && f.max.is_finite());
        }
        out
    }
}

impl results::Results for BuildBenchReport {
    const STEM: &'static str = "build";

    fn markdown(&self, _: &[crate::services::plots::Plot]) -> String {
        BuildBenchReport::markdown(self)
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        Some(BuildBenchReport::rows(self))
    }

    fn plan(&self) -> Option<crate::rows::Plan> {
        Some(BuildBenchReport::plan(self))
    }

    fn files(&self) -> Result<Vec<(&'static str, String)>> {
        Ok(vec![("build.csv", self.csv()?), ("layouts.csv", self.layouts_csv()?)])
    }
}

impl crate::report::Report for BuildBenchReport {
    fn to_text(&self) -> String {
        let partial = self.partial().map(|n| format!("{n}\n\n")).unwrap_or_default();
        if self.layouts.is_empty() {
            format!("{partial}{}", self.table().to_text())
        } else {
            format!("{partial}{}\n{}", self.table().to_text(), self.layouts_table().to_text())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peer_tree_round_trips_through_the_file_format() {
        let mesh = Mesh::from_triangles(
            vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]],
            vec![[0, 1, 2], [3, 4, 5], [0, 0, 0]],
        );
        let o = BuildOptions::new(1);
        let bvh = Bvh::build(&mesh, &o);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.tlbvh");
        let mut bytes = b"TLBVHOUT".to_vec();
        bytes.extend((bvh.nodes.len() as u64).to_le_bytes());
        bytes.extend((bvh.prim_ids.len() as u64).to_le_bytes());
        bytes.extend(bytemuck::cast_slice(&bvh.nodes));
        bytes.extend(bytemuck::cast_slice(&bvh.prim_ids));
        std::fs::write(&p, &bytes).unwrap();
        let mut back = read_tree(&p, &o, 1).unwrap();
        back.degenerate_excluded = 1;
        back.validate(&mesh).unwrap();
        assert_eq!(back.nodes, bvh.nodes);
        assert_eq!(back.sah_cost(&o), bvh.sah_cost(&o));
        // Truncated, or a child index pointing backwards: errors, not panics.
        std::fs::write(&p, &bytes[..bytes.len() - 1]).unwrap();
        assert!(read_tree(&p, &o, 1).is_err());
        let mut looped = bytes.clone();
        looped[24 + 12..24 + 16].copy_from_slice(&0u32.to_le_bytes());
        std::fs::write(&p, &looped).unwrap();
        assert!(read_tree(&p, &o, 1).unwrap_err().to_string().contains("bad children"));
        // Input file: header counts and one 32-byte record per non-degenerate triangle.
        let input = dir.path().join("in.tlbuild");
        write_input(&input, &mesh, &bvh).unwrap();
        let len = std::fs::metadata(&input).unwrap().len() as usize;
        assert_eq!(len, 32 + 6 * 12 + 3 * 12 + 2 * 32);
    }
}
