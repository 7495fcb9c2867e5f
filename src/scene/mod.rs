//! Scenes: triangle meshes loaded from OBJ+MTL.
//!
//! Triangle ids are OBJ face order after fan triangulation, across all objects and groups in
//! file order (docs/formats.md); every later stage keeps them.

mod aabb;
pub mod find;
mod library;
mod material;
mod mtl;
mod obj;
mod obj_statements;
mod text;
pub mod synthetic;

pub use find::{resolve, set_scene_dir, SceneSource};
pub use material::{BsdfKind, GpuMaterial, Material, MtlLines};
pub use obj::{load_obj, parse_obj_bytes};

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

pub use aabb::Aabb;

/// A scene's short name for tables and messages: the file name without `.gz` and `.obj`
/// (`dragon_full_draco11.obj.gz` -> `dragon_full_draco11`), or a `synth:` spec as given.
pub fn scene_name(path: &Path) -> String {
    if synthetic::is_spec(path) {
        return path.to_string_lossy().into_owned();
    }
    let file = path.file_name().map_or_else(|| path.to_string_lossy(), |f| f.to_string_lossy()).into_owned();
    let file = file.strip_suffix(".gz").unwrap_or(&file);
    file.strip_suffix(".obj").unwrap_or(file).to_owned()
}

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Where it came from (for messages); empty for synthetic meshes.
    pub source: PathBuf,
    pub positions: Vec<[f32; 3]>,
    /// Vertex indices per triangle, in triangle-id order.
    pub triangles: Vec<[u32; 3]>,
    /// Material index per triangle.
    pub material_ids: Vec<u32>,
    pub materials: Vec<Material>,
    /// MTL files read (outputs must never overwrite them).
    pub mtl_files: Vec<PathBuf>,
    /// What loading ignored or could not represent ("file: material `m`: `key` problem").
    pub warnings: Vec<String>,
}

impl Mesh {
    /// A mesh from raw data with one default material (synthetic scenes and tests).
    /// Panics if an index is out of range: callers build the data themselves.
    pub fn from_triangles(positions: Vec<[f32; 3]>, triangles: Vec<[u32; 3]>) -> Mesh {
        let n = positions.len() as u32;
        assert!(triangles.iter().flatten().all(|&i| i < n), "vertex index out of range");
        let material_ids = vec![0; triangles.len()];
        Mesh {
            source: PathBuf::new(),
            positions,
            triangles,
            material_ids,
            materials: vec![Material::default()],
            mtl_files: vec![],
            warnings: vec![],
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three vertices of triangle `id`.
    pub fn vertices(&self, id: usize) -> [Vec3; 3] {
        self.triangles[id].map(|i| Vec3::from_array(self.positions[i as usize]))
    }

    /// The three vertices of triangle `id`, widened to f64 (exactly).
    pub fn vertices_f64(&self, id: usize) -> [DVec3; 3] {
        self.triangles[id].map(|i| Vec3::from_array(self.positions[i as usize]).as_dvec3())
    }

    /// True when the triangle has zero area: its vertices are collinear or repeated.
    ///
    /// Decided exactly: the edges of f32 vertices are exact in f64, their products are exact,
    /// and a difference of two doubles is zero only when they are equal, so the f64 cross
    /// product is zero exactly when the f32 triangle is degenerate (for coordinates whose
    /// exponents differ by less than 29, which covers every real scene).
    pub fn is_degenerate(&self, id: usize) -> bool {
        let [a, b, c] = self.vertices_f64(id);
        (b - a).cross(c - a) == DVec3::ZERO
    }

    /// Ids of all zero-area triangles. They are kept in the mesh (ids stay stable), left out
    /// of the BVH, and can never be hit.
    pub fn degenerate_ids(&self) -> Vec<u32> {
        (0..self.triangles.len()).filter(|&i| self.is_degenerate(i)).map(|i| i as u32).collect()
    }

    /// Bounds of all vertices referenced by triangles.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for t in &self.triangles {
            for &i in t {
                b.grow_point(Vec3::from_array(self.positions[i as usize]));
            }
        }
        b
    }
}

/// A test mesh of `n` small slanted triangles on a 17-wide grid (unit tests of the placement and
/// the pipeline build trees over it).
#[cfg(test)]
pub(crate) fn test_grid(n: u32) -> Mesh {
    let mut pos = Vec::new();
    let mut tris = Vec::new();
    for i in 0..n {
        let (x, y) = ((i % 17) as f32, (i / 17) as f32);
        pos.extend([[x, y, 0.0], [x + 0.9, y, 0.3], [x, y + 0.9, 0.6]]);
        tris.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    Mesh::from_triangles(pos, tris)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_names_drop_obj_and_gz_and_keep_synthetic_specs() {
        assert_eq!(scene_name(Path::new("../shared/scenes/dragon_full_draco11.obj.gz")), "dragon_full_draco11");
        assert_eq!(scene_name(Path::new("scenes/bunny.obj")), "bunny");
        assert_eq!(scene_name(Path::new("a.gz")), "a");
        assert_eq!(scene_name(Path::new("mesh.ply")), "mesh.ply");
        assert_eq!(scene_name(Path::new("synth:terrain:10M")), "synth:terrain:10M");
    }
}
