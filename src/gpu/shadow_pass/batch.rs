//! What the batch `render` ([`crate::gpu::GpuRenderer::render`], the
//! CLI's and the bench's frame on this same pass) asks of a pass beyond
//! a host's: its first frame may skip the slow exact way after a
//! cell-list overrun (it is recorded again after growing), its last frame
//! slot's dispatches timed one by one, and its buffers listed by pass.

use super::ShadowPass;
use crate::gpu::frame_memory::memory_by_pass;
use crate::gpu::frame_report::PassMemory;
use crate::gpu::timestamps::StepMarks;
use crate::gpu::GpuError;

impl ShadowPass<'_> {
    /// Whether a frame whose cell list overruns stays exact the slow way
    /// (on unless turned off here). Off only where an overrun frame is
    /// never used but recorded again after [`Self::grow`] (the batch
    /// `render`, whose second overrun is an error): on lavapipe
    /// hairball's `Paired64` frame took past the 600 s limit the slow way.
    pub(crate) fn set_overrun_exact(&mut self, exact: bool) {
        self.overrun_exact = exact;
    }

    /// Times each dispatch of the last frame slot's frames from now on
    /// ([`Self::step_millis`]).
    ///
    /// # Safety
    /// No frame of the pass is executing (a frame the last slot recorded
    /// before may write the query pool this replaces).
    pub(crate) unsafe fn time_steps(&mut self) -> Result<(), GpuError> {
        self.step_marks = Some(StepMarks::new(self.renderer.shared())?);
        Ok(())
    }

    /// Per dispatch of the last frame slot's last frame: kernel and
    /// milliseconds (empty without step timing or timestamps).
    ///
    /// # Safety
    /// That frame has finished executing, and none of the pass is
    /// executing now.
    pub(crate) unsafe fn step_millis(&self) -> Result<Vec<(String, f64)>, GpuError> {
        self.step_marks
            .as_ref()
            .map_or(Ok(Vec::new()), StepMarks::millis)
    }

    /// Host seconds the ray-cast G-buffer's BVH took to build (0 without).
    pub(crate) fn bvh_build_seconds(&self) -> f64 {
        self.bvh_build_seconds
    }

    /// The pass's device buffers by pass, each once (a pass for one view
    /// shares some); the frame slots' status, uploads, the restaged BVH
    /// and the read-back buffer are host-visible and not counted.
    pub(crate) fn memory(&self) -> Vec<PassMemory> {
        memory_by_pass(&self.distinct_buffers())
    }
}
