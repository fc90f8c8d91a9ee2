//! The IZB as a pass recorded into the caller's command buffers
//! (`izb::gpu::shadow_pass`): made once, then per frame only commands —
//! no buffer, descriptor set, mapping, wait or read-back — with masks
//! bit-identical to `GpuRenderer::render`'s for the same view, a cell
//! list that overruns staying exact and growing between frames, and bad
//! views refused by name. With `IZB_VALIDATION=1` the device runs the
//! validation layer with synchronization validation, and any message
//! fails the test. No Vulkan device: the test prints that it skipped,
//! unless `IZB_REQUIRE_GPU=1`.

mod common;

use ash::vk;
use common::gpu::{assert_no_validation_messages, own_renderer};
use glam::{DMat3, DVec3};
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use izb::cpu::{IzbSettings, SampleMode};
use izb::gpu::context::DeviceShared;
use izb::gpu::host_images::HostImage;
use izb::gpu::resources::GpuBuffer;
use izb::gpu::shadow_pass::{FrameView, GBufferInput, ShadowPass, ShadowPassConfig};
use izb::gpu::{GBufferSource, GpuError, GpuOptions, GpuRenderer};
use izb::scene::{self, Light, Scene};
use std::sync::Arc;
use std::time::Instant;

/// Frames recorded per mode.
const FRAMES: usize = 30;
/// Every this many frames, the pass's masks are compared with `render`'s.
const COMPARE_EVERY: usize = 10;

fn pass_renderer() -> Option<GpuRenderer> {
    let mut options = GpuOptions::from_env();
    options.sync_validation = options.validation;
    own_renderer(&options)
}

fn settings(mode: SampleMode) -> IzbSettings {
    IzbSettings {
        mode,
        edge_surfaces: false,
        ..Default::default()
    }
}

/// Frame `k`'s view: the light turned by 2° a frame about the camera's
/// up axis, the camera turned by 0.2° a frame about its eye.
fn view_at(scene: &Scene, k: usize) -> FrameView {
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
        visibility: None,
    }
}

fn scene_at(scene: &Scene, view: &FrameView) -> Scene {
    let mut s = scene.clone();
    (s.camera, s.light, s.light_radius) = (view.camera, view.light, view.light_radius);
    s
}

/// Records frame `k` into its own submission and waits (the test's
/// host: one frame at a time, slots alternating).
fn run_frame(r: &GpuRenderer, pass: &mut ShadowPass, k: usize, view: &FrameView) -> f64 {
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

#[test]
fn a_resident_pass_records_frames_equal_to_render_allocating_nothing() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let mut compared = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            gbuffer: GBufferInput::RayCast,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let mut record_us = Vec::new();
        let (mut buffers, mut sets) = (0, 0);
        for k in 0..FRAMES {
            let view = view_at(&scene, k);
            let before = r.context.shared.allocations();
            record_us.push(run_frame(&r, &mut pass, k, &view));
            let after = r.context.shared.allocations();
            buffers += after[0] - before[0];
            sets += after[1] - before[1];
            // SAFETY: the frame's submission was waited for.
            let status = unsafe { pass.status(k % 2) }.unwrap();
            assert!(
                !status.cell_list_overrun && status.loop_cap_trips == 0,
                "{status:?}"
            );
            if k % COMPARE_EVERY == 0 {
                // SAFETY: nothing of the pass is executing.
                let images = unsafe { pass.read_back() }.unwrap();
                let moved = scene_at(&scene, &view);
                let batch = r.render(&moved, s, GBufferSource::Gpu).unwrap();
                assert_eq!(images.masks, batch.masks, "{mode:?}, frame {k}");
                assert_eq!(status.shadow_tested, batch.report.counters.shadow_tested);
                compared += 1;
            }
        }
        record_us.sort_by(f64::total_cmp);
        println!(
            "{mode:?}: {FRAMES} frames, record median {:.1} µs (max {:.1}); buffers {buffers}, \
             descriptor sets {sets} made while recording",
            record_us[FRAMES / 2],
            record_us[FRAMES - 1]
        );
        assert_eq!(
            (buffers, sets),
            (0, 0),
            "{mode:?}: allocations inside frames"
        );
        assert_no_validation_messages(&r, "shadow pass");
    }
    assert_eq!(compared, 2 * FRAMES / COMPARE_EVERY);
}

#[test]
fn an_overrun_frame_is_exact_says_so_and_the_pass_grows() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let s = settings(SampleMode::Exact32);
    let config = ShadowPassConfig {
        settings: s,
        frames_in_flight: 2,
        cell_capacity: Some(64),
        gbuffer: GBufferInput::RayCast,
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let view = view_at(&scene, 0);
    let batch = r
        .render(&scene_at(&scene, &view), s, GBufferSource::Gpu)
        .unwrap();
    let need = u64::from(batch.report.counters.cell_entries);
    // The old list is released once both slots have recorded after the
    // growth: still held after frame 1 (slot 1), gone after frame 2.
    let retired_after = [1, 1, 0];
    let mut frames = 0;
    for (k, retired) in retired_after.into_iter().enumerate() {
        run_frame(&r, &mut pass, k, &view);
        // SAFETY: the frame was waited for; nothing is executing.
        let (status, images) = unsafe { (pass.status(k % 2).unwrap(), pass.read_back().unwrap()) };
        assert_eq!(status.cell_list_overrun, k == 0, "frame {k}: {status:?}");
        assert_eq!(status.cell_entries, need);
        assert_eq!(images.masks, batch.masks, "frame {k}'s masks");
        assert_eq!(pass.grow(&status).unwrap(), k == 0);
        assert_eq!(pass.retired_sets(), retired, "after frame {k}");
        frames += 1;
    }
    assert_eq!(pass.cell_capacity(), need);
    assert_eq!(frames, 3);
    assert_no_validation_messages(&r, "shadow pass overrun");
}

#[test]
fn bad_views_and_configurations_are_refused_by_name() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let edge = ShadowPassConfig {
        settings: IzbSettings {
            edge_surfaces: true,
            ..IzbSettings::default()
        },
        frames_in_flight: 2,
        cell_capacity: None,
        gbuffer: GBufferInput::RayCast,
    };
    let refused = ShadowPass::new(&r, scene.clone(), edge).err().unwrap();
    assert!(refused.to_string().contains("edge_surfaces"), "{refused}");
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        ..edge
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let good = view_at(&scene, 1);
    let mut moved_eye = good;
    moved_eye.camera.eye += DVec3::new(0.5, 0.0, 0.0);
    let mut far_light = good;
    far_light.light = Light::Point {
        position: DVec3::splat(1e12),
    };
    let mut area = good;
    area.light_radius = 0.05;
    let cases: [(&FrameView, usize, &str); 4] = [
        (&moved_eye, 0, "the eye moved"),
        (&far_light, 0, "point light"),
        (&area, 0, "area"),
        (&good, 2, "frame slot 2"),
    ];
    let mut checked = 0;
    for (view, slot, said) in cases {
        let mut error = None;
        let record = |cmd| {
            // SAFETY: as in `run_frame`.
            error = unsafe { pass.record(cmd, slot, view) }.err();
            Ok(())
        };
        // SAFETY: the pass outlives the call, which waits.
        unsafe { r.context.submit_and_wait(record) }.unwrap();
        let e: GpuError = error.unwrap_or_else(|| panic!("{said}: recorded"));
        assert!(e.to_string().contains(said), "{said}: {e}");
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    // The refused views left the scene's view as it was: a good frame
    // still records.
    run_frame(&r, &mut pass, 0, &good);
    assert_no_validation_messages(&r, "refused views");
}

/// The host's `R32_UINT` visibility image of the tests below: made once,
/// filled by a copy recorded before each frame, freed after the device
/// has idled (the renderer's submissions wait).
struct VisibilityImage {
    shared: Arc<DeviceShared>,
    image: vk::Image,
    view: vk::ImageView,
    allocation: Option<Allocation>,
    extent: [u32; 2],
    /// Where the previous frame left it (`HostImage::layout_after`).
    layout: vk::ImageLayout,
}

impl VisibilityImage {
    fn new(shared: &Arc<DeviceShared>, extent: [u32; 2]) -> Self {
        let d = &shared.device;
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(vk::Format::R32_UINT)
            .extent(vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(Self::USAGE)
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
                name: "host visibility",
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .unwrap();
        // SAFETY: made for this image's requirements; not bound yet.
        unsafe { d.bind_image_memory(image, allocation.memory(), allocation.offset()) }.unwrap();
        let range = vk::ImageSubresourceRange::default()
            .aspect_mask(vk::ImageAspectFlags::COLOR)
            .level_count(1)
            .layer_count(1);
        let info = vk::ImageViewCreateInfo::default()
            .image(image)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(vk::Format::R32_UINT)
            .subresource_range(range);
        // SAFETY: `image` is bound; `info` outlives the call.
        let view = unsafe { d.create_image_view(&info, None) }.unwrap();
        VisibilityImage {
            shared: shared.clone(),
            image,
            view,
            allocation: Some(allocation),
            extent,
            layout: vk::ImageLayout::UNDEFINED,
        }
    }

    const USAGE: vk::ImageUsageFlags = vk::ImageUsageFlags::from_raw(
        vk::ImageUsageFlags::SAMPLED.as_raw() | vk::ImageUsageFlags::TRANSFER_DST.as_raw(),
    );

    /// Records the copy of `staging` (one id per pixel) into the image —
    /// after the previous frame's reads, as the contract asks of a host's
    /// later write — and returns the image as the next frame declares it.
    ///
    /// # Safety
    /// `cmd` is recording on this image's device; `staging` outlives its
    /// execution.
    unsafe fn record_fill(&mut self, cmd: vk::CommandBuffer, staging: &GpuBuffer) -> HostImage {
        let d = &self.shared.device;
        let range = vk::ImageSubresourceRange::default()
            .aspect_mask(vk::ImageAspectFlags::COLOR)
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
                    .aspect_mask(vk::ImageAspectFlags::COLOR)
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
            format: vk::Format::R32_UINT,
            extent: self.extent,
            usage: Self::USAGE,
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

impl Drop for VisibilityImage {
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
fn run_visibility_frame(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    image: &mut VisibilityImage,
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
            visibility: Some(declared),
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

/// A pass fed the host's visibility buffer: the GPU ray cast's ids of each
/// frame's view, copied into an `R32_UINT` image before the pass in the
/// same command buffer, give `render`'s masks bit for bit (the same
/// triangle, the same plane) while the camera and light move; the pass's
/// G-buffer matches its CPU twin (`gbuffer_from_visibility`) entry by
/// entry; nothing is allocated while recording and the validation layer,
/// with synchronization validation, stays silent about the declared
/// layouts and barriers.
#[test]
fn a_host_visibility_buffer_gives_render_s_masks_bit_for_bit() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let mut compared = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            gbuffer: GBufferInput::Visibility,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        let mut image = VisibilityImage::new(&r.context.shared, scene.resolution);
        for k in 0..VISIBILITY_FRAMES {
            let view = view_at(&scene, 3 * k);
            let moved = scene_at(&scene, &view);
            let batch = r.render(&moved, s, GBufferSource::Gpu).unwrap();
            let ids = &batch.gbuffer.triangle_id;
            let (_, made) = run_visibility_frame(&r, &mut pass, &mut image, k, &view, ids).unwrap();
            assert_eq!(
                made,
                [0, 0],
                "{mode:?} frame {k}: allocations while recording"
            );
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images) =
                unsafe { (pass.status(k % 2).unwrap(), pass.read_back().unwrap()) };
            assert_eq!(status.visibility_rejected, 0, "{status:?}");
            assert_eq!(status.shadow_tested, batch.report.counters.shadow_tested);
            assert_eq!(images.masks, batch.masks, "{mode:?} frame {k}: masks");
            let twin = izb::gbuffer::gbuffer_from_visibility(&moved, ids).unwrap();
            assert_eq!(twin.rejected, 0);
            let mut differ = 0;
            for (i, &word) in images.gbuffer_words.iter().enumerate() {
                let (id, f) = izb::gpu::shared::unpack_id_flags(word);
                let f = f & !izb::gpu::shared::FLAG_NORMAL_FLIPPED;
                assert_eq!(id, twin.gbuffer.triangle_id[i], "pixel {i}");
                differ += usize::from(f != twin.gbuffer.flags[i]);
            }
            // f32 against f64: a pixel whose N·L is within rounding of 0
            // may be shadow-tested on one side only.
            let pixels = images.gbuffer_words.len();
            assert!(differ * 1000 <= pixels, "{differ} of {pixels} flags differ");
            compared += 1;
        }
        assert_no_validation_messages(&r, "visibility input");
    }
    assert_eq!(compared, 2 * VISIBILITY_FRAMES);
}

/// Frames of the visibility test per mode.
const VISIBILITY_FRAMES: usize = 4;

/// Bad visibility inputs are refused by name at record time, before any
/// command — a wrong format, size or usage, an undefined layout, a
/// visibility buffer to a ray-cast pass or none to a visibility pass —
/// and ids that name no triangle are stored as misses and counted, never
/// read out of bounds.
#[test]
fn bad_visibility_inputs_are_refused_or_counted() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let config = ShadowPassConfig {
        settings: settings(SampleMode::Lut32),
        frames_in_flight: 2,
        cell_capacity: None,
        gbuffer: GBufferInput::Visibility,
    };
    let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
    let mut image = VisibilityImage::new(&r.context.shared, scene.resolution);
    let view = view_at(&scene, 0);
    let batch = r
        .render(&scene, config.settings, GBufferSource::Gpu)
        .unwrap();
    let mut ids = batch.gbuffer.triangle_id.clone();
    let triangles = scene.triangles.len() as u32;
    let hits: Vec<usize> = (0..ids.len()).filter(|&i| ids[i] != u32::MAX).collect();
    for &i in hits.iter().step_by(7) {
        ids[i] = triangles + i as u32;
    }
    let bad = hits.iter().step_by(7).count() as u32;
    run_visibility_frame(&r, &mut pass, &mut image, 0, &view, &ids).unwrap();
    // SAFETY: the frame was waited for.
    let status = unsafe { pass.status(0) }.unwrap();
    assert_eq!(status.visibility_rejected, bad);
    assert!(bad > 10);
    assert_no_validation_messages(&r, "out-of-range ids");

    let good = HostImage {
        image: image.image,
        view: image.view,
        format: vk::Format::R32_UINT,
        extent: scene.resolution,
        usage: VisibilityImage::USAGE,
        layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
        written_by: (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty()),
    };
    let with = |change: &dyn Fn(&mut HostImage)| {
        let mut v = good;
        change(&mut v);
        FrameView {
            visibility: Some(v),
            ..view
        }
    };
    let cases: [(FrameView, &str); 5] = [
        (with(&|v| v.format = vk::Format::R32_SFLOAT), "R32_UINT"),
        (with(&|v| v.extent = [32, 36]), "32x36"),
        (
            with(&|v| v.usage = vk::ImageUsageFlags::STORAGE),
            "lacks SAMPLED",
        ),
        (
            with(&|v| v.layout = vk::ImageLayout::UNDEFINED),
            "UNDEFINED",
        ),
        (
            FrameView {
                visibility: None,
                ..view
            },
            "lacks a visibility buffer",
        ),
    ];
    let mut checked = 0;
    for (view, said) in &cases {
        let mut error = None;
        let record = |cmd| {
            // SAFETY: as in `run_frame`; the image is alive.
            error = unsafe { pass.record(cmd, 1, view) }.err();
            Ok(())
        };
        // SAFETY: the pass and image outlive the call, which waits.
        unsafe { r.context.submit_and_wait(record) }.unwrap();
        let e = error.unwrap_or_else(|| panic!("{said}: recorded"));
        assert!(e.to_string().contains(said), "{said}: {e}");
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    let ray_cast = ShadowPassConfig {
        gbuffer: GBufferInput::RayCast,
        ..config
    };
    let mut ray_pass = ShadowPass::new(&r, scene.clone(), ray_cast).unwrap();
    let given = with(&|_| {});
    let mut error = None;
    let record = |cmd| {
        // SAFETY: as in `run_frame`.
        error = unsafe { ray_pass.record(cmd, 0, &given) }.err();
        Ok(())
    };
    // SAFETY: the pass outlives the call, which waits.
    unsafe { r.context.submit_and_wait(record) }.unwrap();
    let e = error.expect("a ray-cast pass took a visibility buffer");
    assert!(e.to_string().contains("gives a visibility buffer"), "{e}");
    assert_no_validation_messages(&r, "refused visibility inputs");
}
