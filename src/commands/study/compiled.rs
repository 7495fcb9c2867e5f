//! The card's question on GPUs (issue 50): what AMD's real compiler makes of the study's kernels
//! on the paper's HD 7850 (pitcairn, GCN 1) and on today's chips, and what that implies for
//! claim (c), Quad unit 5-20 % faster than Möller-Trumbore.
//!
//! The compiled figures come from RADV's null device, one worker per chip
//! ([`crate::services::driver_stats::collect_targets`]): VGPRs and subgroups per SIMD of each
//! method's kernels, the ray-casting kernel and the path tracer as the study ran them.
//!
//! **A model, labelled as one.** A GPU hides a dependent fetch's latency with the other
//! subgroups on the SIMD (Little's law: the subgroups a SIMD needs are the latency times the
//! rate it issues at; Volkov, "Understanding Latency Hiding on GPUs", 2016), and BVH traversal
//! is bound by its chains of dependent fetches more than by arithmetic (Aila & Laine,
//! "Understanding the Efficiency of Ray Traversal on GPUs", HPG 2009). Per ray, a kernel waits
//! on `R` dependent fetch rounds: one per node visited, and per primitive tested as many as its
//! data's chain of buffers (MT: the index triple, then its vertices, 2; the unit triangle and
//! the Quad forms: 1), from the work the study counted (nodes, triangles, Quad slots per ray,
//! diffuse rays, leaf size 4, the binary tree). Two bounds follow for the Quad-unit/MT time
//! ratio on a chip:
//! - **latency hidden** (both kernels have subgroups enough): `R_quad / R_mt`;
//! - **latency-bound** (too few subgroups, time inversely proportional to them):
//!   `(R_quad / w_quad) / (R_mt / w_mt)`, `w` the subgroups per SIMD the compiler allows.
//!
//! The arithmetic is left out (a Quad test is about four MT tests' work done at once), and so
//! are divergence and caches: the bounds say which way occupancy pushes, not a speed. Table 4
//! of the paper (HD 7850, path tracing, leaf size 4) measured Quad-unit/MT 0.824 (Buddha), 0.818
//! (Bunny), 0.838 (Dragon), set beside them.

use serde::Serialize;

use crate::encoding::{Layout, Method, SceneCounts};
use crate::gpu::amd::Chip;
use crate::matrix::{TargetAxes, TargetItem};
use crate::report::{Status, Table};
use crate::services::driver_stats::report::names;
use crate::services::driver_stats::target::{Compiler, GpuTarget, MesaBuild};
use crate::services::driver_stats::{collect_targets, KernelStats, TargetOptions, TargetStats};
use crate::services::rayset::RaySet;

use super::{cell, scenes, StudyReport};

/// Table 4 of the paper (AMD HD 7850, path tracing, 1000 samples, leaf size 4): seconds for
/// (scene, MT, Quad unit).
pub const TABLE4_HD7850: [(&str, f64, f64); 3] =
    [("buddha", 38.03, 31.35), ("bunny", 36.48, 29.85), ("dragon", 65.56, 54.92)];

/// Table 4's Quad-unit/MT time ratio, geometric mean over its three scenes.
pub fn table4_ratio() -> f64 {
    let logs: f64 = TABLE4_HD7850.iter().map(|(_, mt, q)| (q / mt).ln()).sum();
    (logs / TABLE4_HD7850.len() as f64).exp()
}

/// The chips the study compiles for: the paper's HD 7850, then one of each later generation.
pub const CHIPS: [&str; 5] = ["pitcairn", "polaris10", "navi21", "navi31", "gfx1201"];

/// How the study compiles its kernels for GPUs.
#[derive(Clone, Debug)]
pub struct CompiledOptions {
    /// This executable (each chip's worker).
    pub exe: std::path::PathBuf,
    pub validation: bool,
}

impl CompiledOptions {
    /// The targets: [`CHIPS`] with ACO at wave64, the installed Mesa (the axes' default).
    pub fn targets() -> Vec<GpuTarget> {
        let items = CHIPS
            .iter()
            .map(|c| TargetItem {
                chip: Chip::named(c).expect("known chips"),
                compiler: Some(Compiler::Aco),
                wave: Some(64),
            })
            .collect();
        TargetAxes { items, mesa: vec![] }.targets().expect("every chip compiles at wave64")
    }
}

/// The study's section on GPU compilers.
#[derive(Clone, Debug, Serialize)]
pub struct CompiledSection {
    pub status: Status,
    pub note: String,
    /// What each chip's compiler made of the study's kernels.
    pub targets: Vec<TargetStats>,
    /// The model's bounds per chip and kernel kind.
    pub model: Vec<ModelRow>,
}

/// One chip's bounds for one kind of kernel (path tracing, ray casting).
#[derive(Clone, Debug, Serialize)]
pub struct ModelRow {
    pub chip: String,
    pub architecture: &'static str,
    /// `path tracing` or `ray casting`.
    pub kernels: &'static str,
    pub mt_kernel: String,
    pub quad_kernel: String,
    pub mt_vgprs: f64,
    pub quad_vgprs: f64,
    /// Subgroups per SIMD as RADV reports them.
    pub mt_subgroups: f64,
    pub quad_subgroups: f64,
    /// Dependent fetch rounds per ray (geometric mean over scenes).
    pub mt_rounds: f64,
    pub quad_rounds: f64,
    /// Quad-unit/MT time, latency hidden.
    pub hidden: f64,
    /// Quad-unit/MT time, latency-bound.
    pub latency_bound: f64,
}

/// Dependent fetch rounds per primitive a method's data takes: the length of its chain of
/// buffers (MT's index triples point into its vertex list: 2; a self-contained triangle or
/// quad: 1), read from the method's memory placement.
pub fn rounds_per_primitive(m: Method) -> usize {
    let one = SceneCounts { triangles: 1, vertices: 3, nodes: 1, slots: 1, quads: 1 };
    (m.intersector().placement)(&one).len()
}

/// Dependent fetch rounds per diffuse ray for `m` in `report` at leaf size 4 on the binary tree,
/// geometric mean over its scenes (`None` where it did not measure them).
pub fn rounds_per_ray(report: &StudyReport, m: Method) -> Option<f64> {
    let mut logs = vec![];
    for scene in scenes(report) {
        let row = cell(report, &scene, 4, m, Layout::DEFAULT)?;
        let t = &row.set(RaySet::Diffuse)?.traversal;
        let prims = if m.group_size() > 1 { t.slots.mean / m.group_size() as f64 } else { t.triangles.mean };
        logs.push((t.nodes.mean + rounds_per_primitive(m) as f64 * prims).ln());
    }
    (!logs.is_empty()).then(|| (logs.iter().sum::<f64>() / logs.len() as f64).exp())
}

/// Compiles the study's kernels for [`CHIPS`] and bounds the Quad-unit/MT ratio on each.
pub fn section(report: &StudyReport, o: &CompiledOptions) -> CompiledSection {
    let mut kernels: Vec<&'static crate::kernels::KernelSource> = vec![];
    for r in &report.rows {
        for name in [r.render_kernel, r.raycast_kernel] {
            if let Some(k) = crate::kernels::KERNELS.iter().find(|k| k.name == name) {
                if !kernels.iter().any(|x| x.id == k.id) {
                    kernels.push(k);
                }
            }
        }
    }
    if kernels.is_empty() {
        return CompiledSection {
            status: Status::NotApplicable,
            note: "no kernels ran".into(),
            targets: vec![],
            model: vec![],
        };
    }
    if let Err(e) = MesaBuild::Installed.icd() {
        return CompiledSection { status: Status::Unsupported, note: e.to_string(), targets: vec![], model: vec![] };
    }
    let to = TargetOptions {
        exe: o.exe.clone(),
        validation: o.validation,
        timeout: std::time::Duration::from_secs(600),
        jobs: std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let targets = collect_targets(&CompiledOptions::targets(), &kernels, &to, &|_| {});
    let model = model(report, &targets);
    let failed: Vec<String> =
        targets.iter().filter(|t| t.status != Status::Measured).map(|t| format!("{}: {}", t.target, t.note)).collect();
    CompiledSection {
        status: if failed.len() == targets.len() { Status::Unsupported } else { Status::Measured },
        note: if failed.is_empty() { String::new() } else { format!("not compiled: {}", failed.join("; ")) },
        targets,
        model,
    }
}

/// The kernel of `m` a study row ran, `render` (the path tracer) or not (ray casting), at leaf
/// size 4 on the binary tree, as `t` compiled it.
fn compiled<'a>(report: &StudyReport, t: &'a TargetStats, m: Method, render: bool) -> Option<&'a KernelStats> {
    let row = report.rows.iter().find(|r| r.method == m && r.layout == Layout::DEFAULT && r.leaf_size == 4)?;
    let name = if render { row.render_kernel } else { row.raycast_kernel };
    t.kernels.iter().find(|k| k.name == name)
}

/// The bounds per chip and kernel kind, where MT's and Quad unit's kernels compiled and their
/// work was counted.
pub fn model(report: &StudyReport, targets: &[TargetStats]) -> Vec<ModelRow> {
    let (Some(mt_rounds), Some(quad_rounds)) =
        (rounds_per_ray(report, Method::Mt), rounds_per_ray(report, Method::QuadUnit))
    else {
        return vec![];
    };
    let mut out = vec![];
    for t in targets {
        for (render, kind) in [(true, "path tracing"), (false, "ray casting")] {
            let (Some(mt), Some(q)) =
                (compiled(report, t, Method::Mt, render), compiled(report, t, Method::QuadUnit, render))
            else {
                continue;
            };
            let (Some(wm), Some(wq)) = (mt.statistic(names::SUBGROUPS), q.statistic(names::SUBGROUPS)) else {
                continue;
            };
            let hidden = quad_rounds / mt_rounds;
            out.push(ModelRow {
                chip: t.compiled_for.chip.map_or("?".into(), |c| c.name.to_owned()),
                architecture: t.compiled_for.chip.map_or("?", |c| c.gfx.architecture()),
                kernels: kind,
                mt_kernel: mt.name.clone(),
                quad_kernel: q.name.clone(),
                mt_vgprs: mt.statistic(names::VGPRS).unwrap_or(f64::NAN),
                quad_vgprs: q.statistic(names::VGPRS).unwrap_or(f64::NAN),
                mt_subgroups: wm,
                quad_subgroups: wq,
                mt_rounds,
                quad_rounds,
                hidden,
                latency_bound: hidden * wm / wq,
            });
        }
    }
    out
}

/// The compiled table: per chip, each method's kernels' VGPRs and subgroups per SIMD.
fn compiled_table(report: &StudyReport, s: &CompiledSection) -> Table {
    let methods: Vec<Method> = {
        let mut v: Vec<Method> = vec![];
        for r in &report.rows {
            if !v.contains(&r.method) {
                v.push(r.method);
            }
        }
        v
    };
    let mut headers = vec!["chip".to_owned(), "architecture".into(), "kernels".into()];
    headers.extend(methods.iter().map(|m| format!("{} VGPRs / subgroups", m.intersector().title)));
    let mut t = Table::new(headers);
    for target in s.targets.iter().filter(|t| t.status == Status::Measured) {
        let chip = target.compiled_for.chip;
        for (render, kind) in [(true, "path tracing"), (false, "ray casting")] {
            let mut cells = vec![
                chip.map_or("?".into(), |c| format!("{c} ({})", c.product)),
                chip.map_or("?".into(), |c| c.gfx.architecture().to_owned()),
                kind.to_owned(),
            ];
            for &m in &methods {
                cells.push(compiled(report, target, m, render).map_or("-".into(), |k| {
                    let v = |n: &str| k.statistic(n).map_or("-".into(), |x| format!("{x:.0}"));
                    let spills = k.statistic(names::SPILLED_VGPRS).unwrap_or(0.0);
                    let spill = if spills > 0.0 { format!(", {spills:.0} spilled") } else { String::new() };
                    format!("{} / {}{spill}", v(names::VGPRS), v(names::SUBGROUPS))
                }));
            }
            t.row(cells);
        }
    }
    t
}

/// The section's Markdown.
pub fn markdown(report: &StudyReport) -> String {
    let Some(s) = &report.compiled else { return String::new() };
    let mut out = String::from(
        "\n## The paper's question on GPUs: what AMD's compiler makes of the methods\n\n\
         Each method's kernels as this study ran them (the path tracer, and the closest-hit ray-casting kernel, leaf \
         size 4, the binary tree), compiled by Mesa's RADV with ACO at wave64 on its null device (`RADV_FORCE_FAMILY`: \
         no GPU, the real compiler; `trilab driver-stats --targets` compiles every kernel, results/radv/). VGPRs / \
         subgroups per SIMD (RADV's count: on RDNA a wave64 subgroup counts twice).\n\n",
    );
    if s.status != Status::Measured {
        out.push_str(&format!("Not compiled: {}\n", s.note));
        return out;
    }
    if !s.note.is_empty() {
        out.push_str(&format!("{}\n\n", s.note));
    }
    out.push_str(&compiled_table(report, s).to_markdown());
    if s.model.is_empty() {
        out.push_str(
            "\nThe model needs MT and Quad unit at leaf size 4 on the binary tree, with their work counted.\n",
        );
        return out;
    }
    let r0 = &s.model[0];
    out.push_str(&format!(
        "\n### A model of claim (c) from the compiled code\n\n\
         A model, not a measurement: per diffuse ray MT waits on {:.1} dependent fetch rounds (nodes, then 2 per \
         triangle: its index triple, then the vertices) and Quad unit on {:.1} (nodes, then 1 per quad), from the \
         work this study counted (geometric mean over its scenes). With latency hidden the ratio is the rounds' \
         ratio; latency-bound, each kernel's time also goes as 1 / its subgroups per SIMD. Table 4 of the paper \
         measured Quad unit / MT = {:.3} on the HD 7850 (geometric mean of 0.824, 0.818, 0.838; path tracing). \
         Arithmetic, divergence and caches are left out.\n\n",
        r0.mt_rounds,
        r0.quad_rounds,
        table4_ratio()
    ));
    let mut t = Table::new([
        "chip",
        "kernels",
        "MT VGPRs / subgroups",
        "Quad unit VGPRs / subgroups",
        "Quad/MT, latency hidden",
        "Quad/MT, latency-bound",
        "Table 4 (HD 7850)",
    ]);
    for m in &s.model {
        t.row([
            format!("{} ({})", m.chip, m.architecture),
            m.kernels.to_owned(),
            format!("{:.0} / {:.0}", m.mt_vgprs, m.mt_subgroups),
            format!("{:.0} / {:.0}", m.quad_vgprs, m.quad_subgroups),
            format!("{:.3}", m.hidden),
            format!("{:.3}", m.latency_bound),
            if m.chip == "pitcairn" && m.kernels == "path tracing" {
                format!("{:.3}", table4_ratio())
            } else {
                "-".into()
            },
        ]);
    }
    out.push_str(&t.to_markdown());
    out.push_str(&verdict(&s.model));
    out
}

/// What the compiled code says about claim (c), chip by chip and kernel by kernel.
pub fn verdict(model: &[ModelRow]) -> String {
    let mut out = String::from("\n");
    for m in model {
        let occupancy = m.quad_subgroups / m.mt_subgroups;
        let halves = if occupancy <= 0.55 {
            "halves (or worse)"
        } else if occupancy < 1.0 {
            "cuts"
        } else if occupancy == 1.0 {
            "keeps"
        } else {
            "raises"
        };
        let holds = match (m.hidden < 0.95, m.latency_bound < 0.95) {
            (true, true) => "Quad unit is at least 5 % faster under either bound: claim (c) holds in the model",
            (true, false) => {
                "Quad unit is faster only where the SIMD hides latency with the fewer subgroups it has: \
                              claim (c) rests on latency hiding"
            }
            (false, _) => "Quad unit is not 5 % faster even with latency hidden: claim (c) does not hold in the model",
        };
        out.push_str(&format!(
            "- **{} ({}), {}**: Quad unit {halves} MT's occupancy ({:.0} against {:.0} subgroups per SIMD, {:.0} \
             against {:.0} VGPRs); the bounds are {:.3} (latency hidden) and {:.3} (latency-bound). {holds}.",
            m.chip,
            m.architecture,
            m.kernels,
            m.quad_subgroups,
            m.mt_subgroups,
            m.quad_vgprs,
            m.mt_vgprs,
            m.hidden,
            m.latency_bound
        ));
        if m.chip == "pitcairn" && m.kernels == "path tracing" {
            let t4 = table4_ratio();
            let (lo, hi) = (m.hidden.min(m.latency_bound), m.hidden.max(m.latency_bound));
            out.push_str(&if t4 < lo {
                format!(" The paper's {t4:.3} on this chip is below both bounds: Quad unit gained more than its fewer fetch rounds explain.")
            } else if t4 > hi {
                format!(
                    " The paper's {t4:.3} on this chip is above both bounds: Quad unit gained less than its fewer fetch \
                     rounds would give, the share of time the model leaves out (the arithmetic, four triangles' tests \
                     done for every quad, padding included) being larger on the HD 7850."
                )
            } else {
                format!(
                    " The paper's {t4:.3} on this chip lies between the bounds: the HD 7850 hid part of the latency with \
                     Quad unit's fewer subgroups, not all of it."
                )
            });
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_study_compiles_its_chips_with_aco_at_wave64_on_the_installed_mesa() {
        let t: Vec<String> = CompiledOptions::targets().iter().map(|t| t.to_string()).collect();
        assert_eq!(
            t,
            [
                "pitcairn:aco:64@installed",
                "polaris10:aco:64@installed",
                "navi21:aco:64@installed",
                "navi31:aco:64@installed",
                "gfx1201:aco:64@installed"
            ]
        );
    }

    #[test]
    fn table_4_gives_quad_unit_about_0_83_of_mt() {
        let r = table4_ratio();
        assert!((r - (0.824f64 * 0.818 * 0.838).cbrt()).abs() < 1e-3, "{r}");
    }

    /// MT's index triples point into a vertex list: two dependent rounds per triangle; the unit
    /// triangle and the quads are self-contained: one.
    #[test]
    fn fetch_rounds_follow_each_methods_buffers() {
        assert_eq!(rounds_per_primitive(Method::Mt), 2);
        assert_eq!(rounds_per_primitive(Method::Watertight), 2);
        assert_eq!(rounds_per_primitive(Method::Unit), 1);
        assert_eq!(rounds_per_primitive(Method::QuadUnit), 1);
        assert_eq!(rounds_per_primitive(Method::QuadMt), 1);
    }

    /// The bounds from known inputs: 36.7 rounds for MT, 25.4 for Quad unit, occupancy 6 and 3
    /// (pitcairn's raycast kernels at 40 and 84 VGPRs).
    #[test]
    fn the_bounds_scale_the_rounds_by_occupancy() {
        let m = ModelRow {
            chip: "pitcairn".into(),
            architecture: "GCN 1",
            kernels: "path tracing",
            mt_kernel: String::new(),
            quad_kernel: String::new(),
            mt_vgprs: 40.0,
            quad_vgprs: 84.0,
            mt_subgroups: 6.0,
            quad_subgroups: 3.0,
            mt_rounds: 36.7,
            quad_rounds: 25.4,
            hidden: 25.4 / 36.7,
            latency_bound: 25.4 / 36.7 * 2.0,
        };
        let v = verdict(std::slice::from_ref(&m));
        assert!(v.contains("halves (or worse) MT's occupancy (3 against 6"), "{v}");
        assert!(v.contains("0.692 (latency hidden) and 1.384 (latency-bound)"), "{v}");
        assert!(v.contains("claim (c) rests on latency hiding"), "{v}");
        assert!(v.contains("lies between the bounds"), "{v}");
        // The same occupancy for both: the bounds meet, and Table 4's 0.827 is above them.
        let same = ModelRow { quad_subgroups: 6.0, latency_bound: m.hidden, ..m };
        let v = verdict(&[same]);
        assert!(v.contains("keeps MT's occupancy") && v.contains("holds in the model"), "{v}");
        assert!(v.contains("is above both bounds"), "{v}");
    }
}
