//! `bench`'s peer tables: per scene and ray set, trilab's fastest row (any method, any layout)
//! beside each peer's validated speed on the same rays in the same rounds (medians, the peer's
//! min..max beside), the ratios trilab / peer of the medians, and issue 15's
//! speed target: at least 0.6x Embree and tinybvh `cpu-bvh8`, at least 1.5x tinybvh's best
//! OpenCL layout.

use serde::Serialize;

use crate::encoding::Layout;
use crate::report::Table;
use crate::services::peers::{PeerKind, PeerOutcome, PeerResult, TinybvhLayout};
use crate::services::rayset::RaySet;

/// The target against Embree and against tinybvh `cpu-bvh8`: trilab / peer at least this.
pub const TARGET_CPU: f64 = 0.6;
/// The target against tinybvh's fastest OpenCL layout.
pub const TARGET_OPENCL: f64 = 1.5;

/// The fastest trilab row of a scene and ray set.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrilabBest {
    /// The method (or `ray-query`).
    pub method: String,
    /// Its BVH node layout, where the row has one.
    pub layout: Option<Layout>,
    /// At its median run.
    pub mrays_per_s: f64,
}

impl TrilabBest {
    /// The fastest of `(method, layout, Mrays/s)` rows (`-` at 0 where there are none).
    pub fn fastest(rows: impl IntoIterator<Item = (String, Option<Layout>, f64)>) -> TrilabBest {
        rows.into_iter()
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map(|(method, layout, mrays_per_s)| TrilabBest { method, layout, mrays_per_s })
            .unwrap_or(TrilabBest { method: "-".into(), layout: None, mrays_per_s: 0.0 })
    }

    pub fn label(&self) -> String {
        match self.layout {
            Some(l) => format!("{} {l}", self.method),
            None => self.method.clone(),
        }
    }
}

/// One cell of the speed target.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TargetCell {
    /// The peer it is judged against (for the OpenCL cell, the fastest ocl-* layout).
    pub peer: PeerKind,
    /// trilab / peer.
    pub ratio: f64,
    pub goal: f64,
    pub met: bool,
}

impl TargetCell {
    fn new(peer: PeerKind, ratio: f64, goal: f64) -> TargetCell {
        TargetCell { peer, ratio, goal, met: ratio >= goal }
    }

    fn text(&self) -> String {
        format!("{:.2} {}", self.ratio, if self.met { "met" } else { "short" })
    }
}

/// Issue 15's speed target on one scene and ray set; `None` where that peer was not run,
/// skipped or failed validation.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TargetCheck {
    pub vs_embree: Option<TargetCell>,
    pub vs_cpu_bvh8: Option<TargetCell>,
    pub vs_best_opencl: Option<TargetCell>,
}

/// One scene and ray set: trilab's best beside every peer.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PeerComparison {
    pub scene: String,
    pub ray_set: RaySet,
    pub rays: usize,
    pub trilab: TrilabBest,
    pub peers: Vec<PeerResult>,
    pub target: TargetCheck,
}

impl PeerComparison {
    pub fn new(scene: &str, ray_set: RaySet, rays: usize, trilab: TrilabBest, peers: Vec<PeerResult>) -> Self {
        let ratio = |p: &PeerResult| p.mrays_per_s().map(|m| trilab.mrays_per_s / m);
        let cell = |kind: PeerKind, goal: f64| {
            peers.iter().find(|p| p.peer == kind).and_then(|p| ratio(p).map(|r| TargetCell::new(kind, r, goal)))
        };
        let best_ocl = peers
            .iter()
            .filter(|p| matches!(p.peer, PeerKind::Tinybvh(l) if l.is_opencl()))
            .filter_map(|p| p.mrays_per_s().map(|m| (p.peer, m)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let target = TargetCheck {
            vs_embree: cell(PeerKind::Embree, TARGET_CPU),
            vs_cpu_bvh8: cell(PeerKind::Tinybvh(TinybvhLayout::CpuBvh8), TARGET_CPU),
            vs_best_opencl: best_ocl.map(|(k, m)| TargetCell::new(k, trilab.mrays_per_s / m, TARGET_OPENCL)),
        };
        PeerComparison { scene: scene.to_owned(), ray_set, rays, trilab, peers, target }
    }

    /// The target cell this peer is judged by, if any.
    fn target_of(&self, peer: PeerKind) -> Option<&TargetCell> {
        let t = &self.target;
        [&t.vs_embree, &t.vs_cpu_bvh8, &t.vs_best_opencl].into_iter().flatten().find(|c| c.peer == peer)
    }
}

/// What the peer table says about how the figures were taken.
pub const PEER_NOTE: &str = "\
Peers on the same ray files in the same rounds as trilab's kernels (each peer program started
once a round, tracing the set once, its own clock; its BVH build not counted), every round
validated against the f64 reference before its speed counts. Mrays/s is the median round for
trilab's best row and for each peer, min..max the peer's slowest and fastest (its best) round;
trilab/it and the speed target compare the medians. Issue 15's speed target: trilab / peer >=
0.6 vs embree3 and tinybvh cpu-bvh8, >= 1.5 vs the fastest tinybvh ocl-* layout.";

/// One line per tracer: trilab's best, then each peer with its ratio and target cell.
pub fn peer_table(comparisons: &[PeerComparison]) -> Table {
    let mut t = Table::new(["scene", "set", "tracer", "Mrays/s", "min..max", "agree %", "trilab/it", "target"]);
    for c in comparisons {
        let (scene, set) = (c.scene.clone(), c.ray_set.to_string());
        t.row([
            scene.clone(),
            set.clone(),
            format!("trilab {}", c.trilab.label()),
            format!("{:.2}", c.trilab.mrays_per_s),
            "-".into(),
            "-".into(),
            "-".into(),
            String::new(),
        ]);
        for p in &c.peers {
            let (rate, range, agree) = match &p.outcome {
                PeerOutcome::Timed { mrays_per_s, mrays_per_s_min: lo, mrays_per_s_max: hi, agreement, .. } => {
                    (format!("{mrays_per_s:.2}"), format!("{lo:.2}..{hi:.2}"), format!("{:.4}", 100.0 * agreement))
                }
                PeerOutcome::WrongHits { agreement, .. } => (
                    "wrong hits".into(),
                    "-".into(),
                    agreement.map_or_else(|| "-".into(), |a| format!("{:.4}", 100.0 * a)),
                ),
                PeerOutcome::Skipped { .. } => ("skipped".into(), "-".into(), "-".into()),
            };
            let ratio = p.mrays_per_s().map_or_else(|| "-".into(), |m| format!("{:.2}", c.trilab.mrays_per_s / m));
            let target = c
                .target_of(p.peer)
                .map(|cell| format!("{} (>= {})", if cell.met { "met" } else { "short" }, cell.goal))
                .unwrap_or_default();
            t.row([scene.clone(), set.clone(), p.peer.to_string(), rate, range, agree, ratio, target]);
        }
    }
    t
}

/// The speed target alone: one line per scene and ray set.
pub fn target_table(comparisons: &[PeerComparison]) -> Table {
    let mut t = Table::new(["scene", "set", "trilab best", "vs embree3", "vs cpu-bvh8", "vs best ocl"]);
    let cell = |c: &Option<TargetCell>| c.as_ref().map_or_else(|| "-".into(), TargetCell::text);
    for c in comparisons {
        t.row([
            c.scene.clone(),
            c.ray_set.to_string(),
            c.trilab.label(),
            cell(&c.target.vs_embree),
            cell(&c.target.vs_cpu_bvh8),
            c.target.vs_best_opencl.as_ref().map_or_else(
                || "-".into(),
                |x| format!("{} ({})", x.text(), x.peer.to_string().trim_start_matches("tinybvh ")),
            ),
        ]);
    }
    t
}

/// Why peers failed or were skipped, one line each.
pub fn peer_notes(comparisons: &[PeerComparison]) -> Vec<String> {
    let mut notes = vec![];
    for c in comparisons {
        for p in &c.peers {
            match &p.outcome {
                PeerOutcome::WrongHits { reason, .. } => {
                    notes.push(format!("{} {} {}: failed validation, not timed: {reason}", c.scene, c.ray_set, p.peer))
                }
                PeerOutcome::Skipped { reason } => {
                    notes.push(format!("{} {} {}: skipped: {reason}", c.scene, c.ray_set, p.peer))
                }
                PeerOutcome::Timed { .. } => {}
            }
        }
    }
    notes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::Summary;

    fn timed(peer: PeerKind, m: f64) -> PeerResult {
        PeerResult {
            peer,
            outcome: PeerOutcome::Timed {
                mrays_per_s: m,
                mrays_per_s_min: 0.9 * m,
                mrays_per_s_max: 1.1 * m,
                trace_ms: Summary { median: 1.0, min: 0.9, max: 1.1, runs: 3 },
                build_ms: None,
                threads: None,
                agreement: 1.0,
            },
        }
    }

    fn comparison(peers: Vec<PeerResult>) -> PeerComparison {
        let best = TrilabBest { method: "mt".into(), layout: Some(Layout::Bvh4), mrays_per_s: 12.0 };
        PeerComparison::new("bunny", RaySet::Primary, 1000, best, peers)
    }

    #[test]
    fn targets_judge_embree_cpu_bvh8_and_the_fastest_opencl_layout() {
        let c = comparison(vec![
            timed(PeerKind::Embree, 20.0),
            timed(PeerKind::Tinybvh(TinybvhLayout::CpuBvh8), 24.0),
            timed(PeerKind::Tinybvh(TinybvhLayout::OclBvh2), 8.0),
            timed(PeerKind::Tinybvh(TinybvhLayout::OclCwbvh), 4.0),
        ]);
        let e = c.target.vs_embree.as_ref().unwrap();
        assert!((e.ratio - 0.6).abs() < 1e-12 && e.met, "12/20 = 0.6 meets 0.6");
        let b = c.target.vs_cpu_bvh8.as_ref().unwrap();
        assert!((b.ratio - 0.5).abs() < 1e-12 && !b.met);
        let o = c.target.vs_best_opencl.as_ref().unwrap();
        assert_eq!(o.peer, PeerKind::Tinybvh(TinybvhLayout::OclBvh2), "the fastest OpenCL layout");
        assert!((o.ratio - 1.5).abs() < 1e-12 && o.met);
        let text = target_table(std::slice::from_ref(&c)).to_text();
        assert!(
            text.contains("0.60 met") && text.contains("0.50 short") && text.contains("1.50 met (ocl-bvh2)"),
            "{text}"
        );
        let text = peer_table(&[c]).to_text();
        assert!(text.contains("trilab mt bvh4"), "{text}");
        assert!(text.lines().any(|l| l.contains("tinybvh ocl-cwbvh") && l.contains("3.00") && !l.contains("met")));
        assert!(text.lines().all(|l| l.chars().count() < 100), "{text}");
    }

    #[test]
    fn the_fastest_row_is_trilabs_best_whatever_its_layout() {
        let rows = [("mt", Some(Layout::Bvh2), 3.0), ("unit", Some(Layout::Bvh4), 5.0), ("quad-mt", None, 4.0)];
        let best = TrilabBest::fastest(rows.map(|(m, l, r)| (m.to_string(), l, r)));
        assert_eq!((best.label(), best.mrays_per_s), ("unit bvh4".to_string(), 5.0));
        assert_eq!(TrilabBest::fastest([]).label(), "-");
    }

    #[test]
    fn failing_and_skipped_peers_have_no_ratio_and_no_target() {
        let c = comparison(vec![
            PeerResult {
                peer: PeerKind::Embree,
                outcome: PeerOutcome::WrongHits { agreement: Some(0.5), reason: "disagree".into() },
            },
            PeerResult {
                peer: PeerKind::Tinybvh(TinybvhLayout::OclBvh2),
                outcome: PeerOutcome::Skipped { reason: "no OpenCL device".into() },
            },
        ]);
        assert_eq!(c.target, TargetCheck::default());
        let text = peer_table(std::slice::from_ref(&c)).to_text();
        let line = text.lines().find(|l| l.contains("embree3")).unwrap();
        assert!(line.contains("wrong hits") && line.contains("50.0000") && !line.contains("met"), "{line}");
        let notes = peer_notes(&[c]);
        assert!(notes[0].contains("failed validation") && notes[1].contains("no OpenCL device"), "{notes:?}");
    }
}
