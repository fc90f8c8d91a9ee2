//! A frame of the pass recorded into the host's command buffer: the
//! checks and the parameters on the CPU, then three parts in order —
//! the *opening* secondary (the barrier after the previous frame, the
//! parameters' copies, the fills, the vertices' translation), the
//! commands that name the host's objects (their barriers, the set of the
//! host's images and buffers, `gather_draws` and the G-buffer step), the
//! *core* secondary (light setup, bin, evaluate, resolve, the status
//! copy), and last `export_images` into the host's images.
//!
//! The two secondaries are the frame slot's, recorded again only when
//! what they depend on changed (`slot_commands.rs`): most frames record
//! about a dozen commands. With the batch `render`'s step timing on they
//! are recorded straight into the host's command buffer instead (each
//! frame's marks are named as it records).

use super::frame_view::unorm_depth_step;
use super::slot_commands::SegmentsKey;
use super::{slot_uploads, FrameView, GBufferInput, ShadowPass};
use crate::cpu::gather_draws::eye_relative_bounds;
use crate::gpu::frame_inputs::frame_params;
use crate::gpu::frame_memory::reset_pass_state;
use crate::gpu::gather_draws::FrameGeometry;
use crate::gpu::host_images::ImageUse;
use crate::gpu::shared::{binding, LightState};
use crate::gpu::timestamps::StepMarks;
use crate::gpu::{GpuError, Recorder};
use ash::vk;

impl ShadowPass<'_> {
    /// Records frame `slot`'s shadow pass for `view` into `cmd`.
    ///
    /// # Safety
    /// `cmd` is a primary command buffer of this pass's device in the
    /// recording state, outside a render pass and with no query active,
    /// recorded on this thread, submitted to a queue of the device's
    /// compute family after every earlier frame of this pass (frames
    /// execute in submission order: a barrier at the start orders each
    /// after the one before); slot `slot`'s previous frame has finished
    /// executing, and no command buffer that recorded an earlier frame of
    /// this slot is submitted after this call (the slot's secondaries,
    /// which it executes, may be recorded again); the pass outlives this
    /// frame's execution. Each image in `view.images` is a live image and
    /// view of this device, declared truthfully
    /// ([`crate::gpu::host_images::HostImage`]: its layout and last access
    /// when the frame starts executing), alive until the frame has
    /// executed.
    pub unsafe fn record(
        &mut self,
        cmd: vk::CommandBuffer,
        slot: usize,
        view: &FrameView,
    ) -> Result<(), GpuError> {
        // SAFETY: the caller's promise.
        unsafe { self.record_frame(cmd, slot, view, None) }
    }

    /// [`Self::record`] or [`Self::record_host_geometry`]: `geometry`
    /// must be given exactly to a pass made for the host's geometry.
    ///
    /// # Safety
    /// As [`Self::record_host_geometry`]'s.
    pub(super) unsafe fn record_frame(
        &mut self,
        cmd: vk::CommandBuffer,
        slot: usize,
        view: &FrameView,
        geometry: Option<&FrameGeometry>,
    ) -> Result<(), GpuError> {
        if slot >= self.status.len() {
            return Err(GpuError::Unsupported(format!(
                "frame slot {slot}: the pass has {} frames in flight",
                self.status.len()
            )));
        }
        let images = view.images;
        let halves = self.config.settings.mask_halves(&self.scene);
        images.check(self.config.gbuffer.images(), self.scene.resolution, halves)?;
        self.take_view(view)?;
        let drawn = self.take_geometry(geometry)?;
        // This slot's previous frame is done (the caller): what only it
        // still held is released.
        for retired in &mut self.retired {
            retired.slots_pending &= !(1u64 << slot);
        }
        self.retired.retain(|r| r.slots_pending != 0);
        let key = self.write_parameters(slot, &images)?;
        if let (Some(g), Some(h)) = (geometry, &mut self.host_geometry) {
            h.buffer_handles.clear();
            h.buffer_handles.extend(g.buffers.iter().map(|b| b.buffer));
        }
        self.slot_edge_slots[slot] = self.edge_slots();
        let steps = self
            .step_marks
            .as_ref()
            .filter(|_| slot + 1 == self.status.len());
        let segments = match steps {
            Some(_) => None,
            // SAFETY: the slot's previous frame is done and no earlier
            // recording of the slot will be submitted (the caller).
            None => Some(unsafe { self.slot_commands.begin(slot, &key) }?),
        };
        if let Some(s) = segments.filter(|s| s.to_record) {
            // SAFETY: both are begun, recorded on this thread, executed
            // only by this slot's frames (`record`'s promise covers them).
            unsafe {
                self.record_opening(s.opening, slot, &key, None);
                self.record_core(s.core, slot, &key, None);
            }
            self.slot_commands.end(slot, key)?;
        }
        let device = &self.renderer.shared().device;
        // SAFETY: the caller's promise covers `cmd`: a primary command
        // buffer, recording outside a render pass; the secondaries are
        // executable (recorded above or at an earlier frame of the same
        // key) and name only the pass's objects.
        let execute = |secondary| unsafe { device.cmd_execute_commands(cmd, &[secondary]) };
        self.label(cmd, Some("izb_shadow_pass"));
        match segments {
            Some(s) => execute(s.opening),
            // SAFETY: as `record`'s promise.
            None => unsafe { self.record_opening(cmd, slot, &key, steps) },
        }
        // SAFETY: the host declared its images and buffers (checked above
        // and in `take_geometry`) and keeps them alive through the frame;
        // the slot's previous frame, the last user of its set, is done.
        let host_set = unsafe { self.record_host_inputs(cmd, slot, &images, geometry) };
        // SAFETY: as above; `host_set` was written for this frame.
        unsafe { self.record_gbuffer(cmd, host_set, drawn, &key, steps) };
        self.timestamps[slot].write(cmd, 1);
        match segments {
            Some(s) => execute(s.core),
            // SAFETY: as `record`'s promise.
            None => unsafe { self.record_core(cmd, slot, &key, steps) },
        }
        if images.masks.is_some() || images.lit_fraction.is_some() {
            // SAFETY: as above; both sets bound again (no state survives
            // a secondary's execution).
            let rec = unsafe { self.recorder(cmd, steps) };
            // SAFETY: `host_set` was written for this frame and holds the
            // output images, alive through the frame (the caller).
            unsafe { rec.bind_host_images(host_set) };
            let kernels = &self.renderer.kernels;
            crate::gpu::export_images::export_images(&rec, kernels, key.size, &images, halves);
        }
        self.timestamps[slot].write(cmd, 5);
        self.label(cmd, None);
        Ok(())
    }

    /// Opens a debug label `name` on `cmd`, or with `None` closes the one
    /// open (no-op without debug utils).
    fn label(&self, cmd: vk::CommandBuffer, name: Option<&str>) {
        let Some(debug) = &self.renderer.shared().debug_device else {
            return;
        };
        match name {
            Some(name) => {
                let name = std::ffi::CString::new(name).unwrap_or_default();
                let label = vk::DebugUtilsLabelEXT::default().label_name(&name);
                // SAFETY: `cmd` is recording (`record`'s promise); `label`
                // outlives the call.
                unsafe { debug.cmd_begin_debug_utils_label(cmd, &label) };
            }
            // SAFETY: `cmd` is recording, and `record_frame` opened the
            // label it closes.
            None => unsafe { debug.cmd_end_debug_utils_label(cmd) },
        }
    }

    /// A recorder of `cmd` with the pass's set bound, timing `steps`.
    ///
    /// # Safety
    /// As [`Recorder::new`]'s, for `cmd`.
    unsafe fn recorder<'a>(
        &'a self,
        cmd: vk::CommandBuffer,
        steps: Option<&'a StepMarks>,
    ) -> Recorder<'a> {
        let renderer = self.renderer;
        // SAFETY: the caller's promise.
        let mut rec = unsafe { Recorder::new(renderer.shared(), cmd, &renderer.layout, &self.set) };
        if let Some(steps) = steps {
            rec.time_steps(steps);
        }
        rec
    }

    /// The frame's parameters, light state's start and draw table written
    /// through slot `slot`'s mapping, and the key of the commands that
    /// copy them and run the frame.
    fn write_parameters(
        &mut self,
        slot: usize,
        images: &crate::gpu::host_images::FrameImages,
    ) -> Result<SegmentsKey, GpuError> {
        let renderer = self.renderer;
        let shared = renderer.shared();
        let settings = self.config.settings;
        let scene = &self.scene;
        let mut params = frame_params(
            scene,
            settings,
            self.frame_triangles as usize,
            self.sizes.max_cells,
            self.sizes.cell_capacity,
            self.loop_budget,
            renderer.heavy_entries(),
        );
        // Nothing reruns a recorded frame (but the batch `render`'s
        // first): an overrun stays exact.
        params.overrun_exact = u32::from(self.overrun_exact);
        if let Some(w) = &self.world {
            [params.eye_hi, params.eye_lo] = w.eye(scene.camera.eye).map(|v| v.to_array());
            params.world_vertex_count = w.pairs.len() as u32;
            params.world_node_count = w.bvh_nodes;
        }
        if let GBufferInput::DepthNormal(c) = self.config.gbuffer {
            params.depth_near = c.near as f32;
            params.depth_near_over_far = c.near_over_far() as f32;
            params.depth_span = (1.0 - c.near_over_far()) as f32;
            params.depth_reversed = u32::from(c.reversed);
            params.depth_step = images.depth.map_or(0.0, |d| unorm_depth_step(d.format));
        }
        self.edge_params(&mut params);
        let [w, h] = scene.resolution;
        let rows = [w, self.receiver_rows()];
        if let Some(h) = &self.host_geometry {
            params.draw_count = h.table.len() as u32;
            let [lo, hi] = eye_relative_bounds(self.bounds, scene.camera.eye);
            (params.bounds_lo, params.bounds_hi) = (lo.to_array(), hi.to_array());
        }
        let draws = self
            .host_geometry
            .as_ref()
            .map_or(&[][..], |h| &h.table[..]);
        let key = SegmentsKey {
            size: [w, h],
            rows,
            frame_triangles: self.frame_triangles,
            max_cells: self.sizes.max_cells,
            gather: settings.skips.behind_receivers.then_some(rows[0] * rows[1]),
            heavy: crate::gpu::evaluate::heavy_step(&params, &shared.info),
            halves: settings.mask_halves(scene),
            traced_edges: self.traced_edge_slots().is_some(),
            draws: draws.len(),
        };
        // SAFETY: the slot's previous frame, the ring's last reader, is
        // done (`record`'s promise).
        unsafe {
            let parts = (&params, &LightState::reset(), draws);
            self.uploads.write(slot, parts)
        }?;
        Ok(key)
    }

    /// The opening: the barrier after the previous frame, the parameters'
    /// copies, the one-view BVH's restaging, the fills, the first
    /// timestamp and the vertices' translation.
    ///
    /// # Safety
    /// `cmd` is recording on this thread, outside a render pass; it runs
    /// after the slot's previous frame and before the pass is dropped.
    unsafe fn record_opening(
        &self,
        cmd: vk::CommandBuffer,
        slot: usize,
        key: &SegmentsKey,
        steps: Option<&StepMarks>,
    ) {
        let device = &self.renderer.shared().device;
        let buffer = |b: u32| self.buffers[b as usize].buffer;
        // SAFETY: the caller's promise; the set and kernels are the pass's.
        let mut rec = unsafe { self.recorder(cmd, None) };
        rec.begin_label("izb_opening");
        let timestamps = &self.timestamps[slot];
        timestamps.reset(cmd);
        // The previous frame's reads and writes of every buffer are done
        // before this frame's.
        rec.barrier();
        let targets = slot_uploads::UploadTargets {
            frame: buffer(binding::FRAME),
            light: buffer(binding::LIGHT),
            draws: buffer(binding::DRAWS),
        };
        let uploads = &self.uploads;
        // SAFETY: the caller's promise; the targets are the pass's, sized
        // for a frame's parameters and its draws.
        unsafe { uploads.record_copies(device, cmd, slot, key.draws, targets) };
        if let Some(bvh) = &self.restaged_bvh {
            // SAFETY: as above; the previous frame's bin, which overwrote
            // the BVH's buffers, is done (the barrier above).
            unsafe { bvh.record(device, cmd, buffer) };
        }
        reset_pass_state(device, cmd, buffer, key.traced_edges);
        rec.barrier();
        timestamps.write(cmd, 0);
        if let Some(steps) = steps {
            steps.reset(cmd);
            steps.mark(cmd, "start");
            rec.time_steps(steps);
        }
        if let Some(w) = &self.world {
            let threads = (w.pairs.len() as u32).max(w.bvh_nodes);
            let kernels = &self.renderer.kernels;
            crate::gpu::translate_vertices::translate_vertices(&rec, kernels, threads);
        }
        rec.end_label();
    }

    /// The host's images and buffers made visible to the pass, and the
    /// slot's set of them written; the set (bound by whoever dispatches
    /// with it), or a null handle when the frame has none.
    ///
    /// # Safety
    /// `cmd` is recording on this thread; the host declared its images and
    /// buffers truthfully and keeps them alive through the frame; the
    /// slot's previous frame, the last user of its set, is done.
    unsafe fn record_host_inputs(
        &self,
        cmd: vk::CommandBuffer,
        slot: usize,
        images: &crate::gpu::host_images::FrameImages,
        geometry: Option<&FrameGeometry>,
    ) -> vk::DescriptorSet {
        let device = &self.renderer.shared().device;
        let host = [
            (images.visibility, ImageUse::Read),
            (images.depth, ImageUse::Read),
            (images.normal, ImageUse::Read),
            (images.masks, ImageUse::Write),
            (images.lit_fraction, ImageUse::Write),
        ];
        if let (Some(g), Some(h)) = (geometry, &self.host_geometry) {
            // SAFETY: the caller's promise; `record_frame` took the
            // frame's buffer handles.
            unsafe {
                crate::gpu::gather_draws::acquire(device, cmd, g.buffers);
                self.host_sets.write_geometry(slot, &h.buffer_handles);
            }
        }
        if self.host_geometry.is_none() && host.iter().all(|(image, _)| image.is_none()) {
            return vk::DescriptorSet::null();
        }
        // SAFETY: the caller's promise.
        unsafe {
            for (image, usage) in &host {
                if let Some(image) = image {
                    crate::gpu::host_images::acquire(device, cmd, image, *usage);
                }
            }
            self.host_sets.write(slot, images);
        }
        self.host_sets.handle(slot)
    }

    /// The host's draws gathered (`drawn`: their triangles) and the
    /// G-buffer step of the pass's input; `host_set`: the frame's set of
    /// the host's images and buffers (null without).
    ///
    /// # Safety
    /// As [`Self::record_opening`]'s; `host_set` is written for this frame
    /// and holds the images and buffers the steps read.
    unsafe fn record_gbuffer(
        &self,
        cmd: vk::CommandBuffer,
        host_set: vk::DescriptorSet,
        drawn: Option<u32>,
        key: &SegmentsKey,
        steps: Option<&StepMarks>,
    ) {
        let k = &self.renderer.kernels;
        let (size, edges) = (key.size, key.traced_edges);
        // SAFETY: the caller's promise.
        let rec = unsafe { self.recorder(cmd, steps) };
        if host_set != vk::DescriptorSet::null() {
            // SAFETY: the caller's promise.
            unsafe { rec.bind_host_images(host_set) };
        }
        if let Some(triangles) = drawn {
            crate::gpu::gather_draws::gather_draws(&rec, k, triangles);
        }
        use crate::gpu::gbuffer as g;
        match self.config.gbuffer {
            GBufferInput::RayCast => g::gbuffer(&rec, k, size, edges),
            GBufferInput::Visibility => g::gbuffer_from_visibility(&rec, k, size),
            GBufferInput::MultisampledVisibility { .. } => {
                g::gbuffer_from_multisampled_visibility(&rec, k, size, edges)
            }
            GBufferInput::DepthNormal(_) => g::gbuffer_from_depth(&rec, k, size),
            // Written when the pass was made.
            GBufferInput::Uploaded => {}
        }
    }

    /// The core: light setup, bin, evaluate and resolve with their
    /// timestamps, then the counters copied into the slot's status buffer.
    ///
    /// # Safety
    /// As [`Self::record_opening`]'s.
    unsafe fn record_core(
        &self,
        cmd: vk::CommandBuffer,
        slot: usize,
        key: &SegmentsKey,
        steps: Option<&StepMarks>,
    ) {
        let renderer = self.renderer;
        let kernels = &renderer.kernels;
        let timestamps = &self.timestamps[slot];
        // SAFETY: the caller's promise.
        let rec = unsafe { self.recorder(cmd, steps) };
        rec.begin_label("izb_core");
        crate::gpu::light_setup::light_setup(&rec, kernels, key.rows);
        timestamps.write(cmd, 2);
        let (triangles, cells) = (key.frame_triangles, key.max_cells);
        crate::gpu::bin::bin(&rec, kernels, triangles, cells, key.gather);
        timestamps.write(cmd, 3);
        crate::gpu::evaluate::evaluate(&rec, kernels, key.rows, key.heavy, key.halves);
        timestamps.write(cmd, 4);
        crate::gpu::resolve::resolve(&rec, kernels, key.size);
        let status = &self.status[slot];
        let counters = self.buffers[binding::COUNTERS as usize].buffer;
        let region = [vk::BufferCopy::default().size(status.size())];
        let device = &renderer.shared().device;
        // SAFETY: `cmd` is recording; the status buffer is the counters'
        // size and the slot's previous frame is done (the caller).
        unsafe {
            device.cmd_copy_buffer(cmd, counters, status.buffer, &region);
            crate::gpu::transfers_visible_to_host(device, cmd);
        }
        rec.end_label();
    }
}
