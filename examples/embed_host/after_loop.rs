//! What the host measures after its frame loop, with the device idle:
//! `record`'s own cost, the last frame's images read back, and how its
//! masks compare with `izb render`'s of the same view.

use crate::frames::{pass_settings, HostRun};
use crate::host_device::HostGpu;
use crate::raster::{whole, OwnedBuffer, OwnedImage};
use ash::vk;
use gpu_allocator::MemoryLocation;
use izb::cpu::SampleMode;
use izb::gpu::gather_draws::FrameGeometry;
use izb::gpu::shadow_pass::{FrameView, ShadowPass};
use izb::scene::Scene;
use std::time::Instant;

/// How the last frame's masks compare with `izb render`'s of the same
/// view (on the CPU, its twin, with its own ray-cast G-buffer), over the
/// pixels render shadow-tests.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct Agreement {
    /// Pixels render shadow-tests.
    pub tested: usize,
    /// Of them, where the host's masks equal render's.
    pub equal: usize,
    /// Of them, where the host's rasteriser saw render's triangle (with
    /// `--msaa`: where the pass's centre, chosen among the samples, is
    /// render's triangle).
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
    moved.resolution = run.resolution;
    let bvh = izb::bvh::SceneBvh::build(&moved);
    let render = izb::cpu::render_cpu(&moved, &bvh, pass_settings(mode, run.msaa > 1));
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

/// Recordings of [`HostRun::record_alone_us`].
pub const RECORD_ALONE: usize = 100;

/// Recordings of [`HostRun::record_cold_us`].
pub const RECORD_COLD: usize = 20;

/// Bytes swept before each cold recording: far more than this machine's
/// per-core caches (2 × 4 MiB of L2), as a frame of lavapipe's shader
/// work sweeps them.
const CACHE_SWEEP: usize = 64 << 20;

/// `record`'s host time with the device idle: `view` recorded into slot
/// `slot` `RECORD_ALONE` times back to back (warm caches), then
/// `RECORD_COLD` times each after sweeping `CACHE_SWEEP` bytes (cold),
/// each into a fresh recording of one command buffer that is reset, never
/// submitted. Returns (warm, cold) microseconds.
pub fn record_alone(
    gpu: &HostGpu,
    pool: vk::CommandPool,
    pass: &mut ShadowPass,
    slot: usize,
    view: &FrameView,
    geometry: &FrameGeometry,
) -> Result<(Vec<f64>, Vec<f64>), String> {
    let d = &gpu.device;
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(1);
    // SAFETY: the pool is live and only this thread uses it.
    let cmd = unsafe { d.allocate_command_buffers(&alloc) }.map_err(|e| e.to_string())?[0];
    let mut micros = Vec::with_capacity(RECORD_ALONE + RECORD_COLD);
    let mut sweep = vec![0u8; CACHE_SWEEP];
    for k in 0..RECORD_ALONE + RECORD_COLD {
        if k >= RECORD_ALONE {
            for i in (0..sweep.len()).step_by(64) {
                sweep[i] = sweep[i].wrapping_add(1);
            }
            std::hint::black_box(&mut sweep);
        }
        let begin = vk::CommandBufferBeginInfo::default();
        // SAFETY: `cmd` is not pending (never submitted); nothing executes
        // (the caller waited), so the slot's previous frame is done.
        unsafe { d.begin_command_buffer(cmd, &begin) }.map_err(|e| e.to_string())?;
        let start = Instant::now();
        // SAFETY: as above; the recording is never submitted.
        let recorded = unsafe { pass.record_host_geometry(cmd, slot, view, geometry) };
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
    let cold = micros.split_off(RECORD_ALONE);
    Ok((micros, cold))
}

/// Colour images of four bytes a texel (the visibility buffer, the
/// masks, the host's shaded image), each in the layout given, last
/// written by a compute shader or the raster, copied back in one
/// submission, waited on: one word a texel each.
pub fn read_back(
    gpu: &HostGpu,
    pool: vk::CommandPool,
    images: &[(&OwnedImage, vk::ImageLayout)],
    extent: [u32; 2],
) -> Vec<Vec<u32>> {
    let d = &gpu.device;
    let bytes = extent[0] as u64 * extent[1] as u64 * 4;
    let mut out: Vec<OwnedBuffer> = (0..images.len())
        .map(|_| {
            let usage = vk::BufferUsageFlags::TRANSFER_DST;
            OwnedBuffer::new(gpu, "read_back", bytes, usage, MemoryLocation::GpuToCpu)
        })
        .collect();
    let record = |cmd| {
        // SAFETY: `cmd` is recording (`submit_once`); the images are
        // live in the layouts given, the buffers are the copies' size.
        unsafe {
            let barriers: Vec<_> = images
                .iter()
                .map(|(image, old)| {
                    vk::ImageMemoryBarrier::default()
                        // Compute writes, or the raster's.
                        .src_access_mask(
                            vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                        )
                        .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
                        .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
                        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .old_layout(*old)
                        .image(image.image)
                        .subresource_range(whole(vk::ImageAspectFlags::COLOR))
                })
                .collect();
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER
                    | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
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
            for ((image, _), buffer) in images.iter().zip(&out) {
                d.cmd_copy_image_to_buffer(
                    cmd,
                    image.image,
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
        }
    };
    // SAFETY: the pool is live; nothing executes (the caller waited); the
    // images and buffers outlive the call, which waits.
    unsafe { gpu.submit_once(pool, record) };
    let words: Vec<Vec<u32>> = out
        .iter_mut()
        .map(|b| bytemuck::pod_collect_to_vec(b.bytes()))
        .collect();
    for b in &mut out {
        b.destroy(gpu);
    }
    words
}
