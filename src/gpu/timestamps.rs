//! GPU time of recorded command ranges: a pool of (start, end) timestamp pairs.

use ash::vk;

use super::context::Context;
use crate::error::{Result, VkContext};

/// `pairs` timestamp pairs; the pool is destroyed on drop (after every submit using it was
/// waited for).
pub(crate) struct Timestamps<'a> {
    ctx: &'a Context,
    pool: vk::QueryPool,
    pairs: u32,
}

impl Drop for Timestamps<'_> {
    fn drop(&mut self) {
        // SAFETY: every submit using the pool was waited for (or never made).
        unsafe { self.ctx.device.raw.destroy_query_pool(self.pool, None) };
    }
}

impl<'a> Timestamps<'a> {
    pub(crate) fn new(ctx: &'a Context, pairs: u32) -> Result<Timestamps<'a>> {
        let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2 * pairs);
        // SAFETY: valid device and create info; destroyed on drop.
        let pool =
            unsafe { ctx.device.raw.create_query_pool(&info, None) }.during("creating the timestamp query pool")?;
        Ok(Timestamps { ctx, pool, pairs })
    }

    /// Whether the device's compute queue writes timestamps at all.
    pub(crate) fn supported(ctx: &Context) -> bool {
        ctx.info().timestamp_valid_bits > 0
    }

    /// Records the reset of pair `i`; record it before `start` and `end`, outside their range.
    ///
    /// # Safety
    /// `cmd` is a command buffer of this device in the recording state.
    pub(crate) unsafe fn reset(&self, d: &ash::Device, cmd: vk::CommandBuffer, i: u32) {
        d.cmd_reset_query_pool(cmd, self.pool, 2 * i, 2);
    }

    /// Records the start of pair `i` (when earlier commands have started).
    ///
    /// # Safety
    /// As [`Timestamps::reset`].
    pub(crate) unsafe fn start(&self, d: &ash::Device, cmd: vk::CommandBuffer, i: u32) {
        d.cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, self.pool, 2 * i);
    }

    /// Records the end of pair `i` (when earlier commands have finished).
    ///
    /// # Safety
    /// As [`Timestamps::reset`].
    pub(crate) unsafe fn end(&self, d: &ash::Device, cmd: vk::CommandBuffer, i: u32) {
        d.cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.pool, 2 * i + 1);
    }

    /// Milliseconds between start and end of every pair, each written by a completed submit.
    pub(crate) fn read_ms(&self) -> Result<Vec<f64>> {
        let info = self.ctx.info();
        let mut ts = vec![0u64; 2 * self.pairs as usize];
        // SAFETY: the caller waited for the submits that wrote every query.
        unsafe {
            self.ctx.device.raw.get_query_pool_results(
                self.pool,
                0,
                &mut ts,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .during("reading timestamps")
        // A lost device surfaces here first when the submit itself succeeded: name the dispatch.
        .map_err(|e| self.ctx.fault(e))?;
        let mask = if info.timestamp_valid_bits >= 64 { u64::MAX } else { (1u64 << info.timestamp_valid_bits) - 1 };
        let ns = info.timestamp_period_ns as f64;
        Ok(ts.chunks_exact(2).map(|p| (p[1].wrapping_sub(p[0]) & mask) as f64 * ns * 1e-6).collect())
    }
}
