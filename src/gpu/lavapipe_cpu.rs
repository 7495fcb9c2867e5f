//! The CPU features lavapipe's JIT compiles for: this host's x86 features as Mesa's
//! `util_cpu_detect` reads them, less what `GALLIUM_OVERRIDE_CPU_CAPS` removes.
//!
//! lavapipe (llvmpipe's gallivm) hands LLVM exactly these features (`+avx2`, `-avx512f`, ...),
//! not LLVM's own view of the host, so one machine can compile as a smaller one does: under
//! `GALLIUM_OVERRIDE_CPU_CAPS=avx` a Zen 4 host compiles as a Zen 3 does (AVX2 and FMA, no
//! AVX-512, 256-bit vectors), under `sse4.1` as a host without AVX (128-bit vectors). The CI
//! host matrix (`scripts/test-width.sh BITS CAPS`) runs the GPU tests so, and `trilab devices`
//! and every report's provenance name the result, so a run says which code it measured.
//!
//! The rule is Mesa's (src/util/u_cpu_detect.c, `check_cpu_caps_override`, Mesa 22 to 25):
//! each value clears one feature, and clearing one clears those that need it (no SSE4.1: no
//! AVX; no AVX: no AVX2, FMA, F16C or AVX-512; no AVX-512F: no other AVX-512). A value Mesa
//! does not know changes nothing. tests/lavapipe_cpu.rs holds this model against what the
//! installed Mesa prints under `GALLIUM_DUMP_CPU`.

use serde::Serialize;

/// The environment variable Mesa reads.
pub const OVERRIDE: &str = "GALLIUM_OVERRIDE_CPU_CAPS";

/// The values Mesa accepts, each with the feature it clears.
pub const OVERRIDES: &[(&str, &str)] = &[
    ("nosse", "sse"),
    ("sse", "sse2"),
    ("sse2", "sse3"),
    ("sse3", "ssse3"),
    ("ssse3", "sse4.1"),
    ("sse4.1", "avx"),
    ("avx", "avx512f"),
];

/// The features named, in the order Mesa's cascade runs: each entry is cleared when the one
/// it needs is (`needs`), as `check_cpu_caps_override` clears them.
const FEATURES: &[(&str, Option<&str>)] = &[
    ("sse", None),
    ("sse2", Some("sse")),
    ("sse3", Some("sse2")),
    ("ssse3", Some("sse3")),
    ("sse4.1", Some("ssse3")),
    ("sse4.2", Some("sse4.1")),
    ("avx", Some("sse4.1")),
    ("avx2", Some("avx")),
    ("fma", Some("avx")),
    ("f16c", Some("avx")),
    ("avx512f", Some("avx")),
    ("avx512dq", Some("avx512f")),
    ("avx512cd", Some("avx512f")),
    ("avx512bw", Some("avx512f")),
    ("avx512vl", Some("avx512f")),
];

/// What lavapipe compiles for on this host.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct LavapipeCpu {
    /// The features it compiles for, in [`FEATURES`] order.
    pub features: Vec<&'static str>,
    /// The host's features that `GALLIUM_OVERRIDE_CPU_CAPS` took away.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub removed: Vec<&'static str>,
    /// `GALLIUM_OVERRIDE_CPU_CAPS` as set (a value Mesa does not know included: it removes
    /// nothing, and the report says so).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu_caps_override: Option<String>,
    /// The widest vectors these features give (Mesa's `max_vector_bits`: 512 with AVX-512F,
    /// 256 with AVX, else 128): lavapipe's default SIMD width is the smaller of this and 256.
    pub max_vector_bits: u32,
}

impl LavapipeCpu {
    /// This host under this process's `GALLIUM_OVERRIDE_CPU_CAPS`; `None` off x86-64.
    pub fn current() -> Option<LavapipeCpu> {
        // Mesa reads an empty value as unset.
        let caps = std::env::var(OVERRIDE).ok().filter(|v| !v.is_empty());
        Some(LavapipeCpu::of(&host_features()?, caps.as_deref()))
    }

    /// What a host with `host` features compiles for under `cpu_caps_override`.
    pub fn of(host: &[&'static str], cpu_caps_override: Option<&str>) -> LavapipeCpu {
        let cleared = cpu_caps_override.and_then(|v| OVERRIDES.iter().find(|(name, _)| *name == v)).map(|(_, f)| *f);
        let mut features: Vec<&'static str> = Vec::new();
        for &(f, needs) in FEATURES {
            let kept = host.contains(&f) && Some(f) != cleared && needs.is_none_or(|n| features.contains(&n));
            if kept {
                features.push(f);
            }
        }
        let removed = FEATURES.iter().map(|(f, _)| *f).filter(|f| host.contains(f) && !features.contains(f)).collect();
        let max_vector_bits = if features.contains(&"avx512f") {
            512
        } else if features.contains(&"avx") {
            256
        } else {
            128
        };
        LavapipeCpu { features, removed, cpu_caps_override: cpu_caps_override.map(str::to_owned), max_vector_bits }
    }

    /// Whether Mesa knows the override's value (an unknown one changes nothing).
    pub fn override_known(&self) -> bool {
        self.cpu_caps_override.as_deref().is_none_or(|v| OVERRIDES.iter().any(|(name, _)| *name == v))
    }

    /// One line: the widest features it compiles for, then what the override took away
    /// ("avx avx2 fma f16c, no avx512f (GALLIUM_OVERRIDE_CPU_CAPS=avx); vectors up to 256 bits").
    pub fn summary(&self) -> String {
        // The SSE levels below the widest say nothing a reader needs.
        let shown: Vec<&str> = match self.features.iter().position(|f| f.starts_with("avx")) {
            Some(at) => self.features[at..].to_vec(),
            None => self.features.last().copied().into_iter().collect(),
        };
        let mut s = if shown.is_empty() { "no SSE".to_owned() } else { shown.join(" ") };
        match (&self.cpu_caps_override, self.removed.is_empty()) {
            (Some(v), _) if !self.override_known() => {
                s += &format!(" ({OVERRIDE}={v} is not a value Mesa knows: it changes nothing)")
            }
            (Some(v), false) => s += &format!(", not {} ({OVERRIDE}={v})", self.removed.join(" ")),
            (Some(v), true) => s += &format!(" ({OVERRIDE}={v}: this host had nothing more)"),
            (None, _) => {}
        }
        s + &format!("; vectors up to {} bits", self.max_vector_bits)
    }
}

/// The host's features among [`FEATURES`], as the CPU and the OS offer them (Rust's detection,
/// like Mesa's, asks the OS whether it saves the wider registers: XGETBV).
#[cfg(target_arch = "x86_64")]
pub fn host_features() -> Option<Vec<&'static str>> {
    use std::arch::is_x86_feature_detected as has;
    let all = [
        ("sse", has!("sse")),
        ("sse2", has!("sse2")),
        ("sse3", has!("sse3")),
        ("ssse3", has!("ssse3")),
        ("sse4.1", has!("sse4.1")),
        ("sse4.2", has!("sse4.2")),
        ("avx", has!("avx")),
        ("avx2", has!("avx2")),
        ("fma", has!("fma")),
        ("f16c", has!("f16c")),
        ("avx512f", has!("avx512f")),
        ("avx512dq", has!("avx512dq")),
        ("avx512cd", has!("avx512cd")),
        ("avx512bw", has!("avx512bw")),
        ("avx512vl", has!("avx512vl")),
    ];
    Some(all.into_iter().filter(|(_, yes)| *yes).map(|(f, _)| f).collect())
}

/// Off x86-64 Mesa's override does nothing and trilab names no features.
#[cfg(not(target_arch = "x86_64"))]
pub fn host_features() -> Option<Vec<&'static str>> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Zen 4 (AVX-512) host, written out by hand from AMD's feature list.
    const ZEN4: &[&str] = &[
        "sse", "sse2", "sse3", "ssse3", "sse4.1", "sse4.2", "avx", "avx2", "fma", "f16c", "avx512f", "avx512dq",
        "avx512cd", "avx512bw", "avx512vl",
    ];

    #[test]
    fn avx_removes_only_avx512_so_a_zen4_compiles_as_a_zen3() {
        let c = LavapipeCpu::of(ZEN4, Some("avx"));
        assert!(c.features.contains(&"avx2") && c.features.contains(&"fma"), "{c:?}");
        assert!(!c.features.iter().any(|f| f.starts_with("avx512")), "{c:?}");
        assert_eq!(c.removed, ["avx512f", "avx512dq", "avx512cd", "avx512bw", "avx512vl"]);
        assert_eq!(c.max_vector_bits, 256);
        assert_eq!(
            c.summary(),
            "avx avx2 fma f16c, not avx512f avx512dq avx512cd avx512bw avx512vl (GALLIUM_OVERRIDE_CPU_CAPS=avx); \
             vectors up to 256 bits"
        );
    }

    #[test]
    fn sse41_removes_avx_and_everything_that_needs_it() {
        let c = LavapipeCpu::of(ZEN4, Some("sse4.1"));
        assert_eq!(c.features, ["sse", "sse2", "sse3", "ssse3", "sse4.1", "sse4.2"]);
        assert_eq!(c.max_vector_bits, 128);
        assert!(c.summary().starts_with("sse4.2, not avx avx2 fma f16c avx512f"), "{}", c.summary());
    }

    #[test]
    fn nosse_leaves_nothing_and_no_override_leaves_all() {
        assert!(LavapipeCpu::of(ZEN4, Some("nosse")).features.is_empty());
        let all = LavapipeCpu::of(ZEN4, None);
        assert_eq!(all.features, ZEN4);
        assert_eq!(all.max_vector_bits, 512);
        assert!(all.removed.is_empty());
    }

    #[test]
    fn an_unknown_value_changes_nothing_and_says_so() {
        let c = LavapipeCpu::of(ZEN4, Some("avx2"));
        assert_eq!(c.features, ZEN4);
        assert!(c.summary().contains("is not a value Mesa knows"), "{}", c.summary());
    }

    #[test]
    fn a_host_without_avx512_keeps_what_it_has_under_avx() {
        let zen3: Vec<&str> = ZEN4.iter().copied().filter(|f| !f.starts_with("avx512")).collect();
        let c = LavapipeCpu::of(&zen3, Some("avx"));
        assert_eq!(c.features, zen3);
        assert!(c.summary().contains("this host had nothing more"), "{}", c.summary());
    }
}
