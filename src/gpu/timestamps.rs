//! The frame's timestamp queries: one per pass boundary, read back as
//! milliseconds per pass, and one after each dispatch of the timed
//! repetition ([`StepMarks`]), read back per dispatch.

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

    /// Milliseconds per pass, from `repeats` repetitions of the frame's
    /// timestamps: the median of each pass over the repetitions after the
    /// first (the only one when there is one).
    pub(super) fn millis(&self, repeats: u32) -> Result<Option<GpuPassMillis>, GpuError> {
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
        let per = (self.count / repeats.max(1)) as usize;
        let timed = if repeats > 1 {
            1..repeats as usize
        } else {
            0..1
        };
        // Median over the timed repetitions of the span from timestamp a
        // to b.
        let ms = |a: usize, b: usize| {
            let mut v: Vec<f64> = timed
                .clone()
                .map(|r| ticks[r * per + b].wrapping_sub(ticks[r * per + a]) as f64 * period * 1e-6)
                .collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
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

/// Most dispatches a frame times one by one.
const MAX_STEPS: u32 = 64;

/// A timestamp after each dispatch of one repetition of a frame's passes,
/// named by its kernel: where a pass's time goes, step by step.
pub struct StepMarks {
    pool: TimestampPool,
    names: std::cell::RefCell<Vec<&'static str>>,
}

impl StepMarks {
    pub(super) fn new(shared: &Arc<DeviceShared>) -> Result<Self, GpuError> {
        Ok(StepMarks {
            pool: TimestampPool::new(shared, MAX_STEPS)?,
            names: Default::default(),
        })
    }

    pub(super) fn reset(&self, cmd: vk::CommandBuffer) {
        self.pool.reset(cmd);
    }

    /// A timestamp once the work recorded so far is done, named `name`
    /// (the first one starts the clock); past [`MAX_STEPS`], none.
    pub(super) fn mark(&self, cmd: vk::CommandBuffer, name: &'static str) {
        let mut names = self.names.borrow_mut();
        if (names.len() as u32) < MAX_STEPS {
            self.pool.write(cmd, names.len() as u32);
            names.push(name);
        }
    }

    /// (name, milliseconds since the previous mark) per mark after the
    /// first; empty without timestamps.
    pub(super) fn millis(&self) -> Result<Vec<(String, f64)>, GpuError> {
        let (Some(pool), Some(period)) = (self.pool.pool, self.pool.shared.timestamp_period_ns)
        else {
            return Ok(Vec::new());
        };
        let names = self.names.borrow();
        if names.len() < 2 {
            return Ok(Vec::new());
        }
        let mut ticks = vec![0u64; names.len()];
        // SAFETY: called after the frame's fence wait returned, so every
        // query written (one per name) is available; `ticks` holds them.
        unsafe {
            self.pool.shared.device.get_query_pool_results(
                pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(GpuError::vk)?;
        Ok((1..names.len())
            .map(|i| {
                let ms = ticks[i].wrapping_sub(ticks[i - 1]) as f64 * period * 1e-6;
                (names[i].to_string(), ms)
            })
            .collect())
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
