//! `trilab analyze`: a scene's numerical conditioning and the cheapest method, offset scheme and
//! placement that meet an accuracy target on it (the reasoning is `conditioning`'s; this is the
//! command's report).

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::conditioning::{self, Conditioning, Frontier, Recommendation, Target};
use crate::encoding::Method;
use crate::error::{Error, Result};
use crate::gpu::context::choose_device;
use crate::gpu::{Context, EnabledFeatures};
use crate::report::Report;
use crate::scene::load_obj;

/// What `trilab analyze` reports (`--json` prints it).
#[derive(Clone, Debug, Serialize)]
pub struct AnalyzeReport {
    pub scene: String,
    pub conditioning: Conditioning,
    pub target: Target,
    pub frontier: Frontier,
    pub available_methods: Vec<Method>,
    pub recommendation: Recommendation,
    /// Where the available methods come from.
    #[serde(skip)]
    pub device_note: String,
    /// What loading the scene warned about (a missing MTL, ignored normals): the CLI prints them.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Analyzes the scene at `scene` for `target`, judging methods by `frontier` (a `frontier.csv`,
/// or the built-in lavapipe one). `device` (as `--device` takes it) only decides which methods
/// can run; no device is needed.
pub fn run(scene: &Path, target: Target, frontier: Option<&Path>, device: Option<&str>) -> Result<AnalyzeReport> {
    for (name, v) in [("--max-leaks-per-million", target.max_leaks_per_million), ("--max-t-ulps", target.max_t_ulps)] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(Error::Usage(format!("{name} {v}: must be a finite number >= 0")));
        }
    }
    let mesh = load_obj(scene)?;
    let frontier = match frontier {
        Some(p) => Frontier::read(p)?,
        None => Frontier::builtin(),
    };
    let (available, device_note) =
        match Context::list_devices().ok().and_then(|l| choose_device(&l, device).ok().map(|i| l[i].clone())) {
            Some(info) => {
                let f = EnabledFeatures::for_device(&info);
                let caps = crate::gpu::Capabilities::new(&info, &f);
                (conditioning::available_methods(&caps), format!("methods this device ({}) can run", info.name))
            }
            None => (Method::ALL.to_vec(), "no Vulkan device found: every method assumed available".to_owned()),
        };
    let conditioning = Conditioning::of(&mesh);
    let recommendation =
        conditioning::recommend(&conditioning, &target, &frontier, &available, conditioning::OFFSET_SCHEME);
    Ok(AnalyzeReport {
        scene: PathBuf::from(scene).display().to_string(),
        conditioning,
        target,
        frontier,
        available_methods: available,
        recommendation,
        device_note,
        warnings: mesh.warnings.clone(),
    })
}

impl Report for AnalyzeReport {
    fn to_json(&self) -> String {
        crate::report::value_json(self)
    }

    fn to_text(&self) -> String {
        let (c, rec, target) = (&self.conditioning, &self.recommendation, &self.target);
        let b = |v: [f64; 3]| format!("({:.6e}, {:.6e}, {:.6e})", v[0], v[1], v[2]);
        let mut s = format!("scene {} ({} triangles, {} degenerate)\n", self.scene, c.triangles, c.degenerate);
        s += &format!("  bounds                 {} .. {}\n", b(c.bounds_min), b(c.bounds_max));
        s += &format!("  extent (largest side)  {:.6e}\n", c.extent);
        s += &format!(
            "  centre from origin     {:.6e} ({:.2}x the extent)\n",
            c.centre_distance,
            c.centre_distance / c.extent.max(f64::MIN_POSITIVE)
        );
        s += &format!("  max |coordinate|       {:.6e}  (f32 ULP there: {:.3e})\n", c.max_abs_coord, c.position_ulp);
        s += &format!("  edges min/median/max   {:.3e} / {:.3e} / {:.3e}\n", c.edge_min, c.edge_median, c.edge_max);
        s += &format!("  magnitude / min edge   {:.3e}\n", c.magnitude_over_edge);
        s += &format!(
            "  f32 bits across the smallest edge: {:.1} as placed, {:.1} recentred\n",
            c.edge_bits, c.edge_bits_recentred
        );
        s += &format!(
            "  sliver ratio (longest edge / shortest altitude) median {:.3}, p99 {:.3}, max {:.3e}\n",
            c.sliver_median, c.sliver_p99, c.sliver_max
        );
        s += &format!(
            "target: <= {} leaks per 10^6 rays, p99 t error <= {} ULPs; {}: {}\n",
            target.max_leaks_per_million,
            target.max_t_ulps,
            self.device_note,
            self.available_methods.iter().map(|m| m.name()).collect::<Vec<_>>().join(", ")
        );
        if !rec.meets_target && !rec.missing_from_frontier.is_empty() {
            s += &format!(
                "recommendation: none: no method in the frontier meets the target, and it lacks {} (which this \
                 device can run); {} is only its most accurate method, and it does NOT meet the target\n",
                rec.missing_from_frontier.iter().map(|m| m.name()).collect::<Vec<_>>().join(", "),
                rec.method
            );
        } else {
            s += &format!(
                "recommendation: --method {}, offset scheme {}, {}{}\n",
                rec.method,
                rec.offset_scheme,
                if rec.recentre { "recentre the scene in f64 before upload" } else { "no recentring needed" },
                if rec.meets_target { "" } else { " (the target is NOT met)" }
            );
        }
        for r in &rec.reasons {
            s += &format!("  {r}\n");
        }
        s
    }
}
