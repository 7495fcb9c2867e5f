//! What lavapipe compiles for, as trilab names it (`gpu::lavapipe_cpu`), against what the
//! installed Mesa says it compiles for (issue 51): for each `GALLIUM_OVERRIDE_CPU_CAPS` the CI
//! host matrix uses (and none), `trilab devices` names a set of features, and Mesa's own
//! `GALLIUM_DUMP_CPU=1` prints its `util_cpu_caps` after the override; the two must agree, and
//! the device's SIMD width ("llvmpipe (LLVM 15.0.6, 256 bits)") must be the one those features
//! give. A Mesa whose rule differed from the model (another cascade, a new value) fails here.
//!
//! Needs lavapipe (scripts/install-deps.sh); fails, never skips, without it.

mod common;

use std::collections::BTreeSet;

use common::cli::{ok, run};

/// Mesa's `util_cpu_caps.has_<name>` for trilab's feature names.
fn mesa_name(feature: &str) -> String {
    format!("has_{}", feature.replace('.', "_"))
}

/// `trilab devices` (text and JSON) under `caps`: lavapipe's JSON record, the features Mesa's dump
/// says it has on (among those trilab names), and the device's width in bits.
fn observe(caps: Option<&str>) -> (serde_json::Value, BTreeSet<String>, u32) {
    // Empty is unset to Mesa (and to trilab): the case without an override, whatever the
    // environment this test runs in (the CI matrix's avx pass sets one).
    let env = [("GALLIUM_DUMP_CPU", "1"), ("GALLIUM_OVERRIDE_CPU_CAPS", caps.unwrap_or(""))];
    let (text, _) = run(&["devices"], None, &env, 60);
    ok(&text);
    let stdout = String::from_utf8_lossy(&text.stdout).to_string();
    // `util_cpu_caps.has_avx2 = 1` lines (from Mesa's src/util/u_cpu_detect.c) go to stdout.
    let dumped: BTreeSet<String> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("util_cpu_caps."))
        .filter_map(|l| l.split_once(" = "))
        .filter(|(_, v)| v.trim() == "1")
        .map(|(k, _)| k.to_owned())
        .collect();
    assert!(
        stdout.contains("util_cpu_caps.has_sse2 = "),
        "GALLIUM_DUMP_CPU=1 printed no util_cpu_caps lines (this Mesa no longer dumps them?):\n{stdout}"
    );
    let line = stdout.lines().find(|l| l.contains("compiles for (CPU):"));
    assert!(line.is_some(), "`trilab devices` names no CPU features for lavapipe:\n{stdout}");
    if let Some(c) = caps {
        assert!(line.unwrap().contains(&format!("GALLIUM_OVERRIDE_CPU_CAPS={c}")), "{}", line.unwrap());
    }

    let (json, _) = run(&["devices", "--json"], None, &env[1..], 60);
    ok(&json);
    let devices: serde_json::Value = serde_json::from_slice(&json.stdout).expect("devices --json is JSON");
    let lp = devices
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["driver_id"] == "MESA_LLVMPIPE")
        .expect("lavapipe is installed")
        .clone();
    let name = lp["name"].as_str().unwrap();
    let bits: u32 = name
        .split(", ")
        .find_map(|p| p.strip_suffix(" bits)"))
        .and_then(|b| b.parse().ok())
        .unwrap_or_else(|| panic!("no SIMD width in the device name {name:?}"));
    (lp, dumped, bits)
}

#[test]
fn the_features_trilab_names_are_those_mesa_compiles_for() {
    // None: the host itself; avx: the CI matrix's smaller CPU (a Zen 3's AVX2 without AVX-512);
    // sse4.1: no AVX at all (128-bit vectors); sse2: one more step down the cascade.
    for caps in [None, Some("avx"), Some("sse4.1"), Some("sse2")] {
        let (lp, dumped, bits) = observe(caps);
        let named: Vec<&str> = lp["compiles_for"]["features"]
            .as_array()
            .unwrap_or_else(|| panic!("no compiles_for in {lp}"))
            .iter()
            .map(|f| f.as_str().unwrap())
            .collect();
        // Those Mesa's dump prints (it has no line for FMA).
        for f in ["sse", "sse2", "sse3", "ssse3", "sse4.1", "sse4.2", "avx", "avx2", "f16c", "avx512f", "avx512bw"] {
            assert_eq!(
                named.contains(&f),
                dumped.contains(&mesa_name(f)),
                "GALLIUM_OVERRIDE_CPU_CAPS={caps:?}: trilab says {f} is {}, Mesa's dump says {}\ntrilab: {named:?}\nMesa: {dumped:?}",
                if named.contains(&f) { "on" } else { "off" },
                if dumped.contains(&mesa_name(f)) { "on" } else { "off" },
            );
        }
        // lavapipe's default width: the widest vectors the features give, at most 256 bits.
        let max = lp["compiles_for"]["max_vector_bits"].as_u64().unwrap() as u32;
        assert_eq!(bits, max.min(256), "GALLIUM_OVERRIDE_CPU_CAPS={caps:?}: device width {bits}, features give {max}");
        println!("GALLIUM_OVERRIDE_CPU_CAPS={caps:?}: {bits} bits, {named:?}");
    }
}
