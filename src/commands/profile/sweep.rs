//! Which subgroup and workgroup sizes a device lets the profile sweep, and why not others.

use crate::gpu::{DeviceInfo, EnabledFeatures};

/// The subgroup sizes to require, each power of two from the device's min to max, and a note
/// (why there is nothing to sweep, or which sizes were left out). `Err`: the device cannot
/// require a compute subgroup size at all.
pub fn subgroup_sizes(
    info: &DeviceInfo,
    enabled: &EnabledFeatures,
    local_size: u32,
) -> std::result::Result<(Vec<u32>, String), String> {
    if !enabled.subgroup_size_control {
        return Err("unsupported (VK_EXT_subgroup_size_control / subgroupSizeControl absent)".into());
    }
    if !info.required_subgroup_size_compute {
        return Err("unsupported (requiredSubgroupSizeStages does not include COMPUTE)".into());
    }
    let Some((min, max)) = info.subgroup_size_control else {
        return Err("unsupported (no subgroup size range reported)".into());
    };
    let mut sizes = vec![];
    let mut skipped = vec![];
    let mut s = min.max(1).next_power_of_two();
    while s <= max {
        // VUID-VkPipelineShaderStageCreateInfo-pNext-02756: the workgroup must fit in
        // maxComputeWorkgroupSubgroups subgroups of the required size.
        if u64::from(local_size) <= u64::from(s) * u64::from(info.max_compute_workgroup_subgroups) {
            sizes.push(s);
        } else {
            skipped.push(format!(
                "{s} (a workgroup of {local_size} exceeds maxComputeWorkgroupSubgroups {} x {s})",
                info.max_compute_workgroup_subgroups
            ));
        }
        s *= 2;
    }
    let mut note = if min == max {
        format!("only size {min}: the device allows min = max = {min}, so there is nothing to sweep; timed with that size required explicitly")
    } else {
        format!("sizes {min}..{max} allowed")
    };
    if !skipped.is_empty() {
        note.push_str(&format!("; left out: {}", skipped.join(", ")));
    }
    Ok((sizes, note))
}

/// The wanted workgroup sizes the device accepts, and a note on those it does not.
pub fn workgroup_sizes(info: &DeviceInfo, wanted: &[u32]) -> (Vec<u32>, String) {
    let limit = info.max_compute_workgroup_invocations.min(info.max_compute_workgroup_size[0]);
    let (ok, too_big): (Vec<u32>, Vec<u32>) = wanted.iter().copied().partition(|&s| s >= 1 && s <= limit);
    let mut note = format!(
        "maxComputeWorkGroupInvocations {}, maxComputeWorkGroupSize[0] {}",
        info.max_compute_workgroup_invocations, info.max_compute_workgroup_size[0]
    );
    if !too_big.is_empty() {
        note.push_str(&format!("; left out (over the limit or 0): {too_big:?}"));
    }
    (ok, note)
}
