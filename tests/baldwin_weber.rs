//! Baldwin and Weber's intersector (`glsl/intersect/baldwin_weber.glsl`) against the CPU f64
//! reference: the bunny's primary, diffuse and random rays pass the project's acceptance rule
//! (`validate::validate_hits`) at every leaf size, with every fixed column in use; triangles that
//! are zero-area or whose map does not fit f32 are never hit; no hit has a NaN.

mod common;

use trilab::agreement::{compare_any, compare_closest};
use trilab::bvh::{BuildOptions, Bvh};
use trilab::encoding::{BwTriangle, Method, BW_NEVER_HIT};
use trilab::reference::Reference;
use trilab::scene::Mesh;
use trilab::services::rayset::{ray_sets, RaySetSizes};
use trilab::services::validate::validate_hits;

#[test]
fn baldwin_weber_agrees_with_the_f64_reference_on_bunny_rays() {
    let lines = common::with_gpu(900, |ctx| {
        let k = common::MethodKernels::new(ctx, Method::BaldwinWeber);
        let mesh = common::bunny();
        let o = RaySetSizes { width: 240, height: 180, diffuse_per_hit: 1, random_rays: 20_000, seed: 7 };
        let bvh4 = Bvh::build(&mesh, &BuildOptions::new(4));
        let sets = ray_sets(&mesh, "bunny", &Reference::new(&mesh, &bvh4), &o, None).unwrap();
        // The bunny's normals point every way: all three fixed columns occur, in both signs.
        let enc = Method::BaldwinWeber.encode(&mesh, &bvh4);
        assert!(enc.unrepresentable.is_empty());
        let tris: &[BwTriangle] = bytemuck::cast_slice(&enc.prims[0].bytes);
        for k in [0.0, 1.0, 2.0] {
            let n = tris.iter().filter(|t| t.plane[3] == k).count();
            assert!(n > tris.len() / 10, "fixed column {k}: {n} of {} triangles", tris.len());
        }
        let mut lines = vec![];
        for leaf in [1, 2, 3, 4, 8, 16] {
            let bvh = Bvh::build(&mesh, &BuildOptions::new(leaf));
            let reference = Reference::new(&mesh, &bvh);
            for (name, rays) in &sets {
                let ref_hits = reference.trace_all(rays, false);
                let (closest, any) = k.cast(ctx, &mesh, &bvh, rays);
                let agreement = validate_hits(&mesh, rays, &closest, &ref_hits)
                    .unwrap_or_else(|e| panic!("leaf {leaf}, {name} rays: {e}"));
                let any_check = compare_any(&mesh, rays, &closest, &any);
                assert!(any_check.passes(), "leaf {leaf}, {name} any-hit: {any_check:?}");
                assert!(common::no_nan(&closest) && common::no_nan(&any), "leaf {leaf}, {name}: NaN");
                lines.push(format!("leaf {leaf:>2} {name:>7}: {}", agreement.summary()));
            }
        }
        lines
    });
    for l in lines {
        println!("{l}");
    }
}

#[test]
fn zero_area_and_unrepresentable_triangles_are_never_hit() {
    // A grid of unit squares (two triangles each, unshared vertices). The BVH is built on the
    // sound grid, then every third triangle is made zero-area (a repeated vertex, or its third
    // vertex on the first edge) inside its leaf's box, so the encoder, not the BVH, must keep
    // it from being hit; and one triangle is shrunk to f32-subnormal edges (1e-40), whose map
    // (coefficients about 1/|edge|) overflows f32.
    let common::DegenerateGrid { sound, positions: mut pos, triangles: tris, zero_area } = common::degenerate_grid();
    let mut never = zero_area.clone();
    let tiny = 1;
    let [a, b, c] = tris[tiny].map(|v| v as usize);
    pos[b] = [pos[a][0] + 1e-40, pos[a][1], 0.0];
    pos[c] = [pos[a][0], pos[a][1] + 1e-40, 0.0];
    never.push(tiny as u32);
    never.sort_unstable();
    let broken = Mesh::from_triangles(pos, tris);
    assert_eq!(broken.degenerate_ids(), zero_area);
    assert!(!broken.is_degenerate(tiny), "the tiny triangle has nonzero area in f64");
    let rays = common::grid_rays();
    let results = common::with_gpu(300, move |ctx| {
        let k = common::MethodKernels::new(ctx, Method::BaldwinWeber);
        let mut out = vec![];
        for leaf in [1, 4, 16] {
            let bvh = Bvh::build(&sound, &BuildOptions::new(leaf));
            let enc = Method::BaldwinWeber.encode(&broken, &bvh);
            let mut unrep = enc.unrepresentable.clone();
            unrep.sort_unstable();
            let reference = Reference::new(&broken, &bvh).trace_all(&rays, false);
            let (closest, any) = k.cast(ctx, &broken, &bvh, &rays);
            // Every never-hit slot is marked for the kernel to skip.
            let tris: &[BwTriangle] = bytemuck::cast_slice(&enc.prims[0].bytes);
            let skipped = tris.iter().filter(|t| t.plane[3] == BW_NEVER_HIT).count();
            let agreement = compare_closest(&broken, &rays, &closest, &reference);
            out.push((leaf, unrep, skipped, closest, any, agreement));
        }
        (out, never, rays.len())
    });
    let (results, never, n_rays) = results;
    for (leaf, unrep, skipped, closest, any, agreement) in results {
        assert_eq!(unrep, never, "leaf {leaf}: zero-area and overflowing maps are reported unrepresentable");
        assert_eq!(skipped, never.len(), "leaf {leaf}");
        for hits in [&closest, &any] {
            let bad: Vec<_> = hits.iter().filter(|h| h.is_hit() && never.contains(&h.id)).collect();
            assert!(bad.is_empty(), "leaf {leaf}: hits on never-hit triangles: {bad:?}");
            assert!(common::no_nan(hits), "leaf {leaf}: NaN");
        }
        // Every other ray agrees with the reference or lies on an edge (the reference may hit
        // the tiny triangle, whose map does not exist in f32: those rays are at its vertex,
        // within ULPs of an edge).
        assert!(agreement.all_explained(), "leaf {leaf}: {} {:?}", agreement.summary(), agreement.disagreements);
        let n = closest.iter().filter(|h| h.is_hit()).count();
        assert!(n > n_rays / 2, "leaf {leaf}: rays through the grid should hit ({n}/{n_rays})");
    }
}
