//! The paper's three claims (Shumskiy & Parshin, sec. 4), checked against a study's render
//! times: (a) 4 triangles per leaf is optimal; (b) Möller-Trumbore is up to 5 % faster than the
//! unit-triangle test; (c) Quad unit triangle is 5-20 % faster than Möller-Trumbore on NVIDIA and
//! up to 2x on VLIW AMD. Each verdict comes with the numbers it rests on. A difference counts as
//! real only when the two configurations' min-max ranges over the timed rounds do not overlap.
//!
//! Each claim is judged per node layout (`--layouts`): a verdict for the binary tree the paper
//! measured, and one for each wide layout on the same scenes.
//!
//! The claims judge from a [`Grid`] of render-time summaries, which is built either from one
//! run's [`StudyReport`] ([`Grid::of`]) or from the rows of many runners and shards of one device
//! (`trilab merge`, `commands::merge`): both give the same verdicts on the same numbers.

use std::fmt::Write as _;

use serde::Serialize;

use super::{layouts_of, names_layouts, scenes, StudyCell, StudyReport};
use crate::encoding::{Layout, Method};
use crate::report::Summary;

/// The render times (seconds) the claims judge from: the matrix's axes in their order and one
/// summary per measured cell (scene, leaf size, method, layout). Cells may be missing.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Grid {
    pub scenes: Vec<String>,
    pub leaf_sizes: Vec<u32>,
    pub methods: Vec<Method>,
    pub layouts: Vec<Layout>,
    /// Timed rounds behind the times (the fewest of any cell): below 2 there is no run-to-run
    /// spread, and the claims are not judged.
    pub repeat: usize,
    pub times: Vec<GridCell>,
}

/// One cell's render seconds.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridCell {
    #[serde(flatten)]
    pub cell: StudyCell,
    pub seconds: Summary,
}

impl Grid {
    /// The render times of a study's report, on its axes.
    pub fn of(report: &StudyReport) -> Grid {
        Grid {
            scenes: scenes(report),
            leaf_sizes: report.options.leaf_sizes.clone(),
            methods: report.options.methods.clone(),
            layouts: layouts_of(report),
            repeat: report.options.repeat,
            times: report.rows.iter().map(|r| GridCell { cell: r.cell(), seconds: r.render_seconds() }).collect(),
        }
    }

    /// Render seconds of the cell (scene, leaf, method, layout).
    pub fn time(&self, scene: &str, leaf: u32, m: Method, l: Layout) -> Option<Summary> {
        self.times
            .iter()
            .find(|c| c.cell.scene == scene && c.cell.leaf == leaf && c.cell.method == m && c.cell.layout == l)
            .map(|c| c.seconds)
    }

    /// Whether the grid can judge the claims: a difference is real only when the min-max ranges
    /// of the timed rounds do not overlap, and a single round has no range.
    pub fn can_judge(&self) -> bool {
        self.repeat >= 2
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    Holds,
    /// Holds only where the differences are real; elsewhere within the run-to-run spread.
    HoldsWithinNoise,
    Partly,
    /// Every difference lies within the run-to-run spread and the medians do not side with it.
    Inconclusive,
    DoesNotHold,
    /// The study lacks the cells the claim needs.
    NotMeasured,
    /// One timed round: no run-to-run spread to tell a real difference from noise.
    NotJudged,
}

impl Verdict {
    pub fn label(self) -> &'static str {
        match self {
            Verdict::Holds => "holds",
            Verdict::HoldsWithinNoise => "holds within noise",
            Verdict::Partly => "partly holds",
            Verdict::Inconclusive => "inconclusive (all differences within the run-to-run spread)",
            Verdict::DoesNotHold => "does not hold",
            Verdict::NotMeasured => "not measured",
            Verdict::NotJudged => "not judged (a single timed round has no run-to-run spread)",
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Claim {
    pub id: char,
    /// The layout whose render times judged it.
    pub layout: Layout,
    pub statement: &'static str,
    pub verdict: Verdict,
    /// One line per scene (and method or leaf size) with the numbers.
    pub evidence: Vec<String>,
    pub summary: String,
}

/// Render seconds of the cell (scene, leaf, method, layout).
pub fn time(report: &StudyReport, scene: &str, leaf: u32, m: Method, l: Layout) -> Option<Summary> {
    super::cell(report, scene, leaf, m, l).map(super::StudyRow::render_seconds)
}

/// Whether two min-max ranges overlap: then their difference is not called real.
pub fn overlap(a: Summary, b: Summary) -> bool {
    a.min <= b.max && b.min <= a.max
}

/// Geometric mean over scenes of `m`'s render time over `base`'s at `leaf`, both on `layout`.
pub fn relative_time(report: &StudyReport, m: Method, base: Method, leaf: u32, layout: Layout) -> Option<f64> {
    relative_time_in(&Grid::of(report), m, base, leaf, layout)
}

/// [`relative_time`] on a grid.
pub fn relative_time_in(g: &Grid, m: Method, base: Method, leaf: u32, layout: Layout) -> Option<f64> {
    let ratios: Vec<f64> = g
        .scenes
        .iter()
        .filter_map(|s| Some(g.time(s, leaf, m, layout)?.median / g.time(s, leaf, base, layout)?.median))
        .collect();
    (!ratios.is_empty()).then(|| (ratios.iter().map(|r| r.ln()).sum::<f64>() / ratios.len() as f64).exp())
}

/// (a) 4 triangles per leaf is optimal: for each scene and method, the fastest leaf size on
/// `layout`.
pub fn leaf_four_optimal(report: &StudyReport, layout: Layout) -> Claim {
    leaf_four_optimal_in(&Grid::of(report), layout)
}

/// [`leaf_four_optimal`] on a grid.
pub fn leaf_four_optimal_in(g: &Grid, layout: Layout) -> Claim {
    let mut evidence = vec![];
    let (mut best4, mut noise, mut other, mut total) = (0, 0, 0, 0);
    for scene in &g.scenes {
        for &m in &g.methods {
            let times: Vec<(u32, Summary)> =
                g.leaf_sizes.iter().filter_map(|&l| Some((l, g.time(scene, l, m, layout)?))).collect();
            let Some(&(best_leaf, best)) = times.iter().min_by(|a, b| a.1.median.total_cmp(&b.1.median)) else {
                continue;
            };
            let Some(&(_, four)) = times.iter().find(|(l, _)| *l == 4) else { continue };
            total += 1;
            let line = format!(
                "{scene} {m}: fastest at leaf {best_leaf} ({:.3} s); leaf 4 {:.3} s ({:+.1} %)",
                best.median,
                four.median,
                100.0 * (four.median / best.median - 1.0)
            );
            if best_leaf == 4 {
                best4 += 1;
                evidence.push(line);
            } else if overlap(best, four) {
                noise += 1;
                evidence.push(line + ", ranges overlap");
            } else {
                other += 1;
                evidence.push(line);
            }
        }
    }
    let verdict = match (total, best4, other) {
        (0, _, _) => Verdict::NotMeasured,
        (t, b, _) if b == t => Verdict::Holds,
        (_, _, 0) => Verdict::HoldsWithinNoise,
        (_, 0, _) if noise == 0 => Verdict::DoesNotHold,
        _ => Verdict::Partly,
    };
    Claim {
        id: 'a',
        layout,
        statement: "4 triangles per BVH leaf is optimal",
        verdict,
        summary: format!(
            "leaf 4 fastest in {best4} of {total} scene x method pairs, within the run-to-run spread of the fastest \
             in {noise}, clearly slower in {other}"
        ),
        evidence,
    }
}

/// (b) Möller-Trumbore is up to 5 % faster than the unit-triangle test (every leaf size), on
/// `layout`.
pub fn mt_faster_than_unit(report: &StudyReport, layout: Layout) -> Claim {
    mt_faster_than_unit_in(&Grid::of(report), layout)
}

/// [`mt_faster_than_unit`] on a grid.
pub fn mt_faster_than_unit_in(g: &Grid, layout: Layout) -> Claim {
    let mut evidence = vec![];
    let (mut mt_wins, mut unit_wins, mut ties, mut ratios) = (0, 0, 0, vec![]);
    for scene in &g.scenes {
        for &leaf in &g.leaf_sizes {
            let (Some(mt), Some(unit)) =
                (g.time(scene, leaf, Method::Mt, layout), g.time(scene, leaf, Method::Unit, layout))
            else {
                continue;
            };
            let r = unit.median / mt.median;
            ratios.push(r);
            let real = !overlap(mt, unit);
            match (r > 1.0, real) {
                (_, false) => ties += 1,
                (true, true) => mt_wins += 1,
                (false, true) => unit_wins += 1,
            }
            evidence.push(format!(
                "{scene} leaf {leaf}: unit / MT time = {r:.3}{}",
                if real { "" } else { " (ranges overlap)" }
            ));
        }
    }
    let n = ratios.len();
    let verdict = if n == 0 {
        Verdict::NotMeasured
    } else if unit_wins == 0 && mt_wins == n {
        Verdict::Holds
    } else if unit_wins == 0 && ratios.iter().all(|&r| r >= 1.0) {
        Verdict::HoldsWithinNoise
    } else if mt_wins == 0 && unit_wins == 0 {
        Verdict::Inconclusive
    } else if mt_wins == 0 {
        Verdict::DoesNotHold
    } else {
        Verdict::Partly
    };
    let (lo, hi) = ratios.iter().fold((f64::MAX, f64::MIN), |(a, b), &r| (a.min(r), b.max(r)));
    Claim {
        id: 'b',
        layout,
        statement: "Möller-Trumbore is up to 5 % faster than unit triangle",
        verdict,
        summary: if n == 0 {
            "no cell has both methods".into()
        } else {
            format!(
                "unit / MT render time {lo:.3}-{hi:.3} over {n} cells: MT clearly faster in {mt_wins}, unit clearly \
                 faster in {unit_wins}, within the spread in {ties}"
            )
        },
        evidence,
    }
}

/// (c) Quad unit triangle is 5-20 % faster than Möller-Trumbore (NVIDIA), up to 2x (VLIW AMD),
/// at the paper's 4 triangles per leaf, on `layout`.
pub fn quad_unit_faster_than_mt(report: &StudyReport, layout: Layout) -> Claim {
    quad_unit_faster_than_mt_in(&Grid::of(report), layout)
}

/// [`quad_unit_faster_than_mt`] on a grid.
pub fn quad_unit_faster_than_mt_in(g: &Grid, layout: Layout) -> Claim {
    let mut evidence = vec![];
    let mut speedups = vec![];
    let mut real_5 = 0;
    for scene in &g.scenes {
        let (Some(mt), Some(q)) = (g.time(scene, 4, Method::Mt, layout), g.time(scene, 4, Method::QuadUnit, layout))
        else {
            continue;
        };
        let s = mt.median / q.median;
        speedups.push(s);
        // "5 % faster" is real when even the slowest Quad run beats the fastest MT run by 5 %.
        if mt.min / q.max >= 1.05 {
            real_5 += 1;
        }
        evidence.push(format!(
            "{scene} leaf 4: MT {:.3} s, Quad unit {:.3} s, speed-up {s:.3} (range {:.3}-{:.3})",
            mt.median,
            q.median,
            mt.min / q.max,
            mt.max / q.min
        ));
    }
    let n = speedups.len();
    let in_band = speedups.iter().filter(|&&s| s >= 1.05).count();
    let verdict = if n == 0 {
        Verdict::NotMeasured
    } else if real_5 == n {
        Verdict::Holds
    } else if in_band == n {
        Verdict::HoldsWithinNoise
    } else if in_band == 0 {
        Verdict::DoesNotHold
    } else {
        Verdict::Partly
    };
    Claim {
        id: 'c',
        layout,
        statement: "Quad unit triangle is 5-20 % faster than Möller-Trumbore on NVIDIA, up to 2x on VLIW",
        verdict,
        summary: if n == 0 {
            "no scene has MT and Quad unit at leaf 4".into()
        } else {
            format!(
                "speed-up at leaf 4: {} (>= 1.05 in {in_band} of {n} scenes, beyond the spread in {real_5})",
                speedups.iter().map(|s| format!("{s:.3}")).collect::<Vec<_>>().join(", ")
            )
        },
        evidence,
    }
}

/// Whether the study can judge the claims: a difference is real only when the min-max ranges of
/// the timed rounds do not overlap, and a single round has no range.
pub fn can_judge(report: &StudyReport) -> bool {
    report.options.repeat >= 2
}

/// Every claim on every layout of the report, layout by layout.
pub fn all(report: &StudyReport) -> Vec<Claim> {
    all_in(&Grid::of(report))
}

/// [`all`] on a grid.
pub fn all_in(g: &Grid) -> Vec<Claim> {
    let mut claims: Vec<Claim> = g
        .layouts
        .iter()
        .flat_map(|&l| [leaf_four_optimal_in(g, l), mt_faster_than_unit_in(g, l), quad_unit_faster_than_mt_in(g, l)])
        .collect();
    if !g.can_judge() {
        for c in &mut claims {
            if c.verdict != Verdict::NotMeasured {
                c.verdict = Verdict::NotJudged;
            }
        }
    }
    claims
}

pub fn markdown(report: &StudyReport) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "Measured on {} with render times (the paper's metric).\n", report.provenance.device);
    if let Some(shard) = report.options.shard {
        let _ = writeln!(
            s,
            "**Partial: shard {shard} of the matrix.** These verdicts judge only this shard's {} of the matrix's {} \
             cells; `trilab merge` of every shard's folder judges the whole matrix.\n",
            report.rows.len(),
            report.options.plan_cells().len()
        );
    }
    if !can_judge(report) {
        let _ = writeln!(
            s,
            "**This run cannot judge the paper's claims:** it has {} timed round ({} preset), so no run-to-run \
             spread to tell a real difference from noise; the numbers below are shown, not judged. Run \
             `trilab study --preset lavapipe` (or `--repeat 3` or more) for verdicts.\n",
            report.options.repeat, report.options.preset
        );
    }
    let claims = all(report);
    if names_layouts(report) {
        let _ = writeln!(s, "Each claim is judged on each node layout's render times.\n");
        let _ = writeln!(s, "{}", verdicts_table(report, &claims).to_markdown());
    }
    let mut last = None;
    for c in claims {
        if names_layouts(report) && last != Some(c.layout) {
            let _ = writeln!(s, "### On {} (`{}`)\n", c.layout.title(), c.layout);
            last = Some(c.layout);
        }
        let _ = writeln!(s, "**({}) {}: {}.** {}.\n", c.id, c.statement, c.verdict.label(), c.summary);
        for e in &c.evidence {
            let _ = writeln!(s, "- {e}");
        }
        s.push('\n');
    }
    s
}

/// One row per claim, one verdict column per layout.
pub fn verdicts_table(report: &StudyReport, claims: &[Claim]) -> crate::report::Table {
    let ls = layouts_of(report);
    let mut head = vec!["claim".to_string()];
    head.extend(ls.iter().map(|l| format!("{} ({l})", l.title())));
    let mut t = crate::report::Table::new(head);
    let mut ids: Vec<char> = vec![];
    for c in claims {
        if !ids.contains(&c.id) {
            ids.push(c.id);
        }
    }
    for id in ids {
        let mut cells = vec![format!("({id})")];
        for &l in &ls {
            let c = claims.iter().find(|c| c.id == id && c.layout == l);
            cells.push(c.map_or_else(|| "-".into(), |c| c.verdict.label().to_string()));
        }
        t.row(cells);
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::study::testing::synthetic;

    /// A report of one layout (bvh2) with render times `t(scene, leaf, method)` and +-`spread`.
    fn report(scenes: &[&str], t: impl Fn(&str, u32, Method) -> f64, spread: f64) -> StudyReport {
        synthetic(scenes, &[Layout::Bvh2], |sc, leaf, m, _| t(sc, leaf, m), spread)
    }

    /// The paper's shape: a U in leaf size with its minimum at 4; MT 3 % faster than unit; Quad
    /// unit 12 % faster than MT.
    fn paperlike(_: &str, leaf: u32, m: Method) -> f64 {
        let base = 1.0 + 0.05 * (leaf as f64 - 4.0).abs();
        base * match m {
            Method::Mt => 1.0,
            Method::Unit => 1.03,
            Method::QuadMt => 0.95,
            Method::QuadUnit => 1.0 / 1.12,
            // The claims read only the paper's four methods.
            _ => 1.0,
        }
    }

    #[test]
    fn the_papers_own_numbers_make_every_claim_hold() {
        let r = report(&["bunny", "dragon"], paperlike, 0.001);
        assert_eq!(leaf_four_optimal(&r, Layout::Bvh2).verdict, Verdict::Holds);
        assert_eq!(mt_faster_than_unit(&r, Layout::Bvh2).verdict, Verdict::Holds);
        assert_eq!(quad_unit_faster_than_mt(&r, Layout::Bvh2).verdict, Verdict::Holds);
    }

    #[test]
    fn contrary_numbers_make_them_fail() {
        // Time falls with leaf size (16 fastest), unit beats MT by 10 %, Quad unit 10 % slower.
        let t = |_: &str, leaf: u32, m: Method| {
            (20.0 - leaf as f64)
                * match m {
                    Method::Mt => 1.0,
                    Method::Unit => 0.9,
                    Method::QuadMt => 1.0,
                    Method::QuadUnit => 1.1,
                    _ => 1.0,
                }
        };
        let r = report(&["bunny"], t, 0.01);
        assert_eq!(leaf_four_optimal(&r, Layout::Bvh2).verdict, Verdict::DoesNotHold);
        assert_eq!(mt_faster_than_unit(&r, Layout::Bvh2).verdict, Verdict::DoesNotHold);
        assert_eq!(quad_unit_faster_than_mt(&r, Layout::Bvh2).verdict, Verdict::DoesNotHold);
    }

    #[test]
    fn differences_inside_the_spread_are_not_called_real() {
        // Same shape as the paper's but with a run-to-run spread of +-20 %.
        let r = report(&["bunny"], paperlike, 0.2);
        let b = mt_faster_than_unit(&r, Layout::Bvh2);
        assert_eq!(b.verdict, Verdict::HoldsWithinNoise, "{}", b.summary);
        // Quad unit's 12 % is inside +-20 %: not beyond the spread.
        assert_eq!(quad_unit_faster_than_mt(&r, Layout::Bvh2).verdict, Verdict::HoldsWithinNoise);
    }

    #[test]
    fn relative_time_is_a_geometric_mean_over_scenes() {
        let t = |sc: &str, _: u32, m: Method| {
            if m == Method::Unit && sc == "a" {
                2.0
            } else if m == Method::Unit {
                0.5
            } else {
                1.0
            }
        };
        let r = report(&["a", "b"], t, 0.0);
        assert!((relative_time(&r, Method::Unit, Method::Mt, 4, Layout::Bvh2).unwrap() - 1.0).abs() < 1e-12);
    }

    /// Verdicts are per layout: the paper's shape on bvh2, the contrary on bvh8 (leaf 16
    /// fastest, unit beating MT, Quad unit slower), in one report.
    #[test]
    fn each_layout_gets_its_own_verdict() {
        let t = |sc: &str, leaf: u32, m: Method, l: Layout| {
            if l == Layout::Bvh2 {
                paperlike(sc, leaf, m)
            } else {
                (20.0 - leaf as f64)
                    * match m {
                        Method::Unit => 0.9,
                        Method::QuadUnit => 1.1,
                        _ => 1.0,
                    }
            }
        };
        let r = synthetic(&["bunny"], &[Layout::Bvh2, Layout::Bvh8], t, 0.001);
        let claims = all(&r);
        assert_eq!(claims.len(), 6, "three claims on each of two layouts");
        for c in &claims {
            let want = if c.layout == Layout::Bvh2 { Verdict::Holds } else { Verdict::DoesNotHold };
            assert_eq!(c.verdict, want, "({}) on {}: {}", c.id, c.layout, c.summary);
        }
        let md = markdown(&r);
        assert!(md.contains("### On BVH8 (`bvh8`)") && md.contains("| (a) | holds | does not hold |"), "{md}");
        assert_eq!(md.matches("| (a) |").count(), 1, "one row per claim: {md}");
    }
}
