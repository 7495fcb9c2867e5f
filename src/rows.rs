//! Self-describing result rows: the one format `trilab compare` and `trilab merge` read.
//!
//! Every command that writes results (bench, study, accuracy, profile, spirv, build-bench, the
//! driver statistics) also writes `rows.jsonl` beside its other files: one JSON object per line,
//! either a [`Row`] (one cell of the command's matrix: where it ran, what the cell is, its
//! figures) or a [`Plan`] (the whole matrix a run or shard belongs to, so a merge can name the
//! cells nobody measured). A row carries its own device, driver, commit and settings, so rows
//! from many runners, shards and devices can be concatenated and still be told apart, the way
//! deqp-runner's result lists merge.
//!
//! A figure says how to compare it ([`Class`]): a timing carries its min-max over the timed rounds
//! (a difference is real only when two ranges do not overlap, the rule of the study's claims);
//! a count (SPIR-V or machine instructions, spills) is exact; a correctness figure (agreement,
//! leaks, NaN hits) is always reported when it changes.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::report::Summary;

/// The file name every command writes its rows to, in its output folder.
pub const FILE: &str = "rows.jsonl";

/// The schema tag on every line; a reader refuses lines of another schema by name.
pub const SCHEMA: &str = "trilab-rows/1";

/// Which way a figure is better.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Better {
    Lower,
    Higher,
}

/// How a figure is compared between two runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Class {
    /// A measured time or rate over several rounds: median with min-max.
    Timing,
    /// An exact count from a compiler (instructions, spills, calls): any change is real.
    Count,
    /// Agreement with the reference, leaks, NaN hits: any change is reported, a worsening fails.
    Correctness,
}

/// One figure of a cell.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Figure {
    pub median: f64,
    pub min: f64,
    pub max: f64,
    /// Timed rounds behind median/min/max (1 for counts and correctness figures).
    pub runs: usize,
    pub unit: String,
    pub better: Better,
    pub class: Class,
}

impl Figure {
    /// A timing from the rounds' summary.
    pub fn timing(s: Summary, unit: &str, better: Better) -> Figure {
        Figure {
            median: s.median,
            min: s.min,
            max: s.max,
            runs: s.runs,
            unit: unit.into(),
            better,
            class: Class::Timing,
        }
    }

    /// An exact count (lower is better).
    pub fn count(value: f64, unit: &str) -> Figure {
        Figure::exact(value, unit, Better::Lower, Class::Count)
    }

    /// An exact count better the other way, or either way: a compiler's statistic such as the
    /// subgroups a SIMD holds (higher is better).
    pub fn count_toward(value: f64, unit: &str, better: Better) -> Figure {
        Figure::exact(value, unit, better, Class::Count)
    }

    /// A correctness figure, such as agreement (higher is better) or leaks (lower is better).
    pub fn correctness(value: f64, unit: &str, better: Better) -> Figure {
        Figure::exact(value, unit, better, Class::Correctness)
    }

    fn exact(value: f64, unit: &str, better: Better, class: Class) -> Figure {
        Figure { median: value, min: value, max: value, runs: 1, unit: unit.into(), better, class }
    }

    /// Whether the two figures' min-max ranges overlap (then their difference is not real).
    pub fn overlaps(&self, other: &Figure) -> bool {
        self.min <= other.max && other.min <= self.max
    }
}

/// The setting naming the CPU a driver's JIT compiled the row's kernels for ([`crate::host::Host::cpu_id`]):
/// lavapipe's machine code is LLVM's for the host CPU, so the driver statistics of two runs are
/// the same code's only when their `jit_cpu` agree; `trilab compare` does not judge counts whose
/// rows name different ones.
pub const JIT_CPU: &str = "jit_cpu";

/// The setting naming the GLSL compiler that made the row's SPIR-V ([`crate::kernels::SPIRV_COMPILER`]):
/// glslang and SPIRV-Tools decide the modules, so instruction counts (and the machine code a
/// driver makes of them) are the same code's only when two rows name the same compiler;
/// `trilab compare` does not judge counts whose rows name different ones.
pub const SPIRV_COMPILER: &str = "spirv_compiler";

/// The setting naming the driver build that compiled the row's kernels (its `driverInfo`, such
/// as `Mesa 25.0.7-2~bpo12+1`, with the LLVM it uses): another build of the same driver compiles
/// other code, so `trilab compare` (and the gate) do not judge the counts of rows whose
/// `driver_build` differ, and say so.
pub const DRIVER_BUILD: &str = "driver_build";

/// Where a row was measured: enough to tell runners, devices and driver settings apart.
#[derive(Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Source {
    pub device: String,
    pub driver: String,
    pub commit: String,
    pub date: String,
    /// The driver settings that change what is measured (`LP_NATIVE_VECTOR_WIDTH`,
    /// `LP_NUM_THREADS`, the subgroup size, ...), name to value.
    #[serde(default)]
    pub settings: BTreeMap<String, String>,
    /// The host CPU the run ran on (model, logical CPUs, load average): on lavapipe it is the
    /// device. `None` in rows of figures no host changes (SPIR-V counts) and in rows written
    /// before it was recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<crate::host::Host>,
}

impl Source {
    /// The label a merge gives a device: its name, and the settings that tell two runs of one
    /// device apart.
    pub fn device_label(&self) -> String {
        let mut s = self.device.clone();
        for (k, v) in &self.settings {
            if k != "LP_NUM_THREADS" {
                s.push_str(&format!(", {k}={v}"));
            }
        }
        s
    }
}

/// A cell's coordinates within its command's matrix (`scene=bunny`, `set=primary`,
/// `method=mt`, `layout=bvh2`, `leaf=4`, ...), in a stable order.
pub type Cell = BTreeMap<String, String>;

/// Builds a [`Cell`] from pairs.
pub fn cell<K: Into<String>, V: ToString>(pairs: impl IntoIterator<Item = (K, V)>) -> Cell {
    pairs.into_iter().map(|(k, v)| (k.into(), v.to_string())).collect()
}

/// One cell's figures, self-describing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    /// The command that measured it: `bench`, `study`, `accuracy`, `profile`, `spirv`,
    /// `build-bench`, `driver-stats`, ...
    pub command: String,
    pub cell: Cell,
    pub figures: BTreeMap<String, Figure>,
    /// What identifies the cell's result rather than measures it (a compiled kernel's hash), as
    /// text: compared as changed or unchanged, never as better or worse.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub identities: BTreeMap<String, String>,
    pub source: Source,
}

impl Row {
    pub fn new(command: &str, cell: Cell, source: &Source) -> Row {
        Row {
            command: command.into(),
            cell,
            figures: BTreeMap::new(),
            identities: BTreeMap::new(),
            source: source.clone(),
        }
    }

    /// With an identity (a hash): see [`Row::identities`].
    pub fn with_identity(mut self, name: &str, value: &str) -> Row {
        self.identities.insert(name.into(), value.into());
        self
    }

    pub fn with(mut self, name: &str, f: Figure) -> Row {
        self.figures.insert(name.into(), f);
        self
    }

    /// `command scene=bunny set=primary ...`: how a report names the cell.
    pub fn key(&self) -> String {
        cell_key(&self.command, &self.cell)
    }
}

/// The name of a cell of a command: `study scene=bunny leaf=4 method=mt`.
pub fn cell_key(command: &str, cell: &Cell) -> String {
    let mut s = command.to_owned();
    for (k, v) in cell {
        s.push_str(&format!(" {k}={v}"));
    }
    s
}

/// Whether a row's `cell` fills the `planned` cell: it agrees on every coordinate the plan
/// names. A plan names a cell by what the options choose; a row may add coordinates that are
/// measured (bench's `rays`, the size of a ray set that depends on the scene's hits).
pub fn plan_matches(planned: &Cell, cell: &Cell) -> bool {
    planned.iter().all(|(k, v)| cell.get(k) == Some(v))
}

/// Which share of a matrix a run took: shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl Shard {
    /// Whether cell number `i` (0-based, in the matrix's order) belongs to this shard
    /// (round-robin, so every shard gets a share of every scene).
    pub fn owns(&self, i: usize) -> bool {
        i % self.count as usize == (self.index - 1) as usize
    }
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Shard, String> {
        let bad = || format!("`{s}`: a shard is I/N with 1 <= I <= N, such as 2/4");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (i.trim().parse::<u32>().map_err(|_| bad())?, n.trim().parse::<u32>().map_err(|_| bad())?);
        if count == 0 || index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The whole matrix of a run (every cell of every shard), written once per rows file so that a
/// merge can list the cells no runner measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub command: String,
    /// The shard this run took, if it took one.
    pub shard: Option<Shard>,
    pub cells: Vec<Cell>,
    pub source: Source,
}

/// One line of a rows file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum Line {
    Plan(Plan),
    Row(Row),
}

#[derive(Serialize, Deserialize)]
struct Tagged {
    schema: String,
    #[serde(flatten)]
    line: Line,
}

/// Rows and plans read from one or more files.
#[derive(Clone, Debug, Default)]
pub struct RowSet {
    pub rows: Vec<Row>,
    pub plans: Vec<Plan>,
    /// The files they came from.
    pub files: Vec<PathBuf>,
}

impl RowSet {
    pub fn extend(&mut self, other: RowSet) {
        self.rows.extend(other.rows);
        self.plans.extend(other.plans);
        self.files.extend(other.files);
    }
}

/// The text of a rows file: an optional plan, then the rows, one JSON object per line.
pub fn to_jsonl(plan: Option<&Plan>, rows: &[Row]) -> String {
    let mut out = String::new();
    let lines = plan.map(|p| Line::Plan(p.clone())).into_iter().chain(rows.iter().cloned().map(Line::Row));
    for line in lines {
        let tagged = Tagged { schema: SCHEMA.into(), line };
        out.push_str(&serde_json::to_string(&tagged).expect("rows serialize"));
        out.push('\n');
    }
    out
}

/// Writes `dir/rows.jsonl` atomically.
pub fn write(dir: &Path, plan: Option<&Plan>, rows: &[Row]) -> Result<PathBuf> {
    let path = dir.join(FILE);
    crate::io::write_atomic(&path, to_jsonl(plan, rows).as_bytes())?;
    Ok(path)
}

/// Parses a rows file's text; errors name `path` and the line.
pub fn parse(path: &Path, text: &str) -> Result<RowSet> {
    let mut set = RowSet { files: vec![path.to_owned()], ..RowSet::default() };
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let value: serde_json::Value = serde_json::from_str(line)
            .map_err(|e| Error::bad_input(path, Some(i + 1), format!("not a JSON object: {e}")))?;
        match value.get("schema").and_then(|s| s.as_str()) {
            Some(SCHEMA) => {}
            Some(other) => {
                return Err(Error::bad_input(
                    path,
                    Some(i + 1),
                    format!("schema `{other}`; this trilab reads `{SCHEMA}`"),
                ))
            }
            None => {
                return Err(Error::bad_input(path, Some(i + 1), format!("no `schema` field (expected `{SCHEMA}`)")))
            }
        }
        let tagged: Tagged = serde_json::from_value(value)
            .map_err(|e| Error::bad_input(path, Some(i + 1), format!("not a trilab row or plan: {e}")))?;
        match tagged.line {
            Line::Plan(p) => set.plans.push(p),
            Line::Row(r) => {
                if let Some((name, _)) = r.figures.iter().find(|(_, f)| !(f.min <= f.median && f.median <= f.max)) {
                    return Err(Error::bad_input(
                        path,
                        Some(i + 1),
                        format!("figure `{name}` of {}: median outside min-max", r.key()),
                    ));
                }
                set.rows.push(r)
            }
        }
    }
    Ok(set)
}

/// Reads one rows file (`rows.jsonl`, or `rows.jsonl.gz` as committed results keep it).
pub fn read_file(path: &Path) -> Result<RowSet> {
    parse(path, &crate::io::read_text(path)?)
}

/// Whether `name` is a rows file's: [`FILE`], or [`FILE`] gzip-compressed.
fn is_rows_file(name: &std::ffi::OsStr) -> bool {
    name == FILE || name.to_str().and_then(|n| n.strip_suffix(crate::io::GZ)) == Some(FILE)
}

/// Every `rows.jsonl` (or `rows.jsonl.gz`) under `path` (a folder, searched recursively in name
/// order), or `path` itself when it is a file. A folder without any rows file is an error that
/// says so, and so is one folder holding both forms (one run, or two that would count twice?).
pub fn read(path: &Path) -> Result<RowSet> {
    if !path.exists() {
        return Err(Error::bad_input(path, None, "no such file or folder"));
    }
    if path.is_file() {
        return read_file(path);
    }
    let mut files = vec![];
    collect(path, &mut files)?;
    if files.is_empty() {
        return Err(Error::bad_input(
            path,
            None,
            format!("no {FILE} below this folder (results written before trilab wrote rows cannot be compared)"),
        ));
    }
    let mut set = RowSet::default();
    for f in files {
        set.extend(read_file(&f)?);
    }
    Ok(set)
}

fn collect(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    let mut entries: Vec<PathBuf> =
        std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    let mut here = vec![];
    for p in entries {
        if p.is_dir() {
            collect(&p, out)?;
        } else if p.file_name().is_some_and(is_rows_file) {
            here.push(p);
        }
    }
    if let [plain, gz] = &here[..] {
        return Err(Error::bad_input(
            gz,
            None,
            format!("{} is beside it: a folder holds one rows file, plain or compressed", plain.display()),
        ));
    }
    out.extend(here);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn source() -> Source {
        Source { device: "llvmpipe (LLVM 15.0.6, 256 bits)".into(), driver: "Mesa 25.0.7".into(), ..Source::default() }
    }

    #[test]
    fn rows_and_plans_survive_a_round_trip() {
        let s = source();
        let c = cell([("scene", "bunny"), ("leaf", "4")]);
        let row = Row::new("study", c.clone(), &s)
            .with("render_s", Figure::timing(Summary { median: 2.0, min: 1.5, max: 2.5, runs: 3 }, "s", Better::Lower))
            .with("agreement", Figure::correctness(0.999, "fraction", Better::Higher));
        let plan =
            Plan { command: "study".into(), shard: Some(Shard { index: 1, count: 2 }), cells: vec![c], source: s };
        let text = to_jsonl(Some(&plan), std::slice::from_ref(&row));
        assert_eq!(text.lines().count(), 2);
        let back = parse(Path::new("x/rows.jsonl"), &text).unwrap();
        assert_eq!(back.rows, vec![row]);
        assert_eq!(back.plans, vec![plan]);
    }

    #[test]
    fn bad_lines_name_the_file_and_line() {
        let p = Path::new("base/rows.jsonl");
        let e = parse(p, "\n{\"schema\":\"trilab-rows/9\",\"type\":\"row\"}\n").unwrap_err().to_string();
        assert!(e.contains("base/rows.jsonl") && e.contains('2') && e.contains("trilab-rows/9"), "{e}");
        let e = parse(p, "{not json").unwrap_err().to_string();
        assert!(e.contains("base/rows.jsonl") && e.contains("JSON"), "{e}");
        let bad = "{\"schema\":\"trilab-rows/1\",\"type\":\"row\",\"command\":\"bench\",\"cell\":{},\"source\":{\"device\":\"d\",\
                   \"driver\":\"v\",\"commit\":\"c\",\"date\":\"t\"},\"figures\":{\"ms\":{\"median\":5,\"min\":1,\"max\":2,\
                   \"runs\":3,\"unit\":\"ms\",\"better\":\"lower\",\"class\":\"timing\"}}}";
        let e = parse(p, bad).unwrap_err().to_string();
        assert!(e.contains("median outside min-max"), "{e}");
    }

    #[test]
    fn a_row_fills_the_planned_cell_it_agrees_with_on_the_plan_s_coordinates() {
        let planned = cell([("scene", "bunny"), ("set", "diffuse")]);
        assert!(plan_matches(&planned, &cell([("scene", "bunny"), ("set", "diffuse"), ("rays", "812")])));
        assert!(plan_matches(&planned, &planned));
        assert!(!plan_matches(&planned, &cell([("scene", "bunny"), ("set", "primary"), ("rays", "812")])));
        assert!(!plan_matches(&planned, &cell([("scene", "bunny")])), "a row lacking a planned coordinate");
    }

    #[test]
    fn shards_split_a_matrix_exactly_once() {
        let shards: Vec<Shard> = (1..=3).map(|i| format!("{i}/3").parse().unwrap()).collect();
        for cell in 0..10 {
            assert_eq!(shards.iter().filter(|s| s.owns(cell)).count(), 1, "cell {cell}");
        }
        for bad in ["0/3", "4/3", "1/0", "2", "a/b", "1/-2"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        assert_eq!("2/5".parse::<Shard>().unwrap().to_string(), "2/5");
    }

    #[test]
    fn reads_every_rows_file_below_a_folder_and_refuses_an_empty_one() {
        let dir = tempfile::tempdir().unwrap();
        let s = source();
        std::fs::create_dir_all(dir.path().join("bench")).unwrap();
        write(&dir.path().join("bench"), None, &[Row::new("bench", cell([("set", "primary")]), &s)]).unwrap();
        write(dir.path(), None, &[Row::new("study", Cell::new(), &s)]).unwrap();
        let set = read(dir.path()).unwrap();
        assert_eq!(set.rows.len(), 2);
        assert_eq!(set.files.len(), 2);
        let empty = tempfile::tempdir().unwrap();
        let e = read(empty.path()).unwrap_err().to_string();
        assert!(e.contains("no rows.jsonl"), "{e}");
    }

    /// Committed results keep bulky rows gzip-compressed: a reader finds and reads them as the
    /// plain file, and refuses a folder that holds both forms.
    #[test]
    fn compressed_rows_read_as_the_plain_ones() {
        use std::io::Write as _;
        let dir = tempfile::tempdir().unwrap();
        let s = source();
        let rows = [Row::new("bench", cell([("set", "primary")]), &s), Row::new("study", Cell::new(), &s)];
        let plain = write(dir.path(), None, &rows).unwrap();
        let text = std::fs::read(&plain).unwrap();
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        e.write_all(&text).unwrap();
        std::fs::write(sub.join("rows.jsonl.gz"), e.finish().unwrap()).unwrap();
        assert_eq!(read(&sub).unwrap().rows, read(&plain).unwrap().rows);
        assert_eq!(read(&sub.join("rows.jsonl.gz")).unwrap().rows.len(), 2);
        std::fs::copy(&plain, sub.join("rows.jsonl")).unwrap();
        let e = read(&sub).unwrap_err().to_string();
        assert!(e.contains("rows.jsonl.gz") && e.contains("one rows file"), "{e}");
    }
}
