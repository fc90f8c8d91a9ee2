//! A frame's parameters on their way to the device: per frame slot one
//! host-visible buffer, made and mapped once with the pass, which
//! `record` writes through its mapping (the slot's previous frame, its
//! last reader, is done) and the slot's opening commands copy into the
//! device buffers the shaders read (`B_FRAME`, `B_LIGHT`, `B_DRAWS`) — the ring mapped once
//! of issue 29's point 2, as Granite's and kajiya's per-frame upload
//! rings.
//!
//! Why not `vkCmdUpdateBuffer`, which needs no buffer of its own: it
//! copies its data into the command buffer, and on lavapipe those copies
//! into a just-reset command buffer were a third of `record`'s time with
//! cold caches (17 of about 60 µs), where a copy command carries no data.

use crate::gpu::context::DeviceShared;
use crate::gpu::resources::{BufferDesc, BufferDomain, GpuBuffer};
use crate::gpu::shared::{FrameParams, GpuDraw, LightState};
use crate::gpu::GpuError;
use ash::vk;
use std::sync::Arc;

/// Where each part lies in a slot's buffer: the frame parameters at 0,
/// then the light state, then the draw table, each at a 16-byte offset.
struct Offsets {
    light: u64,
    draws: u64,
    size: u64,
}

fn offsets(max_draws: u32) -> Offsets {
    let align = |n: usize| (n as u64).next_multiple_of(16);
    let light = align(size_of::<FrameParams>());
    let draws = light + align(size_of::<LightState>());
    Offsets {
        light,
        draws,
        size: draws + u64::from(max_draws) * size_of::<GpuDraw>() as u64,
    }
}

/// The device buffers a frame's parameters are copied into.
pub(super) struct UploadTargets {
    pub frame: vk::Buffer,
    pub light: vk::Buffer,
    pub draws: vk::Buffer,
}

/// Per frame slot, its upload buffer.
pub(super) struct SlotUploads {
    buffers: Vec<GpuBuffer>,
    offsets: Offsets,
    max_draws: u32,
}

impl SlotUploads {
    /// `slots` buffers holding the parameters, the light state and up to
    /// `max_draws` draws.
    pub(super) fn new(
        shared: &Arc<DeviceShared>,
        slots: usize,
        max_draws: u32,
    ) -> Result<Self, GpuError> {
        let offsets = offsets(max_draws);
        let buffers = (0..slots)
            .map(|_| {
                let desc = BufferDesc {
                    name: "frame_uploads",
                    pass: "frame",
                    size: offsets.size,
                    domain: BufferDomain::Upload,
                };
                GpuBuffer::new(shared, desc)
            })
            .collect::<Result<_, _>>()?;
        Ok(SlotUploads {
            buffers,
            offsets,
            max_draws,
        })
    }

    /// Writes slot `slot`'s parameters, light state and draw table into
    /// its mapped buffer, for [`Self::record_copies`]' commands to copy.
    /// The host's writes reach the device with the submission
    /// (host-coherent memory, written before `vkQueueSubmit`).
    ///
    /// # Safety
    /// This slot's previous frame, which read the buffer being
    /// overwritten, is done.
    pub(super) unsafe fn write(
        &mut self,
        slot: usize,
        (params, light, draws): (&FrameParams, &LightState, &[GpuDraw]),
    ) -> Result<(), GpuError> {
        if draws.len() > self.max_draws as usize {
            return Err(GpuError::Unsupported(format!(
                "{} draws: the pass was made for {}",
                draws.len(),
                self.max_draws
            )));
        }
        let o = &self.offsets;
        let bytes = self.buffers[slot].mapped_mut()?;
        let parts: [(u64, &[u8]); 3] = [
            (0, bytemuck::bytes_of(params)),
            (o.light, bytemuck::bytes_of(light)),
            (o.draws, bytemuck::cast_slice(draws)),
        ];
        for (offset, part) in parts {
            let start = offset as usize;
            bytes[start..start + part.len()].copy_from_slice(part);
        }
        Ok(())
    }

    /// Records the copies of slot `slot`'s parameters, light state and
    /// first `draws` draws into `to`; the caller's next barrier orders
    /// them before the shaders. The commands name only the slot's buffer,
    /// so a frame slot's recorded copies serve every frame that writes as
    /// many draws ([`Self::write`]).
    ///
    /// # Safety
    /// `cmd` is recording, outside a render pass, and executes after this
    /// slot's previous frame and after the slot's [`Self::write`];
    /// `draws` is at most the pass's `max_draws`; `to`'s buffers hold a
    /// `FrameParams`, a `LightState` and `draws` draws.
    pub(super) unsafe fn record_copies(
        &self,
        device: &ash::Device,
        cmd: vk::CommandBuffer,
        slot: usize,
        draws: usize,
        to: UploadTargets,
    ) {
        let o = &self.offsets;
        let copy = |offset: u64, size: usize| {
            [vk::BufferCopy::default()
                .src_offset(offset)
                .size(size as u64)]
        };
        let source = self.buffers[slot].buffer;
        let (params, light) = (size_of::<FrameParams>(), size_of::<LightState>());
        // SAFETY: the caller's promise; each region lies within both
        // buffers (`offsets`, and `to`'s sizes).
        unsafe {
            device.cmd_copy_buffer(cmd, source, to.frame, &copy(0, params));
            device.cmd_copy_buffer(cmd, source, to.light, &copy(o.light, light));
            if draws != 0 {
                let region = copy(o.draws, draws * size_of::<GpuDraw>());
                device.cmd_copy_buffer(cmd, source, to.draws, &region);
            }
        }
    }

    /// Bytes the slots' buffers hold.
    pub(super) fn memory_bytes(&self) -> u64 {
        self.buffers.iter().map(GpuBuffer::size).sum()
    }
}
