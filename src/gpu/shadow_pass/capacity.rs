//! What changes the pass's buffers between frames: the cell list growing
//! after an overrun ([`ShadowPass::grow`]) and the image changing size
//! ([`ShadowPass::resize`]). Both make new buffers and a new descriptor
//! set and retire the old set with the buffers it holds until every
//! frame slot has recorded again — each slot's previous frame, which may
//! still use it, is then known done (Granite's per-frame destroy lists).
//! Nothing is uploaded or waited on: the scene's buffers are kept.

use super::edge_slots::checked_receivers;
use super::{PassStatus, ShadowPass};
use crate::gpu::edge_surfaces::edge_tiles;
use crate::gpu::frame_memory::frame_buffer_descs;
use crate::gpu::izb_frame::max_cells;
use crate::gpu::pipeline::DescriptorSet;
use crate::gpu::resources::{BufferDesc, GpuBuffer};
use crate::gpu::shared::binding;
use crate::gpu::GpuError;
use std::sync::Arc;

/// A descriptor set replaced by [`ShadowPass::grow`] or
/// [`ShadowPass::resize`] (it holds its buffers), or upload buffers
/// replaced by [`ShadowPass::reserve_host_geometry`], kept until every
/// frame slot has recorded again ([`ShadowPass::record`]'s promise).
pub(super) struct Retired {
    _set: Option<DescriptorSet>,
    _uploads: Option<super::slot_uploads::SlotUploads>,
    /// Bit s: slot s has not recorded since.
    pub(super) slots_pending: u64,
}

impl ShadowPass<'_> {
    /// Makes room after a frame whose `status` says it overran: the cell
    /// list, the edge surfaces' slots or both (new buffers and a new
    /// descriptor set); whether anything grew.
    pub fn grow(&mut self, status: &PassStatus) -> Result<bool, GpuError> {
        let edges = status.edge_slots_overrun && self.grow_edge_slots(status.edge_slots_needed)?;
        let cells = self.grow_cells(status)?;
        Ok(edges || cells)
    }

    /// Makes the cell list hold half again `status`'s need when it
    /// overran (a new buffer and descriptor set); whether it grew. A frame
    /// slot's status says the need of its own frame; the half again is
    /// for a moving view, whose need changes from frame to frame (grown to
    /// one frame's exact need, the list overruns again on the next larger
    /// one); a pass for one view grows to the exact need, in one buffer
    /// with the BVH it shares (`one_view.rs`). A need past the device's
    /// largest storage buffer is refused by name; the pass goes on exact
    /// the slow way. Frames in flight may still use the old list and set:
    /// they are released once every slot has recorded again.
    fn grow_cells(&mut self, status: &PassStatus) -> Result<bool, GpuError> {
        if !status.cell_list_overrun || status.cell_entries <= self.sizes.cell_capacity {
            return Ok(false);
        }
        let shared = self.renderer.shared();
        let need = status.cell_entries;
        let most = u64::from(shared.limits.max_storage_buffer_range) / 4;
        if need > most {
            return Err(GpuError::Unsupported(format!(
                "the cell list needs {need} entries; this device's storage buffers hold at \
                 most {most}: the frames stay exact the slow way (the overflow list)"
            )));
        }
        let mut buffers = self.buffers.clone();
        let capacity = if self.is_one_view() {
            let nodes = binding::BVH_NODES as usize;
            let shares = Arc::ptr_eq(&buffers[nodes], &buffers[binding::CELL_TRIANGLES as usize]);
            let mut desc = buffers[binding::CELL_TRIANGLES as usize].desc.clone();
            desc.size = (need * 4).max(if shares { self.bvh_node_bytes() } else { 0 });
            let grown = Arc::new(GpuBuffer::new(shared, desc)?);
            if shares {
                buffers[nodes] = grown.clone();
            }
            buffers[binding::CELL_TRIANGLES as usize] = grown;
            need
        } else {
            let capacity = need.saturating_add(need / 2).min(most);
            let desc = BufferDesc::device("bin", "cell_triangles", capacity * 4);
            buffers[binding::CELL_TRIANGLES as usize] = Arc::new(GpuBuffer::new(shared, desc)?);
            capacity
        };
        self.replace_buffers(buffers)?;
        self.sizes.cell_capacity = capacity;
        Ok(true)
    }

    /// Renders `resolution` from the next recorded frame on (a resized
    /// window or render target): the buffers sized by the pixel count —
    /// the G-buffer, masks, receivers, the cell pyramid — are made anew
    /// and the rest (the scene, BVH, LUT, the cell list) kept; whether any
    /// changed. The host's images of the next frames must have the new
    /// size. Frames in flight keep the old buffers until every slot has
    /// recorded again.
    pub fn resize(&mut self, resolution: [u32; 2]) -> Result<bool, GpuError> {
        if resolution == self.scene.resolution {
            return Ok(false);
        }
        crate::scene::check_resolution(resolution).map_err(GpuError::Unsupported)?;
        if self.is_one_view() {
            return Err(GpuError::Unsupported(
                "a pass for one view (an uploaded G-buffer's, or the batch render's) is one \
                 image size's: make the pass again"
                    .into(),
            ));
        }
        let pixels = u64::from(resolution[0]) * u64::from(resolution[1]);
        let settings = self.config.settings;
        let mut sizes = self.sizes;
        sizes.pixels = pixels;
        let limits = &self.renderer.shared().limits;
        sizes.receivers = checked_receivers(limits, resolution, sizes.edge_surfaces)?;
        if sizes.normal_entries != 0 {
            sizes.normal_entries = pixels;
        }
        sizes.tiles = edge_tiles(resolution);
        sizes.max_cells = max_cells(pixels as usize, self.triangles as usize, settings)?;
        self.replace_sized(sizes)?;
        self.scene.resolution = resolution;
        Ok(true)
    }

    /// Makes room for frames of up to `max_triangles` in `max_draws`
    /// draws of the host's geometry (a pass made with
    /// [`ShadowPass::with_host_geometry`]): the buffers sized by them —
    /// the triangles, vertices, normals, draw table, the cell pyramid —
    /// are made anew, the rest kept; whether any changed. Frames in flight
    /// keep the old buffers until every slot has recorded again.
    pub fn reserve_host_geometry(
        &mut self,
        max_triangles: u32,
        max_draws: u32,
    ) -> Result<bool, GpuError> {
        let Some(mut limits) = self.host_geometry() else {
            return Err(GpuError::Unsupported(
                "reserve_host_geometry: this pass holds the scene's triangles".into(),
            ));
        };
        if (limits.max_triangles, limits.max_draws) == (max_triangles, max_draws) {
            return Ok(false);
        }
        let more_draws = max_draws != limits.max_draws;
        (limits.max_triangles, limits.max_draws) = (max_triangles, max_draws);
        limits.check(&self.config)?;
        let mut sizes = self.sizes;
        sizes.triangles = u64::from(max_triangles);
        sizes.vertices = 3 * u64::from(max_triangles);
        sizes.draws = u64::from(max_draws);
        let pixels = sizes.pixels as usize;
        sizes.max_cells = max_cells(pixels, max_triangles as usize, self.config.settings)?;
        self.replace_sized(sizes)?;
        if more_draws {
            // Frames in flight may still copy from the old ring.
            let slots = self.status.len();
            let ring =
                super::slot_uploads::SlotUploads::new(self.renderer.shared(), slots, max_draws)?;
            let old = std::mem::replace(&mut self.uploads, ring);
            self.slot_commands.invalidate();
            self.retired.push(Retired {
                _set: None,
                _uploads: Some(old),
                slots_pending: (1u64 << slots) - 1,
            });
        }
        self.triangles = max_triangles;
        if let Some(h) = &mut self.host_geometry {
            h.config = limits;
            h.table.reserve(max_draws as usize);
        }
        Ok(true)
    }

    /// New buffers for those whose size differs under `sizes`, bound from
    /// the next frame on.
    pub(super) fn replace_sized(
        &mut self,
        sizes: crate::gpu::frame_memory::FrameSizes,
    ) -> Result<(), GpuError> {
        let shared = self.renderer.shared();
        let (old, new) = (frame_buffer_descs(&self.sizes), frame_buffer_descs(&sizes));
        let mut buffers = self.buffers.clone();
        for (b, (was, now)) in old.into_iter().zip(new).enumerate() {
            if was.size != now.size {
                buffers[b] = Arc::new(GpuBuffer::new(shared, now)?);
            }
        }
        self.replace_buffers(buffers)?;
        self.sizes = sizes;
        Ok(())
    }

    /// Descriptor sets (with their buffers) replaced by [`Self::grow`]
    /// or [`Self::resize`] and not released yet.
    pub fn retired_sets(&self) -> usize {
        self.retired.len()
    }

    /// Binds `buffers` through a new descriptor set from the next frame
    /// on and retires the old one.
    fn replace_buffers(
        &mut self,
        buffers: [Arc<GpuBuffer>; super::BINDINGS],
    ) -> Result<(), GpuError> {
        let shared = self.renderer.shared();
        let set = DescriptorSet::new(shared, &self.renderer.layout, buffers.clone())?;
        let old = std::mem::replace(&mut self.set, set);
        self.slot_commands.invalidate();
        self.retired.push(Retired {
            _set: Some(old),
            _uploads: None,
            slots_pending: (1u64 << self.status.len()) - 1,
        });
        self.buffers = buffers;
        Ok(())
    }
}
