//! `trilab hits`: hit files (the output of `raycast`) read back for people: print them, check
//! them against the CPU f64 reference the way `raycast --reference` does, and diff two of them.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::agreement::{compare_any, compare_closest, Disagreement, DisagreementKind};
use crate::bvh::BuildOptions;
use crate::error::{Error, Result};
use crate::pipeline::HostScene;
use crate::rays::{self, Hit};
use crate::report::{Report, Table};
use crate::scene::load_obj;

/// One hit record as printed: `None` t and triangle for a miss (JSON has no infinity).
#[derive(Clone, Debug, Serialize)]
pub struct HitRow {
    pub ray: usize,
    pub t: Option<f32>,
    pub u: f32,
    pub v: f32,
    pub triangle: Option<u32>,
}

impl HitRow {
    fn of(ray: usize, h: &Hit) -> HitRow {
        let hit = h.is_hit();
        HitRow { ray, t: hit.then_some(h.t), u: h.u, v: h.v, triangle: hit.then_some(h.id) }
    }

    fn cells(&self) -> [String; 5] {
        [
            self.ray.to_string(),
            self.t.map_or_else(|| "-".into(), |t| format!("{t}")),
            format!("{}", self.u),
            format!("{}", self.v),
            self.triangle.map_or_else(|| "miss".into(), |id| id.to_string()),
        ]
    }
}

/// `hits show`: the first records of a hit file and its counts.
#[derive(Clone, Debug, Serialize)]
pub struct ShowReport {
    pub file: PathBuf,
    pub rays: usize,
    pub hits: usize,
    pub misses: usize,
    /// The first `limit` records.
    pub shown: Vec<HitRow>,
}

/// Reads `file` and keeps its first `limit` records for printing.
pub fn show(file: &Path, limit: usize) -> Result<ShowReport> {
    let hits = rays::read_hits(file)?;
    let n_hit = hits.iter().filter(|h| h.is_hit()).count();
    Ok(ShowReport {
        file: file.to_owned(),
        rays: hits.len(),
        hits: n_hit,
        misses: hits.len() - n_hit,
        shown: hits.iter().take(limit).enumerate().map(|(i, h)| HitRow::of(i, h)).collect(),
    })
}

fn hit_table<'a>(rows: impl IntoIterator<Item = &'a HitRow>) -> Table {
    let mut t = Table::new(["ray", "t", "u", "v", "triangle"]);
    for r in rows {
        t.row(r.cells());
    }
    t
}

impl Report for ShowReport {
    fn to_text(&self) -> String {
        let mut s =
            format!("{}: {} rays, {} hits, {} misses\n", self.file.display(), self.rays, self.hits, self.misses);
        if !self.shown.is_empty() {
            s += &format!("\n{}", hit_table(&self.shown).to_text());
            if self.shown.len() < self.rays {
                s += &format!("... {} more (--limit)\n", self.rays - self.shown.len());
            }
        }
        s
    }
}

/// `hits check`: what the f64 reference says of a hit file.
#[derive(Clone, Debug, Serialize)]
pub struct CheckReport {
    pub file: PathBuf,
    pub scene: PathBuf,
    pub rays_file: PathBuf,
    pub rays: usize,
    pub any_hit: bool,
    /// Closest hits: the fraction of rays agreeing with the reference.
    pub agreement: Option<f64>,
    pub disagreements: usize,
    /// Disagreements rounding cannot explain (farther than the compare module's ULP bound from
    /// an edge or a tie).
    pub unexplained: usize,
    pub invalid: usize,
    /// Every disagreement explained and nothing invalid.
    pub passes: bool,
    pub summary: String,
    /// The first disagreements (closest hits), explained or not.
    pub examples: Vec<Disagreement>,
    /// The first impossible values: (ray, what).
    pub invalid_examples: Vec<(usize, String)>,
    /// The scene's load warnings, and the ray file's sidecar naming another scene.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Checks `file` (closest hits, or any-hit results with `any_hit`) for `rays_file` over `scene`
/// against the f64 reference (on a BVH built with `build`).
pub fn check(scene: &Path, rays_file: &Path, file: &Path, any_hit: bool, build: &BuildOptions) -> Result<CheckReport> {
    let hits = rays::read_hits(file)?;
    let rays = rays::read_rays(rays_file)?;
    if hits.len() != rays.len() {
        return Err(Error::bad_input(
            file,
            None,
            format!(
                "holds {} hit records but {} holds {} rays; not the hits of these rays",
                hits.len(),
                rays_file.display(),
                rays.len()
            ),
        ));
    }
    let mesh = load_obj(scene)?;
    rays::check_reach(rays_file, &rays, &mesh.bounds())?;
    let host = HostScene::build(crate::scene::scene_name(scene), &mesh, build)?;
    let reference = host.reference().trace_all(&rays, false);
    const EXAMPLES: usize = 10;
    let mut report = CheckReport {
        file: file.to_owned(),
        scene: scene.to_owned(),
        rays_file: rays_file.to_owned(),
        rays: rays.len(),
        any_hit,
        agreement: None,
        disagreements: 0,
        unexplained: 0,
        invalid: 0,
        passes: false,
        summary: String::new(),
        examples: vec![],
        invalid_examples: vec![],
        warnings: mesh.warnings.clone(),
    };
    report.warnings.extend(rays::check_sidecar(rays_file, rays.len(), &crate::scene::scene_name(scene), &mesh));
    if any_hit {
        let closest: Vec<Hit> = reference.iter().map(|h| h.to_hit()).collect();
        let c = compare_any(&mesh, &rays, &closest, &hits);
        report.disagreements = c.status_mismatch.len();
        report.unexplained = c.status_mismatch.len();
        report.invalid = c.bogus.len();
        report.passes = c.passes();
        report.summary = format!(
            "{} of {} rays: hit/miss status differs from the reference's, {} hits not on their triangle",
            c.status_mismatch.len(),
            rays.len(),
            c.bogus.len()
        );
        report.invalid_examples = c.bogus.into_iter().take(EXAMPLES).collect();
    } else {
        let a = compare_closest(&mesh, &rays, &hits, &reference);
        report.agreement = Some(a.fraction());
        report.disagreements = a.disagreements.len();
        report.unexplained = a.unexplained;
        report.invalid = a.invalid.len();
        report.passes = a.all_explained();
        report.summary = a.summary();
        // Unexplained ones first: they are what the user must look at.
        let mut d = a.disagreements.clone();
        d.sort_by(|x, y| y.ambiguity_ulps.total_cmp(&x.ambiguity_ulps));
        report.examples = d.into_iter().take(EXAMPLES).collect();
        report.invalid_examples = a.invalid.into_iter().take(EXAMPLES).collect();
    }
    Ok(report)
}

impl Report for CheckReport {
    fn to_text(&self) -> String {
        let mut s = format!(
            "{} ({} hits of {} over {}): {}\n",
            self.file.display(),
            if self.any_hit { "any" } else { "closest" },
            self.rays_file.display(),
            self.scene.display(),
            self.summary
        );
        if !self.examples.is_empty() {
            let mut t = Table::new(["ray", "kind", "t", "triangle", "reference t", "reference triangle", "ULPs"]);
            let id = |id: u32| if id == crate::shared::MISS_ID { "miss".to_string() } else { id.to_string() };
            for d in &self.examples {
                t.row([
                    d.ray.to_string(),
                    match d.kind {
                        DisagreementKind::GpuMissed => "missed",
                        DisagreementKind::GpuFalseHit => "false hit",
                        DisagreementKind::DifferentHit => "different hit",
                    }
                    .to_string(),
                    format!("{}", d.gpu_t),
                    id(d.gpu_id),
                    format!("{}", d.ref_t),
                    id(d.ref_id),
                    format!("{:.1}", d.ambiguity_ulps),
                ]);
            }
            s += &format!(
                "\ndisagreements (largest distance from an edge or tie first; explained at <= {} ULPs):\n{}",
                crate::agreement::AMBIGUITY_ULPS,
                t.to_text()
            );
        }
        for (ray, what) in &self.invalid_examples {
            s += &format!("invalid: ray {ray}: {what}\n");
        }
        s += if self.passes {
            "verdict: agrees with the f64 reference (every disagreement explained by rounding)\n"
        } else {
            "verdict: DISAGREES with the f64 reference\n"
        };
        s
    }
}

/// How far two records may differ and still be the same hit.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct DiffTolerance {
    /// Relative difference in t.
    pub t: f64,
    /// Absolute difference in u and v.
    pub uv: f64,
}

impl DiffTolerance {
    /// Bit for bit.
    pub const EXACT: DiffTolerance = DiffTolerance { t: 0.0, uv: 0.0 };
}

/// One ray whose hit changed.
#[derive(Clone, Debug, Serialize)]
pub struct Change {
    pub ray: usize,
    pub a: HitRow,
    pub b: HitRow,
    /// "triangle", "miss -> hit", "hit -> miss", "t", "u/v".
    pub what: String,
}

/// `hits diff`: the rays whose hits differ between two files.
#[derive(Clone, Debug, Serialize)]
pub struct DiffReport {
    pub a: PathBuf,
    pub b: PathBuf,
    pub rays: usize,
    pub tolerance: DiffTolerance,
    /// Rays whose hit changed (all of them, `changes` holds the first `limit`).
    pub changed: usize,
    pub triangle_changed: usize,
    pub miss_to_hit: usize,
    pub hit_to_miss: usize,
    pub t_or_uv_changed: usize,
    pub changes: Vec<Change>,
}

impl DiffReport {
    pub fn differ(&self) -> bool {
        self.changed > 0
    }
}

/// What changed between two records, if anything beyond `tol` ("triangle", "miss -> hit",
/// "hit -> miss", "t", "u/v"); two misses are the same miss. With a zero tolerance, any
/// difference in t, u or v of a hit on the same triangle (`repro --check`'s rule).
pub fn change(a: &Hit, b: &Hit, tol: &DiffTolerance) -> Option<&'static str> {
    if bytemuck::bytes_of(a) == bytemuck::bytes_of(b) {
        return None;
    }
    match (a.is_hit(), b.is_hit()) {
        (false, false) => None,
        (false, true) => Some("miss -> hit"),
        (true, false) => Some("hit -> miss"),
        (true, true) if a.id != b.id => Some("triangle"),
        (true, true) => {
            let (ta, tb) = (f64::from(a.t), f64::from(b.t));
            let t_ok = ta == tb || (ta - tb).abs() <= tol.t * ta.abs().max(tb.abs());
            let close = |x: f32, y: f32| x == y || (f64::from(x) - f64::from(y)).abs() <= tol.uv;
            if !t_ok || (a.t.is_nan() != b.t.is_nan()) {
                Some("t")
            } else if !(close(a.u, b.u) && close(a.v, b.v)) {
                Some("u/v")
            } else {
                None
            }
        }
    }
}

/// Compares the hit files `a` and `b` ray by ray; keeps the first `limit` changes.
pub fn diff(a: &Path, b: &Path, tol: DiffTolerance, limit: usize) -> Result<DiffReport> {
    if !(tol.t >= 0.0 && tol.uv >= 0.0 && tol.t.is_finite() && tol.uv.is_finite()) {
        return Err(Error::Usage(format!(
            "--t-tolerance {} / --uv-tolerance {}: must be finite and >= 0",
            tol.t, tol.uv
        )));
    }
    let ha = rays::read_hits(a)?;
    let hb = rays::read_hits(b)?;
    if ha.len() != hb.len() {
        return Err(Error::bad_input(
            b,
            None,
            format!("holds {} hit records but {} holds {}; not hits of the same rays", hb.len(), a.display(), ha.len()),
        ));
    }
    let mut r = DiffReport {
        a: a.to_owned(),
        b: b.to_owned(),
        rays: ha.len(),
        tolerance: tol,
        changed: 0,
        triangle_changed: 0,
        miss_to_hit: 0,
        hit_to_miss: 0,
        t_or_uv_changed: 0,
        changes: vec![],
    };
    for (i, (x, y)) in ha.iter().zip(&hb).enumerate() {
        let Some(what) = change(x, y, &tol) else { continue };
        r.changed += 1;
        match what {
            "triangle" => r.triangle_changed += 1,
            "miss -> hit" => r.miss_to_hit += 1,
            "hit -> miss" => r.hit_to_miss += 1,
            _ => r.t_or_uv_changed += 1,
        }
        if r.changes.len() < limit {
            r.changes.push(Change { ray: i, a: HitRow::of(i, x), b: HitRow::of(i, y), what: what.into() });
        }
    }
    Ok(r)
}

impl Report for DiffReport {
    fn to_text(&self) -> String {
        let mut s = String::new();
        if !self.changes.is_empty() {
            let mut t = Table::new([
                "ray",
                "change",
                "a: t",
                "a: u",
                "a: v",
                "a: triangle",
                "b: t",
                "b: u",
                "b: v",
                "b: triangle",
            ]);
            for c in &self.changes {
                let [_, at, au, av, aid] = c.a.cells();
                let [_, bt, bu, bv, bid] = c.b.cells();
                t.row([c.ray.to_string(), c.what.clone(), at, au, av, aid, bt, bu, bv, bid]);
            }
            s += &t.to_text();
            if self.changes.len() < self.changed {
                s += &format!("... {} more (--limit)\n", self.changed - self.changes.len());
            }
            s.push('\n');
        }
        s += &format!(
            "{} vs {}: {} of {} rays differ ({} triangle, {} miss -> hit, {} hit -> miss, {} t or u/v beyond t {:e} relative, u/v {:e})\n",
            self.a.display(),
            self.b.display(),
            self.changed,
            self.rays,
            self.triangle_changed,
            self.miss_to_hit,
            self.hit_to_miss,
            self.t_or_uv_changed,
            self.tolerance.t,
            self.tolerance.uv
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: DiffTolerance = DiffTolerance { t: 1e-6, uv: 1e-6 };

    fn hit(t: f32, id: u32, u: f32, v: f32) -> Hit {
        Hit { t, id, u, v }
    }

    #[test]
    fn changes_are_classified() {
        let h = hit(2.0, 5, 0.25, 0.5);
        assert_eq!(change(&h, &h, &TOL), None);
        assert_eq!(change(&Hit::MISS, &Hit::MISS, &TOL), None);
        assert_eq!(change(&Hit::MISS, &h, &TOL), Some("miss -> hit"));
        assert_eq!(change(&h, &Hit::MISS, &TOL), Some("hit -> miss"));
        assert_eq!(change(&h, &hit(2.0, 6, 0.25, 0.5), &TOL), Some("triangle"));
        assert_eq!(change(&h, &hit(2.0 * (1.0 + 1e-7), 5, 0.25, 0.5), &TOL), None);
        assert_eq!(change(&h, &hit(2.001, 5, 0.25, 0.5), &TOL), Some("t"));
        assert_eq!(change(&h, &hit(2.0, 5, 0.2501, 0.5), &TOL), Some("u/v"));
        assert_eq!(change(&h, &hit(f32::NAN, 5, 0.25, 0.5), &TOL), Some("t"));
    }
}
