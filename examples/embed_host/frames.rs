//! The host's frame loop with the shadow pass inside: each frame records
//! the host's visibility raster and `ShadowPass::record_host_geometry`
//! (the raster's own vertex and index buffers as the pass's geometry,
//! one draw placed by the mesh's origin) into the host's
//! command buffer for its frame slot and submits it under the host's
//! queue lock; the only wait is the host's own, on the fence of the frame
//! that last used the slot, before the slot is recorded again. Nothing of
//! izb's is made, uploaded or read back inside the loop; izb's buffer and
//! descriptor-set counters say so.

use crate::after_loop::{read_back, record_alone};
use crate::first_frame::{twin_on_multisampled_ids, twin_on_pass_gbuffer};
use crate::gpu_timing::{thread_cpu_us, GpuMillis, Mark, PassTimer};
use crate::host_device::HostGpu;
pub use crate::host_run::{HostOptions, HostRun};
use crate::lighting::{compare_lighting, lighting_view};
use crate::mesh::{host_buffer, indexed_mesh};
use crate::multisampled_ids::read_back_samples;
use crate::targets::{declared, Targets};
use ash::vk;
use glam::DMat3;
use izb::cpu::{IzbSettings, SampleMode};
use izb::gpu::context::HostCounts;
use izb::gpu::gather_draws::{FrameGeometry, HostBuffer, HostDraw, HostIndices};
use izb::gpu::host_images::FrameImages;
use izb::gpu::shadow_pass::{
    FrameView, GBufferInput, HostGeometryConfig, PassStatus, ShadowPass, ShadowPassConfig,
};
use izb::gpu::visibility_raster::raster_view;
use izb::gpu::GpuRenderer;
use izb::scene::{Light, Scene};
use std::time::Instant;

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

/// Runs `options.frames` frames of `scene` on the host's device.
pub fn run(gpu: &HostGpu, scene: &Scene, options: HostOptions) -> Result<HostRun, String> {
    let d = &gpu.device;
    // SAFETY: the host's device was made with API 1.2, scalarBlockLayout
    // and a queue of `gpu.family` behind `gpu.queue`, which this host
    // submits under; the renderer and pass are dropped (end of this
    // function, after the idle wait) before the device.
    let renderer = unsafe { GpuRenderer::on_host_device(gpu.host_device(), options.heavy_entries) }
        .map_err(|e| e.to_string())?;
    let multisampled = options.msaa > 1;
    if multisampled && options.depth.is_some() {
        return Err(
            "--msaa with --depth: a multisampled depth + normal G-buffer is not read \
                    (draw the visibility buffer multisampled)"
                .into(),
        );
    }
    let settings = pass_settings(options.mode, multisampled);
    let config = ShadowPassConfig {
        settings,
        frames_in_flight: options.frames_in_flight,
        cell_capacity: options.cell_capacity,
        // The pass's default edge slots for its input (a frame past them
        // says so and the pass grows).
        edge_slots: None,
        gbuffer: match options.depth {
            Some(d) => GBufferInput::DepthNormal(d.convention),
            None if multisampled => GBufferInput::MultisampledVisibility {
                samples: options.msaa,
            },
            None => GBufferInput::Visibility,
        },
    };
    let samples = vk::SampleCountFlags::from_raw(options.msaa);
    if multisampled {
        // SAFETY: the physical device is the host device's.
        let limits = unsafe { gpu.instance.get_physical_device_properties(gpu.physical) }.limits;
        let counts =
            limits.framebuffer_color_sample_counts & limits.framebuffer_depth_sample_counts;
        if !counts.contains(samples) {
            return Err(format!(
                "--msaa {}: the device's colour and depth attachments take {counts:?} samples",
                options.msaa
            ));
        }
    }
    // The pass reads the host's own vertex and index buffers (the raster's).
    let triangles = scene.triangles.len() as u32;
    let limits = HostGeometryConfig {
        max_triangles: triangles,
        max_draws: 1,
        bounds: scene.bounds(),
    };
    let mut pass = ShadowPass::with_host_geometry(&renderer, scene.clone(), config, limits)
        .map_err(|e| e.to_string())?;
    let (lo, hi) = scene.bounds();
    let origin = (lo + hi) * 0.5;

    // The host's resources, made once.
    let (vertices, indices) = indexed_mesh(scene, origin);
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let mut vertex_buffer = host_buffer(
        gpu,
        "vertices",
        bytemuck::cast_slice(&vertices),
        vk::BufferUsageFlags::VERTEX_BUFFER | storage,
    );
    let mut index_buffer = host_buffer(
        gpu,
        "indices",
        bytemuck::cast_slice(&indices),
        vk::BufferUsageFlags::INDEX_BUFFER | storage,
    );
    // Written through a mapping before the first submission, which makes
    // the writes visible: no barrier to ask for.
    let unwritten = (vk::PipelineStageFlags::empty(), vk::AccessFlags::empty());
    let geometry_buffers = [
        HostBuffer {
            buffer: vertex_buffer.buffer,
            size: (vertices.len() * 12).max(4) as u64,
            usage: vk::BufferUsageFlags::VERTEX_BUFFER | storage,
            written_by: unwritten,
        },
        HostBuffer {
            buffer: index_buffer.buffer,
            size: (indices.len() * 4).max(4) as u64,
            usage: vk::BufferUsageFlags::INDEX_BUFFER | storage,
            written_by: unwritten,
        },
    ];
    // One draw: the mesh's positions are relative to `origin`.
    let draws = [HostDraw {
        vertex_buffer: 0,
        vertex_offset: 0,
        vertex_stride: 12,
        vertex_format: vk::Format::R32G32B32_SFLOAT,
        vertex_count: vertices.len() as u32,
        indices: Some(HostIndices {
            buffer: 1,
            offset: 0,
            index_type: vk::IndexType::UINT32,
        }),
        triangle_count: triangles,
        transform: glam::DAffine3::from_translation(origin),
    }];
    let geometry = FrameGeometry {
        buffers: &geometry_buffers,
        draws: &draws,
    };
    let mesh_buffers = (vertex_buffer.buffer, index_buffer.buffer);
    let mut targets = Targets::new(
        gpu,
        scene.resolution,
        options.frames_in_flight,
        (options.depth, samples),
        mesh_buffers,
    );
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
        resolution: scene.resolution,
        triangles: scene.triangles.len(),
        frames: options.frames,
        frames_in_flight: options.frames_in_flight,
        msaa: options.msaa,
        first_frame_multisampled: None,
        allocations_after_first_frame: [0; 2],
        resize_allocations: [0; 2],
        grown: 0,
        record_us: Vec::new(),
        record_cpu_us: Vec::new(),
        frame_cpu_us: Vec::new(),
        record_alone_us: Vec::new(),
        record_cold_us: Vec::new(),
        overruns: 0,
        loop_capped_frames: Vec::new(),
        validation_messages: Vec::new(),
        twin_masks_equal: None,
        in_frames_after_first: HostCounts::default(),
        gpu_ms: None,
        first_frame: None,
        first_frame_lighting: None,
        first_frame_images: None,
        first_frame_host_shaded: Vec::new(),
        pass_millis: Vec::new(),
        last_view: None,
        last_ids: Vec::new(),
        last_masks: Vec::new(),
    };
    let mut after_first = [0; 2];
    let mut timer = PassTimer::new(gpu, options.frames_in_flight);
    // Per slot: the frame submitted on it whose status is not read yet,
    // and whether its output images are new (nothing to keep: UNDEFINED).
    let mut unread: Vec<Option<usize>> = vec![None; options.frames_in_flight];
    let mut fresh = vec![true; options.frames_in_flight];
    let mut fences = fences;
    // Every frame's error ends the loop; the waits and releases below run
    // either way (nothing is dropped under executing work).
    let mut frames = || -> Result<(), String> {
        for k in 0..options.frames {
            let slot = k % options.frames_in_flight;
            // The host's own wait: the frame that last used this slot.
            // SAFETY: the fence is live.
            unsafe { d.wait_for_fences(&[fences[slot]], true, u64::MAX) }
                .map_err(|e| e.to_string())?;
            // SAFETY: the slot's frame is done (its fence) and none runs.
            unsafe { read_status(&mut pass, &mut run, &mut unread, slot, true) }?;
            if let Some(t) = &mut timer {
                // SAFETY: as above.
                unsafe { t.collect(d, slot) };
            }
            if let Some((_, size)) = options.resize.filter(|&(at, _)| at == k) {
                // As a swapchain is recreated: every frame done, the
                // targets made anew, the pass resized.
                // SAFETY: the fences are live.
                unsafe { d.wait_for_fences(&fences, true, u64::MAX) }.map_err(|e| e.to_string())?;
                for s in 0..options.frames_in_flight {
                    // SAFETY: every frame is done (the wait above).
                    unsafe { read_status(&mut pass, &mut run, &mut unread, s, true) }?;
                }
                fresh.fill(true);
                targets.destroy(gpu);
                let slots = options.frames_in_flight;
                let shape = (options.depth, samples);
                targets = Targets::new(gpu, size, slots, shape, mesh_buffers);
                let before = renderer.context.shared.allocations();
                pass.resize(size).map_err(|e| e.to_string())?;
                let after = renderer.context.shared.allocations();
                run.resize_allocations = [after[0] - before[0], after[1] - before[1]];
                run.resolution = size;
            }
            let extent = targets.extent;
            let start = Instant::now();
            let images = &targets.slots[slot];
            let mut view = view_at(scene, k);
            let output_layout = if std::mem::take(&mut fresh[slot]) {
                vk::ImageLayout::UNDEFINED
            } else {
                vk::ImageLayout::GENERAL
            };
            let compute_write = (
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::AccessFlags::SHADER_WRITE,
            );
            let colour_written = (
                vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            );
            let attachment = vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL;
            let (visibility, depth, normal) = match &images.normal {
                None => (
                    Some(declared(
                        &images.visibility,
                        extent,
                        attachment,
                        colour_written,
                    )),
                    None,
                    None,
                ),
                Some(normal) => (
                    None,
                    Some(declared(
                        &images.depth,
                        extent,
                        vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL,
                        (
                            vk::PipelineStageFlags::LATE_FRAGMENT_TESTS,
                            vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
                        ),
                    )),
                    Some(declared(normal, extent, attachment, colour_written)),
                ),
            };
            view.images = FrameImages {
                visibility,
                masks: Some(declared(
                    &images.masks,
                    extent,
                    output_layout,
                    compute_write,
                )),
                lit_fraction: Some(declared(&images.lit, extent, output_layout, compute_write)),
                depth,
                normal,
            };
            let cmd = cmds[slot];
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: the slot's previous submission is done (its fence), so
            // its command buffer may be reset and recorded again.
            unsafe { d.begin_command_buffer(cmd, &begin) }.map_err(|e| e.to_string())?;
            if let Some(t) = &mut timer {
                // SAFETY: `cmd` is recording; the slot's marks were read.
                unsafe { t.start(d, cmd, slot) };
            }
            let reverse_z = izb::gbuffer::DepthConvention {
                near: view.camera.near,
                far: Some(view.camera.far),
                reversed: true,
            };
            let convention = options.depth.map_or(reverse_z, |d| d.convention);
            let push = raster_view(&view.camera, extent, origin, 0, &convention);
            let mesh = (
                vertex_buffer.buffer,
                index_buffer.buffer,
                scene.triangles.len() as u32,
            );
            // SAFETY: `cmd` is recording; the buffers and the slot's images
            // live until after the loop's idle wait; the slot's last frame is
            // done.
            unsafe { targets.raster.record(gpu, cmd, slot, mesh, &push) };
            if let Some(t) = &timer {
                // SAFETY: `cmd` is recording, started above.
                unsafe { t.mark(d, cmd, slot, Mark::RasterDone) };
            }
            let before = renderer.context.shared.allocations();
            let counts_before = renderer.context.shared.host_counts();
            let recorded = Instant::now();
            let cpu_before = thread_cpu_us();
            // SAFETY: `cmd` records on this thread and is submitted below to
            // the pass's queue after every earlier frame; the slot's previous
            // frame is done (its fence); the pass, the images and the vertex
            // and index buffers (declared as made: STORAGE_BUFFER usage, no
            // write after their mapping) outlive the frame (the idle wait
            // below comes before any is dropped).
            let result = unsafe { pass.record_host_geometry(cmd, slot, &view, &geometry) };
            run.record_us.push(recorded.elapsed().as_secs_f64() * 1e6);
            run.record_cpu_us.push(thread_cpu_us() - cpu_before);
            let made = renderer.context.shared.allocations();
            if k > 0 {
                for i in 0..2 {
                    after_first[i] += made[i] - before[i];
                }
                let added = renderer.context.shared.host_counts().since(counts_before);
                run.in_frames_after_first.add(added);
            }
            if let Some(t) = &timer {
                // SAFETY: `cmd` is recording, started above.
                unsafe { t.mark(d, cmd, slot, Mark::ShadowPassDone) };
            }
            // The host's lighting samples the lit fraction the pass left
            // (a refused frame's images are never read: not submitted).
            let lighting = lighting_view(&view, extent, origin);
            let pass_read_visibility = options.depth.is_none();
            // SAFETY: `cmd` is recording after the raster and the pass into
            // the slot's images; the slot's last frame is done; the images
            // and buffers outlive the frame (the idle wait below).
            unsafe {
                let images = images.lighting();
                let lights = &targets.lighting;
                lights.record(d, cmd, slot, &images, pass_read_visibility, &lighting);
            }
            if let Some(t) = &timer {
                // SAFETY: `cmd` is recording, started above.
                unsafe { t.mark(d, cmd, slot, Mark::LightingDone) };
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
            let submitted = unsafe { d.queue_submit(*queue, &submit, fences[slot]) };
            drop(queue);
            if let Err(e) = submitted {
                // Nothing will signal the reset fence: a signalled one
                // takes its place, so the waits below end.
                // SAFETY: the fence is not in use (nothing was submitted).
                unsafe {
                    d.destroy_fence(fences[slot], None);
                    fences[slot] = d
                        .create_fence(&signalled, None)
                        .map_err(|e| e.to_string())?;
                }
                return Err(e.to_string());
            }
            run.frame_cpu_us.push(start.elapsed().as_secs_f64() * 1e6);
            unread[slot] = Some(k);
            run.last_view = Some(view);
            if k == 0 && options.check_first_frame {
                // A check outside the measured frames: frame 0 waited for
                // before frame 1 overwrites the pass's G-buffer.
                // SAFETY: the fence is live.
                unsafe { d.wait_for_fences(&[fences[slot]], true, u64::MAX) }
                    .map_err(|e| e.to_string())?;
                let mesh = (&vertices[..], &indices[..]);
                let twin = if multisampled {
                    let image = &targets.slots[slot].visibility;
                    // SAFETY: frame 0 is done and no other frame was
                    // submitted; this waits for its own dispatch.
                    let ids = unsafe { read_back_samples(gpu, pool, image, extent) };
                    let ids = (&ids[..], options.msaa as usize);
                    // SAFETY: as above.
                    let (twin, mut check) = unsafe {
                        twin_on_multisampled_ids(
                            &pass, scene, &view, &geometry, mesh, settings, ids,
                        )
                    }?;
                    // SAFETY: as above.
                    let status = unsafe { pass.status(slot) }.map_err(|e| e.to_string())?;
                    check.pass_rejected = status.visibility_rejected as usize;
                    check.pass_centre_uncovered = status.centre_uncovered as usize;
                    run.first_frame_multisampled = Some(check);
                    twin
                } else {
                    // SAFETY: frame 0 is done and no other frame was submitted.
                    unsafe { twin_on_pass_gbuffer(&pass, scene, &view, &geometry, mesh, settings) }?
                };
                // SAFETY: as above.
                let images = unsafe { pass.read_back_frame() }.map_err(|e| e.to_string())?;
                let shaded = (&targets.slots[slot].shaded, vk::ImageLayout::GENERAL);
                let host_shaded = read_back(gpu, pool, &[shaded], extent).remove(0);
                run.first_frame_lighting = Some(compare_lighting(&host_shaded, &images.shaded));
                run.first_frame_host_shaded = host_shaded;
                run.first_frame = Some(twin);
                run.first_frame_images = Some((images, view));
            }
        }
        Ok(())
    };
    let mut failure = frames().err();
    // After the loop: wait for everything, read the remaining statuses and
    // the last frame's images back (outside the frames: a test's check).
    // SAFETY: the fences are live.
    let waited = unsafe { d.wait_for_fences(&fences, true, u64::MAX) };
    waited.expect("the host's frames end");
    for s in 0..options.frames_in_flight {
        // SAFETY: every frame is done (the wait above).
        if let Err(e) = unsafe { read_status(&mut pass, &mut run, &mut unread, s, false) } {
            failure = Some(e);
        }
        if let Some(t) = &mut timer {
            // SAFETY: as above.
            unsafe { t.collect(d, s) };
        }
    }
    if let Some(t) = &timer {
        run.gpu_ms = Some(GpuMillis::of(t, &run.pass_millis));
        // SAFETY: nothing executes (the wait above).
        unsafe { t.destroy(d) };
    }
    run.allocations_after_first_frame = after_first;
    if let (None, Some(view)) = (&failure, run.last_view) {
        let slot = (options.frames - 1) % options.frames_in_flight;
        match record_alone(gpu, pool, &mut pass, slot, &view, &geometry) {
            Ok((warm, cold)) => (run.record_alone_us, run.record_cold_us) = (warm, cold),
            Err(e) => failure = Some(e),
        }
    }
    if failure.is_none() && options.frames > 0 && multisampled {
        // A multisampled image cannot be copied to a buffer: the centre
        // triangles are the pass's G-buffer's (the last frame's).
        let last = &targets.slots[(options.frames - 1) % options.frames_in_flight];
        let images = [(&last.masks, vk::ImageLayout::GENERAL)];
        run.last_masks = read_back(gpu, pool, &images, targets.extent).remove(0);
        // SAFETY: every frame is done (the waits above).
        match unsafe { pass.read_back_gbuffer() } {
            Ok(g) => run.last_ids = g.triangle_id,
            Err(e) => failure = Some(e.to_string()),
        }
    } else if failure.is_none() && options.frames > 0 {
        let last = &targets.slots[(options.frames - 1) % options.frames_in_flight];
        // The pass or the host's lighting left the visibility buffer read-only.
        let images = [
            (&last.visibility, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL),
            (&last.masks, vk::ImageLayout::GENERAL),
        ];
        let [ids, masks] = <[Vec<u32>; 2]>::try_from(read_back(gpu, pool, &images, targets.extent))
            .expect("two images");
        (run.last_ids, run.last_masks) = (ids, masks);
    }
    if let (None, Some(_), Some(view)) = (&failure, options.depth, run.last_view) {
        // SAFETY: every frame is done (the waits above).
        let mesh = (&vertices[..], &indices[..]);
        match unsafe { twin_on_pass_gbuffer(&pass, scene, &view, &geometry, mesh, settings) } {
            Ok(c) => {
                run.twin_masks_equal =
                    Some([c.masks_compared - c.mask_mismatches, c.masks_compared])
            }
            Err(e) => failure = Some(e),
        }
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
    targets.destroy(gpu);
    vertex_buffer.destroy(gpu);
    index_buffer.destroy(gpu);
    drop(pass);
    drop(renderer);
    match failure {
        Some(e) => Err(e),
        None => Ok(run),
    }
}

/// The pass's settings for `mode`: edge pixels' extra surfaces with a
/// multisampled visibility buffer (its samples nominate their hits), none
/// with one surface a pixel.
pub fn pass_settings(mode: SampleMode, multisampled: bool) -> IzbSettings {
    IzbSettings {
        mode,
        edge_surfaces: multisampled,
        ..Default::default()
    }
}

/// Reads slot `slot`'s status if a frame of it is unread: notes its
/// overrun and loop-cap trips, and with `grow` grows the pass for it.
///
/// # Safety
/// The slot's frames are done (the host waited on its fence).
unsafe fn read_status(
    pass: &mut ShadowPass,
    run: &mut HostRun,
    unread: &mut [Option<usize>],
    slot: usize,
    grow: bool,
) -> Result<(), String> {
    let Some(frame) = unread[slot].take() else {
        return Ok(());
    };
    // SAFETY: the caller's promise.
    let status: PassStatus = unsafe { pass.status(slot) }.map_err(|e| e.to_string())?;
    // SAFETY: as above.
    if let Some(m) = unsafe { pass.gpu_millis(slot) }.map_err(|e| e.to_string())? {
        run.pass_millis.push(m);
    }
    run.overruns += usize::from(status.cell_list_overrun);
    if status.loop_cap_trips != 0 {
        run.loop_capped_frames.push((frame, status.loop_cap_trips));
    }
    if grow {
        run.grown += usize::from(pass.grow(&status).map_err(|e| e.to_string())?);
    }
    Ok(())
}
