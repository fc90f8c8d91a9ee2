//! The host's frame loop with the shadow pass inside: each frame records
//! the host's visibility raster and `ShadowPass::record` into the host's
//! command buffer for its frame slot and submits it under the host's
//! queue lock; the only wait is the host's own, on the fence of the frame
//! that last used the slot, before the slot is recorded again. Nothing of
//! izb's is made, uploaded or read back inside the loop; izb's buffer and
//! descriptor-set counters say so.

use crate::host_device::HostGpu;
use crate::raster::{whole, OwnedBuffer, OwnedImage, VisibilityRaster};
use ash::vk;
use glam::{DMat3, DVec3, Vec3};
use izb::cpu::{IzbSettings, SampleMode};
use izb::gpu::host_images::{FrameImages, HostImage};
use izb::gpu::shadow_pass::{FrameView, GBufferInput, PassStatus, ShadowPass, ShadowPassConfig};
use izb::gpu::visibility_raster::visibility_view;
use izb::gpu::GpuRenderer;
use izb::scene::{Light, Scene};
use std::collections::HashMap;
use std::time::Instant;

/// What a run is asked to do.
#[derive(Clone, Copy, Debug)]
pub struct HostOptions {
    pub frames: usize,
    pub frames_in_flight: usize,
    pub mode: SampleMode,
    /// Entries of the pass's cell list (`None`: its default).
    pub cell_capacity: Option<u64>,
    /// Evaluate's heavy-step threshold (`None`: the device's default).
    pub heavy_entries: Option<u32>,
}

/// What a run measured, and its last frame read back after the loop.
#[derive(Debug, serde::Serialize)]
pub struct HostRun {
    pub scene: String,
    pub device: String,
    pub resolution: [u32; 2],
    pub triangles: usize,
    pub frames: usize,
    pub frames_in_flight: usize,
    /// izb's buffers and descriptor sets made after the first frame.
    pub allocations_after_first_frame: [u64; 2],
    /// `ShadowPass::record`'s host time per frame, µs.
    pub record_us: Vec<f64>,
    /// The host's time from the command buffer's begin to its submit,
    /// per frame, µs.
    pub frame_cpu_us: Vec<f64>,
    /// `record`'s host time with the device idle, µs: the last frame
    /// recorded again `RECORD_ALONE` times into a command buffer that is
    /// never submitted. On lavapipe the loop's own `record_us` also pays
    /// for the device's worker threads running the previous frame on the
    /// same cores.
    pub record_alone_us: Vec<f64>,
    /// Frames whose status said the cell list overran (the pass grew
    /// before the slot's next frame).
    pub overruns: usize,
    /// Frames a shader stopped at lavapipe's loop cap in (their masks
    /// are cut short), with the trips.
    pub loop_capped_frames: Vec<(usize, u32)>,
    pub validation_messages: Vec<String>,
    /// The last frame's view (not serialised).
    #[serde(skip)]
    pub last_view: Option<FrameView>,
    /// The last frame's visibility buffer and masks, read back after the
    /// loop.
    #[serde(skip)]
    pub last_ids: Vec<u32>,
    #[serde(skip)]
    pub last_masks: Vec<u32>,
}

/// Frame `k`'s view: the eye orbits the target by 0.5° a frame and the
/// light turns by 2° a frame (a point light about the target), both about
/// the camera's up axis.
pub fn view_at(scene: &Scene, k: usize) -> FrameView {
    let up = scene.camera.up.normalize();
    let light_turn = DMat3::from_axis_angle(up, (2.0 * k as f64).to_radians());
    let orbit = DMat3::from_axis_angle(up, (0.5 * k as f64).to_radians());
    let light = match scene.light {
        Light::Directional { direction } => Light::Directional {
            direction: light_turn * direction,
        },
        Light::Point { position } => Light::Point {
            position: scene.camera.target + light_turn * (position - scene.camera.target),
        },
    };
    let mut camera = scene.camera;
    camera.eye = camera.target + orbit * (camera.eye - camera.target);
    FrameView {
        camera,
        light,
        light_radius: scene.light_radius,
        images: FrameImages::default(),
    }
}

/// The scene's triangles as the host's indexed mesh: distinct vertices
/// relative to `origin`, rounded to f32, and three indices a triangle in
/// the scene's order (so `gl_PrimitiveID` is the scene's triangle id).
fn indexed_mesh(scene: &Scene, origin: DVec3) -> (Vec<Vec3>, Vec<u32>) {
    let mut at: HashMap<[u64; 3], u32> = HashMap::new();
    let mut vertices = Vec::new();
    let mut indices = Vec::with_capacity(scene.triangles.len() * 3);
    for t in &scene.triangles {
        for v in t {
            let key = v.to_array().map(f64::to_bits);
            let i = *at.entry(key).or_insert_with(|| {
                vertices.push((*v - origin).as_vec3());
                vertices.len() as u32 - 1
            });
            indices.push(i);
        }
    }
    (vertices, indices)
}

/// One frame slot's images: the raster's visibility and depth targets,
/// the pass's mask and lit-fraction outputs.
struct SlotImages {
    visibility: OwnedImage,
    depth: OwnedImage,
    masks: OwnedImage,
    lit: OwnedImage,
}

/// Runs `options.frames` frames of `scene` on the host's device.
pub fn run(gpu: &HostGpu, scene: &Scene, options: HostOptions) -> Result<HostRun, String> {
    let d = &gpu.device;
    // SAFETY: the host's device was made with API 1.2, scalarBlockLayout
    // and a queue of `gpu.family` behind `gpu.queue`, which this host
    // submits under; the renderer and pass are dropped (end of this
    // function, after the idle wait) before the device.
    let renderer = unsafe { GpuRenderer::on_host_device(gpu.host_device(), options.heavy_entries) }
        .map_err(|e| e.to_string())?;
    let settings = pass_settings(options.mode);
    let config = ShadowPassConfig {
        settings,
        frames_in_flight: options.frames_in_flight,
        cell_capacity: options.cell_capacity,
        gbuffer: GBufferInput::Visibility,
    };
    let mut pass = ShadowPass::new(&renderer, scene.clone(), config).map_err(|e| e.to_string())?;
    let extent = scene.resolution;
    let (lo, hi) = scene.bounds();
    let origin = (lo + hi) * 0.5;

    // The host's resources, made once.
    let (vertices, indices) = indexed_mesh(scene, origin);
    let mut vertex_buffer = host_buffer(
        gpu,
        "vertices",
        bytemuck::cast_slice(&vertices),
        vk::BufferUsageFlags::VERTEX_BUFFER,
    );
    let mut index_buffer = host_buffer(
        gpu,
        "indices",
        bytemuck::cast_slice(&indices),
        vk::BufferUsageFlags::INDEX_BUFFER,
    );
    let sampled_colour = vk::ImageUsageFlags::COLOR_ATTACHMENT
        | vk::ImageUsageFlags::SAMPLED
        | vk::ImageUsageFlags::TRANSFER_SRC;
    let storage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
    let mut slots: Vec<SlotImages> = (0..options.frames_in_flight)
        .map(|_| SlotImages {
            visibility: OwnedImage::new(
                gpu,
                "visibility",
                extent,
                vk::Format::R32_UINT,
                sampled_colour,
            ),
            depth: OwnedImage::new(
                gpu,
                "depth",
                extent,
                vk::Format::D32_SFLOAT,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            ),
            masks: OwnedImage::new(gpu, "masks", extent, vk::Format::R32_UINT, storage),
            lit: OwnedImage::new(gpu, "lit", extent, vk::Format::R16_UNORM, storage),
        })
        .collect();
    let targets: Vec<_> = slots.iter().map(|s| (&s.visibility, &s.depth)).collect();
    let mut raster = VisibilityRaster::new(gpu, extent, &targets);
    let pool_info = vk::CommandPoolCreateInfo::default()
        .queue_family_index(gpu.family)
        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
    // SAFETY: the family is the device's.
    let pool = unsafe { d.create_command_pool(&pool_info, None) }.map_err(|e| e.to_string())?;
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(options.frames_in_flight as u32);
    // SAFETY: the pool is live and only this thread uses it.
    let cmds = unsafe { d.allocate_command_buffers(&alloc) }.map_err(|e| e.to_string())?;
    let signalled = vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED);
    let fences: Vec<vk::Fence> = (0..options.frames_in_flight)
        // SAFETY: creating a fence needs a live device.
        .map(|_| unsafe { d.create_fence(&signalled, None) }.expect("a fence"))
        .collect();

    let mut run = HostRun {
        scene: scene.name.clone(),
        device: gpu.name.clone(),
        resolution: extent,
        triangles: scene.triangles.len(),
        frames: options.frames,
        frames_in_flight: options.frames_in_flight,
        allocations_after_first_frame: [0; 2],
        record_us: Vec::new(),
        frame_cpu_us: Vec::new(),
        record_alone_us: Vec::new(),
        overruns: 0,
        loop_capped_frames: Vec::new(),
        validation_messages: Vec::new(),
        last_view: None,
        last_ids: Vec::new(),
        last_masks: Vec::new(),
    };
    let mut after_first = [0; 2];
    let mut slot_used = vec![false; options.frames_in_flight];
    // Every frame's error ends the loop; the waits and releases below run
    // either way (nothing is dropped under executing work).
    let mut frames = || -> Result<(), String> {
        for k in 0..options.frames {
            let slot = k % options.frames_in_flight;
            // The host's own wait: the frame that last used this slot.
            // SAFETY: the fence is live.
            unsafe { d.wait_for_fences(&[fences[slot]], true, u64::MAX) }
                .map_err(|e| e.to_string())?;
            if slot_used[slot] {
                // SAFETY: the slot's frame is done (its fence) and none runs.
                let status = unsafe { pass.status(slot) }.map_err(|e| e.to_string())?;
                note_status(&mut run, &status, k - options.frames_in_flight);
                pass.grow(&status).map_err(|e| e.to_string())?;
            }
            let start = Instant::now();
            let images = &slots[slot];
            let mut view = view_at(scene, k);
            let output_layout = if slot_used[slot] {
                vk::ImageLayout::GENERAL
            } else {
                vk::ImageLayout::UNDEFINED
            };
            let compute_write = (
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::AccessFlags::SHADER_WRITE,
            );
            view.images = FrameImages {
                visibility: Some(declared(
                    &images.visibility,
                    extent,
                    vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                    (
                        vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                        vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                    ),
                )),
                masks: Some(declared(
                    &images.masks,
                    extent,
                    output_layout,
                    compute_write,
                )),
                lit_fraction: Some(declared(&images.lit, extent, output_layout, compute_write)),
            };
            let cmd = cmds[slot];
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: the slot's previous submission is done (its fence), so
            // its command buffer may be reset and recorded again.
            unsafe { d.begin_command_buffer(cmd, &begin) }.map_err(|e| e.to_string())?;
            let push = visibility_view(&view.camera, extent, origin, 0);
            let mesh = (
                vertex_buffer.buffer,
                index_buffer.buffer,
                scene.triangles.len() as u32,
            );
            // SAFETY: `cmd` is recording; the buffers and the slot's images
            // live until after the loop's idle wait; the slot's last frame is
            // done.
            unsafe { raster.record(gpu, cmd, slot, mesh, &push) };
            let before = renderer.context.shared.allocations();
            let recorded = Instant::now();
            // SAFETY: `cmd` records on this thread and is submitted below to
            // the pass's queue after every earlier frame; the slot's previous
            // frame is done (its fence); the pass and the images outlive the
            // frame (the idle wait below comes before any is dropped).
            let result = unsafe { pass.record(cmd, slot, &view) };
            run.record_us.push(recorded.elapsed().as_secs_f64() * 1e6);
            let made = renderer.context.shared.allocations();
            if k > 0 {
                for i in 0..2 {
                    after_first[i] += made[i] - before[i];
                }
            }
            // SAFETY: `cmd` is recording.
            unsafe { d.end_command_buffer(cmd) }.map_err(|e| e.to_string())?;
            // A refused frame submits nothing: the slot stays as it was.
            result.map_err(|e| e.to_string())?;
            // SAFETY: the fence is live and signalled (waited above).
            unsafe { d.reset_fences(&[fences[slot]]) }.map_err(|e| e.to_string())?;
            let submit = [vk::SubmitInfo::default().command_buffers(std::slice::from_ref(&cmd))];
            let queue = gpu.queue.lock().unwrap();
            // SAFETY: the queue is used under its lock; `cmd` is executable.
            unsafe { d.queue_submit(*queue, &submit, fences[slot]) }.map_err(|e| e.to_string())?;
            drop(queue);
            run.frame_cpu_us.push(start.elapsed().as_secs_f64() * 1e6);
            slot_used[slot] = true;
            run.last_view = Some(view);
        }
        Ok(())
    };
    let mut failure = frames().err();
    // After the loop: wait for everything, read the remaining statuses and
    // the last frame's images back (outside the frames: a test's check).
    // SAFETY: the fences are live.
    let waited = unsafe { d.wait_for_fences(&fences, true, u64::MAX) };
    waited.expect("the host's frames end");
    let submitted = run.frame_cpu_us.len();
    for frame in submitted.saturating_sub(options.frames_in_flight)..submitted {
        // SAFETY: every frame is done.
        match unsafe { pass.status(frame % options.frames_in_flight) } {
            Ok(status) => note_status(&mut run, &status, frame),
            Err(e) => failure = Some(e.to_string()),
        }
    }
    run.allocations_after_first_frame = after_first;
    if let (None, Some(view)) = (&failure, run.last_view) {
        let slot = (options.frames - 1) % options.frames_in_flight;
        match record_alone(gpu, pool, &mut pass, slot, &view) {
            Ok(us) => run.record_alone_us = us,
            Err(e) => failure = Some(e),
        }
    }
    if failure.is_none() && options.frames > 0 {
        let last = &slots[(options.frames - 1) % options.frames_in_flight];
        (run.last_ids, run.last_masks) =
            read_back(gpu, pool, &last.visibility, &last.masks, extent);
    }
    run.validation_messages = gpu.take_messages();
    // SAFETY: nothing executes (the waits above); each object is
    // destroyed once, izb's pass before its context, all before the device.
    unsafe {
        for f in fences {
            d.destroy_fence(f, None);
        }
        d.destroy_command_pool(pool, None);
    }
    raster.destroy(gpu);
    for s in &mut slots {
        for image in [&mut s.visibility, &mut s.depth, &mut s.masks, &mut s.lit] {
            image.destroy(gpu);
        }
    }
    vertex_buffer.destroy(gpu);
    index_buffer.destroy(gpu);
    drop(pass);
    drop(renderer);
    match failure {
        Some(e) => Err(e),
        None => Ok(run),
    }
}

/// The pass's settings for `mode` (edge pixels' extra surfaces are not
/// traced by the pass yet).
pub fn pass_settings(mode: SampleMode) -> IzbSettings {
    IzbSettings {
        mode,
        edge_surfaces: false,
        ..Default::default()
    }
}

/// How the last frame's masks compare with `izb render`'s of the same
/// view (on the CPU, its twin, with its own ray-cast G-buffer), over the
/// pixels render shadow-tests.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Agreement {
    /// Pixels render shadow-tests.
    pub tested: usize,
    /// Of them, where the host's masks equal render's.
    pub equal: usize,
    /// Of them, where the host's rasteriser saw render's triangle.
    pub same_triangle: usize,
    /// Of those, where the masks are equal: all of them, bit for bit,
    /// when the pass is exact.
    pub same_triangle_equal: usize,
}

/// The last frame of `run` against `izb render` (see [`Agreement`]).
pub fn agreement_with_render(scene: &Scene, run: &HostRun, mode: SampleMode) -> Agreement {
    let Some(view) = run.last_view else {
        return Agreement::default();
    };
    let mut moved = scene.clone();
    (moved.camera, moved.light, moved.light_radius) = (view.camera, view.light, view.light_radius);
    let bvh = izb::bvh::SceneBvh::build(&moved);
    let render = izb::cpu::render_cpu(&moved, &bvh, pass_settings(mode));
    let mut a = Agreement::default();
    for i in (0..render.masks.len()).filter(|&i| !render.visibility[i].is_nan()) {
        let equal = run.last_masks.get(i) == Some(&render.masks[i]);
        let same = run.last_ids.get(i) == Some(&render.gbuffer.triangle_id[i]);
        a.tested += 1;
        a.equal += usize::from(equal);
        a.same_triangle += usize::from(same);
        a.same_triangle_equal += usize::from(same && equal);
    }
    a
}

fn note_status(run: &mut HostRun, status: &PassStatus, frame: usize) {
    run.overruns += usize::from(status.cell_list_overrun);
    if status.loop_cap_trips != 0 {
        run.loop_capped_frames.push((frame, status.loop_cap_trips));
    }
}

/// Recordings of [`HostRun::record_alone_us`].
const RECORD_ALONE: usize = 100;

/// `record`'s host time with the device idle: `view` recorded into slot
/// `slot` `RECORD_ALONE` times, each into a fresh recording of one
/// command buffer that is reset, never submitted.
fn record_alone(
    gpu: &HostGpu,
    pool: vk::CommandPool,
    pass: &mut ShadowPass,
    slot: usize,
    view: &FrameView,
) -> Result<Vec<f64>, String> {
    let d = &gpu.device;
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(1);
    // SAFETY: the pool is live and only this thread uses it.
    let cmd = unsafe { d.allocate_command_buffers(&alloc) }.map_err(|e| e.to_string())?[0];
    let mut micros = Vec::with_capacity(RECORD_ALONE);
    for _ in 0..RECORD_ALONE {
        let begin = vk::CommandBufferBeginInfo::default();
        // SAFETY: `cmd` is not pending (never submitted); nothing executes
        // (the caller waited), so the slot's previous frame is done.
        unsafe { d.begin_command_buffer(cmd, &begin) }.map_err(|e| e.to_string())?;
        let start = Instant::now();
        // SAFETY: as above; the recording is never submitted.
        let recorded = unsafe { pass.record(cmd, slot, view) };
        micros.push(start.elapsed().as_secs_f64() * 1e6);
        // SAFETY: `cmd` is recording, then executable and not pending.
        unsafe {
            d.end_command_buffer(cmd).map_err(|e| e.to_string())?;
            d.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .map_err(|e| e.to_string())?;
        }
        recorded.map_err(|e| e.to_string())?;
    }
    // SAFETY: `cmd` is not pending.
    unsafe { d.free_command_buffers(pool, &[cmd]) };
    Ok(micros)
}

/// `image` as the host declares it to the pass.
fn declared(
    image: &OwnedImage,
    extent: [u32; 2],
    layout: vk::ImageLayout,
    written_by: (vk::PipelineStageFlags, vk::AccessFlags),
) -> HostImage {
    HostImage {
        image: image.image,
        view: image.view,
        format: image.format,
        extent,
        usage: image.usage,
        layout,
        written_by,
    }
}

/// A host-visible buffer holding `bytes`.
fn host_buffer(
    gpu: &HostGpu,
    name: &str,
    bytes: &[u8],
    usage: vk::BufferUsageFlags,
) -> OwnedBuffer {
    let mut buffer = OwnedBuffer::new(gpu, name, bytes.len().max(4) as u64, usage);
    buffer.bytes()[..bytes.len()].copy_from_slice(bytes);
    buffer
}

/// The visibility image (left in `SHADER_READ_ONLY_OPTIMAL` by the pass)
/// and the masks (`GENERAL`) copied back, one submission, waited on.
fn read_back(
    gpu: &HostGpu,
    pool: vk::CommandPool,
    visibility: &OwnedImage,
    masks: &OwnedImage,
    extent: [u32; 2],
) -> (Vec<u32>, Vec<u32>) {
    let d = &gpu.device;
    let bytes = extent[0] as u64 * extent[1] as u64 * 4;
    let mut out: Vec<OwnedBuffer> = (0..2)
        .map(|_| OwnedBuffer::new(gpu, "read_back", bytes, vk::BufferUsageFlags::TRANSFER_DST))
        .collect();
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(1);
    // SAFETY: the pool is live; nothing executes (the caller waited).
    unsafe {
        let cmd = d
            .allocate_command_buffers(&alloc)
            .expect("a command buffer")[0];
        d.begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
            .unwrap();
        let barriers = [
            (visibility.image, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL),
            (masks.image, vk::ImageLayout::GENERAL),
        ]
        .map(|(image, old)| {
            vk::ImageMemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE)
                .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
                .old_layout(old)
                .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image)
                .subresource_range(whole(vk::ImageAspectFlags::COLOR))
        });
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &barriers,
        );
        let region = [vk::BufferImageCopy::default()
            .image_subresource(
                vk::ImageSubresourceLayers::default()
                    .aspect_mask(vk::ImageAspectFlags::COLOR)
                    .layer_count(1),
            )
            .image_extent(vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: 1,
            })];
        for (image, buffer) in [visibility.image, masks.image].iter().zip(&out) {
            d.cmd_copy_image_to_buffer(
                cmd,
                *image,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                buffer.buffer,
                &region,
            );
        }
        let to_host = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::HOST_READ)];
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::HOST,
            vk::DependencyFlags::empty(),
            &to_host,
            &[],
            &[],
        );
        d.end_command_buffer(cmd).unwrap();
        let fence = d
            .create_fence(&vk::FenceCreateInfo::default(), None)
            .unwrap();
        let submit = [vk::SubmitInfo::default().command_buffers(std::slice::from_ref(&cmd))];
        let queue = gpu.queue.lock().unwrap();
        d.queue_submit(*queue, &submit, fence).unwrap();
        drop(queue);
        d.wait_for_fences(&[fence], true, u64::MAX).unwrap();
        d.destroy_fence(fence, None);
        d.free_command_buffers(pool, &[cmd]);
    }
    let words: Vec<Vec<u32>> = out
        .iter_mut()
        .map(|b| bytemuck::pod_collect_to_vec(b.bytes()))
        .collect();
    for b in &mut out {
        b.destroy(gpu);
    }
    let [ids, masks] = <[Vec<u32>; 2]>::try_from(words).unwrap();
    (ids, masks)
}
