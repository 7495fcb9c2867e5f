//! The foundation's acceptance test: on 100,000 random rays on the bunny, for every method and
//! leaf size, closest hits agree with the f64 reference on >= 99.99 % of rays, every
//! disagreement lies within a few ULPs of an edge, and any-hit hits exactly where closest-hit
//! does.

mod common;

use trilab::agreement::{compare_any, compare_closest};
use trilab::bvh::BuildOptions;
use trilab::encoding::{Method, Raycast};
use trilab::pipeline::{HostScene, SceneRequest};
use trilab::rays::random_rays;

const LEAF_SIZES: [u32; 6] = [1, 2, 3, 4, 8, 16];

#[test]
fn every_method_and_leaf_size_matches_the_f64_reference_on_the_bunny() {
    let report = common::with_gpu(900, |ctx| {
        let mesh = common::bunny();
        let rays = random_rays(&mesh.bounds(), 100_000, 2024);
        let mut lines = vec![];
        let mut failures = vec![];
        for leaf in LEAF_SIZES {
            let host = HostScene::build("bunny", &mesh, &BuildOptions::new(leaf)).unwrap();
            host.bvh.validate(&mesh).unwrap();
            let reference = host.reference().trace_all(&rays, false);
            let ref_hits = reference.iter().filter(|h| h.is_hit()).count();
            assert!(ref_hits > 20_000 && ref_hits < 80_000, "random rays should hit about half the time ({ref_hits})");
            for method in Method::ALL {
                let scene = host.upload(ctx, &SceneRequest::new(method)).unwrap();
                let c = scene.cast(ctx, Raycast::Closest, &rays, &common::ONCE).unwrap();
                let a = scene.cast(ctx, Raycast::Any, &rays, &common::ONCE).unwrap();
                let agreement = compare_closest(&mesh, &rays, &c.hits, &reference);
                let any_check = compare_any(&mesh, &rays, &c.hits, &a.hits);
                lines.push(format!(
                    "{method:>9} leaf {leaf:>2}: {}; any-hit: {} status mismatches, {} bogus",
                    agreement.summary(),
                    any_check.status_mismatch.len(),
                    any_check.bogus.len()
                ));
                if !agreement.passes(0.9999) {
                    let worst: Vec<_> = agreement
                        .disagreements
                        .iter()
                        .filter(|d| d.ambiguity_ulps > trilab::agreement::AMBIGUITY_ULPS)
                        .take(5)
                        .collect();
                    failures.push(format!(
                        "{method} leaf {leaf}: {} {:?} {:?}",
                        agreement.summary(),
                        worst,
                        &agreement.invalid[..agreement.invalid.len().min(5)]
                    ));
                }
                if !any_check.passes() {
                    failures.push(format!("{method} leaf {leaf} any-hit: {:?}", any_check));
                }
            }
        }
        (lines, failures)
    });
    let (lines, failures) = report;
    for l in &lines {
        println!("{l}");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
