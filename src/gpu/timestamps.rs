//! The frame's timestamp queries: one per pass boundary, read back as
//! milliseconds per pass, and one after each dispatch of the timed
//! repetition or frame ([`StepMarks`]), read back per dispatch.

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

    /// The first `n` timestamps in milliseconds (the device's ticks
    /// scaled by its period), or `None` without timestamps. Call after the
    /// frame's fence wait, with every one of them written.
    fn read_millis(&self, n: u32) -> Result<Option<Vec<f64>>, GpuError> {
        let (Some(pool), Some(period)) = (self.pool, self.shared.timestamp_period_ns) else {
            return Ok(None);
        };
        let mut ticks = vec![0u64; n.min(self.count) as usize];
        // SAFETY: called after the frame's fence wait returned, so the
        // queries read were written; `ticks` holds that many 64-bit results.
        unsafe {
            self.shared.device.get_query_pool_results(
                pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(GpuError::vk)?;
        // Differences of ticks stay exact: relative to the first one.
        let first = ticks.first().copied().unwrap_or(0);
        Ok(Some(
            ticks
                .iter()
                .map(|t| t.wrapping_sub(first) as f64 * period * 1e-6)
                .collect(),
        ))
    }

    /// Milliseconds per pass, from `repeats` repetitions of the frame's
    /// timestamps: the median of each pass over the repetitions after the
    /// first (the only one when there is one).
    pub(super) fn millis(&self, repeats: u32) -> Result<Option<GpuPassMillis>, GpuError> {
        let Some(t) = self.read_millis(self.count)? else {
            return Ok(None);
        };
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
                .map(|r| t[r * per + b] - t[r * per + a])
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

    /// Resets the marks for a new frame's (recorded into `cmd`).
    pub(super) fn reset(&self, cmd: vk::CommandBuffer) {
        self.pool.reset(cmd);
        self.names.borrow_mut().clear();
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
        let names = self.names.borrow();
        if names.len() < 2 {
            return Ok(Vec::new());
        }
        let Some(t) = self.pool.read_millis(names.len() as u32)? else {
            return Ok(Vec::new());
        };
        Ok((1..names.len())
            .map(|i| (names[i].to_string(), t[i] - t[i - 1]))
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
