//! `trilab roofline`: the device's traversal roofline (issue 27), what vkpeak is to arithmetic,
//! for the gathers of a traversal. `glsl/roofline.comp` walks dependent 32-byte nodes (two
//! texels, bvh2's node size) with a slab test per step (`gpu::roofline`); this sweeps it over
//! working-set sizes from the caches to DRAM and over the four ways a kernel reads nodes
//! (texel, storage, address, address32), interleaved: round r runs every cell before round r + 1, so a
//! burst of other work lands on every cell alike. The rate is node steps per second, the median
//! of the rounds with min and max, from GPU timestamps. Every cell's checksums are checked
//! against the CPU's walk (a sample of invocations) before its time counts.
//!
//! [`RooflineReport::at`] reads the rate at any working-set size off a report (interpolated in
//! log-log between the measured sizes), and [`measure_at`] measures the sizes around one size:
//! what `bench --roofline` divides a kernel's node and triangle fetches per second by.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::error::{Error, Result};
use crate::gpu::roofline::{self as kernel, RooflineAccess, RooflineData, RooflinePush, NODE_BYTES};
use crate::gpu::Context;
use crate::memory::show_bytes;
use crate::named::Named;
use crate::report::{Report, Summary, Table};
use crate::services::provenance::Provenance;

/// The default working sets: 16 KiB (in every L1) to 256 MiB (past every cache).
pub const DEFAULT_SIZES: [u64; 8] = [16 << 10, 64 << 10, 256 << 10, 1 << 20, 4 << 20, 16 << 20, 64 << 20, 256 << 20];

/// Invocations of one dispatch by default (2^20).
pub const DEFAULT_INVOCATIONS: u32 = 1 << 20;

/// Dependent steps per invocation by default.
pub const DEFAULT_STEPS: u32 = 64;

/// Invocations whose checksums are checked against the CPU's walk in each cell (spread over the
/// dispatch).
const CHECKED: u32 = 4096;

/// What to sweep.
#[derive(Clone, Debug, Serialize)]
pub struct RooflineOptions {
    /// Working-set sizes in bytes, ascending: each a power of two, at least two nodes (64 B).
    pub sizes: Vec<u64>,
    /// The access paths, in order.
    pub access: Vec<RooflineAccess>,
    /// Timed rounds (at least 1); each runs every cell once.
    pub rounds: usize,
    /// Untimed rounds before them.
    pub warmup: usize,
    pub invocations: u32,
    pub steps: u32,
    pub seed: u32,
}

impl Default for RooflineOptions {
    fn default() -> Self {
        RooflineOptions {
            sizes: DEFAULT_SIZES.to_vec(),
            access: RooflineAccess::ALL.to_vec(),
            rounds: 5,
            warmup: 1,
            invocations: DEFAULT_INVOCATIONS,
            steps: DEFAULT_STEPS,
            seed: 1,
        }
    }
}

impl RooflineOptions {
    /// Refuses options that measure nothing or cannot be laid out, naming the option.
    pub fn check(&self) -> Result<()> {
        if self.sizes.is_empty() {
            return Err(Error::Usage("--sizes: no working-set size given".into()));
        }
        for &s in &self.sizes {
            check_size(s).map_err(|m| Error::Usage(format!("--sizes: {m}")))?;
        }
        if self.access.is_empty() {
            return Err(Error::Usage("--access: no access path given".into()));
        }
        if self.rounds == 0 {
            return Err(Error::Usage("--rounds 0: at least one timed round".into()));
        }
        if self.invocations == 0 {
            return Err(Error::Usage("--invocations 0: at least one invocation".into()));
        }
        if self.steps == 0 {
            return Err(Error::Usage("--steps 0: at least one step per invocation".into()));
        }
        Ok(())
    }
}

/// Why `bytes` is not a working-set size the kernel can walk.
fn check_size(bytes: u64) -> std::result::Result<(), String> {
    if bytes < 2 * NODE_BYTES || !bytes.is_power_of_two() {
        return Err(format!(
            "{} is not a working-set size: a power of two of at least {} bytes (two {NODE_BYTES}-byte nodes)",
            show_size(bytes),
            2 * NODE_BYTES
        ));
    }
    if bytes / NODE_BYTES > 1 << 30 {
        return Err(format!("{} is more than 2^30 nodes", show_size(bytes)));
    }
    Ok(())
}

/// Parses a working-set size: bytes, or a number with `K`, `M`, `G` (binary: `KiB`, `MiB`,
/// `GiB`, `k`, `KB` alike), e.g. `16K`, `256KiB`, `64M`, `1G`. It must be a power of two of at
/// least 64 bytes.
pub fn parse_size(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: u64 = num.parse().map_err(|_| format!("`{s}` is not a size (e.g. 16K, 1M, 256MiB, or bytes)"))?;
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        u => return Err(format!("`{s}`: unknown unit `{u}` (K, M or G, binary)")),
    };
    let bytes = n.checked_mul(1 << shift).ok_or_else(|| format!("`{s}` is too large"))?;
    check_size(bytes)?;
    Ok(bytes)
}

/// `bytes` as the table shows a working set: `16 KiB`, `1 MiB`.
pub fn show_size(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 && b % (1 << 30) == 0 => format!("{} GiB", b >> 30),
        b if b >= 1 << 20 && b % (1 << 20) == 0 => format!("{} MiB", b >> 20),
        b if b >= 1 << 10 && b % (1 << 10) == 0 => format!("{} KiB", b >> 10),
        b => format!("{b} B"),
    }
}

/// A roofline cell: what a row measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub struct RooflineCell {
    pub access: RooflineAccess,
    /// The working set: nodes x 32 bytes.
    pub bytes: u64,
}

impl RooflineCell {
    /// The cell's coordinates, as `rows.jsonl` names them (`steps` and `invocations` where they
    /// are not the defaults).
    pub fn coordinates(&self, o: &RooflineOptions) -> crate::rows::Cell {
        let mut c = crate::rows::cell([("access", self.access.to_string()), ("bytes", self.bytes.to_string())]);
        if o.steps != DEFAULT_STEPS {
            c.insert("steps".into(), o.steps.to_string());
        }
        if o.invocations != DEFAULT_INVOCATIONS {
            c.insert("invocations".into(), o.invocations.to_string());
        }
        c
    }
}

/// One measured cell.
#[derive(Clone, Debug, Serialize)]
pub struct Measured {
    #[serde(flatten)]
    pub cell: RooflineCell,
    pub nodes: u64,
    /// Node steps per second over the rounds, millions.
    pub msteps_per_s: Summary,
    /// Each round's dispatch, milliseconds.
    pub ms: Vec<f64>,
}

/// A cell not measured, and why.
#[derive(Clone, Debug, Serialize)]
pub struct Skipped {
    pub bytes: u64,
    /// `None`: every access path at this size.
    pub access: Option<RooflineAccess>,
    pub why: String,
}

/// The sweep's results.
#[derive(Clone, Debug, Serialize)]
pub struct RooflineReport {
    pub provenance: Provenance,
    pub options: RooflineOptions,
    pub measured: Vec<Measured>,
    pub skipped: Vec<Skipped>,
    /// Invocations per cell whose checksums equalled the CPU's walk.
    pub checked_invocations: u32,
}

/// Runs the sweep on `ctx`'s device; `progress` gets a line per stage.
pub fn run(ctx: &Context, o: &RooflineOptions, mut progress: impl FnMut(&str)) -> Result<RooflineReport> {
    o.check()?;
    let o = &each_access_once(o);
    let info = ctx.info();
    let most = info.max_compute_workgroup_count[0] as u64 * crate::shared::WORKGROUP_SIZE as u64;
    if o.invocations as u64 > most {
        return Err(Error::Usage(format!(
            "--invocations {}: one dispatch holds at most {most} on {}",
            o.invocations, info.name
        )));
    }
    let Uploaded { data, hosts, skipped } = upload(ctx, o, &mut progress)?;
    let cells: Vec<(usize, RooflineAccess)> = (0..data.len())
        .flat_map(|i| o.access.iter().map(move |&a| (i, a)))
        .filter(|&(i, a)| data[i].1.why_not(a).is_none())
        .collect();
    if cells.is_empty() {
        let what = if data.is_empty() { "every size of --sizes" } else { "every path of --access at every size" };
        return Err(Error::Unsupported(format!(
            "roofline: nothing to measure on {} ({what} skipped): {}",
            info.name,
            skipped.iter().map(|s| format!("{}: {}", show_size(s.bytes), s.why)).collect::<Vec<_>>().join("; ")
        )));
    }
    let sample = warm_up_and_check(ctx, o, &data, &hosts, &cells, &mut progress)?;
    drop(hosts);
    let (ms, timed_on_gpu) = timed_rounds(ctx, o, &data, &cells, &mut progress)?;
    let measured = summarise(o, &data, &cells, ms)?;
    let mut provenance = Provenance::of(ctx);
    provenance.timed_on_gpu = timed_on_gpu;
    Ok(RooflineReport { provenance, options: o.clone(), measured, skipped, checked_invocations: sample.len() as u32 })
}

/// `o` with each access path once, where it was first named (a repeated one would be two
/// cells of one name, each timed in half the rounds); sizes are deduplicated by [`upload`].
fn each_access_once(o: &RooflineOptions) -> RooflineOptions {
    let mut o = o.clone();
    let mut seen = vec![];
    o.access.retain(|a| {
        !seen.contains(a) && {
            seen.push(*a);
            true
        }
    });
    o
}

/// The working sets on the device: (bytes, nodes uploaded), each one's nodes on the host (for
/// the checksums), and the sizes and paths skipped with why.
struct Uploaded {
    data: Vec<(u64, RooflineData)>,
    hosts: Vec<Vec<kernel::RooflineNode>>,
    skipped: Vec<Skipped>,
}

/// Makes and uploads each size's nodes, ascending, skipping a size the device or host cannot
/// hold. Every size stays on the device for the whole sweep (the rounds interleave them): keep
/// to 3/4 of the device-local heap (and of its budget left now, where the driver reports one),
/// and each size's host copy to the memory available now.
fn upload(ctx: &Context, o: &RooflineOptions, progress: &mut impl FnMut(&str)) -> Result<Uploaded> {
    let mut sizes = o.sizes.clone();
    sizes.sort_unstable();
    sizes.dedup();
    let limits = ctx.limits()?;
    let heap = limits.device_local_bytes.min(limits.budget_bytes.unwrap_or(u64::MAX));
    let budget = heap / 4 * 3;
    let host = crate::memory::available();
    let mut resident = 0u64;
    let mut up = Uploaded { data: vec![], hosts: vec![], skipped: vec![] };
    for &bytes in &sizes {
        let largest = limits.max_memory_allocation_size.min(limits.max_buffer_size.unwrap_or(u64::MAX));
        let why = if bytes > largest {
            Some(format!("more than the largest buffer the device allows ({})", show_bytes(largest)))
        } else if resident + bytes > budget {
            Some(format!(
                "with the smaller sizes more than 3/4 of the device-local memory ({}, or its budget left)",
                show_bytes(heap)
            ))
        } else if host.is_some_and(|h| bytes.saturating_mul(2) > h) {
            Some(format!(
                "its host copy and upload need more than the memory available now ({})",
                show_bytes(host.unwrap_or(0))
            ))
        } else {
            None
        };
        if let Some(why) = why {
            up.skipped.push(Skipped { bytes, access: None, why });
            continue;
        }
        progress(&format!("roofline: {} ({} nodes)", show_size(bytes), bytes / NODE_BYTES));
        let nodes = kernel::nodes((bytes / NODE_BYTES) as usize, o.seed as u64)?;
        let d = kernel::upload(ctx, &format!("roofline nodes {}", show_size(bytes)), &nodes)?;
        resident += bytes;
        for &access in &o.access {
            if let Some(why) = d.why_not(access) {
                up.skipped.push(Skipped { bytes, access: Some(access), why: why.to_owned() });
            }
        }
        // The host copy is kept only where the checksums are checked against it.
        up.data.push((bytes, d));
        up.hosts.push(nodes);
    }
    Ok(up)
}

/// The push constant of a dispatch over `d`'s nodes.
fn push_of(o: &RooflineOptions, d: &RooflineData) -> RooflinePush {
    RooflinePush { mask: (d.nodes - 1) as u32, steps: o.steps, count: o.invocations, seed: o.seed }
}

/// Warm-up rounds, the first of which checks every cell's checksums against the CPU's walk
/// over a sample of invocations (returned).
fn warm_up_and_check(
    ctx: &Context,
    o: &RooflineOptions,
    data: &[(u64, RooflineData)],
    hosts: &[Vec<kernel::RooflineNode>],
    cells: &[(usize, RooflineAccess)],
    progress: &mut impl FnMut(&str),
) -> Result<Vec<u32>> {
    let stride = (o.invocations / CHECKED.min(o.invocations)).max(1);
    let sample: Vec<u32> = (0..o.invocations).step_by(stride as usize).collect();
    for w in 0..o.warmup.max(1) {
        for &(i, access) in cells {
            let checks = w == 0;
            let t = kernel::run(ctx, &data[i].1, access, &push_of(o, &data[i].1), 0, 1, checks)?;
            if let Some(got) = t.checksums {
                let p = push_of(o, &data[i].1);
                let nodes = &hosts[i];
                if let Some(&bad) =
                    sample.iter().find(|&&inv| got[inv as usize] != kernel::reference_one(nodes, &p, inv))
                {
                    return Err(Error::Usage(format!(
                        "roofline {access} at {}: invocation {bad}'s checksum {:#010x} differs from the CPU's walk \
                         {:#010x}; no speed is reported for a kernel that computes something else",
                        show_size(data[i].0),
                        got[bad as usize],
                        kernel::reference_one(nodes, &p, bad)
                    )));
                }
            }
        }
        if w == 0 {
            progress(&format!("roofline: checksums of {} cells equal the CPU's walk", cells.len()));
        }
    }
    Ok(sample)
}

/// Each cell's dispatch times (milliseconds), by (size index, access path).
type Times = BTreeMap<(usize, RooflineAccess), Vec<f64>>;

/// The timed rounds: every cell once a round, the cell that opens a round rotating; and
/// whether every dispatch was timed on the GPU.
fn timed_rounds(
    ctx: &Context,
    o: &RooflineOptions,
    data: &[(u64, RooflineData)],
    cells: &[(usize, RooflineAccess)],
    progress: &mut impl FnMut(&str),
) -> Result<(Times, bool)> {
    let mut ms: Times = BTreeMap::new();
    let mut timed_on_gpu = true;
    for round in 0..o.rounds {
        progress(&format!("roofline: round {}/{}", round + 1, o.rounds));
        for k in 0..cells.len() {
            let (i, access) = cells[(k + round) % cells.len()];
            let t = kernel::run(ctx, &data[i].1, access, &push_of(o, &data[i].1), 0, 1, false)?;
            timed_on_gpu &= t.timed_on_gpu;
            ms.entry((i, access)).or_default().extend(t.ms);
        }
    }
    Ok((ms, timed_on_gpu))
}

/// Each cell's node steps per second over its timed rounds.
fn summarise(
    o: &RooflineOptions,
    data: &[(u64, RooflineData)],
    cells: &[(usize, RooflineAccess)],
    mut ms: Times,
) -> Result<Vec<Measured>> {
    let steps = o.invocations as f64 * o.steps as f64;
    cells
        .iter()
        .map(|&(i, access)| {
            let times = ms.remove(&(i, access)).unwrap_or_default();
            let rates: Vec<f64> = times.iter().map(|&t| steps / (t * 1e-3) / 1e6).collect();
            let msteps_per_s = Summary::of(&rates).ok_or_else(|| {
                Error::Usage(format!("roofline {access} at {}: no timed round", show_size(data[i].0)))
            })?;
            Ok(Measured {
                cell: RooflineCell { access, bytes: data[i].0 },
                nodes: data[i].1.nodes,
                msteps_per_s,
                ms: times,
            })
        })
        .collect()
}

/// The power-of-two working sets around `bytes` (the one at or below it and the one above; one
/// where `bytes` is a power of two), at least 64 bytes.
pub fn sizes_around(bytes: u64) -> Vec<u64> {
    let b = bytes.max(2 * NODE_BYTES);
    let below = 1u64 << (63 - b.leading_zeros());
    if below == b {
        vec![b]
    } else {
        vec![below, below.saturating_mul(2)]
    }
}

/// Measures the roofline at the working sets around `bytes` ([`sizes_around`]) on `access`
/// paths, with `o`'s other settings: what [`RooflineReport::at`] then reads at `bytes`.
pub fn measure_at(
    ctx: &Context,
    bytes: u64,
    access: &[RooflineAccess],
    o: &RooflineOptions,
    progress: impl FnMut(&str),
) -> Result<RooflineReport> {
    let o = RooflineOptions { sizes: sizes_around(bytes), access: access.to_vec(), ..o.clone() };
    run(ctx, &o, progress)
}

/// The roofline's node steps per second (millions, median) at a working set of `bytes` on each
/// of `o.access` that the device can read at that size: [`measure_at`], then
/// [`RooflineReport::at`] (log-log between the two sizes around `bytes`).
pub fn rates_at(
    ctx: &Context,
    bytes: u64,
    o: &RooflineOptions,
    progress: impl FnMut(&str),
) -> Result<Vec<(RooflineAccess, f64)>> {
    let report = measure_at(ctx, bytes, &o.access, o, progress)?;
    Ok(o.access.iter().filter_map(|&a| Some((a, report.at(a, bytes)?))).collect())
}

impl RooflineReport {
    /// The cell's measurement, if it was measured.
    pub fn get(&self, access: RooflineAccess, bytes: u64) -> Option<&Measured> {
        self.measured.iter().find(|m| m.cell == RooflineCell { access, bytes })
    }

    /// Median node steps per second (millions) `access`'s way at a working set of `bytes`:
    /// interpolated linearly in log(size)-log(rate) between the measured sizes around it, the
    /// nearest measured size's outside them; `None` where the path was measured at no size.
    pub fn at(&self, access: RooflineAccess, bytes: u64) -> Option<f64> {
        let mut pts: Vec<(u64, f64)> = self
            .measured
            .iter()
            .filter(|m| m.cell.access == access && m.msteps_per_s.median > 0.0)
            .map(|m| (m.cell.bytes, m.msteps_per_s.median))
            .collect();
        pts.sort_by_key(|p| p.0);
        let (first, last) = (*pts.first()?, *pts.last()?);
        if bytes <= first.0 {
            return Some(first.1);
        }
        if bytes >= last.0 {
            return Some(last.1);
        }
        let k = pts.iter().position(|p| p.0 >= bytes)?;
        let (a, b) = (pts[k - 1], pts[k]);
        if b.0 == bytes {
            return Some(b.1);
        }
        let ln = |x: u64| (x as f64).ln();
        let f = (ln(bytes) - ln(a.0)) / (ln(b.0) - ln(a.0));
        Some((a.1.ln() + (b.1.ln() - a.1.ln()) * f).exp())
    }

    fn sizes(&self) -> Vec<u64> {
        let mut s: Vec<u64> = self.measured.iter().map(|m| m.cell.bytes).collect();
        s.sort_unstable();
        s.dedup();
        s
    }

    /// Sizes down, access paths across: median Msteps/s (min-max).
    pub fn table(&self) -> Table {
        let mut t = Table::new(
            ["working set", "nodes"]
                .into_iter()
                .map(String::from)
                .chain(self.options.access.iter().map(|a| format!("{a} Msteps/s"))),
        );
        for bytes in self.sizes() {
            let mut row = vec![show_size(bytes), (bytes / NODE_BYTES).to_string()];
            for &a in &self.options.access {
                row.push(match self.get(a, bytes) {
                    Some(m) => {
                        let s = m.msteps_per_s;
                        format!("{:.1} ({:.1}-{:.1})", s.median, s.min, s.max)
                    }
                    None => "-".into(),
                });
            }
            t.row(row);
        }
        t
    }

    fn header(&self) -> String {
        let p = &self.provenance;
        let o = &self.options;
        let timing = if p.timed_on_gpu { "GPU timestamps" } else { "host wall time (no timestamps on this queue)" };
        format!(
            "Traversal roofline on {} ({}): {} invocations x {} dependent steps of one 32-byte node (two 16-byte \
             loads, a slab test, the next index from the loaded words); node steps per second, median (min-max) \
             of {} interleaved rounds after {} warm-up, {timing}; checksums of {} invocations per cell equal to \
             the CPU's walk.\n",
            p.device,
            p.driver,
            o.invocations,
            o.steps,
            o.rounds,
            o.warmup.max(1),
            self.checked_invocations
        )
    }

    fn skipped_text(&self) -> String {
        self.skipped
            .iter()
            .map(|s| match s.access {
                Some(a) => format!("skipped: {} on the {a} path: {}\n", show_size(s.bytes), s.why),
                None => format!("skipped: {}: {}\n", show_size(s.bytes), s.why),
            })
            .collect()
    }

    /// The rows (`rows.jsonl`): per cell `msteps_per_s` (timing, Msteps/s, higher is better) and
    /// `nodes` (count).
    pub fn rows(&self) -> Vec<crate::rows::Row> {
        use crate::rows::{Better, Figure, Row};
        let source = self.provenance.source();
        self.measured
            .iter()
            .map(|m| {
                Row::new("roofline", m.cell.coordinates(&self.options), &source)
                    .with("msteps_per_s", Figure::timing(m.msteps_per_s, "Msteps/s", Better::Higher))
                    .with("nodes", Figure::count(m.nodes as f64, "nodes"))
            })
            .collect()
    }

    /// The report as Markdown (roofline.md).
    pub fn to_markdown(&self) -> String {
        let skipped = self.skipped_text().lines().map(|l| format!("- {l}\n")).collect::<String>();
        let skipped = if skipped.is_empty() { String::new() } else { format!("\n{skipped}") };
        format!("# Traversal roofline\n\n{}\n{}{skipped}", self.header(), self.table().to_markdown())
    }

    /// Writes roofline.json, roofline.md and rows.jsonl into `dir`; the files written.
    pub fn write(&self, dir: &Path) -> Result<Vec<PathBuf>> {
        crate::services::results::write_folder(dir, self)
    }
}

impl crate::services::results::Results for RooflineReport {
    const STEM: &'static str = "roofline";

    fn markdown(&self, _plots: &[crate::services::plots::Plot]) -> String {
        self.to_markdown()
    }

    fn rows(&self) -> Option<Vec<crate::rows::Row>> {
        Some(RooflineReport::rows(self))
    }
}

/// The files `trilab roofline --out DIR` writes.
pub const FILES: [&str; 3] = ["roofline.json", "roofline.md", crate::rows::FILE];

impl Report for RooflineReport {
    fn to_text(&self) -> String {
        format!("{}\n{}{}", self.header(), self.table().to_text(), self.skipped_text())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_binary_units_and_bad_ones_say_why() {
        assert_eq!(parse_size("16K"), Ok(16 << 10));
        assert_eq!(parse_size("256KiB"), Ok(256 << 10));
        assert_eq!(parse_size(" 64m "), Ok(64 << 20));
        assert_eq!(parse_size("1G"), Ok(1 << 30));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("3K").unwrap_err().contains("power of two"));
        assert!(parse_size("32").unwrap_err().contains("at least 64 bytes"));
        assert!(parse_size("1T").unwrap_err().contains("unknown unit"));
        assert!(parse_size("big").unwrap_err().contains("not a size"));
        assert!(parse_size("64G").unwrap_err().contains("2^30 nodes"));
        assert_eq!(show_size(16 << 10), "16 KiB");
        assert_eq!(show_size(3 << 20), "3 MiB");
    }

    #[test]
    fn around_a_size_are_the_powers_of_two_beside_it() {
        assert_eq!(sizes_around(1 << 20), vec![1 << 20]);
        assert_eq!(sizes_around(3 << 20), vec![2 << 20, 4 << 20]);
        assert_eq!(sizes_around(1), vec![64]);
    }

    fn report(points: &[(RooflineAccess, u64, f64)]) -> RooflineReport {
        let provenance = Provenance {
            device: "test device".into(),
            driver: "test driver".into(),
            mesa_version: None,
            commit: "c".into(),
            date: "d".into(),
            host: crate::host::Host::default(),
            lp_num_threads: None,
            timed_on_gpu: true,
            settings: Default::default(),
            scenes: vec![],
            spirv_compiler: "test compiler",
            driver_package: None,
            compiles_for: None,
        };
        RooflineReport {
            provenance,
            options: RooflineOptions::default(),
            measured: points
                .iter()
                .map(|&(access, bytes, r)| Measured {
                    cell: RooflineCell { access, bytes },
                    nodes: bytes / NODE_BYTES,
                    msteps_per_s: Summary { median: r, min: r, max: r, runs: 1 },
                    ms: vec![],
                })
                .collect(),
            skipped: vec![],
            checked_invocations: 0,
        }
    }

    #[test]
    fn the_rate_at_a_size_is_read_in_log_log_between_measured_sizes() {
        use RooflineAccess::*;
        let r = report(&[(Texel, 1 << 10, 400.0), (Texel, 1 << 20, 100.0), (Storage, 1 << 20, 50.0)]);
        // Halfway in log size between 1 KiB and 1 MiB (32 KiB): the geometric mean, 200.
        assert!((r.at(Texel, 1 << 15).unwrap() - 200.0).abs() < 1e-9);
        assert_eq!(r.at(Texel, 1 << 20), Some(100.0));
        // Outside the measured sizes: the nearest one's.
        assert_eq!(r.at(Texel, 1 << 30), Some(100.0));
        assert_eq!(r.at(Texel, 64), Some(400.0));
        assert_eq!(r.at(Storage, 1 << 12), Some(50.0));
        assert_eq!(r.at(Address, 1 << 20), None);
    }

    #[test]
    fn options_that_measure_nothing_are_refused_naming_the_option() {
        let bad = |o: RooflineOptions| o.check().unwrap_err().to_string();
        let d = RooflineOptions::default();
        assert!(bad(RooflineOptions { sizes: vec![], ..d.clone() }).contains("--sizes"));
        assert!(bad(RooflineOptions { sizes: vec![1000], ..d.clone() }).contains("--sizes: 1000 B"));
        assert!(bad(RooflineOptions { rounds: 0, ..d.clone() }).contains("--rounds"));
        assert!(bad(RooflineOptions { steps: 0, ..d.clone() }).contains("--steps"));
        assert!(bad(RooflineOptions { invocations: 0, ..d.clone() }).contains("--invocations"));
        assert!(bad(RooflineOptions { access: vec![], ..d.clone() }).contains("--access"));
        assert!(d.check().is_ok());
    }

    #[test]
    fn rows_name_the_cell_by_access_and_bytes() {
        let r = report(&[(RooflineAccess::Address, 1 << 20, 120.0)]);
        let rows = r.rows();
        assert_eq!(rows.len(), 1);
        assert_eq!(rows[0].command, "roofline");
        assert_eq!(rows[0].key(), "roofline access=address bytes=1048576");
        let f = &rows[0].figures["msteps_per_s"];
        assert_eq!((f.median, f.unit.as_str(), f.better), (120.0, "Msteps/s", crate::rows::Better::Higher));
        let o = RooflineOptions { steps: 8, ..RooflineOptions::default() };
        assert_eq!(
            RooflineCell { access: RooflineAccess::Texel, bytes: 64 }.coordinates(&o).get("steps").map(String::as_str),
            Some("8")
        );
    }
}
