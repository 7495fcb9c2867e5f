//! A planted slowdown of one kernel, for tests of the regression gate and of `trilab ab`: with
//! `TRILAB_INJECT_SLOWDOWN=NAME:F`, every ray-casting dispatch of a kernel whose name contains
//! `NAME` does about `F` times its work between its timestamps: the whole dispatch `floor(F)`
//! times, then the first `frac(F)` of its rays once more (`:1.1` traces a tenth of the rays
//! again). The same rays give the same hits, so every count and correctness figure is unchanged
//! and only the time grows. This is what a kernel that slowed alone looks like to `trilab
//! compare` and `trilab ab`, made without editing a shader. A fractional factor's true size
//! depends on how costly the first rays are against the rest; `ab` measures it.
//!
//! The slowdown is a [`RayDispatch`] around the real kernel ([`Slowed`]), installed by
//! `gpu::cast_rays` alone when the variable is set; the batched dispatch itself
//! (`gpu::cast_rays_with`) knows nothing of it.

use std::collections::BTreeMap;

use ash::vk;

use super::commands::memory_barrier;
use super::descriptors::DescriptorLayout;
use super::device_info::DeviceInfo;
use super::dispatch::{Batch, RayDispatch};
use crate::error::{Error, Result};

/// The environment variable `gpu::cast_rays` reads.
pub const INJECT_SLOWDOWN_ENV: &str = "TRILAB_INJECT_SLOWDOWN";

/// Largest factor: a planted slowdown is a test's, not a way to run for hours.
const MAX_FACTOR: f64 = 64.0;
/// Smallest: below one percent of a dispatch the extra work is lost in a batch's rounding.
const MIN_FACTOR: f64 = 1.01;

/// `NAME:F`: dispatches of kernels whose name contains `NAME` do `F` times their work.
#[derive(Clone, Debug, PartialEq)]
pub struct Slowdown {
    pub kernel: String,
    pub factor: f64,
}

/// What a dispatch of `count` rays records: the whole dispatch `whole` times, then the first
/// `partial` rays once more (0: none).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Repeats {
    pub whole: u32,
    pub partial: u32,
}

impl std::str::FromStr for Slowdown {
    type Err = Error;

    fn from_str(s: &str) -> Result<Slowdown> {
        let bad = || {
            Error::Usage(format!(
                "{INJECT_SLOWDOWN_ENV}=`{s}`: expected NAME:F, a kernel name (or part of one, such as \
                 raycast.unit.closest) and a factor {MIN_FACTOR} <= F <= {MAX_FACTOR} (its work done F times: \
                 2 doubles it, 1.1 adds a tenth)"
            ))
        };
        let (kernel, f) = s.trim().rsplit_once(':').ok_or_else(bad)?;
        let factor: f64 = f.trim().parse().map_err(|_| bad())?;
        if kernel.trim().is_empty() || !(MIN_FACTOR..=MAX_FACTOR).contains(&factor) {
            return Err(bad());
        }
        Ok(Slowdown { kernel: kernel.trim().to_owned(), factor })
    }
}

impl Slowdown {
    /// The slowdown the environment asks for, if any.
    pub fn from_env() -> Result<Option<Slowdown>> {
        match std::env::var(INJECT_SLOWDOWN_ENV) {
            Ok(v) if !v.trim().is_empty() => v.parse().map(Some),
            _ => Ok(None),
        }
    }

    /// What a dispatch of `count` rays of `kernel` records: once, unless it is the one slowed.
    pub fn repeats_for(this: Option<&Slowdown>, kernel: &str, count: u32) -> Repeats {
        match this.filter(|s| kernel.contains(&s.kernel)) {
            None => Repeats { whole: 1, partial: 0 },
            Some(s) => {
                Repeats { whole: s.factor.floor() as u32, partial: (s.factor.fract() * count as f64).round() as u32 }
            }
        }
    }

    /// `kernel` under this slowdown (recorded once where the slowdown does not name it).
    pub fn around<K: RayDispatch + ?Sized>(self, kernel: &K) -> Slowed<'_, K> {
        Slowed { kernel, slowdown: self }
    }
}

/// A kernel under a planted slowdown: the same bindings, stage and limits, and each batch's
/// dispatch recorded as [`Slowdown::repeats_for`] says, between the batch's timestamps.
pub struct Slowed<'a, K: ?Sized> {
    kernel: &'a K,
    slowdown: Slowdown,
}

impl<K: RayDispatch + ?Sized> DescriptorLayout for Slowed<'_, K> {
    fn name(&self) -> &'static str {
        self.kernel.name()
    }

    fn bindings(&self) -> BTreeMap<u32, vk::DescriptorType> {
        self.kernel.bindings()
    }

    fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.kernel.set_layout()
    }
}

impl<K: RayDispatch + ?Sized> RayDispatch for Slowed<'_, K> {
    fn stage(&self) -> vk::PipelineStageFlags {
        self.kernel.stage()
    }

    fn max_rays(&self, info: &DeviceInfo) -> usize {
        self.kernel.max_rays(info)
    }

    unsafe fn record_rays(&self, dev: &ash::Device, cmd: vk::CommandBuffer, set: vk::DescriptorSet, count: u32) {
        self.kernel.record_rays(dev, cmd, set, count);
    }

    /// The kernel's batch, then its dispatch again: `whole - 1` more times over all the batch's
    /// rays, then once over its first `partial`.
    unsafe fn record_batch(&self, dev: &ash::Device, cmd: vk::CommandBuffer, batch: &Batch) {
        self.kernel.record_batch(dev, cmd, batch);
        let repeats = Slowdown::repeats_for(Some(&self.slowdown), self.kernel.name(), batch.count);
        let again = (1..repeats.whole).map(|_| batch.count).chain((repeats.partial > 0).then_some(repeats.partial));
        let stage = self.kernel.stage();
        for rays in again {
            // The same dispatch again over the same outputs, or over its first `rays` (and,
            // for a persistent kernel, a counter zeroed again): the previous one's writes
            // and atomics finish first.
            let shader = (stage, vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE);
            if let Some(c) = batch.counter {
                memory_barrier(dev, cmd, shader, (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE));
                dev.cmd_fill_buffer(cmd, c, 0, 4, 0);
                memory_barrier(dev, cmd, (vk::PipelineStageFlags::TRANSFER, vk::AccessFlags::TRANSFER_WRITE), shader);
            } else {
                memory_barrier(dev, cmd, shader, shader);
            }
            self.kernel.record_rays(dev, cmd, batch.set, rays);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_name_and_factor_and_refuses_the_rest() {
        let s: Slowdown = "raycast.unit.closest:3".parse().unwrap();
        assert_eq!(s, Slowdown { kernel: "raycast.unit.closest".into(), factor: 3.0 });
        let r = |s: Option<&Slowdown>, k: &str| Slowdown::repeats_for(s, k, 1000);
        assert_eq!(r(Some(&s), "raycast.unit.closest_bvh4"), Repeats { whole: 3, partial: 0 });
        assert_eq!(r(Some(&s), "raycast.mt.closest"), Repeats { whole: 1, partial: 0 });
        assert_eq!(r(None, "raycast.unit.closest"), Repeats { whole: 1, partial: 0 });
        let tenth: Slowdown = ".mt.:1.1".parse().unwrap();
        assert_eq!(r(Some(&tenth), "raycast.mt.closest"), Repeats { whole: 1, partial: 100 });
        assert_eq!(Slowdown::repeats_for(Some(&tenth), "raycast.mt.closest", 7), Repeats { whole: 1, partial: 1 });
        let twice_and_a_half: Slowdown = "x:2.5".parse().unwrap();
        assert_eq!(r(Some(&twice_and_a_half), "x"), Repeats { whole: 2, partial: 500 });
        for bad in ["raycast.unit", ":3", "x:1", "x:1.001", "x:0", "x:65", "x:two", "x:NaN", "x:inf"] {
            let e = bad.parse::<Slowdown>().unwrap_err().to_string();
            assert!(e.contains(INJECT_SLOWDOWN_ENV) && e.contains("NAME:F"), "{bad}: {e}");
        }
    }
}
