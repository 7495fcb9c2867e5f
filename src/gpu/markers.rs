//! Crash markers, the dispatch log and fault injection: what lets a lost device or an
//! out-of-memory error name the dispatch it happened in.
//!
//! - **Dispatch log** (host): every dispatch recorded through [`Context::mark_begin`] gets an id
//!   and a description (kernel name, which carries method and variant, then batch or pass and
//!   the ray or sample range); every submit is logged with what it runs.
//! - **GPU breadcrumbs**: an 8-byte host-visible, host-coherent buffer `[begun, done]`. Around
//!   each marked dispatch the command buffer fills `begun = id` (`vkCmdFillBuffer`, then a
//!   barrier so it lands before the dispatch starts) and, after a barrier that waits for the
//!   dispatch, `done = id`. After a loss the host reads both words: the dispatch that began but
//!   never finished is the one the device died in (the technique of AMD's and NVIDIA's crash
//!   breadcrumbs; there with a marker write per stage, here per dispatch).
//! - **Errors**: [`Context::fault`] turns `VK_ERROR_DEVICE_LOST`, `VK_ERROR_OUT_OF_DEVICE_MEMORY`,
//!   `VK_ERROR_OUT_OF_HOST_MEMORY` (from a submit, a fence wait, a query, a map...) and
//!   gpu-allocator's out-of-memory into [`Error::GpuFault`], whose message names the dispatch
//!   being submitted and the last one begun and completed per the markers (per the host log
//!   when the markers cannot be read).
//! - **Fault injection** (lavapipe never loses its device): [`Fault`], set through
//!   `ContextOptions::inject_fault`, `Context::inject_fault` or the environment variable
//!   `TRILAB_INJECT_FAULT` (`device-lost@N`, `oom@N`: the N-th submit that runs a marked
//!   dispatch returns that Vulkan error without running; `alloc-oom@N`: the N-th GPU
//!   allocation fails as gpu-allocator's out-of-memory). An injected device loss is sticky,
//!   as a real one is: every later submit fails too.

use std::collections::{HashMap, VecDeque};
use std::sync::Mutex;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme, Allocator};
use gpu_allocator::MemoryLocation;

use super::commands::memory_barrier;
use crate::error::{Error, Result};

/// The environment variable read by `Context::new` (see the module documentation).
pub const INJECT_FAULT_ENV: &str = "TRILAB_INJECT_FAULT";

/// Dispatch descriptions kept for naming markers (the oldest are forgotten first).
const KEEP_DISPATCHES: usize = 4096;

/// What an injected fault does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// The submit returns `VK_ERROR_DEVICE_LOST`, and so does every later one.
    DeviceLost,
    /// The submit returns `VK_ERROR_OUT_OF_DEVICE_MEMORY`.
    SubmitOutOfMemory,
    /// The allocation fails with gpu-allocator's `OutOfMemory`.
    AllocationOutOfMemory,
}

/// A fault to inject: `kind` at the `at`-th (1-based) dispatch submit or allocation counted
/// from when it is armed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fault {
    pub kind: FaultKind,
    pub at: u64,
}

impl std::str::FromStr for Fault {
    type Err = Error;

    /// `device-lost@N`, `oom@N` or `alloc-oom@N`, N >= 1.
    fn from_str(s: &str) -> Result<Fault> {
        let bad = || {
            Error::Usage(format!("{INJECT_FAULT_ENV}=`{s}`: expected device-lost@N, oom@N or alloc-oom@N with N >= 1"))
        };
        let (kind, n) = s.trim().split_once('@').ok_or_else(bad)?;
        let kind = match kind {
            "device-lost" => FaultKind::DeviceLost,
            "oom" => FaultKind::SubmitOutOfMemory,
            "alloc-oom" => FaultKind::AllocationOutOfMemory,
            _ => return Err(bad()),
        };
        let at: u64 = n.parse().map_err(|_| bad())?;
        if at == 0 {
            return Err(bad());
        }
        Ok(Fault { kind, at })
    }
}

impl Fault {
    /// The fault `TRILAB_INJECT_FAULT` asks for, if it is set.
    pub fn from_env() -> Result<Option<Fault>> {
        match std::env::var(INJECT_FAULT_ENV) {
            Ok(v) if !v.trim().is_empty() => v.parse().map(Some),
            _ => Ok(None),
        }
    }
}

#[derive(Default)]
struct State {
    next_id: u32,
    /// (id, description), oldest first.
    dispatches: VecDeque<(u32, String)>,
    /// Marked dispatch ids recorded into each command buffer (until it is freed).
    by_cmd: HashMap<vk::CommandBuffer, Vec<u32>>,
    last_submitted: Option<String>,
    last_finished: Option<String>,
    /// Dispatch submits and allocations since the fault was armed.
    submits: u64,
    allocations: u64,
    fault: Option<Fault>,
    lost: bool,
}

/// The per-device marker buffer and dispatch log (lives in `Device`).
pub(crate) struct Markers {
    buffer: vk::Buffer,
    allocation: Option<Allocation>,
    state: Mutex<State>,
}

impl Markers {
    /// Creates the marker buffer; without one (no host-visible memory, say) markers are off and
    /// errors fall back to the host log.
    pub(crate) fn new(device: &ash::Device, allocator: &mut Allocator, fault: Option<Fault>) -> Markers {
        let state = Mutex::new(State { next_id: 1, fault, ..Default::default() });
        let none = |state| Markers { buffer: vk::Buffer::null(), allocation: None, state };
        let info = vk::BufferCreateInfo::default()
            .size(8)
            .usage(vk::BufferUsageFlags::TRANSFER_DST)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid device and create info; the buffer is destroyed in `destroy` (or below).
        let Ok(buffer) = (unsafe { device.create_buffer(&info, None) }) else { return none(state) };
        let requirements = unsafe { device.get_buffer_memory_requirements(buffer) };
        // GpuToCpu memory is HOST_VISIBLE | HOST_COHERENT in gpu-allocator, so the device's
        // writes need no vkInvalidateMappedMemoryRanges to be read.
        let allocation = allocator.allocate(&AllocationCreateDesc {
            name: "crash markers",
            requirements,
            location: MemoryLocation::GpuToCpu,
            linear: true,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        });
        match allocation {
            Ok(mut a) if a.mapped_slice().is_some() => {
                // SAFETY: memory made for these requirements, not yet bound.
                if unsafe { device.bind_buffer_memory(buffer, a.memory(), a.offset()) }.is_err() {
                    unsafe { device.destroy_buffer(buffer, None) };
                    let _ = allocator.free(a);
                    return none(state);
                }
                a.mapped_slice_mut().unwrap()[..8].fill(0);
                Markers { buffer, allocation: Some(a), state }
            }
            other => {
                unsafe { device.destroy_buffer(buffer, None) };
                if let Ok(a) = other {
                    let _ = allocator.free(a);
                }
                none(state)
            }
        }
    }

    /// Frees the buffer (`Device::drop`, after `vkDeviceWaitIdle`, before the allocator goes).
    pub(crate) fn destroy(&mut self, device: &ash::Device, allocator: &mut Allocator) {
        // SAFETY: the device is idle; null handles are ignored.
        unsafe { device.destroy_buffer(self.buffer, None) };
        if let Some(a) = self.allocation.take() {
            let _ = allocator.free(a);
        }
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// `[begun, done]` as the device last wrote them; `None` without a marker buffer.
    fn read(&self) -> Option<(u32, u32)> {
        let s = self.allocation.as_ref()?.mapped_slice()?;
        // Host-coherent mapped memory; a volatile read so the compiler does not cache it.
        // SAFETY: the slice is 8 bytes of mapped memory, 4-byte aligned (allocation alignment).
        let (b, d) = unsafe {
            let p = s.as_ptr() as *const u32;
            (std::ptr::read_volatile(p), std::ptr::read_volatile(p.add(1)))
        };
        Some((b, d))
    }
}

impl Markers {
    /// Arms `fault` (counting submits and allocations from now), or disarms with `None`.
    pub fn inject_fault(&self, fault: Option<Fault>) {
        let mut s = self.state();
        s.fault = fault;
        s.submits = 0;
        s.allocations = 0;
    }

    /// Whether the GPU breadcrumb buffer exists (it does wherever there is host-visible memory).
    pub fn markers_active(&self) -> bool {
        self.allocation.is_some()
    }

    /// Records "dispatch `id` begun" into `cmd` and logs `description` (kernel, batch or pass,
    /// ray or sample range); returns the id for [`Markers::mark_end`].
    ///
    /// # Safety
    /// `cmd` is a command buffer of this context's device in the recording state, outside a
    /// render pass; it is freed through `Context::free_command_buffers`.
    pub(crate) unsafe fn mark_begin(&self, d: &ash::Device, cmd: vk::CommandBuffer, description: String) -> u32 {
        let m = self;
        let id = {
            let mut s = m.state();
            let id = s.next_id;
            s.next_id = s.next_id.wrapping_add(1).max(1);
            if s.dispatches.len() == KEEP_DISPATCHES {
                s.dispatches.pop_front();
            }
            s.dispatches.push_back((id, description));
            s.by_cmd.entry(cmd).or_default().push(id);
            id
        };
        if m.allocation.is_some() {
            // Earlier marker writes (this buffer's previous dispatch, or an earlier submit's)
            // before this one: write-after-write on the same words.
            memory_barrier(
                d,
                cmd,
                (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
                (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
            );
            d.cmd_fill_buffer(cmd, m.buffer, 0, 4, id);
            // "Begun" lands before the dispatch starts (an execution dependency; the shader
            // never touches the marker buffer).
            memory_barrier(
                d,
                cmd,
                (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::empty()),
                (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::empty()),
            );
        }
        id
    }

    /// Records "dispatch `id` done" after everything recorded before it in `cmd`.
    ///
    /// # Safety
    /// As [`Markers::mark_begin`].
    pub(crate) unsafe fn mark_end(&self, d: &ash::Device, cmd: vk::CommandBuffer, id: u32) {
        let m = self;
        if m.allocation.is_none() {
            return;
        }
        // The dispatch has finished before "done" is written...
        memory_barrier(
            d,
            cmd,
            (vk::PipelineStageFlags::COMPUTE_SHADER, vk::AccessFlags::empty()),
            (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::empty()),
        );
        // ...after "begun" (same buffer, other word, but keep the writes ordered)...
        memory_barrier(
            d,
            cmd,
            (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
            (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
        );
        d.cmd_fill_buffer(cmd, m.buffer, 4, 4, id);
        // ...and is made visible to the host.
        memory_barrier(
            d,
            cmd,
            (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE),
            (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
        );
    }

    /// Forgets the dispatches recorded in command buffers being freed.
    pub(crate) fn forget_command_buffers(&self, cmds: &[vk::CommandBuffer]) {
        let mut s = self.state();
        for c in cmds {
            s.by_cmd.remove(c);
        }
    }

    /// Logs a submit of `cmd` (`what`) and injects the armed fault when its turn comes.
    pub(crate) fn before_submit(&self, cmd: vk::CommandBuffer, what: &str) -> Result<()> {
        let mut s = self.state();
        s.last_submitted = Some(what.to_owned());
        if s.lost {
            return Err(Error::Vulkan { result: vk::Result::ERROR_DEVICE_LOST, during: what.to_owned() });
        }
        if s.by_cmd.get(&cmd).is_none_or(|ids| ids.is_empty()) {
            return Ok(());
        }
        s.submits += 1;
        let result = match s.fault {
            Some(Fault { kind: FaultKind::DeviceLost, at }) if at == s.submits => {
                s.lost = true;
                vk::Result::ERROR_DEVICE_LOST
            }
            Some(Fault { kind: FaultKind::SubmitOutOfMemory, at }) if at == s.submits => {
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY
            }
            _ => return Ok(()),
        };
        Err(Error::Vulkan { result, during: what.to_owned() })
    }

    /// Logs a submit that finished.
    pub(crate) fn after_submit(&self, what: &str) {
        self.state().last_finished = Some(what.to_owned());
    }

    /// Counts an allocation named `name` and injects the armed allocation fault.
    pub(crate) fn before_allocation(&self, name: &str) -> Result<()> {
        let mut s = self.state();
        s.allocations += 1;
        match s.fault {
            Some(Fault { kind: FaultKind::AllocationOutOfMemory, at }) if at == s.allocations => {
                Err(Error::Allocation { name: name.to_owned(), source: gpu_allocator::AllocationError::OutOfMemory })
            }
            _ => Ok(()),
        }
    }

    /// Turns a device loss or an out-of-memory error into [`Error::GpuFault`] naming the
    /// dispatches involved; any other error is returned as it is.
    pub fn fault(&self, e: Error) -> Error {
        let (what, result, during) = match e {
            Error::Vulkan { result, during } => match result {
                vk::Result::ERROR_DEVICE_LOST => ("device lost (VK_ERROR_DEVICE_LOST)", Some(result), during),
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => {
                    ("out of device memory (VK_ERROR_OUT_OF_DEVICE_MEMORY)", Some(result), during)
                }
                vk::Result::ERROR_OUT_OF_HOST_MEMORY => {
                    ("out of host memory (VK_ERROR_OUT_OF_HOST_MEMORY)", Some(result), during)
                }
                _ => return Error::Vulkan { result, during },
            },
            Error::Allocation { name, source: gpu_allocator::AllocationError::OutOfMemory } => {
                ("out of GPU memory (gpu-allocator)", None, format!("allocating `{name}`"))
            }
            other => return other,
        };
        Error::GpuFault { what: what.to_owned(), result, during, markers: self.marker_report() }
    }

    /// "last dispatch begun: ...; last completed: ..." from the markers, or the host log.
    pub fn marker_report(&self) -> String {
        let m = self;
        let read = m.read();
        let s = m.state();
        let name = |id: u32| -> String {
            if id == 0 {
                return "none".into();
            }
            match s.dispatches.iter().find(|(i, _)| *i == id) {
                Some((_, d)) => format!("{d} (dispatch #{id})"),
                None => format!("dispatch #{id}"),
            }
        };
        match read {
            Some((begun, done)) => {
                format!("GPU markers: last dispatch begun: {}; last completed: {}", name(begun), name(done))
            }
            None => format!(
                "GPU markers unreadable; host log: last submitted: {}; last finished: {}",
                s.last_submitted.as_deref().unwrap_or("none"),
                s.last_finished.as_deref().unwrap_or("none")
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_specs_parse_and_bad_ones_are_refused() {
        assert_eq!("device-lost@3".parse::<Fault>().unwrap(), Fault { kind: FaultKind::DeviceLost, at: 3 });
        assert_eq!("oom@1".parse::<Fault>().unwrap(), Fault { kind: FaultKind::SubmitOutOfMemory, at: 1 });
        assert_eq!("alloc-oom@12".parse::<Fault>().unwrap(), Fault { kind: FaultKind::AllocationOutOfMemory, at: 12 });
        for bad in ["device-lost", "device-lost@0", "oom@x", "lost@2", "@3", ""] {
            let e = bad.parse::<Fault>().unwrap_err().to_string();
            assert!(e.contains(INJECT_FAULT_ENV) && e.contains("device-lost@N"), "{bad}: {e}");
        }
    }
}
