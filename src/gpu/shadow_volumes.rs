//! Shadow volumes on the hardware rasteriser, counted depth-fail in the
//! stencil buffer: the twin of [`crate::baseline::volumes`].
//!
//! A frame: the G-buffer and light setup as for the other methods, then
//! `volume_depth` (compute) writes every receiver's depth into a buffer,
//! which is copied into the depth aspect of a D32_SFLOAT_S8_UINT
//! attachment; one render pass draws 24 vertices per triangle
//! (`shaders/shadow_volume.vert`: light cap, dark cap, sides) with the
//! depth test GREATER and no depth writes, back faces incrementing and
//! front faces decrementing the stencil where the depth test fails; the
//! stencil bytes are copied back behind the depths, and `volume_lookup`
//! turns a count of 0 into lit.

use super::context::DeviceShared;
use super::frame::{GBufferSource, GpuRenderer, GpuShadowMapRender};
use super::frame_report::BaselinePasses;
use super::pipeline::BindingLayout;
use super::shadow_raster::{
    depth_pipeline, depth_render_pass, require_format, vertex_spirv, whole_target, DepthAttachment,
    DepthPipelineDesc,
};
use super::{GpuError, Kernels, Recorder};
use crate::scene::Scene;
use ash::vk;
use std::sync::Arc;

/// Depth for the receivers, stencil for the count.
pub const DEPTH_STENCIL_FORMAT: vk::Format = vk::Format::D32_SFLOAT_S8_UINT;

/// The render pass and pipeline of the volumes' stencil pass.
pub struct VolumeRaster {
    shared: Arc<DeviceShared>,
    render_pass: vk::RenderPass,
    pipeline: vk::Pipeline,
}

impl VolumeRaster {
    /// Builds the pass, or says why this device cannot draw it.
    pub fn new(shared: &Arc<DeviceShared>, layout: &BindingLayout) -> Result<Self, GpuError> {
        if let Some(why) = &shared.raster_missing {
            return Err(GpuError::Unsupported(why.clone()));
        }
        let needed = vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT
            | vk::FormatFeatureFlags::TRANSFER_SRC
            | vk::FormatFeatureFlags::TRANSFER_DST;
        let what = "render D32_SFLOAT_S8_UINT and copy it in and out";
        require_format(shared, DEPTH_STENCIL_FORMAT, needed, what)?;
        let attachment = vk::AttachmentDescription::default()
            .format(DEPTH_STENCIL_FORMAT)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::DONT_CARE)
            .stencil_load_op(vk::AttachmentLoadOp::CLEAR)
            .stencil_store_op(vk::AttachmentStoreOp::STORE)
            .initial_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
            .final_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
        // Before: the receivers' depths were copied in.
        let render_pass = depth_render_pass(
            shared,
            attachment,
            vk::AccessFlags::TRANSFER_WRITE,
            "shadow_volumes stencil pass",
        )?;
        let mut raster = VolumeRaster {
            shared: shared.clone(),
            render_pass,
            pipeline: vk::Pipeline::null(),
        };
        let count = |depth_fail_op| {
            vk::StencilOpState::default()
                .fail_op(vk::StencilOp::KEEP)
                .pass_op(vk::StencilOp::KEEP)
                .depth_fail_op(depth_fail_op)
                .compare_op(vk::CompareOp::ALWAYS)
                .compare_mask(0xFF)
                .write_mask(0xFF)
                .reference(0)
        };
        let desc = DepthPipelineDesc {
            name: "shadow_volumes",
            depth_clamp: false,
            depth_bias: false,
            depth_write: false,
            // Reversed depth: a face passes where it is in front of the
            // receiver; the count runs where it is not (depth-fail).
            compare: vk::CompareOp::GREATER,
            stencil: Some((
                count(vk::StencilOp::DECREMENT_AND_WRAP),
                count(vk::StencilOp::INCREMENT_AND_WRAP),
            )),
        };
        let spirv = vertex_spirv("shadow_volume")?;
        raster.pipeline = depth_pipeline(shared, layout, render_pass, spirv, &desc)?;
        Ok(raster)
    }

    /// The frame's attachment: one layer at the image's size.
    pub fn attachment(&self, size: [u32; 2]) -> Result<DepthAttachment, GpuError> {
        let usage = vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::TRANSFER_DST;
        let aspect = vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL;
        DepthAttachment::with_format(
            &self.shared,
            self.render_pass,
            (DEPTH_STENCIL_FORMAT, aspect, usage),
            size,
            1,
            "shadow_volumes depth and stencil",
        )
    }
}

impl Drop for VolumeRaster {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: frames wait for their fence, so no command buffer using
        // these is pending; destroying a null pipeline is a no-op.
        unsafe {
            self.shared.device.destroy_pipeline(self.pipeline, None);
            self.shared
                .device
                .destroy_render_pass(self.render_pass, None);
        }
    }
}

fn copy_region(size: [u32; 2], offset: u64, aspect: vk::ImageAspectFlags) -> vk::BufferImageCopy {
    vk::BufferImageCopy::default()
        .buffer_offset(offset)
        .buffer_row_length(size[0])
        .buffer_image_height(size[1])
        .image_subresource(
            vk::ImageSubresourceLayers::default()
                .aspect_mask(aspect)
                .mip_level(0)
                .base_array_layer(0)
                .layer_count(1),
        )
        .image_extent(vk::Extent3D {
            width: size[0],
            height: size[1],
            depth: 1,
        })
}

/// Records the stencil pass over `triangles` volumes: the receivers'
/// depths (`volume_depth`), their copy into the attachment, the draw,
/// the stencil's copy out; the lookup, [`volume_lookup`], follows.
pub fn shadow_volumes(
    rec: &Recorder,
    kernels: &Kernels,
    raster: &VolumeRaster,
    target: &DepthAttachment,
    buffer: vk::Buffer,
    triangles: u32,
) {
    rec.begin_label("shadow_volumes");
    let size = target.extent;
    rec.dispatch_pixels(&kernels.volume_depth, size);
    rec.barrier();
    let d = &rec.shared().device;
    let cmd = rec.cmd();
    let pixels = u64::from(size[0]) * u64::from(size[1]);
    let whole = vk::ImageSubresourceRange::default()
        .aspect_mask(vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL)
        .level_count(1)
        .layer_count(1);
    let to_copy = [vk::ImageMemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_READ)
        .dst_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .old_layout(vk::ImageLayout::UNDEFINED)
        .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(target.image)
        .subresource_range(whole)];
    let to_vertex = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::SHADER_READ)];
    // Depth is loaded (the receivers'), only the stencil clears.
    let (area, viewport, clear) = whole_target(size, 0.0);
    // SAFETY: `cmd` is recording (inside the frame's submission); the
    // image, framebuffer, pipeline, layout, set and buffer outlive the
    // frame's fence wait; the copies stay inside the buffer (its first
    // `pixels` words are the depths, the stencil bytes follow).
    unsafe {
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &to_copy,
        );
        let depth_in = [copy_region(size, 0, vk::ImageAspectFlags::DEPTH)];
        d.cmd_copy_buffer_to_image(
            cmd,
            buffer,
            target.image,
            vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            &depth_in,
        );
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::VERTEX_SHADER,
            vk::DependencyFlags::empty(),
            &to_vertex,
            &[],
            &[],
        );
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(raster.render_pass)
            .framebuffer(target.framebuffers[0])
            .render_area(area)
            .clear_values(&clear);
        d.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE);
        d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, raster.pipeline);
        d.cmd_bind_descriptor_sets(
            cmd,
            vk::PipelineBindPoint::GRAPHICS,
            rec.binding().0,
            0,
            &[rec.binding().1],
            &[],
        );
        d.cmd_set_viewport(cmd, 0, &viewport);
        d.cmd_set_scissor(cmd, 0, &[area]);
        // The bias is dynamic state of every depth pipeline
        // (`shadow_raster::depth_pipeline`), so it must be set even
        // though the volumes want none.
        d.cmd_set_depth_bias(cmd, 0.0, 0.0, 0.0);
        d.cmd_draw(cmd, 24 * triangles, 1, 0, 0);
        d.cmd_end_render_pass(cmd);
        let stencil_out = [copy_region(size, pixels * 4, vk::ImageAspectFlags::STENCIL)];
        d.cmd_copy_image_to_buffer(
            cmd,
            target.image,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            buffer,
            &stencil_out,
        );
    }
    rec.mark("shadow_volumes");
    rec.barrier();
    rec.end_label();
}

/// Records the lookup: one invocation per pixel.
pub fn volume_lookup(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("volume_lookup");
    rec.dispatch_pixels(&kernels.volume_lookup, size);
    rec.barrier();
    rec.end_label();
}

impl GpuRenderer {
    /// The volumes' pass and an attachment for `scene`, or why not.
    pub(super) fn volume_target(
        &self,
        scene: &Scene,
    ) -> Result<(&VolumeRaster, DepthAttachment), GpuError> {
        let raster = self.volume_raster.as_ref().map_err(|why| {
            GpuError::Unsupported(format!("volumes draw on the rasteriser, and {why}"))
        })?;
        Ok((raster, raster.attachment(scene.resolution)?))
    }

    /// Renders `volumes` on the GPU: the IZB's G-buffer and light setup,
    /// then the volumes' passes; the twin of
    /// [`crate::baseline::volumes::shadow_volumes`].
    pub fn render_shadow_volumes(
        &self,
        scene: &Scene,
        source: GBufferSource,
    ) -> Result<GpuShadowMapRender, GpuError> {
        let passes = BaselinePasses::Volumes;
        let (upload, out, bytes) = self.run_baseline_frame(scene, source, 1, passes, "volumes")?;
        Ok(GpuShadowMapRender::from_frame(
            scene, source, &upload, out, bytes,
        ))
    }
}
