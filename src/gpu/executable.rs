//! `VK_KHR_pipeline_executable_properties`: the statistics a driver reports about the code it
//! compiled for a pipeline (registers, spills, instruction counts... whatever it chooses), as
//! the driver gives them ([`ExecutableStatistic`]) and typed ([`CompilerStatistic`]).
//!
//! lavapipe does not offer the extension; RADV does, on a GPU and on its null device (issue 50:
//! every kernel compiled for AMD's chips without one), and NVIDIA's driver does.
//!
//! Typed, each statistic has a name without the executable's index, a unit and a direction
//! (which way is better), or is an identity (a hash), compared as changed or unchanged and never
//! as better or worse. What a statistic is comes from the driver's own words where it gives
//! them: RADV describes "Code size" as "Code size in bytes", "Subgroups per SIMD" as "The maximum
//! number of subgroups in flight on a SIMD unit", "Driver pipeline hash" as "Driver pipeline hash
//! used by RGP". [`Kind::of`] reads the unit and the direction from the name and the
//! description, so a statistic a newer driver adds is typed without a rule written for it; the
//! tests hold the reading against every statistic RADV 25.0.7 and 22.3.6 report (ACO and LLVM)
//! and against NVIDIA's names.

use ash::vk;
use serde::{Deserialize, Serialize};

use crate::error::{Result, VkContext};
use crate::gpu::{Context, Kernel};
use crate::rows::{Better, Figure};

/// One statistic of one executable of a pipeline, as the driver gives it.
#[derive(Clone, Debug, Serialize)]
pub struct ExecutableStatistic {
    /// Index of the executable in the pipeline and its name, description and subgroup size.
    pub executable: u32,
    pub executable_name: String,
    pub executable_description: String,
    pub subgroup_size: u32,
    pub name: String,
    pub description: String,
    /// The value as the driver typed it (bool, signed, unsigned or float), as text.
    pub value: String,
}

fn text(s: std::result::Result<&std::ffi::CStr, std::ffi::FromBytesUntilNulError>) -> String {
    s.map(|c| c.to_string_lossy().into_owned()).unwrap_or_default()
}

/// Every statistic of every executable of `kernel`, which must have been created with
/// `PipelineOptions::capture_statistics` on a device with `pipeline_executable_properties`
/// enabled (the caller checks `Context::enabled`).
pub fn executable_statistics(ctx: &Context, kernel: &Kernel) -> Result<Vec<ExecutableStatistic>> {
    let loader = ash::khr::pipeline_executable_properties::Device::new(&ctx.device.instance, &ctx.device.raw);
    let pipeline_info = vk::PipelineInfoKHR::default().pipeline(kernel.pipeline);
    // SAFETY: the extension and pipelineExecutableInfo are enabled on this device (caller's
    // check) and the pipeline is alive for the call.
    let executables = unsafe { loader.get_pipeline_executable_properties(&pipeline_info) }
        .during("vkGetPipelineExecutablePropertiesKHR")?;
    let mut out = Vec::new();
    for (i, e) in executables.iter().enumerate() {
        let exec_info = vk::PipelineExecutableInfoKHR::default().pipeline(kernel.pipeline).executable_index(i as u32);
        // SAFETY: as above; the index is below the count the driver just returned, and the
        // pipeline was created with CAPTURE_STATISTICS.
        let stats = unsafe { loader.get_pipeline_executable_statistics(&exec_info) }
            .during("vkGetPipelineExecutableStatisticsKHR")?;
        for s in &stats {
            // SAFETY: `format` says which member of the value union the driver wrote.
            let value = unsafe {
                match s.format {
                    vk::PipelineExecutableStatisticFormatKHR::BOOL32 => (s.value.b32 != vk::FALSE).to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::INT64 => s.value.i64.to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::UINT64 => s.value.u64.to_string(),
                    vk::PipelineExecutableStatisticFormatKHR::FLOAT64 => s.value.f64.to_string(),
                    f => format!("(unknown format {f:?})"),
                }
            };
            out.push(ExecutableStatistic {
                executable: i as u32,
                executable_name: text(e.name_as_c_str()),
                executable_description: text(e.description_as_c_str()),
                subgroup_size: e.subgroup_size,
                name: text(s.name_as_c_str()),
                description: text(s.description_as_c_str()),
                value,
            });
        }
    }
    Ok(out)
}

/// Which way a statistic is better, or that it is an identity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Direction {
    /// Fewer is better: registers, spills, instructions, bytes, cycles.
    Lower,
    /// More is better: subgroups in flight per SIMD (occupancy).
    Higher,
    /// A hash or a flag: it changed or it did not.
    Identity,
}

/// What a statistic is: its unit and its direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Kind {
    pub unit: &'static str,
    pub direction: Direction,
}

impl Kind {
    /// Reads a statistic's kind from its name and the driver's description of it.
    pub fn of(name: &str, description: &str) -> Kind {
        let n = name.to_ascii_lowercase();
        let d = description.to_ascii_lowercase();
        let has = |w: &str| n.contains(w) || d.contains(w);
        if has("hash") {
            return Kind { unit: "", direction: Direction::Identity };
        }
        // "The maximum number of subgroups in flight on a SIMD unit"; NVIDIA's "Occupancy".
        let direction = if has("in flight") || has("occupancy") || n.contains("per simd") {
            Direction::Higher
        } else {
            Direction::Lower
        };
        let unit = if d.contains("in bytes") || n.ends_with("bytes") {
            "bytes"
        } else if has("cycles") || n == "latency" || n == "inverse throughput" {
            "cycles"
        } else if n.contains("gprs") || has("register") {
            "registers"
        } else if has("clause") {
            "clauses"
        } else if has("subgroup") || has("occupancy") {
            "subgroups"
        } else if has("instruction") || matches!(n.as_str(), "valu" | "salu" | "vmem" | "smem" | "vopd") {
            "instructions"
        } else if has("slot") || has("input") || has("output") {
            "slots"
        } else {
            "count"
        };
        Kind { unit, direction }
    }
}

/// One statistic of one compiled kernel, typed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CompilerStatistic {
    /// The driver's name in snake case, without the executable's index (`vgprs`,
    /// `subgroups_per_simd`); prefixed with the executable's name when a pipeline has several.
    pub name: String,
    /// The driver's own name and description.
    pub driver_name: String,
    pub description: String,
    pub unit: String,
    pub direction: Direction,
    pub value: Value,
}

/// A statistic's value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Value {
    Number(f64),
    /// An identity as the driver gave it (a 64-bit hash does not fit an f64's mantissa).
    Text(String),
}

impl CompilerStatistic {
    /// The statistic as a row's figure (`None` for an identity, which a row keeps as text).
    pub fn figure(&self) -> Option<Figure> {
        let better = match self.direction {
            Direction::Lower => Better::Lower,
            Direction::Higher => Better::Higher,
            Direction::Identity => return None,
        };
        match &self.value {
            Value::Number(v) => Some(Figure::count_toward(*v, &self.unit, better)),
            Value::Text(_) => None,
        }
    }

    /// The value as text (`48`, `0x1a2b...` as the driver gave it).
    pub fn text(&self) -> String {
        match &self.value {
            Value::Number(v) if v.fract() == 0.0 && v.abs() < 1e15 => format!("{v:.0}"),
            Value::Number(v) => format!("{v}"),
            Value::Text(t) => t.clone(),
        }
    }

    /// The number, if it is one.
    pub fn number(&self) -> Option<f64> {
        match self.value {
            Value::Number(v) => Some(v),
            Value::Text(_) => None,
        }
    }
}

/// Every statistic of one pipeline's executables, typed: numbers whose kind is a figure become
/// numbers, identities and flags keep the driver's text.
pub fn typed(stats: &[ExecutableStatistic]) -> Vec<CompilerStatistic> {
    let executables: std::collections::BTreeSet<u32> = stats.iter().map(|s| s.executable).collect();
    stats
        .iter()
        .map(|st| {
            let kind = Kind::of(&st.name, &st.description);
            let mut name = snake(&st.name);
            if executables.len() > 1 {
                name = format!("{}.{name}", snake(&st.executable_name));
            }
            let value = match (kind.direction, st.value.parse::<f64>()) {
                (Direction::Lower | Direction::Higher, Ok(v)) => Value::Number(v),
                _ => Value::Text(st.value.clone()),
            };
            let direction = match value {
                // A flag ("true") is compared as an identity whatever its name says.
                Value::Text(_) => Direction::Identity,
                Value::Number(_) => kind.direction,
            };
            CompilerStatistic {
                name,
                driver_name: st.name.clone(),
                description: st.description.clone(),
                unit: kind.unit.into(),
                direction,
                value,
            }
        })
        .collect()
}

/// `Instruction Count` -> `instruction_count`; `SGPRs (spilled)` -> `sgprs_spilled`.
pub fn snake(s: &str) -> String {
    let mut out = String::new();
    for c in s.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') && !out.is_empty() {
            out.push('_');
        }
    }
    out.trim_end_matches('_').to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn st(executable: u32, name: &str, description: &str, value: &str) -> ExecutableStatistic {
        ExecutableStatistic {
            executable,
            executable_name: "Compute Shader".into(),
            executable_description: String::new(),
            subgroup_size: 64,
            name: name.into(),
            description: description.into(),
            value: value.into(),
        }
    }

    /// Every statistic RADV reports for a compute kernel, with its description, as Mesa 25.0.7
    /// and 22.3.6 print them (ACO adds the instruction-level ones; LLVM reports the first
    /// eleven): tests/data/radv-statistics.txt, read from `trilab driver-stats --json`.
    #[test]
    fn radv_statistics_take_their_unit_and_direction_from_the_driver() {
        let text = include_str!("../../tests/data/radv-statistics.txt");
        let mut seen = 0;
        for line in text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
            let parts: Vec<&str> = line.split('\t').collect();
            let [name, description, unit, direction] = parts[..] else { panic!("bad line {line:?}") };
            let k = Kind::of(name, description);
            let want = match direction {
                "lower" => Direction::Lower,
                "higher" => Direction::Higher,
                "identity" => Direction::Identity,
                d => panic!("bad direction {d}"),
            };
            assert_eq!((k.unit, k.direction), (unit, want), "{name}: {description}");
            seen += 1;
        }
        assert!(seen >= 20, "{seen} statistics");
    }

    #[test]
    fn hashes_are_identities_and_occupancy_is_higher_is_better() {
        let s = typed(&[
            st(0, "Driver pipeline hash", "Driver pipeline hash used by RGP", "16021251867141274000"),
            st(0, "Subgroups per SIMD", "The maximum number of subgroups in flight on a SIMD unit", "18"),
            st(0, "VGPRs", "Number of VGPR registers allocated per subgroup", "84"),
            st(0, "Uses Shared Memory", "", "true"),
        ]);
        assert_eq!(s[0].name, "driver_pipeline_hash");
        assert_eq!(
            (s[0].direction, s[0].value.clone()),
            (Direction::Identity, Value::Text("16021251867141274000".into()))
        );
        assert!(s[0].figure().is_none());
        let f = s[1].figure().unwrap();
        assert_eq!((f.better, f.median, f.unit.as_str()), (Better::Higher, 18.0, "subgroups"));
        let f = s[2].figure().unwrap();
        assert_eq!((s[2].name.as_str(), f.better, f.unit.as_str()), ("vgprs", Better::Lower, "registers"));
        assert_eq!(s[3].direction, Direction::Identity);
    }

    /// What NVIDIA's driver names (no descriptions needed): its occupancy is higher-is-better;
    /// a pipeline of two executables keeps both, each under its executable's name.
    #[test]
    fn several_executables_are_named_apart() {
        let mut b = st(1, "Register Count", "", "40");
        b.executable_name = "Fragment Shader".into();
        let s = typed(&[st(0, "Register Count", "", "96"), st(0, "Occupancy", "", "0.75"), b]);
        let names: Vec<&str> = s.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(
            names,
            ["compute_shader.register_count", "compute_shader.occupancy", "fragment_shader.register_count"]
        );
        assert_eq!((s[0].unit.as_str(), s[1].direction), ("registers", Direction::Higher));
        let one = typed(&[st(0, "Register Count", "", "96")]);
        assert_eq!(one[0].name, "register_count");
    }

    #[test]
    fn snake_case_statistic_names() {
        assert_eq!(snake("Instruction Count"), "instruction_count");
        assert_eq!(snake("SGPRs (spilled)"), "sgprs_spilled");
        assert_eq!(snake("Pre-Sched VGPRs"), "pre_sched_vgprs");
    }
}
