//! The part of a frame's commands that names only the pass's own objects,
//! recorded once per frame slot into two secondary command buffers and
//! executed again by every later frame of that slot while nothing it
//! depends on changed — so that `record` costs the host a parameter write
//! and a few commands, not the frame's ~30 dispatches, ~25 barriers,
//! copies, fills and timestamps (issue 29's `record` ≤ 50 µs: 55–90 µs on
//! an H200 machine's host, where each `vkCmd*` costs more than on
//! lavapipe; `paper-notes/embedding.md`, seventeenth part).
//!
//! Why two and not one: the dispatches that read or write the host's
//! images and vertex buffers bind the slot's set of them, which is
//! written every frame (a handle equal to last frame's may name a new
//! image: Vulkan reuses handles after destruction), and writing a set
//! invalidates every command buffer that bound it. Those dispatches, the
//! host objects' barriers and the set's binding stay in the host's
//! command buffer, between the *opening* secondary (the previous frame's
//! barrier, the parameters' copies, the fills, the vertices' translation)
//! and the *core* one (light setup, bin, evaluate, resolve and the
//! status copy). Secondary command buffers inherit no state: each binds
//! the pass's set itself, and the host's command buffer binds again what
//! it dispatches after one.
//!
//! What a slot's secondaries depend on is [`SegmentsKey`] (the values the
//! recording reads) and the pass's buffers, sets, upload ring and query
//! pools, whose replacement ([`SlotCommands::invalidate`], from `grow`,
//! `resize` and `reserve_host_geometry`) makes every slot record anew.
//! A slot's secondaries are reset and recorded again only by that slot's
//! `record`, when its previous frame — their last execution — is done
//! (`record`'s promise).

use crate::gpu::context::DeviceShared;
use crate::gpu::GpuError;
use ash::vk;
use std::sync::Arc;

/// The values a slot's secondaries were recorded from: equal keys, equal
/// commands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct SegmentsKey {
    pub size: [u32; 2],
    /// `light_setup`'s and `evaluate`'s pixel rows (edge receivers
    /// included).
    pub rows: [u32; 2],
    pub frame_triangles: u32,
    pub max_cells: u64,
    /// The behind-receivers gather's pixels.
    pub gather: Option<u32>,
    /// `evaluate`'s heavy step.
    pub heavy: Option<(u32, u32)>,
    pub halves: usize,
    pub traced_edges: bool,
    /// Draws copied from the upload ring.
    pub draws: usize,
}

/// One frame slot's two secondaries and what they hold.
struct SlotSegments {
    opening: vk::CommandBuffer,
    core: vk::CommandBuffer,
    /// `None`: to be recorded (never yet, invalidated, or a recording
    /// that did not finish).
    recorded: Option<SegmentsKey>,
}

/// The secondaries a frame executes, and whether they must be recorded
/// first ([`SlotCommands::begin`]).
#[derive(Clone, Copy)]
pub(super) struct Segments {
    pub opening: vk::CommandBuffer,
    pub core: vk::CommandBuffer,
    pub to_record: bool,
}

/// Per frame slot, its secondaries, from one command pool of the pass's
/// queue family (used only by `&mut` methods of the pass: the pool's
/// external synchronisation).
pub(super) struct SlotCommands {
    shared: Arc<DeviceShared>,
    pool: vk::CommandPool,
    slots: Vec<SlotSegments>,
    /// Slots' secondaries recorded so far ([`Self::recordings`]).
    recordings: u64,
}

impl SlotCommands {
    /// A pool and two secondaries for each of `slots` frame slots.
    pub(super) fn new(shared: &Arc<DeviceShared>, slots: usize) -> Result<Self, GpuError> {
        let device = &shared.device;
        let info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(shared.queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: the family is the device's (checked when `shared` was
        // made); `info` outlives the call.
        let pool = unsafe { device.create_command_pool(&info, None) }.map_err(GpuError::vk)?;
        let mut commands = SlotCommands {
            shared: shared.clone(),
            pool,
            slots: Vec::with_capacity(slots),
            recordings: 0,
        };
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::SECONDARY)
            .command_buffer_count(2 * slots as u32);
        // SAFETY: the pool is this device's and used by no other thread
        // (just made); on an error `commands`' drop destroys it.
        let buffers = unsafe { device.allocate_command_buffers(&alloc) }.map_err(GpuError::vk)?;
        commands.slots = buffers
            .chunks_exact(2)
            .map(|pair| SlotSegments {
                opening: pair[0],
                core: pair[1],
                recorded: None,
            })
            .collect();
        Ok(commands)
    }

    /// Every slot records its secondaries anew at its next frame: the
    /// pass's buffers, set or upload ring were replaced.
    pub(super) fn invalidate(&mut self) {
        for slot in &mut self.slots {
            slot.recorded = None;
        }
    }

    /// Slot `slot`'s secondaries for a frame of `key`: as they are when
    /// they hold `key`'s commands, or else reset and begun, to be recorded
    /// by the caller and ended by [`Self::end`].
    ///
    /// # Safety
    /// Slot `slot`'s previous frame, the last execution of its
    /// secondaries, is done; no command buffer recorded before holds them
    /// that will still be submitted when they are begun again.
    pub(super) unsafe fn begin(
        &mut self,
        slot: usize,
        key: &SegmentsKey,
    ) -> Result<Segments, GpuError> {
        let segments = &mut self.slots[slot];
        let begun = Segments {
            opening: segments.opening,
            core: segments.core,
            to_record: segments.recorded.as_ref() != Some(key),
        };
        if !begun.to_record {
            return Ok(begun);
        }
        segments.recorded = None;
        let device = &self.shared.device;
        // Outside any render pass, no query inherited: the host's command
        // buffer executes them outside render passes (`record`'s promise).
        let inheritance = vk::CommandBufferInheritanceInfo::default();
        let begin = vk::CommandBufferBeginInfo::default().inheritance_info(&inheritance);
        for cmd in [begun.opening, begun.core] {
            // SAFETY: `cmd` is this pool's, not pending (the caller's
            // promise), and the pool has RESET_COMMAND_BUFFER; `begin`
            // outlives the call.
            unsafe {
                device
                    .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                    .map_err(GpuError::vk)?;
                device
                    .begin_command_buffer(cmd, &begin)
                    .map_err(GpuError::vk)?;
            }
        }
        Ok(begun)
    }

    /// Ends slot `slot`'s secondaries begun by [`Self::begin`], now
    /// holding `key`'s commands.
    pub(super) fn end(&mut self, slot: usize, key: SegmentsKey) -> Result<(), GpuError> {
        let segments = &mut self.slots[slot];
        for cmd in [segments.opening, segments.core] {
            // SAFETY: `cmd` is in the recording state (`begin`, and the
            // caller recorded into it on this thread).
            unsafe { self.shared.device.end_command_buffer(cmd) }.map_err(GpuError::vk)?;
        }
        segments.recorded = Some(key);
        self.recordings += 1;
        Ok(())
    }

    /// How many times a slot's secondaries were recorded: once per slot,
    /// then again after an invalidation or a frame of another key.
    pub(super) fn recordings(&self) -> u64 {
        self.recordings
    }
}

impl Drop for SlotCommands {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: the pass is dropped with the GPU idle (its documented
        // contract), so no secondary is pending; destroying the pool frees
        // them.
        unsafe { self.shared.device.destroy_command_pool(self.pool, None) };
    }
}
