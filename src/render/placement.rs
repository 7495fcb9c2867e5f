//! The path tracer's GPU memory beyond the encoded scene, placed from counts before anything is
//! encoded: per-slot shading and emissive triangles (texel buffers, or storage buffers on the
//! storage path: the path tracer has no address path), materials (texel buffers) and the
//! accumulation image (one storage buffer bound whole).

use crate::bvh::Bvh;
use crate::encoding::placement::check_extras;
use crate::encoding::{AccessPath, BufferPlacement, DeviceLimits, Method, Placement, SceneAccess, SceneCounts};
use crate::error::Result;
use crate::scene::Mesh;
use crate::shared::{Texel, BINDING_ACCUM, BINDING_LIGHTS, BINDING_MATERIALS, BINDING_SHADING};

/// Why the path tracer refuses a scene that needs the address path.
pub const NO_ADDRESS: &str = "the path tracer reads scenes through texel or storage buffers, not device addresses";

/// The buffers [`super::render`] uploads beside the scene read through `access`, each with
/// whether it is bound as a storage buffer (else a texel buffer): `slots` shading records,
/// `emissive` light records (storage buffers on the storage path), `materials` and an image of
/// `pixels`.
pub fn extras(
    access: AccessPath,
    slots: u64,
    emissive: u64,
    materials: u64,
    pixels: u64,
) -> Vec<(BufferPlacement, bool)> {
    let storage = access == AccessPath::Storage;
    vec![
        (BufferPlacement::new("path tracer shading", BINDING_SHADING, Texel::Rgba32Float, slots, 16), storage),
        (BufferPlacement::new("path tracer lights", BINDING_LIGHTS, Texel::Rgba32Float, emissive.max(1), 48), storage),
        (BufferPlacement::new("path tracer materials", BINDING_MATERIALS, Texel::Rgba32Float, materials, 64), false),
        (BufferPlacement::new("path tracer accumulation image", BINDING_ACCUM, Texel::Rgba32Float, pixels, 16), true),
    ]
}

/// [`extras`] for `method`'s encoding of `mesh` (`counts` from its BVH): a shading record per
/// slot (whole quads for the Quad methods), a light record per emissive triangle, and an image of
/// `pixels`.
pub fn extras_for(
    mesh: &Mesh,
    method: Method,
    access: AccessPath,
    counts: &SceneCounts,
    pixels: u64,
) -> Vec<(BufferPlacement, bool)> {
    let slots = if method.group_size() > 1 { 4 * counts.quads } else { counts.slots };
    let emissive =
        mesh.material_ids.iter().filter(|&&m| mesh.materials.get(m as usize).is_some_and(|m| m.is_emissive())).count();
    extras(access, slots, emissive as u64, mesh.materials.len() as u64, pixels)
}

/// Checks a render of `mesh` with `method` on `bvh` at `pixels` against `limits`, before
/// anything is encoded: the scene (texel or storage path) and the path tracer's own buffers.
pub fn check(scene: &str, mesh: &Mesh, bvh: &Bvh, method: Method, pixels: u64, limits: &DeviceLimits) -> Result<()> {
    let placement = Placement::for_bvh(method, mesh, bvh);
    let access = placement.choose_without_address(scene, SceneAccess::Auto, limits, NO_ADDRESS)?;
    check_extras(scene, method, &extras_for(mesh, method, access, &placement.counts, pixels), limits)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BuildOptions;

    use crate::encoding::placement::tests::limits;

    use crate::scene::test_grid as grid;

    #[test]
    fn path_tracer_extras_are_checked() {
        let m = grid(50);
        let bvh = Bvh::build(&m, &BuildOptions::new(4));
        let placement = Placement::for_bvh(Method::Mt, &m, &bvh);
        let mut l = limits();
        let extras = extras(AccessPath::Texel, placement.counts.slots, 0, 1, 1 << 20);
        assert!(check_extras("grid", Method::Mt, &extras, &l).is_ok());
        assert!(check("grid", &m, &bvh, Method::Mt, 1 << 20, &l).is_ok());
        l.max_storage_buffer_range = 1 << 20;
        let e = check_extras("grid", Method::Mt, &extras, &l).unwrap_err().to_string();
        assert!(e.contains("accumulation"), "{e}");
        let e = check("grid", &m, &bvh, Method::Mt, 1 << 20, &l).unwrap_err().to_string();
        assert!(e.contains("accumulation"), "{e}");
        // Beyond the texel bindings the storage path; beyond a storage binding too, refused.
        let mut l = limits();
        l.max_texel_buffer_elements = 16;
        assert!(check("grid", &m, &bvh, Method::Mt, 1 << 10, &l).is_ok());
        l.max_storage_buffer_range = 64;
        let e = check("grid", &m, &bvh, Method::Mt, 1 << 2, &l).unwrap_err().to_string();
        assert!(e.contains("not device addresses") && e.contains("maxStorageBufferRange"), "{e}");
    }
}
