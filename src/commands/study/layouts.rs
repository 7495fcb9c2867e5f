//! Issue 15's question about the layout axis: does the best intersector, and the best leaf
//! size, change with the node layout? Answered from the study's render times (the paper's
//! metric) with the claims' rule: a difference is real only when the two configurations' min-max
//! ranges over the timed rounds do not overlap (`claims::overlap`), and not judged at all from a
//! single timed round.
//!
//! Each layout is compared with the reference layout: `bvh2` (the paper's tree) when the study
//! has it, else the first one asked.
//!
//! - Best intersector per (scene, layout): the method of the fastest cell over every method and
//!   leaf size. Where it is not the reference's, the reference's winner (at its own best leaf on
//!   this layout) is checked against it on this layout: within the spread, or clearly slower.
//! - Best leaf size per (scene, method, layout): the fastest leaf size. Where it is not the
//!   reference's, the reference's best leaf is checked against it on this layout the same way.

use std::fmt::Write as _;

use serde::Serialize;

use super::claims::{can_judge, overlap, time};
use super::{layouts_of, scenes, StudyReport};
use crate::encoding::{Layout, Method};
use crate::report::{Summary, Table};

/// How a layout's best choice relates to the reference layout's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Change {
    /// The reference layout itself.
    Reference,
    /// The same choice is fastest.
    Same,
    /// Another choice is fastest, but the reference's is within its min-max range.
    WithinNoise,
    /// The reference's choice is clearly slower on this layout (the ranges do not overlap).
    Changes,
    /// Another choice is fastest; one timed round has no spread to judge it by.
    NotJudged,
}

impl Change {
    pub fn label(self) -> &'static str {
        match self {
            Change::Reference => "reference",
            Change::Same => "same",
            Change::WithinNoise => "differs within the spread",
            Change::Changes => "changes (ranges do not overlap)",
            Change::NotJudged => "differs (not judged: one timed round)",
        }
    }

    /// `this` is fastest, the reference's choice takes `theirs` on this layout.
    fn judge(report: &StudyReport, same: bool, best: Summary, theirs: Option<Summary>) -> Change {
        match (same, theirs) {
            (true, _) => Change::Same,
            (false, _) if !can_judge(report) => Change::NotJudged,
            // The reference's choice was not measured here: nothing shows it is within reach.
            (false, None) => Change::Changes,
            (false, Some(t)) if overlap(best, t) => Change::WithinNoise,
            (false, Some(_)) => Change::Changes,
        }
    }
}

/// The fastest method on one (scene, layout).
#[derive(Clone, Debug, Serialize)]
pub struct BestMethod {
    pub scene: String,
    pub layout: Layout,
    pub method: Method,
    /// The leaf size of its fastest cell.
    pub leaf_size: u32,
    pub seconds: Summary,
    /// The reference layout's best method, and its best cell on this layout.
    pub reference_method: Method,
    pub reference_seconds: Option<Summary>,
    pub change: Change,
}

/// The fastest leaf size of one (scene, method, layout).
#[derive(Clone, Debug, Serialize)]
pub struct BestLeaf {
    pub scene: String,
    pub method: Method,
    pub layout: Layout,
    pub leaf_size: u32,
    pub seconds: Summary,
    /// The reference layout's best leaf size for this method, and its time on this layout.
    pub reference_leaf: u32,
    pub reference_seconds: Option<Summary>,
    pub change: Change,
}

/// The layout every other is compared with: bvh2 when measured, else the first.
pub fn reference(report: &StudyReport) -> Layout {
    let ls = layouts_of(report);
    if ls.contains(&Layout::DEFAULT) {
        Layout::DEFAULT
    } else {
        ls[0]
    }
}

/// Fastest (by median) of `cells`.
fn fastest<T: Copy>(cells: impl Iterator<Item = (T, Summary)>) -> Option<(T, Summary)> {
    cells.min_by(|a, b| a.1.median.total_cmp(&b.1.median))
}

/// Fastest leaf of (scene, method, layout).
fn best_leaf_of(report: &StudyReport, scene: &str, m: Method, l: Layout) -> Option<(u32, Summary)> {
    fastest(report.options.leaf_sizes.iter().filter_map(|&leaf| Some((leaf, time(report, scene, leaf, m, l)?))))
}

/// Fastest (method, leaf) of (scene, layout).
fn best_cell_of(report: &StudyReport, scene: &str, l: Layout) -> Option<((Method, u32), Summary)> {
    fastest(report.options.methods.iter().filter_map(|&m| {
        let (leaf, s) = best_leaf_of(report, scene, m, l)?;
        Some(((m, leaf), s))
    }))
}

/// The best intersector per scene and layout, against the reference layout's.
pub fn best_methods(report: &StudyReport) -> Vec<BestMethod> {
    let base = reference(report);
    let mut out = vec![];
    for scene in scenes(report) {
        let Some(((ref_method, _), _)) = best_cell_of(report, &scene, base) else { continue };
        for l in layouts_of(report) {
            let Some(((method, leaf_size), seconds)) = best_cell_of(report, &scene, l) else { continue };
            let theirs = best_leaf_of(report, &scene, ref_method, l).map(|(_, s)| s);
            let change = if l == base {
                Change::Reference
            } else {
                Change::judge(report, method == ref_method, seconds, theirs)
            };
            out.push(BestMethod {
                scene: scene.clone(),
                layout: l,
                method,
                leaf_size,
                seconds,
                reference_method: ref_method,
                reference_seconds: theirs,
                change,
            });
        }
    }
    out
}

/// The best leaf size per scene, method and layout, against the reference layout's.
pub fn best_leaves(report: &StudyReport) -> Vec<BestLeaf> {
    let base = reference(report);
    let mut out = vec![];
    for scene in scenes(report) {
        for &m in &report.options.methods {
            let Some((ref_leaf, _)) = best_leaf_of(report, &scene, m, base) else { continue };
            for l in layouts_of(report) {
                let Some((leaf_size, seconds)) = best_leaf_of(report, &scene, m, l) else { continue };
                let theirs = time(report, &scene, ref_leaf, m, l);
                let change = if l == base {
                    Change::Reference
                } else {
                    Change::judge(report, leaf_size == ref_leaf, seconds, theirs)
                };
                out.push(BestLeaf {
                    scene: scene.clone(),
                    method: m,
                    layout: l,
                    leaf_size,
                    seconds,
                    reference_leaf: ref_leaf,
                    reference_seconds: theirs,
                    change,
                });
            }
        }
    }
    out
}

/// Seconds to three significant figures (a smoke run's renders take milliseconds).
fn secs(x: f64) -> String {
    let decimals = if x > 0.0 { (2 - x.log10().floor() as i32).clamp(0, 9) as usize } else { 3 };
    format!("{x:.decimals$}")
}

fn range(s: Summary) -> String {
    format!("{} s ({}-{})", secs(s.median), secs(s.min), secs(s.max))
}

/// The best intersector table: scene, layout, fastest cell, the reference's winner here.
pub fn methods_table(report: &StudyReport, rows: &[BestMethod]) -> Table {
    let base = reference(report);
    let mut t = Table::new([
        "scene".to_string(),
        "layout".into(),
        "fastest method (leaf)".into(),
        "render time".into(),
        format!("{base}'s fastest here"),
        "vs. the reference".into(),
    ]);
    for r in rows {
        t.row([
            r.scene.clone(),
            r.layout.to_string(),
            format!("{} ({})", r.method, r.leaf_size),
            range(r.seconds),
            match (r.change, r.reference_seconds) {
                (Change::Reference | Change::Same, _) => "-".into(),
                (_, Some(s)) => format!("{}: {}", r.reference_method, range(s)),
                (_, None) => format!("{}: not measured", r.reference_method),
            },
            r.change.label().into(),
        ]);
    }
    t
}

/// The best leaf size table: one row per scene and method, one column per layout.
pub fn leaves_table(report: &StudyReport, rows: &[BestLeaf]) -> Table {
    let ls = layouts_of(report);
    let mut head = vec!["scene".to_string(), "method".into()];
    head.extend(ls.iter().map(|l| format!("best leaf on {l}")));
    let mut t = Table::new(head);
    for scene in scenes(report) {
        for &m in &report.options.methods {
            let mine: Vec<&BestLeaf> = rows.iter().filter(|r| r.scene == scene && r.method == m).collect();
            if mine.is_empty() {
                continue;
            }
            let mut cells = vec![scene.clone(), m.to_string()];
            for &l in &ls {
                cells.push(mine.iter().find(|r| r.layout == l).map_or_else(
                    || "-".into(),
                    |r| match (r.change, r.reference_seconds) {
                        (Change::Reference | Change::Same, _) => {
                            format!("{} ({} s)", r.leaf_size, secs(r.seconds.median))
                        }
                        (c, theirs) => format!(
                            "{} ({} s; leaf {}: {}): {}",
                            r.leaf_size,
                            secs(r.seconds.median),
                            r.reference_leaf,
                            theirs.map_or("-".into(), |s| format!("{} s", secs(s.median))),
                            c.label()
                        ),
                    },
                ));
            }
            t.row(cells);
        }
    }
    t
}

/// "a of n" counts of the changes among the non-reference rows.
fn tally(changes: &[Change]) -> String {
    let n = changes.len();
    let count = |c: Change| changes.iter().filter(|&&x| x == c).count();
    let mut s = format!("the same in {} of {n}", count(Change::Same));
    let within = count(Change::WithinNoise);
    let real = count(Change::Changes);
    let unjudged = count(Change::NotJudged);
    if within > 0 {
        let _ = write!(s, ", different within the spread in {within}");
    }
    if real > 0 {
        let _ = write!(s, ", changed beyond the spread in {real}");
    }
    if unjudged > 0 {
        let _ = write!(s, ", different but not judged (one timed round) in {unjudged}");
    }
    s
}

/// The answer, in words: per layout, whether the best intersector and the best leaf size
/// change, and where.
pub fn answer(report: &StudyReport, methods: &[BestMethod], leaves: &[BestLeaf]) -> String {
    let base = reference(report);
    let mut s = String::new();
    for l in layouts_of(report).into_iter().filter(|&l| l != base) {
        let m: Vec<&BestMethod> = methods.iter().filter(|r| r.layout == l).collect();
        let lf: Vec<&BestLeaf> = leaves.iter().filter(|r| r.layout == l).collect();
        let mc: Vec<Change> = m.iter().map(|r| r.change).collect();
        let lc: Vec<Change> = lf.iter().map(|r| r.change).collect();
        let changed_m: Vec<String> = m
            .iter()
            .filter(|r| r.change == Change::Changes)
            .map(|r| format!("{}: {} instead of {}", r.scene, r.method, r.reference_method))
            .collect();
        let changed_l: Vec<String> = lf
            .iter()
            .filter(|r| r.change == Change::Changes)
            .map(|r| format!("{} {}: leaf {} instead of {}", r.scene, r.method, r.leaf_size, r.reference_leaf))
            .collect();
        let verdict = |changed: &[String], all: &[Change]| {
            if !changed.is_empty() {
                format!("**yes** ({})", changed.join("; "))
            } else if all.contains(&Change::NotJudged) {
                "**not judged** (one timed round)".to_owned()
            } else if all.contains(&Change::WithinNoise) {
                "**no difference beyond the spread**".to_owned()
            } else {
                "**no**".to_owned()
            }
        };
        let _ = writeln!(
            s,
            "- **{} (`{l}`)** against `{base}`: does the best intersector change? {} — {} scenes. \
             Does the best leaf size change? {} — {} scene x method pairs.",
            l.title(),
            verdict(&changed_m, &mc),
            tally(&mc),
            verdict(&changed_l, &lc),
            tally(&lc),
        );
    }
    s
}

/// The section of study.md: the answer, then the two tables it rests on.
pub fn markdown(report: &StudyReport) -> String {
    let methods = best_methods(report);
    let leaves = best_leaves(report);
    let base = reference(report);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "Each layout's fastest intersector (over every leaf size) and each method's fastest leaf size, by render \
         time, against `{base}`'s. A different choice counts as a change only when `{base}`'s choice is clearly \
         slower on that layout: its min-max range over the timed rounds does not overlap the winner's (the \
         claims' rule).\n"
    );
    if !can_judge(report) {
        let _ = writeln!(
            s,
            "**This run cannot judge it:** one timed round has no run-to-run spread; differences are shown, not \
             judged.\n"
        );
    }
    s += &answer(report, &methods, &leaves);
    let _ = writeln!(s, "\n### The best intersector per layout\n");
    s += &methods_table(report, &methods).to_markdown();
    let _ = writeln!(s, "\n### The best leaf size per layout\n");
    s += &leaves_table(report, &leaves).to_markdown();
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::commands::study::testing::synthetic;

    /// A U in leaf size around `best`, MT fastest by 10 %.
    fn shape(leaf: u32, m: Method, best: u32, fastest: Method) -> f64 {
        let u = 1.0 + 0.05 * (leaf as f64 - best as f64).abs();
        u * if m == fastest { 0.9 } else { 1.0 }
    }

    #[test]
    fn the_same_shape_on_every_layout_changes_nothing() {
        let r = synthetic(
            &["bunny", "dragon"],
            &[Layout::Bvh2, Layout::Bvh4, Layout::Bvh8],
            |_, leaf, m, l| shape(leaf, m, 4, Method::Mt) * if l == Layout::Bvh8 { 0.7 } else { 1.0 },
            0.001,
        );
        let m = best_methods(&r);
        assert_eq!(m.len(), 6);
        assert!(m.iter().all(|b| b.method == Method::Mt && b.leaf_size == 4));
        assert!(m.iter().all(|b| b.change == if b.layout == Layout::Bvh2 { Change::Reference } else { Change::Same }));
        let l = best_leaves(&r);
        assert_eq!(l.len(), 2 * 4 * 3);
        assert!(l.iter().all(|b| b.leaf_size == 4 && b.change != Change::Changes));
        let md = markdown(&r);
        assert!(md.contains("**BVH8 (`bvh8`)** against `bvh2`: does the best intersector change? **no**"), "{md}");
    }

    #[test]
    fn a_layout_that_moves_the_best_method_and_leaf_is_called_a_change() {
        // On bvh8, Quad unit is fastest and leaf 8 is best; on bvh2, MT at leaf 4.
        let t = |_: &str, leaf: u32, m: Method, l: Layout| match l {
            Layout::Bvh8 => shape(leaf, m, 8, Method::QuadUnit),
            _ => shape(leaf, m, 4, Method::Mt),
        };
        let r = synthetic(&["bunny"], &[Layout::Bvh2, Layout::Bvh8], t, 0.001);
        let m = best_methods(&r);
        let b8 = m.iter().find(|b| b.layout == Layout::Bvh8).unwrap();
        assert_eq!((b8.method, b8.leaf_size, b8.reference_method), (Method::QuadUnit, 8, Method::Mt));
        assert_eq!(b8.change, Change::Changes);
        let leaves = best_leaves(&r);
        for b in leaves.iter().filter(|b| b.layout == Layout::Bvh8) {
            assert_eq!((b.leaf_size, b.reference_leaf, b.change), (8, 4, Change::Changes), "{}", b.method);
        }
        let md = markdown(&r);
        assert!(md.contains("**yes** (bunny: quad-unit instead of mt)"), "{md}");
        assert!(md.contains("bunny mt: leaf 8 instead of 4"), "{md}");
    }

    #[test]
    fn a_different_winner_inside_the_spread_is_not_a_change() {
        // The same move as above but with +-20 % spread: nothing beyond the spread.
        let t = |_: &str, leaf: u32, m: Method, l: Layout| match l {
            Layout::Bvh8 => shape(leaf, m, 8, Method::QuadUnit),
            _ => shape(leaf, m, 4, Method::Mt),
        };
        let r = synthetic(&["bunny"], &[Layout::Bvh2, Layout::Bvh8], t, 0.2);
        assert!(best_methods(&r).iter().all(|b| b.change != Change::Changes));
        let b8 = best_methods(&r).into_iter().find(|b| b.layout == Layout::Bvh8).unwrap();
        assert_eq!(b8.change, Change::WithinNoise);
        assert!(markdown(&r).contains("**no difference beyond the spread**"));
        // One timed round: not judged, whatever the numbers.
        let mut one = synthetic(&["bunny"], &[Layout::Bvh2, Layout::Bvh8], t, 0.001);
        one.options.repeat = 1;
        let b8 = best_methods(&one).into_iter().find(|b| b.layout == Layout::Bvh8).unwrap();
        assert_eq!(b8.change, Change::NotJudged);
    }

    #[test]
    fn without_bvh2_the_first_layout_is_the_reference() {
        let r =
            synthetic(&["bunny"], &[Layout::Bvh8, Layout::Bvh4], |_, leaf, m, _| shape(leaf, m, 4, Method::Mt), 0.0);
        assert_eq!(reference(&r), Layout::Bvh8);
        assert!(markdown(&r).contains("**BVH4 (`bvh4`)** against `bvh8`"));
    }
}
