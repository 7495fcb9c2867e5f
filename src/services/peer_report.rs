//! `bench`'s peer tables: per scene and ray set, trilab's fastest row (any method, any layout)
//! beside each peer's validated speed on the same rays in the same rounds (medians, the peer's
//! min..max beside), the ratios trilab / peer of the medians, and issue 53's speed targets
//! ([`Goals::of`], the one place they are decided): primary rays at least 1.0x Embree's
//! rtcIntersect1 and 0.6x its rtcIntersect8; diffuse and random rays at least 0.6x Embree's
//! rtcIntersect1 and tinybvh `cpu-bvh8`; every set at least 1.5x tinybvh's fastest OpenCL layout.

use serde::Serialize;

use crate::encoding::Layout;
use crate::report::Table;
use crate::services::peers::{EmbreeApi, PeerKind, PeerOutcome, PeerResult, TinybvhLayout};
use crate::services::rayset::RaySet;

/// The goal against Embree's rtcIntersect1 on primary rays: trilab / peer at least this.
pub const TARGET_EMBREE_PRIMARY: f64 = 1.0;
/// The goal against a CPU peer elsewhere: Embree's packets on primary rays, Embree's
/// rtcIntersect1 and tinybvh `cpu-bvh8` on diffuse and random rays.
pub const TARGET_CPU: f64 = 0.6;
/// The goal against tinybvh's fastest OpenCL layout, on every set.
pub const TARGET_OPENCL: f64 = 1.5;

/// Issue 53's goals on one ray set, one per target column: trilab / peer at least this, `None`
/// where the issue sets no goal against that peer on that set.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Goals {
    /// Against Embree's rtcIntersect1 (`embree3`).
    pub embree: Option<f64>,
    /// Against Embree's packets (`embree3 packet8`, or `packet16` where only it ran).
    pub embree_packet: Option<f64>,
    /// Against tinybvh `cpu-bvh8`.
    pub cpu_bvh8: Option<f64>,
    /// Against tinybvh's fastest `ocl-*` layout.
    pub best_opencl: Option<f64>,
}

impl Goals {
    /// The goals of `set`: the one place they are decided (the report's cells, its note and its
    /// `no goal` cells all read them here).
    pub fn of(set: RaySet) -> Goals {
        match set {
            // Coherent rays, where Embree's packets pay: at least rtcIntersect1's speed, and
            // within reach of rtcIntersect8's.
            RaySet::Primary => Goals {
                embree: Some(TARGET_EMBREE_PRIMARY),
                embree_packet: Some(TARGET_CPU),
                cpu_bvh8: None,
                best_opencl: Some(TARGET_OPENCL),
            },
            RaySet::Diffuse | RaySet::Random => Goals {
                embree: Some(TARGET_CPU),
                embree_packet: None,
                cpu_bvh8: Some(TARGET_CPU),
                best_opencl: Some(TARGET_OPENCL),
            },
        }
    }
}

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

/// Issue 53's speed targets on one scene and ray set ([`Goals::of`]); `None` where the set has no
/// goal against that peer, or that peer was not run, skipped or failed validation.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TargetCheck {
    /// Embree's rtcIntersect1 (`embree3`).
    pub vs_embree: Option<TargetCell>,
    /// Embree's packets: `embree3 packet8` where it ran, else `embree3 packet16`.
    pub vs_embree_packet: Option<TargetCell>,
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
        let goals = Goals::of(ray_set);
        let ratio = |p: &PeerResult| p.mrays_per_s().map(|m| trilab.mrays_per_s / m);
        let cell = |kind: PeerKind, goal: Option<f64>| {
            let p = peers.iter().find(|p| p.peer == kind)?;
            Some(TargetCell::new(kind, ratio(p)?, goal?))
        };
        // Embree's packets: the 8-wide call where it ran (passed or not: a failing packet8 is
        // not replaced by packet16), else the 16-wide one.
        let packet = [EmbreeApi::Packet8, EmbreeApi::Packet16]
            .map(PeerKind::Embree)
            .into_iter()
            .find(|&k| peers.iter().any(|p| p.peer == k))
            .unwrap_or(PeerKind::Embree(EmbreeApi::Packet8));
        let best_ocl = peers
            .iter()
            .filter(|p| matches!(p.peer, PeerKind::Tinybvh(l) if l.is_opencl()))
            .filter_map(|p| p.mrays_per_s().map(|m| (p.peer, m)))
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let target = TargetCheck {
            vs_embree: cell(PeerKind::Embree(EmbreeApi::Ray1), goals.embree),
            vs_embree_packet: cell(packet, goals.embree_packet),
            vs_cpu_bvh8: cell(PeerKind::Tinybvh(TinybvhLayout::CpuBvh8), goals.cpu_bvh8),
            vs_best_opencl: best_ocl
                .zip(goals.best_opencl)
                .map(|((k, m), goal)| TargetCell::new(k, trilab.mrays_per_s / m, goal)),
        };
        PeerComparison { scene: scene.to_owned(), ray_set, rays, trilab, peers, target }
    }

    /// The target cell this peer is judged by, if any.
    fn target_of(&self, peer: PeerKind) -> Option<&TargetCell> {
        let t = &self.target;
        [&t.vs_embree, &t.vs_embree_packet, &t.vs_cpu_bvh8, &t.vs_best_opencl]
            .into_iter()
            .flatten()
            .find(|c| c.peer == peer)
    }
}

/// What the peer table says about how the figures were taken; [`target_note`] follows it.
pub const PEER_NOTE: &str = "\
Peers on the same ray files in the same rounds as trilab's kernels (each peer program started
once a round, tracing the set once, its own clock; its BVH build not counted), every round
validated against the f64 reference before its speed counts. Mrays/s is the median round for
trilab's best row and for each peer, min..max the peer's slowest and fastest (its best) round;
trilab/it and the speed target compare the medians. embree3 is Embree's rtcIntersect1, embree3
packet8 and packet16 its rtcIntersect8 and rtcIntersect16 on consecutive rays of the file.";

/// Issue 53's speed targets as the report states them: one line per ray set, written from
/// [`Goals::of`] (so the text cannot state other goals than the cells are judged by).
pub fn target_note() -> String {
    let mut s = "Issue 53's goals (`no goal` where it sets none):".to_owned();
    for &set in <RaySet as crate::named::Named>::ALL {
        let g = Goals::of(set);
        let goals: Vec<String> = [
            ("embree3", g.embree),
            ("embree3 packet8 (packet16 where only it ran)", g.embree_packet),
            ("tinybvh cpu-bvh8", g.cpu_bvh8),
            ("the fastest tinybvh ocl-* layout", g.best_opencl),
        ]
        .into_iter()
        .filter_map(|(peer, goal)| goal.map(|x| format!(">= {x:.1} vs {peer}")))
        .collect();
        s += &format!("\n- {set} rays: {}", goals.join(", "));
    }
    s
}

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
                .map(|cell| format!("{} (>= {:.1})", if cell.met { "met" } else { "short" }, cell.goal))
                .unwrap_or_default();
            t.row([scene.clone(), set.clone(), p.peer.to_string(), rate, range, agree, ratio, target]);
        }
    }
    t
}

/// The speed targets alone: one line per scene and ray set. A cell is `RATIO met|short`, with
/// the peer named where the column has several (`(packet8)`, `(ocl-bvh2)`); `no goal` where the
/// set has none against that peer, `-` where the peer has no validated speed.
pub fn target_table(comparisons: &[PeerComparison]) -> Table {
    let mut t =
        Table::new(["scene", "set", "trilab best", "vs embree3", "vs embree3 packet", "vs cpu-bvh8", "vs best ocl"]);
    let cell = |c: &Option<TargetCell>, goal: Option<f64>, named: bool| match (c, goal) {
        (_, None) => "no goal".to_owned(),
        (None, Some(_)) => "-".to_owned(),
        (Some(x), Some(_)) if named => {
            let name = x.peer.to_string();
            let short = name.trim_start_matches("tinybvh ").trim_start_matches("embree3 ");
            format!("{} ({short})", x.text())
        }
        (Some(x), Some(_)) => x.text(),
    };
    for c in comparisons {
        let g = Goals::of(c.ray_set);
        t.row([
            c.scene.clone(),
            c.ray_set.to_string(),
            c.trilab.label(),
            cell(&c.target.vs_embree, g.embree, false),
            cell(&c.target.vs_embree_packet, g.embree_packet, true),
            cell(&c.target.vs_cpu_bvh8, g.cpu_bvh8, false),
            cell(&c.target.vs_best_opencl, g.best_opencl, true),
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

    fn comparison(set: RaySet, peers: Vec<PeerResult>) -> PeerComparison {
        let best = TrilabBest { method: "mt".into(), layout: Some(Layout::Bvh4), mrays_per_s: 12.0 };
        PeerComparison::new("bunny", set, 1000, best, peers)
    }

    const RAY1: PeerKind = PeerKind::Embree(EmbreeApi::Ray1);
    const PACKET8: PeerKind = PeerKind::Embree(EmbreeApi::Packet8);
    const PACKET16: PeerKind = PeerKind::Embree(EmbreeApi::Packet16);

    /// trilab at 12 Mrays/s; Embree rtcIntersect1 20, rtcIntersect8 16, cpu-bvh8 24, ocl-bvh2 8,
    /// ocl-cwbvh 4: ratios 0.6, 0.75, 0.5, 1.5 (the faster OpenCL layout), 3.0.
    fn every_peer() -> Vec<PeerResult> {
        vec![
            timed(RAY1, 20.0),
            timed(PACKET8, 16.0),
            timed(PeerKind::Tinybvh(TinybvhLayout::CpuBvh8), 24.0),
            timed(PeerKind::Tinybvh(TinybvhLayout::OclBvh2), 8.0),
            timed(PeerKind::Tinybvh(TinybvhLayout::OclCwbvh), 4.0),
        ]
    }

    fn close(cell: &Option<TargetCell>, peer: PeerKind, ratio: f64, goal: f64, met: bool) {
        let c = cell.as_ref().unwrap_or_else(|| panic!("no cell for {peer}"));
        assert_eq!((c.peer, c.goal, c.met), (peer, goal, met), "{c:?}");
        assert!((c.ratio - ratio).abs() < 1e-12, "{c:?} against {ratio}");
    }

    #[test]
    fn issue_53s_goals_by_ray_set() {
        let primary = Goals { embree: Some(1.0), embree_packet: Some(0.6), cpu_bvh8: None, best_opencl: Some(1.5) };
        let incoherent = Goals { embree: Some(0.6), embree_packet: None, cpu_bvh8: Some(0.6), best_opencl: Some(1.5) };
        assert_eq!(Goals::of(RaySet::Primary), primary);
        assert_eq!(Goals::of(RaySet::Diffuse), incoherent);
        assert_eq!(Goals::of(RaySet::Random), incoherent);
        let note = target_note();
        for line in [
            "- primary rays: >= 1.0 vs embree3, >= 0.6 vs embree3 packet8 (packet16 where only it ran), >= 1.5 vs the \
             fastest tinybvh ocl-* layout",
            "- diffuse rays: >= 0.6 vs embree3, >= 0.6 vs tinybvh cpu-bvh8, >= 1.5 vs the fastest tinybvh ocl-* layout",
            "- random rays: >= 0.6 vs embree3, >= 0.6 vs tinybvh cpu-bvh8, >= 1.5 vs the fastest tinybvh ocl-* layout",
        ] {
            assert!(note.lines().any(|l| l == line), "the note lacks `{line}`:\n{note}");
        }
        assert!(note.starts_with("Issue 53's goals"), "{note}");
    }

    #[test]
    fn primary_rays_are_judged_against_embrees_two_calls_and_opencl() {
        let c = comparison(RaySet::Primary, every_peer());
        close(&c.target.vs_embree, RAY1, 0.6, 1.0, false); // 12 / 20 = 0.6 < 1.0
        close(&c.target.vs_embree_packet, PACKET8, 0.75, 0.6, true); // 12 / 16 = 0.75 >= 0.6
        assert_eq!(c.target.vs_cpu_bvh8, None, "no goal against cpu-bvh8 on primary rays");
        close(&c.target.vs_best_opencl, PeerKind::Tinybvh(TinybvhLayout::OclBvh2), 1.5, 1.5, true); // 12 / 8
        let text = target_table(std::slice::from_ref(&c)).to_text();
        let row = text.lines().find(|l| l.contains("primary")).unwrap();
        for cell in ["0.60 short", "0.75 met (packet8)", "no goal", "1.50 met (ocl-bvh2)"] {
            assert!(row.contains(cell), "`{cell}` not in {row}");
        }
        assert!(text.lines().next().unwrap().contains("vs embree3 packet"), "{text}");
        let text = peer_table(&[c]).to_text();
        assert!(text.contains("trilab mt bvh4"), "{text}");
        // The tracer column is padded: a name and two spaces is that peer's line alone.
        let line = |peer: &str| text.lines().find(|l| l.contains(&format!(" {peer}  "))).unwrap().to_owned();
        assert!(line("embree3").contains("short (>= 1.0)"), "{}", line("embree3"));
        assert!(line("embree3 packet8").contains("0.75") && line("embree3 packet8").contains("met (>= 0.6)"));
        let bvh8 = line("tinybvh cpu-bvh8");
        assert!(bvh8.contains("0.50") && !bvh8.contains("met") && !bvh8.contains("short"), "{bvh8}");
        assert!(text.lines().any(|l| l.contains("tinybvh ocl-cwbvh") && l.contains("3.00") && !l.contains("met")));
        assert!(text.lines().all(|l| l.chars().count() < 100), "{text}");
    }

    #[test]
    fn diffuse_and_random_rays_are_judged_against_rtcintersect1_cpu_bvh8_and_opencl() {
        for set in [RaySet::Diffuse, RaySet::Random] {
            let c = comparison(set, every_peer());
            close(&c.target.vs_embree, RAY1, 0.6, 0.6, true); // 12 / 20 = 0.6 meets 0.6
            assert_eq!(c.target.vs_embree_packet, None, "{set}: no goal against Embree's packets");
            close(&c.target.vs_cpu_bvh8, PeerKind::Tinybvh(TinybvhLayout::CpuBvh8), 0.5, 0.6, false); // 12 / 24
            close(&c.target.vs_best_opencl, PeerKind::Tinybvh(TinybvhLayout::OclBvh2), 1.5, 1.5, true);
            let text = target_table(&[c]).to_text();
            let row = text.lines().find(|l| l.contains(&set.to_string())).unwrap();
            for cell in ["0.60 met", "no goal", "0.50 short", "1.50 met (ocl-bvh2)"] {
                assert!(row.contains(cell), "{set}: `{cell}` not in {row}");
            }
        }
    }

    #[test]
    fn the_packet_column_takes_packet8_else_packet16() {
        // Only the 16-wide call ran: it is the packet cell (12 / 10 = 1.2).
        let c = comparison(RaySet::Primary, vec![timed(RAY1, 12.0), timed(PACKET16, 10.0)]);
        close(&c.target.vs_embree, RAY1, 1.0, 1.0, true); // 12 / 12 = 1.0 meets 1.0
        close(&c.target.vs_embree_packet, PACKET16, 1.2, 0.6, true);
        assert!(target_table(&[c]).to_text().contains("1.20 met (packet16)"));
        // Both ran: packet8 (12 / 30 = 0.4), even where packet16 is slower.
        let c = comparison(RaySet::Primary, vec![timed(PACKET16, 40.0), timed(PACKET8, 30.0)]);
        close(&c.target.vs_embree_packet, PACKET8, 0.4, 0.6, false);
        // packet8 ran and failed validation: no cell, packet16 does not stand in for it.
        let failed = PeerResult {
            peer: PACKET8,
            outcome: PeerOutcome::WrongHits { agreement: Some(0.9), reason: "disagree".into() },
        };
        let c = comparison(RaySet::Primary, vec![failed, timed(PACKET16, 10.0)]);
        assert_eq!(c.target.vs_embree_packet, None);
        let text = target_table(&[c]).to_text();
        assert!(!text.contains("packet16") && !text.contains("met"), "{text}");
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
        let c = comparison(
            RaySet::Primary,
            vec![
                PeerResult {
                    peer: RAY1,
                    outcome: PeerOutcome::WrongHits { agreement: Some(0.5), reason: "disagree".into() },
                },
                PeerResult {
                    peer: PeerKind::Tinybvh(TinybvhLayout::OclBvh2),
                    outcome: PeerOutcome::Skipped { reason: "no OpenCL device".into() },
                },
            ],
        );
        assert_eq!(c.target, TargetCheck::default());
        let text = peer_table(std::slice::from_ref(&c)).to_text();
        let line = text.lines().find(|l| l.contains("embree3")).unwrap();
        assert!(line.contains("wrong hits") && line.contains("50.0000") && !line.contains("met"), "{line}");
        let notes = peer_notes(&[c]);
        assert!(notes[0].contains("failed validation") && notes[1].contains("no OpenCL device"), "{notes:?}");
    }
}
