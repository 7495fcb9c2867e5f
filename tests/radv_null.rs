//! trilab on real GPU compilers without a GPU (issue 50): Mesa's RADV on its null device
//! (`RADV_FORCE_FAMILY=<chip>`, the RADV that Debian's `mesa-vulkan-drivers` installs beside
//! lavapipe, chosen with VK_DRIVER_FILES). Such a device compiles through AMD's real compiler
//! (ACO, or LLVM under `RADV_DEBUG=llvm`) and reports `VK_KHR_pipeline_executable_properties`,
//! and runs nothing. What a user meets: `devices` says "compiles only" and why; a command that
//! dispatches refuses it before any work, naming it; `driver-stats` exits 0 (it used to end in
//! SIGSEGV, in `vkDeviceWaitIdle` at teardown) with typed statistics and the subgroup size each
//! kernel was compiled at; `--targets` compiles for several chips, compilers, subgroup sizes and
//! Mesa builds, each in a worker, a chip a Mesa build does not know failing alone.
//!
//! Each run has the validation layer on and a wall-clock limit (tests/common/cli.rs). Without
//! RADV installed (scripts/install-deps.sh installs it) these tests fail; they never skip.

mod common;

use std::path::Path;
use std::process::Output;

use common::cli::{expect_error, ok, run, s};
use trilab::services::driver_stats::target::MesaBuild;

/// The installed RADV's ICD file.
fn radv_icd() -> String {
    let (icd, _) = MesaBuild::Installed.icd().expect("RADV is installed (scripts/install-deps.sh)");
    s(&icd)
}

/// `trilab args` on RADV's null device for `chip`, with `env` added.
fn on_chip(chip: &str, args: &[&str], env: &[(&str, &str)], timeout_s: u64) -> Output {
    let icd = radv_icd();
    let mut all = vec![("VK_DRIVER_FILES", icd.as_str()), ("RADV_FORCE_FAMILY", chip)];
    all.extend_from_slice(env);
    run(args, None, &all, timeout_s).0
}

/// Ended by a signal (SIGSEGV, SIGABRT): what this device's driver did before issue 50.
fn signalled(o: &Output) -> Option<i32> {
    use std::os::unix::process::ExitStatusExt;
    o.status.signal()
}

fn rows(dir: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(dir.join("rows.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .filter(|v: &serde_json::Value| v["type"] == "row")
        .collect()
}

#[test]
fn devices_says_the_null_device_compiles_only() {
    let o = on_chip("navi31", &["devices"], &[], 60);
    assert_eq!(signalled(&o), None);
    ok(&o);
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("Null hardware (RADV NAVI31)"), "{text}");
    assert!(text.contains("cannot run kernels: it compiles only (RADV's null device"), "{text}");
    let o = on_chip("navi31", &["devices", "--json"], &[], 60);
    ok(&o);
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(json[0]["execution"]["kind"], "compiles-only", "{json}");
}

/// Every command that dispatches refuses the device at once, naming it, writing nothing.
#[test]
fn commands_that_dispatch_refuse_it_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let out_s = s(&out);
    for args in [
        vec!["bench", "--width", "8", "--height", "8", "--out", &out_s],
        vec!["study", "--preset", "smoke", "--out", &out_s],
        vec!["render", "--scene", "cornell", "--spp", "1", "--out", &format!("{out_s}/x.exr")],
        vec!["roofline", "--out", &out_s],
        vec!["accuracy", "--out", &out_s],
    ] {
        let start = std::time::Instant::now();
        let o = on_chip("pitcairn", &args, &[], 60);
        assert_eq!(signalled(&o), None, "{args:?}");
        expect_error(&o, &["Null hardware (RADV PITCAIRN): it compiles only", "this command runs kernels"]);
        assert!(start.elapsed().as_secs() < 20, "{args:?} refused late: {:?}", start.elapsed());
        assert!(!out.exists(), "{args:?} wrote {out:?}");
    }
}

/// driver-stats exits 0 where it crashed (navi21, navi31, gfx1201; LLVM on pitcairn), with typed
/// statistics: names without the executable's index, occupancy higher-is-better, hashes as
/// identities, and the subgroup size each kernel was compiled at.
#[test]
fn driver_stats_exits_cleanly_with_typed_statistics_on_every_chip() {
    for (chip, env) in
        [("navi21", vec![]), ("navi31", vec![]), ("gfx1201", vec![]), ("pitcairn", vec![("RADV_DEBUG", "llvm")])]
    {
        let dir = tempfile::tempdir().unwrap();
        let args = [
            "driver-stats",
            "--kernels",
            "raycast",
            "--variants",
            "closest",
            "--methods",
            "mt,quad-unit",
            "--out",
            &s(dir.path()),
        ];
        let o = on_chip(chip, &args, &env, 120);
        assert_eq!(signalled(&o), None, "{chip}: {}", String::from_utf8_lossy(&o.stderr));
        ok(&o);
        let rows = rows(dir.path());
        assert_eq!(rows.len(), 2 * 5, "{chip}: mt and quad-unit on five layouts");
        for r in &rows {
            let f = &r["figures"];
            assert!(f["vgprs"]["median"].as_f64().unwrap() > 0.0, "{chip}: {r}");
            assert!(f.get("0_vgprs").is_none(), "{chip}: no executable index in names: {r}");
            assert_eq!(f["subgroups_per_simd"]["better"], "higher", "{chip}: {r}");
            assert_eq!(f["vgprs"]["better"], "lower", "{chip}: {r}");
            assert_eq!(f["code_size"]["unit"], "bytes", "{chip}: {r}");
            assert!(f.get("driver_pipeline_hash").is_none(), "{chip}: a hash is no figure: {r}");
            assert!(r["identities"]["driver_pipeline_hash"].is_string(), "{chip}: {r}");
            assert_eq!(r["cell"]["chip"], chip, "{r}");
            assert_eq!(r["cell"]["wave"], "64", "{r}");
            let compiler = if env.is_empty() { "aco" } else { "llvm" };
            assert_eq!(r["cell"]["compiler"], compiler, "{r}");
            assert!(r["source"]["settings"].get("subgroup_size").is_none(), "{r}");
            assert!(r["source"]["settings"]["driver_build"].as_str().unwrap().contains("Mesa"), "{r}");
        }
        let md = std::fs::read_to_string(dir.path().join("driver-stats.md")).unwrap();
        assert!(md.contains("| kernel | VGPRs | SGPRs | spills (V/S) | scratch B | subgroups/SIMD |"), "{md}");
        assert!(dir.path().join("driver-stats.csv").is_file());
    }
}

/// The provenance says the subgroup size a kernel was compiled at, read from its executable:
/// under RADV_PERFTEST=cswave32 RADV compiles compute kernels at 32 lanes, and the rows say 32
/// where the device's default (64) used to be recorded.
#[test]
fn the_compiled_subgroup_size_is_the_executables() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "driver-stats",
        "--kernels",
        "raycast",
        "--variants",
        "closest",
        "--methods",
        "mt",
        "--layouts",
        "bvh2",
        "--out",
        &s(dir.path()),
    ];
    ok(&on_chip("navi31", &args, &[("RADV_PERFTEST", "cswave32")], 60));
    let rows = rows(dir.path());
    assert_eq!(rows[0]["cell"]["wave"], "32", "{}", rows[0]);
    let md = std::fs::read_to_string(dir.path().join("driver-stats.md")).unwrap();
    assert!(md.contains("Compiled for: navi31 ACO wave32") && !md.contains("subgroup_size=64"), "{md}");
}

/// One run, many targets: each chip x compiler x subgroup size x Mesa build in its own worker,
/// the subgroup size set through requiredSubgroupSize (and checked against the executable), a
/// chip Debian 12's own Mesa does not know failing alone, named, and wave32 refused on GCN
/// before any work.
#[test]
fn targets_compile_in_their_own_workers() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(dir.path());
    let args = [
        "driver-stats",
        "--targets",
        "pitcairn:aco,navi31:aco,navi21:llvm:32",
        "--mesa",
        "installed,stock",
        "--kernels",
        "raycast,rayquery",
        "--variants",
        "closest",
        "--methods",
        "mt",
        "--layouts",
        "bvh2",
        "--out",
        &out,
    ];
    // Even a switch of the user's that would change the code is not the target's.
    let o = run(&args, None, &[("RADV_PERFTEST", "cswave32")], 300).0;
    let err = ok(&o);
    let rows = rows(dir.path());
    let cells: Vec<String> = rows
        .iter()
        .map(|r| {
            let c = &r["cell"];
            format!(
                "{} {} {} {} {}",
                c["chip"], c["compiler"], c["wave"], r["source"]["settings"]["driver_build"], c["kernel"]
            )
            .replace('"', "")
        })
        .collect();
    let has = |chip: &str, compiler: &str, wave: &str, mesa: &str, kernel: &str| {
        cells.iter().any(|c| {
            c.starts_with(&format!("{chip} {compiler} {wave} radv Mesa {mesa}")) && c.ends_with(&format!(" {kernel}"))
        })
    };
    assert!(has("pitcairn", "aco", "64", "25", "raycast"), "{cells:?}");
    assert!(has("pitcairn", "aco", "64", "22.3.6", "raycast"), "{cells:?}");
    assert!(has("navi31", "aco", "32", "25", "raycast") && has("navi31", "aco", "64", "25", "raycast"), "{cells:?}");
    assert!(has("navi31", "aco", "32", "25", "rayquery"), "RDNA 3 has ray queries: {cells:?}");
    assert!(!has("pitcairn", "aco", "64", "25", "rayquery"), "GCN has none: {cells:?}");
    assert!(has("navi21", "llvm", "32", "22.3.6", "raycast"), "{cells:?}");
    let md = std::fs::read_to_string(dir.path().join("driver-stats.md")).unwrap();
    assert!(md.contains("navi31:aco:64@stock") && md.contains("does not know the chip navi31"), "{md}");
    assert!(md.contains("rayQuery"), "the GCN targets name why the ray-query kernel is not compiled: {md}");
    assert!(err.contains("[8/8]"), "{err}");
    // wave32 on GCN: refused before any work, naming the target.
    let o = run(&["driver-stats", "--targets", "pitcairn:aco:32", "--out", &format!("{out}/x")], None, &[], 30).0;
    expect_error(&o, &["pitcairn:aco:32", "64 lanes only"]);
    let o = run(&["driver-stats", "--targets", "navi99", "--out", &format!("{out}/x")], None, &[], 30).0;
    expect_error(&o, &["no chip `navi99`", "pitcairn"]);
}

/// `trilab compare` of two Mesa builds' statistics (issue 50's 22.3.6 -> 25.0.7 on pitcairn and
/// navi21): more subgroups per SIMD is better, a hash is only changed, the totals are
/// fossil-db's, and the warning says the changes are the drivers'.
#[test]
fn compare_of_two_mesa_builds_judges_each_statistic_by_its_direction() {
    let dir = tempfile::tempdir().unwrap();
    let side = |mesa: &str| {
        let out = dir.path().join(mesa);
        let args = [
            "driver-stats",
            "--targets",
            "navi21:aco:64",
            "--mesa",
            mesa,
            "--kernels",
            "raycast",
            "--variants",
            "closest",
            "--methods",
            "mt,quad-unit",
            "--out",
            &s(&out),
        ];
        ok(&run(&args, None, &[], 120).0);
        out
    };
    let (old, new) = (side("stock"), side("installed"));
    let o = run(&["compare", &s(&old), &s(&new), "--json"], None, &[], 60).0;
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let changes = report["changes"].as_array().unwrap();
    assert!(!changes.is_empty());
    for c in changes {
        let (b, n) = (c["base"]["median"].as_f64().unwrap(), c["new"]["median"].as_f64().unwrap());
        let higher = c["base"]["better"] == "higher";
        let want = if (n > b) == higher { "better" } else { "worse" };
        assert_eq!(c["verdict"], want, "{c}");
        assert!(c["figure"] != "driver_pipeline_hash" && c["figure"] != "hash", "{c}");
        if c["figure"] == "subgroups_per_simd" && n > b {
            assert_eq!(c["regression"], false, "a rise in occupancy is no regression: {c}");
        }
    }
    let ids = report["identities"].as_array().unwrap();
    assert!(ids.iter().any(|i| i["identity"] == "driver_pipeline_hash" && i["cells"] == 10), "{ids:?}");
    let text = String::from_utf8(run(&["compare", &s(&old), &s(&new)], None, &[], 60).0.stdout).unwrap();
    assert!(text.contains("driver-stats totals (10 cells in both"), "{text}");
    assert!(text.contains("compiled by different driver builds"), "{text}");
}

/// A copy of the rows folder `from` in `to`, each row changed by `f`.
fn edited(from: &Path, to: &Path, f: impl Fn(&mut serde_json::Value)) {
    std::fs::create_dir_all(to).unwrap();
    let text: Vec<String> = std::fs::read_to_string(from.join("rows.jsonl"))
        .unwrap()
        .lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            if v["type"] == "row" {
                f(&mut v);
            }
            v.to_string()
        })
        .collect();
    std::fs::write(to.join("rows.jsonl"), text.join("\n") + "\n").unwrap();
}

/// The gate holds the RADV counts as it holds the SPIR-V counts: the studied kernels compiled for
/// pitcairn and navi31 (ACO, wave64), exactly. Four more VGPRs in one kernel fail it, naming the
/// figure; the same rows from another Mesa build are not judged, and it says so.
#[test]
fn the_gate_holds_the_radv_counts_exactly_and_only_for_the_same_mesa() {
    let dir = tempfile::tempdir().unwrap();
    let base = dir.path().join("base");
    let args =
        ["driver-stats", "--targets", "pitcairn:aco:64,navi31:aco:64", "--kernels", "studied", "--out", &s(&base)];
    ok(&run(&args, None, &[], 300).0);
    let n = rows(&base).len();
    assert!(n >= 2 * 40, "the studied kernels on two chips: {n} rows");
    let gate = |new: &Path| {
        let o = run(&["gate", &s(&base), &s(new), "--no-base", "RADV counts only", "--json"], None, &[], 120).0;
        let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        (o.status.code(), r)
    };
    // Measured again: identical, every figure judged.
    let again = dir.path().join("again");
    ok(&run(
        &["driver-stats", "--targets", "pitcairn:aco:64,navi31:aco:64", "--kernels", "studied", "--out", &s(&again)],
        None,
        &[],
        300,
    )
    .0);
    let (code, r) = gate(&again);
    assert_eq!(code, Some(0), "{r}");
    assert!(r["counts"]["totals"]["figures_compared"].as_u64().unwrap() > 10 * n as u64, "{r}");
    // One kernel with four more VGPRs.
    let planted = dir.path().join("planted");
    edited(&base, &planted, |row| {
        if row["cell"]["chip"] == "pitcairn"
            && row["cell"]["method"] == "quad-unit"
            && row["cell"]["variant"] == "closest"
            && row["cell"]["layout"] == "bvh2"
        {
            for k in ["median", "min", "max"] {
                row["figures"]["vgprs"][k] =
                    serde_json::Value::from(row["figures"]["vgprs"][k].as_f64().unwrap() + 4.0);
            }
        }
    });
    let (code, r) = gate(&planted);
    assert_eq!(code, Some(1), "{r}");
    let changes = r["counts"]["changes"].as_array().unwrap();
    assert_eq!(changes.len(), 1, "{r}");
    assert_eq!((changes[0]["figure"].as_str(), changes[0]["regression"].as_bool()), (Some("vgprs"), Some(true)));
    // The same plant in rows of another Mesa build: not judged, and said.
    let other = dir.path().join("other");
    edited(&planted, &other, |row| row["source"]["settings"]["driver_build"] = "radv Mesa 99.0.0".into());
    let (code, r) = gate(&other);
    assert_eq!(code, Some(0), "{r}");
    assert!(r["counts"]["totals"]["counts_other_driver"].as_u64().unwrap() > 0, "{r}");
    let warned = r["counts"]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .any(|w| w.as_str().unwrap().contains("differ by the driver alone, so they are not judged"));
    assert!(warned, "{r}");
}

/// Issue 53's register target for the per-ray (while-if) kernels: on GCN with ACO every layout's
/// closest- and any-hit kernel keeps at least 2 subgroups per SIMD (at most 128 VGPRs), and
/// LLVM's backend spills nothing where it caps a subgroup at 128 VGPRs (navi31, wave64). Before
/// the stack's arrays were sized past RADV's 256-byte line (glsl/shared.glsl,
/// STACK_MIN_ENTRIES), bvh4's, qbvh4's and cwbvh's stacks were held in registers: 180-228 VGPRs,
/// one subgroup on GCN, and 141-322 VGPRs spilled by LLVM (results/radv/stack-53/).
#[test]
fn while_if_kernels_fit_two_subgroups_on_gcn_and_llvm_does_not_spill() {
    let dir = tempfile::tempdir().unwrap();
    let out = s(dir.path());
    let args = [
        "driver-stats",
        "--targets",
        "pitcairn:aco:64,navi31:llvm:64",
        "--kernels",
        "raycast",
        "--variants",
        "closest,any",
        "--out",
        &out,
    ];
    ok(&run(&args, None, &[], 300).0);
    let csv = std::fs::read_to_string(dir.path().join("driver-stats.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (chip, compiler, layout, variant, method) =
        (col("chip"), col("compiler"), col("layout"), col("variant"), col("method"));
    let (sg, spilled, refused) = (col("subgroups_per_simd"), col("spilled_vgprs"), col("refused"));
    let mut seen = std::collections::BTreeSet::new();
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!(f[refused], "", "a kernel was refused: {line}");
        let what = format!("{} {} {} {} {}", f[chip], f[compiler], f[method], f[layout], f[variant]);
        let n = |i: usize| f[i].parse::<u32>().unwrap_or_else(|_| panic!("{what}: column {} is `{}`", header[i], f[i]));
        if f[chip] == "pitcairn" {
            assert!(n(sg) >= 2, "{what}: {} subgroup(s) per SIMD", n(sg));
        } else {
            assert_eq!(n(spilled), 0, "{what}: {} VGPRs spilled", n(spilled));
        }
        seen.insert((f[chip].to_owned(), f[layout].to_owned()));
    }
    for c in ["pitcairn", "navi31"] {
        for l in ["bvh2", "bvh4", "bvh8", "cwbvh", "qbvh4"] {
            assert!(seen.contains(&(c.to_owned(), l.to_owned())), "{c} {l} was compiled: {seen:?}");
        }
    }
}
