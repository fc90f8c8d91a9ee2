//! The frame's timestamp queries: one per pass boundary, read back as
//! milliseconds per pass.

use super::context::DeviceShared;
use super::frame_report::GpuPassMillis;
use super::GpuError;
use ash::vk;
use std::sync::Arc;

/// A timestamp query pool (absent when the queue has no timestamps).
pub(super) struct TimestampPool {
    shared: Arc<DeviceShared>,
    pool: Option<vk::QueryPool>,
    count: u32,
}

impl TimestampPool {
    pub(super) fn new(shared: &Arc<DeviceShared>, count: u32) -> Result<Self, GpuError> {
        let pool = match shared.timestamp_period_ns {
            None => None,
            Some(_) => {
                let info = vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(count);
                Some(
                    // SAFETY: `info` outlives the call; the queue supports timestamps.
                    unsafe { shared.device.create_query_pool(&info, None) }
                        .map_err(GpuError::vk)?,
                )
            }
        };
        Ok(TimestampPool {
            shared: shared.clone(),
            pool,
            count,
        })
    }

    pub(super) fn reset(&self, cmd: vk::CommandBuffer) {
        if let Some(pool) = self.pool {
            // SAFETY: `cmd` is recording and the pool has `count` queries.
            unsafe {
                self.shared
                    .device
                    .cmd_reset_query_pool(cmd, pool, 0, self.count)
            };
        }
    }

    pub(super) fn write(&self, cmd: vk::CommandBuffer, index: u32) {
        if let Some(pool) = self.pool {
            // SAFETY: `cmd` is recording; the caller's indices stay below `count`.
            unsafe {
                self.shared.device.cmd_write_timestamp(
                    cmd,
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    pool,
                    index,
                )
            };
        }
    }

    /// Milliseconds between consecutive timestamps, per pass.
    pub(super) fn millis(&self) -> Result<Option<GpuPassMillis>, GpuError> {
        let (Some(pool), Some(period)) = (self.pool, self.shared.timestamp_period_ns) else {
            return Ok(None);
        };
        let mut ticks = vec![0u64; self.count as usize];
        // SAFETY: called after the frame's fence wait returned, so every
        // query was written; `ticks` holds `count` 64-bit results.
        unsafe {
            self.shared.device.get_query_pool_results(
                pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(GpuError::vk)?;
        let ms = |a: usize, b: usize| ticks[b].wrapping_sub(ticks[a]) as f64 * period * 1e-6;
        Ok(Some(GpuPassMillis {
            gbuffer: ms(0, 1),
            light_setup: ms(1, 2),
            bin: ms(2, 3),
            evaluate: ms(3, 4),
            resolve: ms(4, 5),
            total: ms(0, 5),
        }))
    }
}

impl Drop for TimestampPool {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        if let Some(pool) = self.pool {
            // SAFETY: the frame that wrote the queries has finished (fence wait),
            // and a poisoned device returns above.
            unsafe { self.shared.device.destroy_query_pool(pool, None) };
        }
    }
}
