//! The machine a run ran on: its CPU model and what a JIT compiles for on it, the logical CPUs the process may use and the load
//! average when it was read. On lavapipe the "GPU" is this CPU, so two runs' timings are
//! comparable only when these agree (or when a calibration measured in each run says how the
//! hosts differ: `services::calibration`). Every result row carries it ([`crate::rows::Source`]).
//! Ground floor: it imports nothing of trilab.

use serde::{Deserialize, Serialize};

/// A load average, ordered by value (so a [`Host`] can key a map).
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Load(pub f64);

impl PartialEq for Load {
    fn eq(&self, other: &Self) -> bool {
        self.0.total_cmp(&other.0).is_eq()
    }
}
impl Eq for Load {}
impl PartialOrd for Load {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Load {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// The host CPU as a run saw it.
#[derive(Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Host {
    /// `model name` of /proc/cpuinfo ("unknown" where there is none).
    pub cpu_model: String,
    /// What a JIT compiles for: vendor, family and model from /proc/cpuinfo and a hash of its
    /// feature flags (`AuthenticAMD 25/17 flags:1f2e3d4c`): lavapipe's LLVM picks its code for
    /// this CPU, so its machine code is the same only on CPUs with the same id. Empty in rows
    /// written before it was recorded.
    #[serde(default)]
    pub cpu_id: String,
    /// Logical CPUs this process may run on (its affinity mask: `taskset -c 0` gives 1).
    pub cpus: u32,
    /// The one-minute load average when it was read (/proc/loadavg; `None` where there is none).
    pub load_1m: Option<Load>,
}

impl Host {
    /// This machine, now.
    pub fn current() -> Host {
        Host { cpu_model: cpu_model(), cpu_id: cpu_id(), cpus: cpus() as u32, load_1m: load_1m().map(Load) }
    }

    /// Whether `other` is the same kind of machine: the same CPU (model, and id where both
    /// recorded one) and CPU count (the load may differ; that is what a calibration measures).
    pub fn same_machine(&self, other: &Host) -> bool {
        let same_id = self.cpu_id.is_empty() || other.cpu_id.is_empty() || self.cpu_id == other.cpu_id;
        self.cpu_model == other.cpu_model && same_id && self.cpus == other.cpus
    }

    /// The host without its load: what two rows of one machine share.
    pub fn machine(&self) -> Host {
        Host { load_1m: None, ..self.clone() }
    }

    /// `Intel Xeon ... (GenuineIntel 6/85 flags:1a2b3c4d), 2 CPUs, load 0.42`.
    pub fn label(&self) -> String {
        let mut s = self.cpu_model.clone();
        if !self.cpu_id.is_empty() {
            s.push_str(&format!(" ({})", self.cpu_id));
        }
        s.push_str(&format!(", {} CPU{}", self.cpus, if self.cpus == 1 { "" } else { "s" }));
        if let Some(l) = self.load_1m {
            s.push_str(&format!(", load {:.2}", l.0));
        }
        s
    }
}

/// Logical CPUs available to this process.
pub fn cpus() -> usize {
    std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1)
}

/// The CPU's model name from /proc/cpuinfo, "unknown" where it has none.
pub fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| parse_cpu_model(&s)).unwrap_or_else(|| "unknown".into())
}

fn parse_cpu_model(cpuinfo: &str) -> Option<String> {
    field(cpuinfo, "model name").map(|v| v.split_whitespace().collect::<Vec<_>>().join(" "))
}

/// The first processor's `key : value` in /proc/cpuinfo.
fn field<'a>(cpuinfo: &'a str, key: &str) -> Option<&'a str> {
    cpuinfo.lines().filter_map(|l| l.split_once(':')).find(|(k, _)| k.trim() == key).map(|(_, v)| v.trim())
}

/// What a JIT compiles for ([`Host::cpu_id`]), "unknown" without /proc/cpuinfo.
pub fn cpu_id() -> String {
    std::fs::read_to_string("/proc/cpuinfo").ok().and_then(|s| parse_cpu_id(&s)).unwrap_or_else(|| "unknown".into())
}

fn parse_cpu_id(cpuinfo: &str) -> Option<String> {
    use sha2::Digest;
    let vendor = field(cpuinfo, "vendor_id")?;
    let family = field(cpuinfo, "cpu family").unwrap_or("?");
    let model = field(cpuinfo, "model").unwrap_or("?");
    let mut flags: Vec<&str> = field(cpuinfo, "flags").unwrap_or("").split_whitespace().collect();
    flags.sort_unstable();
    let hash = sha2::Sha256::digest(flags.join(" ").as_bytes());
    Some(format!("{vendor} {family}/{model} flags:{:02x}{:02x}{:02x}{:02x}", hash[0], hash[1], hash[2], hash[3]))
}

/// The one-minute load average, where /proc/loadavg exists.
pub fn load_1m() -> Option<f64> {
    parse_load(&std::fs::read_to_string("/proc/loadavg").ok()?)
}

fn parse_load(loadavg: &str) -> Option<f64> {
    loadavg.split_whitespace().next()?.parse::<f64>().ok().filter(|l| l.is_finite() && *l >= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpuinfo_and_loadavg_are_parsed() {
        let info =
            "processor\t: 0\nvendor_id\t: GenuineIntel\nmodel name\t: Intel(R) Xeon(R)  CPU @ 2.50GHz\nflags\t: fpu\n";
        assert_eq!(parse_cpu_model(info).as_deref(), Some("Intel(R) Xeon(R) CPU @ 2.50GHz"));
        assert_eq!(parse_cpu_model("processor : 0\n"), None);
        let id = parse_cpu_id(info).unwrap();
        assert!(id.starts_with("GenuineIntel ?/? flags:") && id.len() == "GenuineIntel ?/? flags:".len() + 8, "{id}");
        // The flags' order does not matter; another flag does.
        let amd = "vendor_id : AuthenticAMD\ncpu family : 25\nmodel : 17\nflags : avx2 fma sse4_1\n";
        let same = "vendor_id : AuthenticAMD\ncpu family : 25\nmodel : 17\nflags : sse4_1 avx2 fma\n";
        let more = "vendor_id : AuthenticAMD\ncpu family : 25\nmodel : 17\nflags : sse4_1 avx2 fma avx512f\n";
        assert_eq!(parse_cpu_id(amd), parse_cpu_id(same));
        assert_ne!(parse_cpu_id(amd), parse_cpu_id(more));
        assert!(parse_cpu_id(amd).unwrap().starts_with("AuthenticAMD 25/17 flags:"));
        assert_eq!(parse_cpu_id("processor : 0\n"), None);
        assert_eq!(parse_load("0.68 0.16 0.05 1/123 4567\n"), Some(0.68));
        assert_eq!(parse_load("nan 0 0"), None);
        assert_eq!(parse_load(""), None);
    }

    #[test]
    fn the_same_machine_ignores_the_load() {
        let a = Host { cpu_model: "X".into(), cpu_id: "V 1/2 flags:00".into(), cpus: 2, load_1m: Some(Load(0.1)) };
        let b = Host { load_1m: Some(Load(3.0)), ..a.clone() };
        assert!(a.same_machine(&b) && a != b);
        assert!(!a.same_machine(&Host { cpus: 1, ..a.clone() }));
        assert!(!a.same_machine(&Host { cpu_model: "Y".into(), ..a.clone() }));
        assert!(!a.same_machine(&Host { cpu_id: "V 1/3 flags:00".into(), ..a.clone() }));
        assert!(a.same_machine(&Host { cpu_id: String::new(), ..a.clone() }), "an id not recorded is not a difference");
        assert_eq!(b.machine(), Host { load_1m: None, ..a.clone() });
        assert_eq!(a.label(), "X (V 1/2 flags:00), 2 CPUs, load 0.10");
    }
}
