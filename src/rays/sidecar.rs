//! The sidecar of a ray file: `<file>.json` beside `<file>`, saying which scene (by a hash of
//! its triangles) and which generator made the rays (docs/formats.md). `trilab rays` writes it;
//! the commands that read rays with a scene ([`check_sidecar`]) warn when the scene they are
//! given is not the one the rays were made for. Ray files from elsewhere have none, and get no
//! warning.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};
use crate::scene::Mesh;

/// The `format` field of every sidecar this version writes.
pub const SIDECAR_FORMAT: &str = "trilab-rays-sidecar/1";

/// What a sidecar holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RaySidecar {
    /// [`SIDECAR_FORMAT`].
    pub format: String,
    /// Rays in the file (32 bytes each).
    pub count: usize,
    /// The scene's short name (`bunny`) and the file it was read from.
    pub scene: String,
    pub scene_source: String,
    pub scene_triangles: usize,
    /// [`scene_hash`] of the scene.
    pub scene_sha256: String,
    /// `primary`, `diffuse` or `random`.
    pub generator: String,
    /// The generator's settings (width, height, per_hit, count, ...), by name.
    pub settings: BTreeMap<String, serde_json::Value>,
    /// The generator's seed, where it has one.
    pub seed: Option<u64>,
    pub trilab_version: String,
    pub trilab_commit: String,
}

/// `<rays>.json`.
pub fn sidecar_path(rays: &Path) -> PathBuf {
    let mut p = rays.as_os_str().to_owned();
    p.push(".json");
    PathBuf::from(p)
}

/// SHA-256 (hex) of the scene's triangles: each triangle's three vertices (x, y, z as
/// little-endian f32) in triangle-id order. Two files with the same triangles in the same
/// order hash alike whatever their vertex sharing, materials, comments or line endings.
pub fn scene_hash(mesh: &Mesh) -> String {
    let mut h = Sha256::new();
    for t in &mesh.triangles {
        for &i in t {
            for c in mesh.positions[i as usize] {
                h.update(c.to_le_bytes());
            }
        }
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Writes `sidecar` beside the ray file `rays`, atomically.
pub fn write_sidecar(rays: &Path, sidecar: &RaySidecar) -> Result<()> {
    let path = sidecar_path(rays);
    let text = serde_json::to_string_pretty(sidecar)
        .map_err(|e| Error::Usage(format!("{}: cannot encode the sidecar: {e}", path.display())))?;
    crate::io::write_atomic(&path, format!("{text}\n").as_bytes())
}

/// Reads the sidecar of `rays`: `None` when there is none.
pub fn read_sidecar(rays: &Path) -> Result<Option<RaySidecar>> {
    let path = sidecar_path(rays);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(&path, e)),
    };
    serde_json::from_str(&text)
        .map(Some)
        .map_err(|e| Error::bad_input(&path, Some(e.line()), format!("not a ray-file sidecar: {e}")))
}

/// The warning to give when the ray file `rays` (holding `count` rays) has a sidecar that says
/// it was made for another scene than `mesh` (named `scene`), or for another number of rays
/// (the file was replaced after the sidecar was written); `None` when it matches or there is
/// no sidecar. An unreadable sidecar is a warning too: it never stops the command.
pub fn check_sidecar(rays: &Path, count: usize, scene: &str, mesh: &Mesh) -> Option<String> {
    let sidecar = match read_sidecar(rays) {
        Ok(Some(s)) => s,
        Ok(None) => return None,
        Err(e) => return Some(format!("{e}; the rays' scene is not checked")),
    };
    let short = |h: &str| h.chars().take(12).collect::<String>();
    let hash = scene_hash(mesh);
    if sidecar.scene_sha256 != hash {
        return Some(format!(
            "{}: these {} rays were made for scene `{}` ({} triangles, sha256 {}; by `trilab rays {}`), \
             not for the scene given, `{scene}` ({} triangles, sha256 {}): their hits say nothing about the \
             scene they were made for ({})",
            rays.display(),
            sidecar.generator,
            sidecar.scene,
            sidecar.scene_triangles,
            short(&sidecar.scene_sha256),
            sidecar.generator,
            mesh.triangle_count(),
            short(&hash),
            sidecar_path(rays).display(),
        ));
    }
    if sidecar.count != count {
        return Some(format!(
            "{}: holds {count} rays but its sidecar {} describes {}: the file was replaced after the sidecar \
             was written, so the sidecar's scene check means nothing",
            rays.display(),
            sidecar_path(rays).display(),
            sidecar.count
        ));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(z: f32) -> Mesh {
        Mesh::from_triangles(vec![[0.0, 0.0, z], [1.0, 0.0, z], [0.0, 1.0, z]], vec![[0, 1, 2]])
    }

    fn sidecar(mesh: &Mesh, count: usize) -> RaySidecar {
        RaySidecar {
            format: SIDECAR_FORMAT.into(),
            count,
            scene: "a".into(),
            scene_source: "a.obj".into(),
            scene_triangles: mesh.triangle_count(),
            scene_sha256: scene_hash(mesh),
            generator: "random".into(),
            settings: BTreeMap::from([("count".to_owned(), serde_json::json!(count))]),
            seed: Some(7),
            trilab_version: "0".into(),
            trilab_commit: "x".into(),
        }
    }

    #[test]
    fn sidecars_round_trip_and_catch_another_scene() {
        let dir = tempfile::tempdir().unwrap();
        let rays = dir.path().join("r.rays");
        let (a, b) = (tri(0.0), tri(1.0));
        assert_ne!(scene_hash(&a), scene_hash(&b));
        assert_eq!(check_sidecar(&rays, 3, "a", &a), None, "no sidecar, no warning");
        write_sidecar(&rays, &sidecar(&a, 3)).unwrap();
        assert_eq!(read_sidecar(&rays).unwrap(), Some(sidecar(&a, 3)));
        assert!(sidecar_path(&rays).ends_with("r.rays.json"));
        assert_eq!(check_sidecar(&rays, 3, "a", &a), None);
        let w = check_sidecar(&rays, 3, "b", &b).unwrap();
        assert!(w.contains("made for scene `a`") && w.contains("`b`"), "{w}");
        let w = check_sidecar(&rays, 4, "a", &a).unwrap();
        assert!(w.contains("holds 4 rays") && w.contains("describes 3"), "{w}");
        std::fs::write(sidecar_path(&rays), "{").unwrap();
        let w = check_sidecar(&rays, 3, "a", &a).unwrap();
        assert!(w.contains("r.rays.json") && w.contains("not a ray-file sidecar"), "{w}");
    }
}
