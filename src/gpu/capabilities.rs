//! One home for what a device can do (issue 38): every command asks [`Capabilities`] "can this
//! device run X, and if not, why" — per kernel, method, access path, traversal, driver peer and
//! statistic — and turns a "no" into a note with its reason while the rest of the run goes on.
//! A run fails only when nothing it asked for can run ([`Capabilities::keep`]).
//!
//! The answers come from three typed sources, never from a spelled driver name elsewhere:
//! the driver ([`DriverKind`], read once from `VkDriverId`), the features the context enabled
//! ([`EnabledFeatures`]) and the device's properties ([`DeviceInfo`]). A kernel's needs are read
//! from its SPIR-V (`spirv::capabilities`), so a new kernel that uses 64-bit floats is refused on
//! SwiftShader without anyone writing a rule for it.
//!
//! To add the next driver's quirk: give the driver a [`DriverKind`] arm (its `VkDriverId` in
//! [`DriverKind::of`]) and answer for it in the one `match` that asks about it here (a statistic
//! it offers, a traversal it runs wrongly); the tests in this file describe each known device.

use std::fmt;

use super::{DeviceInfo, EnabledFeatures, Peer};
use crate::encoding::{AccessPath, Method, Raycast, Traversal, COOP_SUBGROUP_OPERATIONS, PACKET_SUBGROUP_OPERATIONS};
use crate::kernels::KernelSource;
use crate::named::Named;

/// The Vulkan implementation, from `VkDriverId` (`DeviceInfo::driver_id`): the one place that
/// compares driver names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DriverKind {
    /// Mesa's lavapipe (llvmpipe's JIT): `LP_NUM_THREADS`, `GALLIVM_DEBUG=asm`.
    Lavapipe,
    /// Google's SwiftShader (Subzero JIT).
    SwiftShader,
    /// NVIDIA's proprietary driver.
    Nvidia,
    /// Any other driver: asked only through its features and properties.
    Other,
}

impl DriverKind {
    pub fn of(info: &DeviceInfo) -> DriverKind {
        // ash prints `vk::DriverId` by its Rust name (`MESA_LLVMPIPE`); raw values of drivers
        // newer than ash print as numbers and land in `Other`.
        match info.driver_id.as_str() {
            "MESA_LLVMPIPE" => DriverKind::Lavapipe,
            "GOOGLE_SWIFTSHADER" => DriverKind::SwiftShader,
            "NVIDIA_PROPRIETARY" => DriverKind::Nvidia,
            _ => DriverKind::Other,
        }
    }

    /// The folder under `results/` for a known software driver (`lavapipe`, `swiftshader`);
    /// `None` for a hardware device, which is named after the device.
    pub fn results_dir(self) -> Option<&'static str> {
        match self {
            DriverKind::Lavapipe => Some("lavapipe"),
            DriverKind::SwiftShader => Some("swiftshader"),
            DriverKind::Nvidia | DriverKind::Other => None,
        }
    }
}

/// A figure a command may want from the driver beyond hits and timings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Statistic {
    /// GPU timestamps on the compute queue (every timing).
    Timestamps,
    /// Pipeline statistics queries (compute shader invocations).
    PipelineStatistics,
    /// `VK_KHR_pipeline_executable_properties`: the driver's own compile statistics.
    ExecutableStatistics,
    /// `VK_KHR_shader_clock`'s subgroup clock (`trilab profile`'s ticks per ray).
    ShaderClock,
    /// The compiled machine code a driver prints (lavapipe's `GALLIVM_DEBUG=asm`).
    MachineCode,
    /// A driver thread count set per process (lavapipe's `LP_NUM_THREADS`).
    ThreadCount,
}

impl Statistic {
    pub fn name(self) -> &'static str {
        match self {
            Statistic::Timestamps => "timestamps",
            Statistic::PipelineStatistics => "pipeline statistics",
            Statistic::ExecutableStatistics => "pipeline executable statistics",
            Statistic::ShaderClock => "shader clock",
            Statistic::MachineCode => "machine code (GALLIVM_DEBUG=asm)",
            Statistic::ThreadCount => "thread count (LP_NUM_THREADS)",
        }
    }

    pub const ALL: [Statistic; 6] = [
        Statistic::Timestamps,
        Statistic::PipelineStatistics,
        Statistic::ExecutableStatistics,
        Statistic::ShaderClock,
        Statistic::MachineCode,
        Statistic::ThreadCount,
    ];
}

/// What cannot run, and why: the reason a cell becomes a note. Shown as "`what`: `why` on
/// `device`"; a report that names the device in its header shows `why` alone.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unsupported {
    /// The thing asked for, in the command line's words (`method f64`, `--traversal coop`).
    pub what: String,
    /// Why, naming the feature or limit ("shaderInt64 ... is not enabled").
    pub why: String,
    /// The device (and, for a driver peer, its driver).
    pub device: String,
}

impl fmt::Display for Unsupported {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {} on {}", self.what, self.why, self.device)
    }
}

impl From<Unsupported> for crate::error::Error {
    fn from(u: Unsupported) -> Self {
        crate::error::Error::Unsupported(u.to_string())
    }
}

/// What one device, with the features its context enabled, can run.
#[derive(Clone, Copy, Debug)]
pub struct Capabilities<'a> {
    pub info: &'a DeviceInfo,
    pub enabled: &'a EnabledFeatures,
}

impl<'a> Capabilities<'a> {
    pub fn new(info: &'a DeviceInfo, enabled: &'a EnabledFeatures) -> Self {
        Capabilities { info, enabled }
    }

    pub fn driver(&self) -> DriverKind {
        DriverKind::of(self.info)
    }

    /// The device runs kernels at all: a device that only compiles (RADV's null device,
    /// [`super::Execution::CompilesOnly`]) answers no, with why; every command that dispatches
    /// asks this (through the context it makes) before any work.
    pub fn runs(&self) -> Result<(), Unsupported> {
        match &self.info.execution {
            super::Execution::Runs => Ok(()),
            super::Execution::CompilesOnly { why } => self.no("running kernels", format!("it compiles only ({why})")),
        }
    }

    /// The device is a CPU (`VK_PHYSICAL_DEVICE_TYPE_CPU`: lavapipe, SwiftShader): `auto`
    /// choices that are slow on a CPU (the driver peers) stay off.
    pub fn is_cpu(&self) -> bool {
        self.info.device_type == "CPU"
    }

    fn no(&self, what: impl Into<String>, why: impl fmt::Display) -> Result<(), Unsupported> {
        Err(Unsupported { what: what.into(), why: why.to_string(), device: self.info.name.clone() })
    }

    /// A SPIR-V module (`name` in the answer): every optional feature its `OpCapability`
    /// instructions need is enabled. Kernel creation asks this before it creates a pipeline.
    pub fn module(&self, name: &str, words: &[u32]) -> Result<(), Unsupported> {
        match crate::spirv::required_features(words) {
            Err(e) => self.no(format!("kernel {name}"), format!("its SPIR-V does not parse ({e})")),
            Ok(needs) => self.requirements(name, &needs),
        }
    }

    /// A module's optional features, already read from its SPIR-V (`spirv::required_features`):
    /// every one is enabled.
    pub fn requirements(&self, name: &str, needs: &[crate::spirv::Requirement]) -> Result<(), Unsupported> {
        match needs.iter().find(|r| !self.enabled.has(r.feature)) {
            Some(r) => self.no(
                format!("kernel {name}"),
                format!("{} (SPIR-V capability {}) is not enabled", r.feature.name(), r.capability),
            ),
            None => Ok(()),
        }
    }

    /// The first optional feature `words` needs that is not enabled.
    fn missing(&self, words: &[u32]) -> Option<crate::spirv::Requirement> {
        crate::spirv::required_features(words).ok()?.into_iter().find(|r| !self.enabled.has(r.feature))
    }

    /// A compiled kernel of the registry ([`Capabilities::module`]).
    pub fn kernel(&self, k: &KernelSource) -> Result<(), Unsupported> {
        self.module(k.name, &k.words())
    }

    /// A method: its closest-hit kernel on the texel path (every variant of a method needs what
    /// that one needs, and more only for the clock or the address path, which are asked apart).
    pub fn method(&self, m: Method) -> Result<(), Unsupported> {
        let k = m.raycast_kernel(Raycast::Closest, AccessPath::Texel);
        match self.missing(&k.words()) {
            Some(r) => self.no(
                format!("method {m}"),
                format!("its kernels need {} (SPIR-V capability {}), not enabled", r.feature.name(), r.capability),
            ),
            None => Ok(()),
        }
    }

    /// A scene access path (whether a scene fits it is the memory placement's question).
    pub fn access(&self, a: AccessPath) -> Result<(), Unsupported> {
        let what = format!("--scene-access {}", a.name());
        match a {
            AccessPath::Texel | AccessPath::Storage => Ok(()),
            AccessPath::Address if !self.enabled.buffer_device_address => {
                self.no(what, "bufferDeviceAddress is not enabled")
            }
            // The address path loads 16-byte texels as two 64-bit words (glsl/types.glsl).
            AccessPath::Address if !self.enabled.shader_int64 => {
                self.no(what, "shaderInt64 (64-bit loads on the address path) is not enabled")
            }
            AccessPath::Address => Ok(()),
        }
    }

    /// The access path `auto` takes first where a scene fits it: storage buffers on SwiftShader
    /// (1.40-1.78x the texel path's Mrays/s there on a 10,000-triangle soup, and the roofline's
    /// fastest path), texel buffers elsewhere (lavapipe: storage 0.60-0.86x texel on the bunny;
    /// results/swiftshader/access-paths/, issue 38).
    pub fn preferred_access(&self) -> AccessPath {
        match self.driver() {
            DriverKind::SwiftShader => AccessPath::Storage,
            DriverKind::Lavapipe | DriverKind::Nvidia | DriverKind::Other => AccessPath::Texel,
        }
    }

    /// A traversal: the cooperative kernel needs subgroup operations in compute shaders and at
    /// least four lanes; the packet kernel needs subgroup operations.
    pub fn traversal(&self, t: Traversal) -> Result<(), Unsupported> {
        let (size, ops) = (self.info.subgroup_size, self.info.subgroup_operations);
        let what = format!("--traversal {t}");
        match t {
            Traversal::Coop if ops & COOP_SUBGROUP_OPERATIONS != COOP_SUBGROUP_OPERATIONS => self.no(
                what,
                format!(
                    "it needs subgroup basic, vote, arithmetic, ballot and shuffle operations in compute shaders \
                     (the device has {ops:#x})"
                ),
            ),
            Traversal::Coop if size < 4 => {
                self.no(what, format!("it needs a subgroup of at least 4 lanes (the device has {size})"))
            }
            Traversal::Packet | Traversal::Hybrid if ops & PACKET_SUBGROUP_OPERATIONS != PACKET_SUBGROUP_OPERATIONS => {
                self.no(
                    what,
                    format!(
                    "it needs subgroup basic, vote, arithmetic, ballot and shuffle operations in compute shaders (the \
                     device has {ops:#x})"
                ),
                )
            }
            _ => Ok(()),
        }
    }

    /// A driver peer (ray query, ray tracing pipeline).
    pub fn peer(&self, p: Peer) -> Result<(), Unsupported> {
        let on = match p {
            Peer::RayQuery => self.enabled.ray_query,
            Peer::RayTracingPipeline => self.enabled.ray_tracing_pipeline,
        };
        match on {
            true => Ok(()),
            false => Err(Unsupported {
                what: p.feature().into(),
                why: "unsupported".into(),
                device: format!("{} ({})", self.info.name, self.info.driver_label()),
            }),
        }
    }

    /// A statistic.
    pub fn statistic(&self, s: Statistic) -> Result<(), Unsupported> {
        let what = s.name();
        let (on, why) = match s {
            Statistic::Timestamps => (self.info.timestamp_valid_bits > 0, "the compute queue has no timestamps"),
            Statistic::PipelineStatistics => {
                (self.enabled.pipeline_statistics_query, "pipelineStatisticsQuery is not enabled")
            }
            Statistic::ExecutableStatistics => {
                (self.enabled.pipeline_executable_properties, "VK_KHR_pipeline_executable_properties is not enabled")
            }
            Statistic::ShaderClock => {
                (self.enabled.shader_clock, "VK_KHR_shader_clock's subgroup clock is not enabled")
            }
            Statistic::MachineCode | Statistic::ThreadCount if self.driver() != DriverKind::Lavapipe => {
                let why = match s {
                    Statistic::MachineCode => "printed only by lavapipe, not",
                    _ => "a lavapipe setting, not read",
                };
                return Err(Unsupported {
                    what: what.into(),
                    why: why.into(),
                    device: format!("{} ({})", self.info.name, self.info.driver_id),
                });
            }
            Statistic::MachineCode | Statistic::ThreadCount => (true, ""),
        };
        match on {
            true => Ok(()),
            false => self.no(what, why),
        }
    }

    /// The items of `asked` this device can run, each refused one as a note (its
    /// [`Unsupported`]) in `notes`; an error when none can run. `what` names the axis in the
    /// error ("methods"), `can` asks about one item.
    pub fn keep<T: Copy>(
        &self,
        what: &str,
        asked: &[T],
        can: impl Fn(&Self, T) -> Result<(), Unsupported>,
        notes: &mut Vec<String>,
    ) -> crate::error::Result<Vec<T>> {
        let (mut kept, mut refused) = (vec![], vec![]);
        for &x in asked {
            match can(self, x) {
                Ok(()) => kept.push(x),
                Err(u) => refused.push(format!("{u}; left out")),
            }
        }
        if kept.is_empty() && !asked.is_empty() {
            return Err(crate::error::Error::Unsupported(format!(
                "none of the {what} asked for can run on {}: {}",
                self.info.name,
                refused.join("; ")
            )));
        }
        notes.extend(refused);
        Ok(kept)
    }

    /// Every method, access path, traversal, peer and statistic with this device's answer:
    /// the table `trilab devices` prints.
    pub fn table(&self) -> Vec<(String, Option<String>)> {
        let mut out = vec![];
        let mut push = |what: String, r: Result<(), Unsupported>| out.push((what, r.err().map(|u| u.why)));
        push("kernels".into(), self.runs());
        for m in Method::ALL {
            push(format!("method {m}"), self.method(m));
        }
        for a in AccessPath::ALL {
            push(format!("access {}", a.name()), self.access(a));
        }
        for &t in Traversal::ALL {
            push(format!("traversal {t}"), self.traversal(t));
        }
        for &p in Peer::ALL {
            push(format!("peer {p}"), self.peer(p));
        }
        for s in Statistic::ALL {
            push(s.name().to_string(), self.statistic(s));
        }
        out
    }
}

impl super::Context {
    /// What this device, with the features this context enabled, can run.
    pub fn capabilities(&self) -> Capabilities<'_> {
        Capabilities::new(self.info(), self.enabled())
    }
}
