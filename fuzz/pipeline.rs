//! What the fuzz targets run, shared with the stable-Rust replay test (`tests/fuzz_corpus.rs`
//! includes this file with `#[path]`), so CI replays every corpus file and regression input
//! through exactly the code libFuzzer drives. Each function takes arbitrary bytes; an `Err`
//! from the library is a fine outcome, a panic (including the assertions below) is a finding.

use std::path::Path;

use trilab::bvh::{BuildOptions, Builder, Bvh, LeafPolicy};
use trilab::conditioning::Conditioning;
use trilab::encoding::Method;
use trilab::rays::{parse_hits, parse_rays};
use trilab::scene::parse_obj_bytes;
use trilab::Error;

/// The name the OBJ part is loaded under; MTL paths resolve next to it.
pub const OBJ_NAME: &str = "fuzz.obj";

/// Bins the binned builder may be asked for (byte 0, bits 5..8).
const BINS: [u32; 8] = [32, 2, 3, 4, 8, 16, 64, 1];

/// Input layout: byte 0 picks the leaf size (`1 + (b & 15)`), the builder (bit 4: sweep
/// rather than binned) and the bin count (bits 5..8). The rest is the OBJ text up to the first
/// NUL byte; what follows the NUL is served as every MTL file the OBJ names (no NUL: every
/// `mtllib` is missing). The mesh is built with both leaf policies, validated, and encoded by
/// every method; its conditioning is measured.
pub fn obj_pipeline(data: &[u8]) {
    let Some((&control, rest)) = data.split_first() else { return };
    let (obj, mtl) = match rest.iter().position(|&b| b == 0) {
        Some(i) => (&rest[..i], Some(&rest[i + 1..])),
        None => (rest, None),
    };
    let leaf = 1 + u32::from(control & 15);
    let builder =
        if control & 16 != 0 { Builder::Sweep } else { Builder::Binned { bins: BINS[usize::from(control >> 5)] } };
    let mesh = match parse_obj_bytes(Path::new(OBJ_NAME), obj, |_| mtl.map(<[u8]>::to_vec)) {
        Ok(mesh) => mesh,
        Err(e) => {
            assert!(matches!(e, Error::BadInput { .. }), "not a BadInput error: {e}");
            return;
        }
    };
    let nverts = mesh.positions.len() as u32;
    assert!(mesh.triangles.iter().flatten().all(|&i| i < nverts), "vertex index out of range");
    assert_eq!(mesh.material_ids.len(), mesh.triangles.len());
    assert!(mesh.material_ids.iter().all(|&m| (m as usize) < mesh.materials.len()), "material id out of range");
    assert!(mesh.positions.iter().flatten().all(|c| c.is_finite()), "non-finite vertex accepted");
    for m in &mesh.materials {
        let g = m.gpu;
        let numbers = [&g.diffuse[..], &g.specular, &g.emission, &[g.exponent, g.exponent_v, g.ior, g.sigma]].concat();
        assert!(numbers.iter().all(|x| x.is_finite() && *x >= 0.0), "material value the kernels cannot honour: {g:?}");
    }
    for leaf_policy in [LeafPolicy::Fill, LeafPolicy::Sah] {
        let options = BuildOptions { leaf_policy, builder, ..BuildOptions::new(leaf) };
        let bvh = Bvh::build(&mesh, &options);
        if let Err(e) = bvh.validate(&mesh) {
            panic!("invalid BVH (leaf {leaf}, {leaf_policy}): {e}");
        }
        for method in Method::ALL {
            std::hint::black_box(method.encode(&mesh, &bvh));
        }
    }
    std::hint::black_box(Conditioning::of(&mesh));
}

/// The bytes as a ray file and as a hit file. Whatever is accepted must be exactly the records
/// the bytes hold, and every accepted ray must be traceable.
pub fn ray_file(data: &[u8]) {
    match parse_rays(Path::new("fuzz.rays"), data) {
        Ok(rays) => {
            assert_eq!(rays.len() * 32, data.len());
            assert!(rays.iter().all(|r| r.problem().is_none()), "accepted a ray with a problem");
        }
        Err(e) => assert!(matches!(e, Error::BadInput { .. }), "not a BadInput error: {e}"),
    }
    match parse_hits(Path::new("fuzz.hits"), data) {
        Ok(hits) => assert_eq!(hits.len() * 16, data.len()),
        Err(e) => assert!(matches!(e, Error::BadInput { .. }), "not a BadInput error: {e}"),
    }
}
