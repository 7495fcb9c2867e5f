//! The occupancy model (`gpu::amd::subgroups_per_simd`) against what RADV itself reported: for
//! every kernel of every Mesa 25.0.7 target committed in `results/radv/driver-stats/` (every
//! kernel on pitcairn, polaris10, vega10, navi21, navi31 and gfx1201, ACO and LLVM (but LLVM on
//! gfx1201), wave32 and wave64), the model's subgroups per SIMD from the kernel's VGPRs, SGPRs and LDS equal the
//! driver's. The cliffs trilab names rest on it. No GPU and no driver needed: the figures are
//! the committed ones.

use std::collections::BTreeMap;
use std::path::Path;

use trilab::gpu::amd::{subgroups_per_simd, Chip, Resources};
use trilab::kernels::KERNELS;

/// The committed CSV (stored compressed when large: results/README.md).
fn committed_csv() -> String {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("results/radv/driver-stats");
    let plain = dir.join("driver-stats.csv");
    let path = if plain.is_file() { plain } else { dir.join("driver-stats.csv.gz") };
    trilab::io::read_text(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Each kernel's workgroup size, from its SPIR-V.
fn workgroups() -> BTreeMap<String, u32> {
    KERNELS
        .iter()
        .map(|k| {
            let l = trilab::spirv::reflect::reflect(k.name, &k.words()).unwrap();
            (k.name.to_owned(), l.local_size.0 * l.local_size.1 * l.local_size.2)
        })
        .collect()
}

#[test]
fn the_model_gives_radvs_subgroups_per_simd_for_every_committed_kernel() {
    let text = committed_csv();
    let mut csv = csv::Reader::from_reader(text.as_bytes());
    let headers = csv.headers().unwrap().clone();
    let col = |n: &str| headers.iter().position(|h| h == n).unwrap_or_else(|| panic!("no column {n}"));
    let wgs = workgroups();
    let (mut checked, mut targets) = (0, std::collections::BTreeSet::new());
    let mut wrong = vec![];
    for r in csv.records().map(Result::unwrap) {
        if !r[col("refused")].is_empty() || !r[col("driver")].contains("25.0.7") {
            continue;
        }
        let n = |c: &str| r[col(c)].parse::<f64>().unwrap_or(0.0) as u32;
        let chip: Chip = r[col("chip")].parse().unwrap();
        let name = format!("{}.{}.{}", &r[col("kernel")], &r[col("method")], {
            // results/radv was compiled before the access-path variants took the command line's
            // and traversals' words (issue 52: `_bda` is `_address`, `_sb` is `_storage`, `_ww` is
            // `_while_while`).
            let v = &r[col("variant")]
                .replace("_bda", "_address")
                .replace("_sb", "_storage")
                .replace("_ww", "_while_while");
            let l = &r[col("layout")];
            if l == "bvh2" {
                v.to_owned()
            } else {
                format!("{v}_{l}")
            }
        });
        let Some(&workgroup) = wgs.get(&name) else { panic!("no kernel {name} in this build") };
        let res =
            Resources { wave: n("wave"), vgprs: n("vgprs"), sgprs: n("sgprs"), lds_bytes: n("lds_bytes"), workgroup };
        let model = subgroups_per_simd(chip, &res);
        if model != n("subgroups_per_simd") {
            wrong.push(format!(
                "{} {name}: {res:?}: model {model}, RADV {}",
                &r[col("target")],
                n("subgroups_per_simd")
            ));
        }
        checked += 1;
        targets.insert(r[col("target")].to_owned());
    }
    assert!(wrong.is_empty(), "{} of {checked} kernels differ:\n{}", wrong.len(), wrong.join("\n"));
    // Every default target of Mesa 25.0.7 but gfx1201 with LLVM, which its LLVM 15 has no
    // backend for (results/radv/README.md).
    assert_eq!(targets.len(), 16, "{targets:?}");
    assert!(checked > 16 * 700, "{checked} kernels checked");
}
