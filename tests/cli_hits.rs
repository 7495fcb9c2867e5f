//! `trilab hits show|check|diff` (issue 14, defect 11): hit files printed, checked against the
//! CPU f64 reference, diffed; bad files named. Every run has a wall-clock limit; hits are made
//! by `raycast` on the device with the validation layer.

mod common;

use common::cli::s;

use std::path::Path;
use std::process::Output;

use trilab::rays::{read_hits, write_hits};

const BUNNY: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/bunny.obj");

fn trilab(args: &[&str]) -> Output {
    common::cli::trilab(args, 120)
}

fn out(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn err(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Primary rays of the bunny (24 x 16) and their closest hits from `raycast --method mt`.
fn cast(dir: &Path) -> (String, String) {
    let rays = s(&dir.join("p.rays"));
    let hits = s(&dir.join("mt.hits"));
    let o = trilab(&["rays", "primary", "--scene", BUNNY, "--out", &rays, "--width", "24", "--height", "16"]);
    assert!(o.status.success(), "{}", err(&o));
    let o = trilab(&["raycast", "--scene", BUNNY, "--rays", &rays, "--out", &hits, "--method", "mt", "--validation"]);
    assert!(o.status.success(), "{}", err(&o));
    (rays, hits)
}

#[test]
fn show_check_and_diff() {
    let dir = tempfile::tempdir().unwrap();
    let (rays, hits) = cast(dir.path());
    let records = read_hits(Path::new(&hits)).unwrap();
    let n_hit = records.iter().filter(|h| h.is_hit()).count();
    assert!(n_hit > 0 && n_hit < records.len());

    // show: counts and readable rows.
    let o = trilab(&["hits", "show", &hits, "--limit", "3"]);
    assert!(o.status.success(), "{}", err(&o));
    let t = out(&o);
    assert!(t.contains(&format!("{} rays, {n_hit} hits, {} misses", records.len(), records.len() - n_hit)), "{t}");
    assert!(t.contains("triangle") && t.contains("miss"), "{t}");
    let o = trilab(&["hits", "show", &hits, "--json", "--limit", "1000"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["shown"].as_array().unwrap().len(), records.len());
    assert_eq!(v["hits"], n_hit);

    // check: the kernel's hits agree with the reference; corrupted ones do not.
    let o = trilab(&["hits", "check", "--scene", BUNNY, "--rays", &rays, &hits]);
    assert!(o.status.success(), "{}{}", out(&o), err(&o));
    assert!(out(&o).contains("agrees with the f64 reference"), "{}", out(&o));
    let first_hit = records.iter().position(|h| h.is_hit()).unwrap();
    let mut bad = records.clone();
    let first_miss = records.iter().position(|h| !h.is_hit()).unwrap();
    bad[first_miss] = trilab::rays::Hit { t: 1.0, id: records[first_hit].id, u: 0.1, v: 0.1 }; // a false hit
    let bad_path = dir.path().join("bad.hits");
    write_hits(&bad_path, &bad).unwrap();
    let o = trilab(&["hits", "check", "--scene", BUNNY, "--rays", &rays, &s(&bad_path)]);
    assert_eq!(o.status.code(), Some(1), "{}{}", out(&o), err(&o));
    assert!(out(&o).contains("DISAGREES") && err(&o).contains("bad.hits"), "{}{}", out(&o), err(&o));

    // diff: identical files agree (exit 0); changes are listed by kind (exit 1).
    let o = trilab(&["hits", "diff", &hits, &hits]);
    assert_eq!(o.status.code(), Some(0), "{}", err(&o));
    assert!(out(&o).contains(&format!("0 of {} rays differ", records.len())), "{}", out(&o));
    let mut changed = records.clone();
    changed[first_hit].t *= 1.0 + 1e-7; // within a tolerance of 1e-6
    changed[first_miss] = bad[first_miss]; // miss -> hit
    let last_hit = records.iter().rposition(|h| h.is_hit()).unwrap();
    changed[last_hit].id ^= 1; // another triangle
    let changed_path = dir.path().join("changed.hits");
    write_hits(&changed_path, &changed).unwrap();
    let o = trilab(&["hits", "diff", &hits, &s(&changed_path), "--t-tolerance", "1e-6", "--json"]);
    assert_eq!(o.status.code(), Some(1), "{}", err(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        (v["changed"].as_u64(), v["miss_to_hit"].as_u64(), v["triangle_changed"].as_u64()),
        (Some(2), Some(1), Some(1))
    );
    let rays_listed: Vec<u64> = v["changes"].as_array().unwrap().iter().map(|c| c["ray"].as_u64().unwrap()).collect();
    assert_eq!(rays_listed, vec![first_miss.min(last_hit) as u64, first_miss.max(last_hit) as u64]);
    // Without the tolerance the t change counts too.
    let o = trilab(&["hits", "diff", &hits, &s(&changed_path)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(out(&o).contains(&format!("3 of {} rays differ", records.len())), "{}", out(&o));
}

#[test]
fn bad_hit_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let (rays, hits) = cast(dir.path());
    let odd = dir.path().join("odd.hits");
    std::fs::write(&odd, [0u8; 17]).unwrap();
    let short = dir.path().join("short.hits");
    std::fs::write(&short, &std::fs::read(&hits).unwrap()[..32]).unwrap();
    let cases: Vec<(Vec<String>, Vec<String>)> = vec![
        (vec!["show".into(), s(&odd)], vec![s(&odd), "multiple of 16".into()]),
        (vec!["show".into(), "/no/such.hits".into()], vec!["/no/such.hits".into()]),
        (
            vec!["check".into(), "--scene".into(), BUNNY.into(), "--rays".into(), rays.clone(), s(&short)],
            vec![s(&short), "2 hit records".into(), rays.clone()],
        ),
        (vec!["diff".into(), hits.clone(), s(&short)], vec![s(&short), "not hits of the same rays".into()]),
        (vec!["diff".into(), hits.clone(), s(&odd)], vec![s(&odd)]),
    ];
    for (args, needles) in cases {
        let mut a = vec!["hits"];
        a.extend(args.iter().map(String::as_str));
        let o = trilab(&a);
        let e = err(&o);
        assert!(matches!(o.status.code(), Some(1 | 2)), "trilab {a:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
        for n in &needles {
            assert!(e.contains(n.as_str()), "trilab {a:?} should mention `{n}`: {e}");
        }
    }
}
