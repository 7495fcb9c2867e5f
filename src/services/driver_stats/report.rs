//! The compiler's statistics as tables people read: kernels as rows; VGPRs, SGPRs, spills,
//! scratch, subgroups per SIMD, instructions and code bytes as columns; for GPU targets a
//! summary row per target and the occupancy cliffs, the kernels that one more VGPR would cost
//! a subgroup per SIMD ([`crate::gpu::amd::Occupancy`]). `driver-stats.csv` holds every kernel
//! of every target, one line each, for a spreadsheet.

use crate::gpu::amd::{Occupancy, Resources};
use crate::report::Table;

use super::{KernelStats, TargetStats};

/// RADV's statistics the tables show, by their typed names ([`crate::gpu::executable`]).
pub mod names {
    pub const VGPRS: &str = "vgprs";
    pub const SGPRS: &str = "sgprs";
    pub const SPILLED_VGPRS: &str = "spilled_vgprs";
    pub const SPILLED_SGPRS: &str = "spilled_sgprs";
    pub const SCRATCH: &str = "scratch_size";
    pub const LDS: &str = "lds_size";
    pub const SUBGROUPS: &str = "subgroups_per_simd";
    pub const INSTRUCTIONS: &str = "instructions";
    pub const CODE: &str = "code_size";
    pub const LATENCY: &str = "latency";
    pub const INVERSE_THROUGHPUT: &str = "inverse_throughput";
}

/// A kernel's place on its chip's occupancy curve, from its statistics (`None` off RADV, or
/// without VGPRs), and the subgroups per SIMD the driver reported beside it.
pub fn occupancy(k: &KernelStats) -> Option<(Occupancy, Option<u32>)> {
    let compiled = k.compiled.as_ref()?;
    let chip = compiled.chip?;
    let stat = |n: &str| k.statistic(n).map(|v| v as u32);
    let lds_bytes = stat(names::LDS).unwrap_or(0);
    // The workgroup's size matters only to a kernel with LDS: its SPIR-V is reflected then only
    // (a table of every kernel of every target asks this tens of thousands of times).
    let workgroup = if lds_bytes == 0 {
        0
    } else {
        k.source()
            .and_then(|s| crate::spirv::reflect::reflect(s.name, &s.words()).ok())
            .map_or(64, |l| l.local_size.0 * l.local_size.1 * l.local_size.2)
    };
    let r = Resources {
        wave: compiled.wave,
        vgprs: stat(names::VGPRS)?,
        sgprs: stat(names::SGPRS).unwrap_or(0),
        lds_bytes,
        workgroup,
    };
    Some((Occupancy::of(chip, &r), stat(names::SUBGROUPS)))
}

fn cell(k: &KernelStats, name: &str) -> String {
    k.statistic(name).map_or("-".into(), |v| format!("{v:.0}"))
}

/// The compiled kernels, one row each.
pub fn compiled_table(kernels: &[&KernelStats]) -> Table {
    let mut t = Table::new([
        "kernel",
        "VGPRs",
        "SGPRs",
        "spills (V/S)",
        "scratch B",
        "subgroups/SIMD",
        "+VGPRs to lose one",
        "-VGPRs to gain one",
        "instructions",
        "code B",
    ]);
    for k in kernels {
        let occ = occupancy(k);
        let subgroups = match occ {
            Some((o, Some(reported))) if o.subgroups != reported => format!("{reported} (model {})", o.subgroups),
            _ => cell(k, names::SUBGROUPS),
        };
        let opt = |v: Option<u32>| v.map_or("-".into(), |v| v.to_string());
        t.row([
            k.name.clone(),
            cell(k, names::VGPRS),
            cell(k, names::SGPRS),
            format!("{}/{}", cell(k, names::SPILLED_VGPRS), cell(k, names::SPILLED_SGPRS)),
            cell(k, names::SCRATCH),
            subgroups,
            occ.map_or("-".into(), |(o, _)| opt(o.vgprs_to_loss)),
            occ.map_or("-".into(), |(o, _)| opt(o.vgprs_to_gain)),
            cell(k, names::INSTRUCTIONS),
            cell(k, names::CODE),
        ]);
    }
    t
}

/// What the compiled table's columns are.
pub const COMPILED_LEGEND: &str = "\nVGPRs, SGPRs: registers allocated per subgroup; spills: VGPRs/SGPRs spilled; \
     scratch B: private memory per subgroup (the stack arrays of a kernel the compiler does not keep in registers, and \
     spills); subgroups/SIMD: the most subgroups in flight on a SIMD as RADV counts them (on RDNA a wave64 subgroup \
     counts twice); +VGPRs to lose one: how many more VGPRs would cost a subgroup per SIMD (1: the kernel is on an \
     occupancy cliff; - : none would, the limit being elsewhere), -VGPRs to gain one: how many fewer would gain one; \
     instructions: ACO's count (LLVM reports none); code B: code size. All are static, from the compiler; nothing \
     ran.\n";

/// The numbers of one target's kernels, for its summary row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Summary {
    pub kernels: usize,
    pub refused: usize,
    pub vgprs_median: Option<f64>,
    pub vgprs_max: Option<f64>,
    /// Kernels that spill VGPRs (or SGPRs).
    pub spilling: usize,
    /// Kernels with scratch memory.
    pub scratch: usize,
    pub subgroups_median: Option<f64>,
    pub subgroups_min: Option<f64>,
    /// Kernels at one subgroup per SIMD (two wave32 slots, on RDNA's count of wave64).
    pub one_subgroup: usize,
    /// Kernels one more VGPR would cost a subgroup per SIMD.
    pub on_cliff: Vec<String>,
    /// Kernels whose reported subgroups per SIMD the model does not give (its cliffs are then
    /// not to be trusted for them).
    pub model_disagrees: usize,
}

fn median(mut xs: Vec<f64>) -> Option<f64> {
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    (n > 0).then(|| if n % 2 == 1 { xs[n / 2] } else { (xs[n / 2 - 1] + xs[n / 2]) / 2.0 })
}

impl Summary {
    pub fn of(kernels: &[KernelStats], refused: usize) -> Summary {
        let get = |n: &str| kernels.iter().filter_map(|k| k.statistic(n)).collect::<Vec<_>>();
        let vgprs = get(names::VGPRS);
        let subgroups = get(names::SUBGROUPS);
        // RDNA counts a wave64 subgroup twice: one subgroup of 64 lanes reads 2.
        let one = |k: &KernelStats, v: f64| {
            let doubled =
                k.compiled.as_ref().is_some_and(|c| c.wave == 64 && c.chip.is_some_and(|chip| chip.gfx.is_rdna()));
            v <= if doubled { 2.0 } else { 1.0 }
        };
        let mut on_cliff = vec![];
        let mut model_disagrees = 0;
        for k in kernels {
            if let Some((o, reported)) = occupancy(k) {
                if o.on_cliff() {
                    on_cliff.push(k.name.clone());
                }
                if reported.is_some_and(|r| r != o.subgroups) {
                    model_disagrees += 1;
                }
            }
        }
        Summary {
            kernels: kernels.len(),
            refused,
            vgprs_median: median(vgprs.clone()),
            vgprs_max: vgprs.iter().copied().reduce(f64::max),
            spilling: kernels
                .iter()
                .filter(|k| {
                    k.statistic(names::SPILLED_VGPRS).unwrap_or(0.0) > 0.0
                        || k.statistic(names::SPILLED_SGPRS).unwrap_or(0.0) > 0.0
                })
                .count(),
            scratch: kernels.iter().filter(|k| k.statistic(names::SCRATCH).unwrap_or(0.0) > 0.0).count(),
            subgroups_median: median(subgroups.clone()),
            subgroups_min: subgroups.iter().copied().reduce(f64::min),
            one_subgroup: kernels.iter().filter(|k| k.statistic(names::SUBGROUPS).is_some_and(|v| one(k, v))).count(),
            on_cliff,
            model_disagrees,
        }
    }
}

/// One row per target: what compiled, the median and worst VGPRs, spills, scratch, occupancy,
/// the kernels at one subgroup per SIMD and on a cliff.
pub fn targets_table(targets: &[TargetStats]) -> Table {
    let mut t = Table::new([
        "target",
        "architecture",
        "driver",
        "kernels",
        "refused",
        "VGPRs median (max)",
        "spilling",
        "with scratch",
        "subgroups/SIMD median (min)",
        "at one subgroup",
        "on a cliff",
    ]);
    let n = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.0}"));
    for s in targets {
        let arch = s.compiled_for.chip.map_or("-".into(), |c| c.gfx.architecture().to_owned());
        if s.kernels.is_empty() {
            t.row(
                [s.target.clone(), arch, "-".into(), "0".into(), s.refused.len().to_string()]
                    .into_iter()
                    .chain(std::iter::repeat_n("-".to_owned(), 6)),
            );
            continue;
        }
        let m = Summary::of(&s.kernels, s.refused.len());
        t.row([
            s.target.clone(),
            arch,
            s.driver_info.clone(),
            m.kernels.to_string(),
            m.refused.to_string(),
            format!("{} ({})", n(m.vgprs_median), n(m.vgprs_max)),
            m.spilling.to_string(),
            m.scratch.to_string(),
            format!("{} ({})", n(m.subgroups_median), n(m.subgroups_min)),
            m.one_subgroup.to_string(),
            m.on_cliff.len().to_string(),
        ]);
    }
    t
}

/// The most kernels a target's table in the Markdown lists: past it, the table keeps the
/// closest-hit ray-casting kernels (every method and layout, the study's kernels) and
/// `driver-stats.csv` holds the rest.
pub const TABLE_KERNELS: usize = 200;

/// The kernels a target's table lists ([`TABLE_KERNELS`]), and whether some were left out.
pub fn tabled(kernels: &[KernelStats]) -> (Vec<&KernelStats>, bool) {
    if kernels.len() <= TABLE_KERNELS {
        return (kernels.iter().collect(), false);
    }
    let closest: Vec<&KernelStats> =
        kernels.iter().filter(|k| k.cell.kernel == "raycast" && k.cell.variant == "closest").collect();
    (closest, true)
}

/// `driver-stats.csv`: every compiled kernel of every target (or of this device), one line each,
/// with its occupancy; refused kernels with the reason.
pub fn csv(r: &super::DriverStatsReport) -> crate::error::Result<String> {
    let header = [
        "target",
        "chip",
        "compiler",
        "wave",
        "driver",
        "kernel",
        "variant",
        "method",
        "layout",
        "vgprs",
        "sgprs",
        "spilled_vgprs",
        "spilled_sgprs",
        "scratch_bytes",
        "lds_bytes",
        "subgroups_per_simd",
        "vgprs_to_lose_one",
        "vgprs_to_gain_one",
        "instructions",
        "code_bytes",
        "latency",
        "inverse_throughput",
        "refused",
    ];
    let mut lines: Vec<Vec<String>> = vec![];
    let device = super::TargetStats {
        target: r.provenance.device.clone(),
        compiled_for: super::CompiledFor { chip: None, compiler: None, wave: 0 },
        mesa_build: String::new(),
        device: r.provenance.device.clone(),
        driver: r.provenance.driver.clone(),
        driver_info: r.provenance.driver.clone(),
        mesa_version: r.provenance.mesa_version.clone(),
        status: r.status,
        note: String::new(),
        kernels: r.kernels.iter().filter(|k| !k.statistics.is_empty()).cloned().collect(),
        refused: vec![],
    };
    for t in r.targets.iter().chain(std::iter::once(&device)) {
        for k in &t.kernels {
            let c = k.compiled.clone().unwrap_or(t.compiled_for.clone());
            let occ = occupancy(k).map(|(o, _)| o);
            let opt = |v: Option<u32>| v.map_or(String::new(), |v| v.to_string());
            let stat = |n: &str| k.statistic(n).map_or(String::new(), |v| format!("{v}"));
            lines.push(vec![
                t.target.clone(),
                c.chip.map_or(String::new(), |c| c.name.to_owned()),
                c.compiler.map_or(String::new(), |c| c.to_string()),
                c.wave.to_string(),
                t.driver_info.clone(),
                k.cell.kernel.clone(),
                k.cell.variant.clone(),
                k.cell.method.clone(),
                k.cell.layout.clone(),
                stat(names::VGPRS),
                stat(names::SGPRS),
                stat(names::SPILLED_VGPRS),
                stat(names::SPILLED_SGPRS),
                stat(names::SCRATCH),
                stat(names::LDS),
                stat(names::SUBGROUPS),
                occ.map_or(String::new(), |o| opt(o.vgprs_to_loss)),
                occ.map_or(String::new(), |o| opt(o.vgprs_to_gain)),
                stat(names::INSTRUCTIONS),
                stat(names::CODE),
                stat(names::LATENCY),
                stat(names::INVERSE_THROUGHPUT),
                String::new(),
            ]);
        }
        for f in &t.refused {
            let c = &t.compiled_for;
            let mut line = vec![
                t.target.clone(),
                c.chip.map_or(String::new(), |c| c.name.to_owned()),
                c.compiler.map_or(String::new(), |c| c.to_string()),
                c.wave.to_string(),
                t.driver_info.clone(),
            ];
            let cell = crate::kernels::KERNELS.iter().find(|k| k.name == f.kernel).map(super::KernelCell::of);
            line.extend(match cell {
                Some(c) => [c.kernel, c.variant, c.method, c.layout],
                None => [f.kernel.clone(), String::new(), String::new(), String::new()],
            });
            line.extend(std::iter::repeat_n(String::new(), 13));
            line.push(f.why.clone());
            lines.push(line);
        }
    }
    crate::services::results::csv("driver-stats.csv", header, lines)
}
