//! The host's GPU time per pass: timestamps around its raster, izb's
//! shadow pass and its lighting in each frame's command buffer, read once the slot's fence
//! says the frame is done (no wait of their own, no read-back of a
//! buffer: a query pool the host owns).

use crate::host_device::HostGpu;
use ash::vk;
use izb::settings::PassTimes;

/// Timestamps a frame writes: before the raster, between the raster and
/// izb's pass, between izb's pass and the lighting, after the lighting.
const MARKS: u32 = 4;

/// Per frame slot four timestamps, and the frames' times read so far.
pub struct PassTimer {
    pool: vk::QueryPool,
    period_ns: f64,
    /// Per slot: a frame's marks written and not read yet.
    pending: Vec<bool>,
    /// Per frame read: the raster's, izb's pass's and the lighting's
    /// milliseconds.
    pub raster_ms: Vec<f64>,
    pub izb_ms: Vec<f64>,
    pub lighting_ms: Vec<f64>,
}

/// Where in the frame a timestamp is written.
#[derive(Clone, Copy)]
pub enum Mark {
    FrameStart = 0,
    RasterDone = 1,
    ShadowPassDone = 2,
    LightingDone = 3,
}

impl PassTimer {
    /// A pool for `slots` frame slots; `None` when the queue family writes
    /// no timestamps.
    pub fn new(gpu: &HostGpu, slots: usize) -> Option<PassTimer> {
        // SAFETY: the physical device is the host's, alive with its instance.
        let families = unsafe {
            gpu.instance
                .get_physical_device_queue_family_properties(gpu.physical)
        };
        let valid_bits = families.get(gpu.family as usize)?.timestamp_valid_bits;
        // SAFETY: as above.
        let limits = unsafe { gpu.instance.get_physical_device_properties(gpu.physical) }.limits;
        if valid_bits == 0 || limits.timestamp_period <= 0.0 {
            return None;
        }
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(MARKS * slots as u32);
        // SAFETY: the device is live.
        let pool = unsafe { gpu.device.create_query_pool(&info, None) }.ok()?;
        Some(PassTimer {
            pool,
            period_ns: f64::from(limits.timestamp_period),
            pending: vec![false; slots],
            raster_ms: Vec::new(),
            izb_ms: Vec::new(),
            lighting_ms: Vec::new(),
        })
    }

    /// Resets slot `slot`'s queries and writes its first mark.
    ///
    /// # Safety
    /// `cmd` is recording; the slot's previous frame is done and its
    /// marks were read ([`Self::collect`]).
    pub unsafe fn start(&mut self, d: &ash::Device, cmd: vk::CommandBuffer, slot: usize) {
        // SAFETY: the caller's promise; the queries lie in the pool.
        unsafe {
            d.cmd_reset_query_pool(cmd, self.pool, MARKS * slot as u32, MARKS);
            self.mark(d, cmd, slot, Mark::FrameStart);
        }
        self.pending[slot] = true;
    }

    /// Writes `mark` once the commands recorded before it are done.
    ///
    /// # Safety
    /// `cmd` is recording, after [`Self::start`] for `slot`.
    pub unsafe fn mark(&self, d: &ash::Device, cmd: vk::CommandBuffer, slot: usize, mark: Mark) {
        let stage = match mark {
            Mark::FrameStart => vk::PipelineStageFlags::TOP_OF_PIPE,
            _ => vk::PipelineStageFlags::BOTTOM_OF_PIPE,
        };
        let query = MARKS * slot as u32 + mark as u32;
        // SAFETY: the caller's promise; the query lies in the pool.
        unsafe { d.cmd_write_timestamp(cmd, stage, self.pool, query) };
    }

    /// Reads slot `slot`'s marks, if a frame wrote them.
    ///
    /// # Safety
    /// The slot's frame is done (the host waited on its fence).
    pub unsafe fn collect(&mut self, d: &ash::Device, slot: usize) {
        if !std::mem::take(&mut self.pending[slot]) {
            return;
        }
        let mut ticks = [0u64; MARKS as usize];
        // SAFETY: the frame that wrote them is done; the queries lie in
        // the pool.
        let read = unsafe {
            d.get_query_pool_results(
                self.pool,
                MARKS * slot as u32,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64,
            )
        };
        if read.is_ok() {
            let ms = |a: u64, b: u64| b.saturating_sub(a) as f64 * self.period_ns * 1e-6;
            self.raster_ms.push(ms(ticks[0], ticks[1]));
            self.izb_ms.push(ms(ticks[1], ticks[2]));
            self.lighting_ms.push(ms(ticks[2], ticks[3]));
        }
    }

    /// # Safety
    /// No frame that writes the pool is executing.
    pub unsafe fn destroy(&self, d: &ash::Device) {
        // SAFETY: the caller's promise.
        unsafe { d.destroy_query_pool(self.pool, None) };
    }
}

/// Medians of the host's passes, GPU milliseconds: the host's
/// timestamps around its raster and izb's pass, and izb's own per step.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct GpuMillis {
    /// The host's raster of its G-buffer.
    pub raster: f64,
    /// izb's shadow pass, everything `record` recorded.
    pub shadow_pass: f64,
    /// The host's lighting, sampling the pass's lit fraction.
    pub lighting: f64,
    /// Frames timed.
    pub frames: usize,
    /// Within izb's pass (`ShadowPass::gpu_millis`): the G-buffer (with
    /// the gather), light setup, bin, evaluate, resolve (with the images).
    pub gbuffer: f64,
    pub light_setup: f64,
    pub bin: f64,
    pub evaluate: f64,
    pub resolve: f64,
}

impl GpuMillis {
    /// The medians of `timer`'s frames and of izb's `steps`.
    pub fn of(timer: &PassTimer, steps: &[PassTimes]) -> GpuMillis {
        let step = |f: fn(&PassTimes) -> f64| median(&steps.iter().map(f).collect::<Vec<_>>());
        GpuMillis {
            raster: median(&timer.raster_ms),
            shadow_pass: median(&timer.izb_ms),
            lighting: median(&timer.lighting_ms),
            frames: timer.izb_ms.len(),
            gbuffer: step(|m| m.gbuffer),
            light_setup: step(|m| m.light_setup),
            bin: step(|m| m.bin),
            evaluate: step(|m| m.evaluate),
            resolve: step(|m| m.resolve),
        }
    }
}

/// CPU microseconds this thread has run (`CLOCK_THREAD_CPUTIME_ID`): its
/// own work, without the time it was off the CPU.
pub fn thread_cpu_us() -> f64 {
    izb::thread_time::thread_cpu_seconds() * 1e6
}

/// The median of `v` (0 when empty).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    match s.len() {
        0 => 0.0,
        n => s[n / 2],
    }
}
