//! What a frame of the shadow pass reports in its slot's status buffer
//! (host-visible, copied from the counters at the frame's end), read once
//! the host knows the frame is done: the cell list's need, lavapipe's loop
//! cap, rejected host inputs and host geometry wrong on the device — each
//! a named refusal where the frame must not be used.

use super::ShadowPass;
use crate::gpu::frame_inputs::LLVMPIPE_LOOP_CAP;
use crate::gpu::shared::counter;
use crate::gpu::GpuError;
use crate::settings::PassTimes;

/// What a frame's status buffer says, read once the host knows the
/// frame is done.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PassStatus {
    /// Entries the cell list needed.
    pub cell_entries: u64,
    /// The list was smaller: the frame ran the slow exact way, and
    /// [`ShadowPass::grow`] makes room for the next.
    pub cell_list_overrun: bool,
    /// A shader stopped at lavapipe's loop cap in this frame after this
    /// many trips (0: none): its masks are cut short, and the frame must
    /// not be used.
    pub loop_cap_trips: u32,
    /// Pixels shadow-tested.
    pub shadow_tested: u32,
    /// Receivers (pixels and edge pixels' extra surfaces) that ran
    /// frustum-triangle tests, and the tests they ran: the frame's work,
    /// steadier than its time.
    pub pixels_tested: u32,
    pub tests_spawned: u64,
    /// Pixels of the host's visibility buffer stored as misses because
    /// their id (with a multisampled buffer: any of their samples' ids)
    /// named no triangle of the pass, or a triangle whose plane their
    /// centre ray does not cross in front of the eye.
    pub visibility_rejected: u32,
    /// With a multisampled visibility buffer: pixels some of whose samples
    /// saw a triangle but whose centre ray meets none that the samples of
    /// the pixel and its neighbours saw (the background between a
    /// silhouette's samples, or a triangle no sample saw), stored as
    /// misses; the twin's `VisibilityGBuffer::uncovered`.
    pub centre_uncovered: u32,
    /// With the host's geometry: triangles with an index at or past their
    /// draw's vertex count, and triangles with a vertex outside the
    /// bounds the pass was made for ([`Self::geometry_error`]).
    pub index_out_of_range: u32,
    pub outside_bounds: u32,
    /// With edge surfaces: the slots the frame's edge pixels needed
    /// (extra surfaces or records, whichever is more).
    pub edge_slots_needed: u64,
    /// They were more than the frame had: the pixels past them kept
    /// tangent-plane masks (all samples on the centre's surface), and
    /// [`ShadowPass::grow`] makes room for the next frame.
    pub edge_slots_overrun: bool,
}

impl PassStatus {
    /// A frame whose host geometry was wrong on the device (an index past
    /// its draw's vertices, a vertex outside the pass's bounds), named:
    /// its masks must not be used.
    pub fn geometry_error(&self) -> Option<GpuError> {
        match (self.index_out_of_range, self.outside_bounds) {
            (0, 0) => None,
            (indices, outside) => Some(GpuError::Unsupported(format!(
                "the host's draws were wrong on the device: {indices} triangles indexed past \
                 their draw's vertex_count (collapsed, casting nothing), {outside} triangles \
                 left the bounds the pass was made for (outside its precision envelope)"
            ))),
        }
    }
}

impl ShadowPass<'_> {
    /// What slot `slot`'s last frame wrote to its status buffer.
    ///
    /// # Safety
    /// That frame has finished executing (the host waited for its fence)
    /// and no frame of the slot is executing now.
    pub unsafe fn status(&self, slot: usize) -> Result<PassStatus, GpuError> {
        let bytes = self.status[slot].mapped()?;
        let c: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes[..counter::WORDS * 4]);
        let needed = crate::gpu::edge_surfaces::slots_needed(&c);
        Ok(PassStatus {
            cell_entries: u64::from(c[counter::CELL_ENTRIES]),
            cell_list_overrun: c[counter::CAPACITY_EXCEEDED] != 0,
            loop_cap_trips: c[counter::LOOP_BUDGET_EXCEEDED],
            shadow_tested: c[counter::SHADOW_TESTED],
            pixels_tested: c[counter::PIXELS_TESTED],
            tests_spawned: u64::from(c[counter::TESTS_SPAWNED])
                | (u64::from(c[counter::TESTS_SPAWNED + 1]) << 32),
            visibility_rejected: c[counter::VISIBILITY_REJECTED],
            centre_uncovered: c[counter::CENTRE_UNCOVERED],
            index_out_of_range: c[counter::INDEX_OUT_OF_RANGE],
            outside_bounds: c[counter::OUTSIDE_BOUNDS],
            edge_slots_needed: needed,
            edge_slots_overrun: needed > self.slot_edge_slots[slot],
        })
    }

    /// GPU milliseconds of slot `slot`'s last frame per pass (the
    /// G-buffer with `gather_draws`, `translate_vertices` and the edge
    /// surfaces; light setup; bin; evaluate; resolve with the output
    /// images), from its timestamps; `None` where the queue has none.
    ///
    /// # Safety
    /// That frame has finished executing (the host waited for its fence)
    /// and no frame of the slot is executing now.
    pub unsafe fn gpu_millis(&self, slot: usize) -> Result<Option<PassTimes>, GpuError> {
        self.timestamps[slot].millis(1)
    }

    /// `LLVMPIPE_LOOP_CAP` as a status's refusal.
    pub fn loop_cap_error(&self, status: &PassStatus) -> Option<GpuError> {
        (status.loop_cap_trips != 0).then(|| GpuError::LoopCap {
            device: self.renderer.context.info().name.clone(),
            cap: LLVMPIPE_LOOP_CAP,
            trips: status.loop_cap_trips,
        })
    }
}
