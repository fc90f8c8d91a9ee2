//! The shadow pass's test host (`izb::gpu::shadow_pass`): its renderer
//! (synchronization validation on whenever validation is), frames whose
//! camera and light move, one frame per submission, and the host's own
//! input images (an `R32_UINT` visibility buffer, or a depth and a normal)
//! filled before each frame.

use super::gpu::own_renderer;
use ash::vk;
use glam::DMat3;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use izb::cpu::{IzbSettings, SampleMode};
use izb::gpu::context::DeviceShared;
use izb::gpu::host_images::{format_aspects, FrameImages, HostImage};
use izb::gpu::resources::GpuBuffer;
use izb::gpu::shadow_pass::{FrameView, ShadowPass};
use izb::gpu::{GpuError, GpuOptions, GpuRenderer};
use izb::scene::{Light, Scene};
use std::sync::Arc;
use std::time::Instant;

pub fn pass_renderer() -> Option<GpuRenderer> {
    let mut options = GpuOptions::from_env();
    options.sync_validation = options.validation;
    own_renderer(&options)
}

pub fn settings(mode: SampleMode) -> IzbSettings {
    IzbSettings {
        mode,
        edge_surfaces: false,
        ..Default::default()
    }
}

/// Frame `k`'s view: the light turned by 2° a frame about the camera's
/// up axis, the camera turned by 0.2° a frame about its eye.
pub fn view_at(scene: &Scene, k: usize) -> FrameView {
    let up = scene.camera.up.normalize();
    let light_turn = DMat3::from_axis_angle(up, (2.0 * k as f64).to_radians());
    let look_turn = DMat3::from_axis_angle(up, (0.2 * k as f64).to_radians());
    let light = match scene.light {
        Light::Directional { direction } => Light::Directional {
            direction: light_turn * direction,
        },
        Light::Point { position } => Light::Point {
            position: light_turn * position,
        },
    };
    let mut camera = scene.camera;
    camera.target = camera.eye + look_turn * (camera.target - camera.eye);
    FrameView {
        camera,
        light,
        light_radius: scene.light_radius,
        images: FrameImages::default(),
    }
}

pub fn scene_at(scene: &Scene, view: &FrameView) -> Scene {
    let mut s = scene.clone();
    (s.camera, s.light, s.light_radius) = (view.camera, view.light, view.light_radius);
    s
}

/// Records frame `k` into its own submission and waits (the test's
/// host: one frame at a time, slots alternating).
pub fn run_frame(r: &GpuRenderer, pass: &mut ShadowPass, k: usize, view: &FrameView) -> f64 {
    let slot = k % pass.frames_in_flight();
    let mut micros = 0.0;
    let record = |cmd| {
        let start = Instant::now();
        // SAFETY: `cmd` is recording on this thread and is submitted to
        // the pass's device after every earlier frame; the wait below
        // ends every earlier frame, and the pass outlives this one.
        let recorded = unsafe { pass.record(cmd, slot, view) };
        micros = start.elapsed().as_secs_f64() * 1e6;
        recorded
    };
    // SAFETY: the pass and its buffers outlive the call, which waits.
    unsafe { r.context.submit_and_wait(record) }.unwrap();
    micros
}

/// An image of the test host's: the `R32_UINT` visibility buffer (filled
/// by a copy recorded before each frame) or an output the pass writes
/// (copied out after it); made once, freed after the device has idled
/// (the renderer's submissions wait).
pub struct HostTestImage {
    shared: Arc<DeviceShared>,
    pub image: vk::Image,
    pub view: vk::ImageView,
    allocation: Option<Allocation>,
    pub extent: [u32; 2],
    format: vk::Format,
    usage: vk::ImageUsageFlags,
    /// Where the previous frame left it (`HostImage::layout_after`).
    layout: vk::ImageLayout,
}

impl HostTestImage {
    /// A visibility buffer (`R32_UINT`, sampled, filled by copies).
    pub fn visibility(shared: &Arc<DeviceShared>, extent: [u32; 2]) -> Self {
        Self::input(shared, extent, vk::Format::R32_UINT)
    }

    /// An input of `format` (sampled, filled by copies): a depth image's
    /// view has the depth aspect alone.
    pub fn input(shared: &Arc<DeviceShared>, extent: [u32; 2], format: vk::Format) -> Self {
        Self::new(shared, extent, format, Self::USAGE)
    }

    /// The aspect a view and a copy of the image name: depth for a depth
    /// format, else colour.
    fn view_aspect(&self) -> vk::ImageAspectFlags {
        if format_aspects(self.format) == vk::ImageAspectFlags::COLOR {
            vk::ImageAspectFlags::COLOR
        } else {
            vk::ImageAspectFlags::DEPTH
        }
    }

    /// An output of `format` (storage, copied out).
    pub fn output(shared: &Arc<DeviceShared>, extent: [u32; 2], format: vk::Format) -> Self {
        let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
        Self::new(shared, extent, format, usage)
    }

    pub fn new(
        shared: &Arc<DeviceShared>,
        extent: [u32; 2],
        format: vk::Format,
        usage: vk::ImageUsageFlags,
    ) -> Self {
        Self::with_samples(shared, extent, format, usage, vk::SampleCountFlags::TYPE_1)
    }

    /// [`Self::new`] with `samples` samples a pixel.
    pub fn with_samples(
        shared: &Arc<DeviceShared>,
        extent: [u32; 2],
        format: vk::Format,
        usage: vk::ImageUsageFlags,
        samples: vk::SampleCountFlags,
    ) -> Self {
        let d = &shared.device;
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(samples)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: `info` outlives the call.
        let image = unsafe { d.create_image(&info, None) }.unwrap();
        // SAFETY: `image` was just created on this device.
        let requirements = unsafe { d.get_image_memory_requirements(image) };
        let allocation = shared
            .allocator
            .lock()
            .unwrap()
            .allocate(&AllocationCreateDesc {
                name: "test host image",
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .unwrap();
        // SAFETY: made for this image's requirements; not bound yet.
        unsafe { d.bind_image_memory(image, allocation.memory(), allocation.offset()) }.unwrap();
        let view_aspect = if format_aspects(format) == vk::ImageAspectFlags::COLOR {
            vk::ImageAspectFlags::COLOR
        } else {
            vk::ImageAspectFlags::DEPTH
        };
        let range = vk::ImageSubresourceRange::default()
            .aspect_mask(view_aspect)
            .level_count(1)
            .layer_count(1);
        let info = vk::ImageViewCreateInfo::default()
            .image(image)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(format)
            .subresource_range(range);
        // SAFETY: `image` is bound; `info` outlives the call.
        let view = unsafe { d.create_image_view(&info, None) }.unwrap();
        HostTestImage {
            shared: shared.clone(),
            image,
            view,
            allocation: Some(allocation),
            extent,
            format,
            usage,
            layout: vk::ImageLayout::UNDEFINED,
        }
    }

    /// A visibility buffer's usage.
    pub const USAGE: vk::ImageUsageFlags = vk::ImageUsageFlags::from_raw(
        vk::ImageUsageFlags::SAMPLED.as_raw() | vk::ImageUsageFlags::TRANSFER_DST.as_raw(),
    );

    /// Records the copy of `staging` (a texel per pixel; a depth image's
    /// depth aspect, 4 bytes a texel) into the image —
    /// after the previous frame's reads, as the contract asks of a host's
    /// later write — and returns the image as the next frame declares it.
    ///
    /// # Safety
    /// `cmd` is recording on this image's device; `staging` outlives its
    /// execution.
    pub unsafe fn record_fill(&mut self, cmd: vk::CommandBuffer, staging: &GpuBuffer) -> HostImage {
        let d = &self.shared.device;
        let range = vk::ImageSubresourceRange::default()
            .aspect_mask(format_aspects(self.format))
            .level_count(1)
            .layer_count(1);
        let to_transfer = [vk::ImageMemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::empty())
            .dst_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .old_layout(self.layout)
            .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(self.image)
            .subresource_range(range)];
        let region = [vk::BufferImageCopy::default()
            .image_subresource(
                vk::ImageSubresourceLayers::default()
                    .aspect_mask(self.view_aspect())
                    .layer_count(1),
            )
            .image_extent(vk::Extent3D {
                width: self.extent[0],
                height: self.extent[1],
                depth: 1,
            })];
        // SAFETY: the caller's promise; the barrier waits for the previous
        // frame's compute-shader reads (write-after-read).
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &to_transfer,
            );
            d.cmd_copy_buffer_to_image(
                cmd,
                staging.buffer,
                self.image,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &region,
            );
        }
        let declared = HostImage {
            image: self.image,
            view: self.view,
            format: self.format,
            extent: self.extent,
            usage: self.usage,
            samples: vk::SampleCountFlags::TYPE_1,
            layout: vk::ImageLayout::TRANSFER_DST_OPTIMAL,
            written_by: (
                vk::PipelineStageFlags::TRANSFER,
                vk::AccessFlags::TRANSFER_WRITE,
            ),
        };
        self.layout = declared.layout_after();
        declared
    }
}

impl HostTestImage {
    /// The output as the next frame declares it: where the last frame (or
    /// nothing) left it, last read by the copy out.
    pub fn as_output(&self) -> HostImage {
        let written_by = if self.layout == vk::ImageLayout::UNDEFINED {
            (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty())
        } else {
            (
                vk::PipelineStageFlags::TRANSFER,
                vk::AccessFlags::TRANSFER_READ,
            )
        };
        HostImage {
            image: self.image,
            view: self.view,
            format: self.format,
            extent: self.extent,
            usage: self.usage,
            samples: vk::SampleCountFlags::TYPE_1,
            layout: self.layout,
            written_by,
        }
    }

    /// Records the copy of the output the pass just wrote (left in
    /// `GENERAL`) into `to`, made visible to the host; the image is left
    /// in `TRANSFER_SRC_OPTIMAL`, which the next frame declares.
    ///
    /// # Safety
    /// `cmd` is recording on this image's device, after the frame that
    /// wrote the image; `to` outlives its execution.
    pub unsafe fn record_copy_out(&mut self, cmd: vk::CommandBuffer, to: &GpuBuffer) {
        let d = &self.shared.device;
        let written = [vk::ImageMemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
            .old_layout(vk::ImageLayout::GENERAL)
            .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(self.image)
            .subresource_range(
                vk::ImageSubresourceRange::default()
                    .aspect_mask(vk::ImageAspectFlags::COLOR)
                    .level_count(1)
                    .layer_count(1),
            )];
        let region = [vk::BufferImageCopy::default()
            .image_subresource(
                vk::ImageSubresourceLayers::default()
                    .aspect_mask(vk::ImageAspectFlags::COLOR)
                    .layer_count(1),
            )
            .image_extent(vk::Extent3D {
                width: self.extent[0],
                height: self.extent[1],
                depth: 1,
            })];
        let to_host = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::HOST_READ)];
        // SAFETY: the caller's promise; the pass left the image in GENERAL
        // (`host_images`' contract), written by compute shaders.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &written,
            );
            d.cmd_copy_image_to_buffer(
                cmd,
                self.image,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                to.buffer,
                &region,
            );
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &to_host,
                &[],
                &[],
            );
        }
        self.layout = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
    }
}

impl Drop for HostTestImage {
    fn drop(&mut self) {
        // SAFETY: every submission that used the image was waited for.
        unsafe {
            self.shared.device.destroy_image_view(self.view, None);
            self.shared.device.destroy_image(self.image, None);
        }
        if let Some(a) = self.allocation.take() {
            let _ = self.shared.allocator.lock().unwrap().free(a);
        }
    }
}

/// Frame `k`'s visibility ids copied into the host's image and the pass
/// recorded after them, in one command buffer; returns the pass's record
/// time in µs and the buffers and sets made while recording.
pub fn run_visibility_frame(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    image: &mut HostTestImage,
    k: usize,
    view: &FrameView,
    ids: &[u32],
) -> Result<(f64, [u64; 2]), GpuError> {
    let shared = &r.context.shared;
    let staging = GpuBuffer::staging(shared, bytemuck::cast_slice(ids))?;
    let slot = k % pass.frames_in_flight();
    let (mut micros, mut made) = (0.0, [0; 2]);
    let record = |cmd| {
        // SAFETY: `cmd` is recording; the staging buffer outlives the
        // submission, which the call waits for.
        let declared = unsafe { image.record_fill(cmd, &staging) };
        let view = FrameView {
            images: FrameImages {
                visibility: Some(declared),
                ..view.images
            },
            ..*view
        };
        let before = shared.allocations();
        let start = Instant::now();
        // SAFETY: as in `run_frame`; the image lives until the wait.
        let recorded = unsafe { pass.record(cmd, slot, &view) };
        micros = start.elapsed().as_secs_f64() * 1e6;
        let after = shared.allocations();
        made = [after[0] - before[0], after[1] - before[1]];
        recorded
    };
    // SAFETY: the pass, the image and the staging buffer outlive the
    // call, which waits.
    unsafe { r.context.submit_and_wait(record) }?;
    Ok((micros, made))
}

/// Records `view` into frame slot `slot` expecting a refusal before any
/// command (the empty command buffer is still submitted, which the
/// validation layer sees) and asserts its message says `said`.
pub fn assert_refused(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    slot: usize,
    view: &FrameView,
    said: &str,
) {
    let mut error = None;
    let record = |cmd| {
        // SAFETY: `cmd` is recording on this thread and submitted to the
        // pass's device after every earlier frame; the wait below ends
        // it, and the pass and the view's images outlive it.
        error = unsafe { pass.record(cmd, slot, view) }.err();
        Ok(())
    };
    // SAFETY: the pass outlives the call, which waits.
    unsafe { r.context.submit_and_wait(record) }.unwrap();
    let e = error.unwrap_or_else(|| panic!("{said}: recorded"));
    assert!(e.to_string().contains(said), "{said}: {e}");
}
