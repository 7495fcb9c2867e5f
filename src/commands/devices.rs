//! `trilab devices`: every Vulkan device the loader reports, its driver and the features trilab
//! uses, and which one a command would pick.

use serde::Serialize;

use crate::error::Result;
use crate::gpu::context::choose_device;
use crate::gpu::{Context, DeviceInfo};
use crate::report::Report;

/// The devices, in the loader's order (serialised as the bare list).
#[derive(Clone, Debug, Serialize)]
#[serde(transparent)]
pub struct DevicesReport {
    pub devices: Vec<DeviceInfo>,
}

/// Lists the devices (no device is created).
pub fn run() -> Result<DevicesReport> {
    Ok(DevicesReport { devices: Context::list_devices()? })
}

impl Report for DevicesReport {
    fn to_text(&self) -> String {
        if self.devices.is_empty() {
            return "no Vulkan devices\n".into();
        }
        let chosen = choose_device(&self.devices, None).ok();
        let mut s = String::new();
        for d in &self.devices {
            s += &d.report();
            // What it cannot run, and why (gpu::Capabilities, with the features a context
            // would enable).
            let enabled = crate::gpu::EnabledFeatures::for_device(d);
            let caps = crate::gpu::Capabilities::new(d, &enabled);
            for (what, why) in caps.table() {
                if let Some(why) = why {
                    s += &format!("    cannot run {what}: {why}\n");
                }
            }
            if Some(d.index) == chosen {
                s += "    (default choice)\n";
            }
        }
        s
    }
}
