//! A device's limits as the memory placement (`encoding::placement`) checks them.

use ash::vk;

use super::context::Context;
use crate::encoding::DeviceLimits;
use crate::error::Result;

pub use super::context::TEST_LIMITS_VAR;

impl Context {
    /// The limits of this device, with the memory budget read now (where supported), lowered by
    /// `ContextOptions::test_limits` or `TRILAB_TEST_LIMITS` when set.
    pub fn limits(&self) -> Result<DeviceLimits> {
        let info = self.info();
        let limits = DeviceLimits {
            max_texel_buffer_elements: u64::from(info.max_texel_buffer_elements),
            max_storage_buffer_range: u64::from(info.max_storage_buffer_range),
            max_buffer_size: info.max_buffer_size,
            max_memory_allocation_size: info.max_memory_allocation_size,
            device_local_bytes: info.device_local_heap_bytes,
            budget_bytes: if info.memory_budget { budget(self) } else { None },
            buffer_device_address: self.enabled().buffer_device_address,
            shader_int64: self.enabled().shader_int64,
            preferred_access: self.capabilities().preferred_access(),
        };
        match &self.device.test_limits {
            Some(spec) => limits.with_overrides(spec),
            None => Ok(limits),
        }
    }
}

/// The largest device-local heap's budget left, from `VK_EXT_memory_budget`.
fn budget(ctx: &Context) -> Option<u64> {
    let d = &ctx.device;
    let mut b = vk::PhysicalDeviceMemoryBudgetPropertiesEXT::default();
    let mut p2 = vk::PhysicalDeviceMemoryProperties2::default().push_next(&mut b);
    // SAFETY: live instance and physical device; the device reports VK_EXT_memory_budget
    // (DeviceInfo::memory_budget), whose physical-device query needs no enabling on Vulkan 1.1+.
    unsafe { d.instance.get_physical_device_memory_properties2(d.physical, &mut p2) };
    let props = p2.memory_properties;
    let heaps = &props.memory_heaps[..props.memory_heap_count as usize];
    (0..heaps.len())
        .filter(|&i| heaps[i].flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
        .max_by_key(|&i| heaps[i].size)
        .map(|i| b.heap_budget[i].saturating_sub(b.heap_usage[i]))
        .filter(|&left| left > 0)
}
