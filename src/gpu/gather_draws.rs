//! The shadow pass's step for the host's geometry, `gather_draws`
//! (`shaders/gather_draws.comp`): the host's own vertex and index buffers,
//! several draws with per-instance transforms, read where they lie and
//! written as the pass's eye-relative triangles each frame — the twin of
//! [`crate::cpu::gather_draws`], whose module says why the arithmetic keeps
//! the precision envelope.
//!
//! What the host declares per frame ([`FrameGeometry`]): its buffers (at
//! most `HOST_GEOMETRY_SLOTS` distinct ones, each made with
//! `STORAGE_BUFFER` usage, with the stage and access of its last write)
//! and its draws, each naming its buffers by their index in that list.
//! The pass checks every range on the host before recording (a vertex or
//! index range past its buffer, a misaligned offset or stride, a position
//! format other than `R32G32B32_SFLOAT`, a transform that does not round
//! to finite `f32`, more draws or triangles than the pass was made for:
//! each refused by name). An index is data on the device, so it is
//! checked there: one at or past its draw's `vertex_count` collapses its
//! triangle (it casts no shadow, nothing is read out of bounds) and is
//! counted in the frame's status (`PassStatus::index_out_of_range`), which
//! makes the frame unusable ([`super::shadow_pass::PassStatus::geometry_error`]).
//!
//! Triangle ids: draw k's triangle j is id `Σ_{i<k} triangle_count_i + j`,
//! the order a visibility buffer's ids must follow
//! (`VisibilityView::first_triangle` per draw: [`first_triangles`]).

use super::shared::{host_image, GpuDraw};
use super::{GpuError, Kernels, Recorder};
use crate::cpu::gather_draws::fold_transform;
use ash::vk;
use glam::{DAffine3, DVec3};
use izb_contract::word::NO_INDICES;

/// One of the host's buffers a frame's draws read.
#[derive(Clone, Copy, Debug)]
pub struct HostBuffer {
    pub buffer: vk::Buffer,
    /// Its size in bytes.
    pub size: u64,
    /// The usage it was created with (the pass reads it as a storage
    /// buffer: `STORAGE_BUFFER`).
    pub usage: vk::BufferUsageFlags,
    /// The stage and access of the host's last write before the frame
    /// (an upload, a skinning dispatch): the source scope of the pass's
    /// barrier. Empty flags: nothing to wait for.
    pub written_by: (vk::PipelineStageFlags, vk::AccessFlags),
}

/// A draw's indices.
#[derive(Clone, Copy, Debug)]
pub struct HostIndices {
    /// Index into [`FrameGeometry::buffers`].
    pub buffer: usize,
    /// Byte offset of its first index, a multiple of the index size.
    pub offset: u64,
    /// `UINT16` or `UINT32`.
    pub index_type: vk::IndexType,
}

/// One of the host's draws: triangles of one mesh placed by one transform.
#[derive(Clone, Copy, Debug)]
pub struct HostDraw {
    /// Index into [`FrameGeometry::buffers`] of its positions.
    pub vertex_buffer: usize,
    /// Byte offset of vertex 0's position and the byte stride between
    /// vertices, both multiples of 4.
    pub vertex_offset: u64,
    pub vertex_stride: u64,
    /// `R32G32B32_SFLOAT` (the one position format read so far).
    pub vertex_format: vk::Format,
    /// Vertices the draw may index (its range in the buffer).
    pub vertex_count: u32,
    /// `None`: triangle t's corners are vertices 3t, 3t + 1, 3t + 2.
    pub indices: Option<HostIndices>,
    pub triangle_count: u32,
    /// Object to world, in `f64` (the pass folds the eye in before it
    /// rounds).
    pub transform: DAffine3,
}

/// The host's geometry for one frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameGeometry<'a> {
    pub buffers: &'a [HostBuffer],
    pub draws: &'a [HostDraw],
}

/// Each draw's first triangle id: the running sum of the counts before it.
pub fn first_triangles(draws: &[HostDraw]) -> Vec<u32> {
    draws
        .iter()
        .scan(0u32, |first, d| {
            let this = *first;
            *first += d.triangle_count;
            Some(this)
        })
        .collect()
}

/// Checks `geometry` and writes its draw table for `eye` into `table`
/// (cleared first); returns the frame's triangles. `max_range` is the
/// device's `maxStorageBufferRange`.
pub fn draw_table(
    geometry: &FrameGeometry,
    eye: DVec3,
    max_range: u64,
    table: &mut Vec<GpuDraw>,
) -> Result<u32, GpuError> {
    let refuse = |what: String| Err(GpuError::Unsupported(what));
    let slots = host_image::GEOMETRY_SLOTS as usize;
    if geometry.buffers.is_empty() || geometry.buffers.len() > slots {
        return refuse(format!(
            "{} host geometry buffers: from 1 to {slots} (HOST_GEOMETRY_SLOTS)",
            geometry.buffers.len()
        ));
    }
    for (i, b) in geometry.buffers.iter().enumerate() {
        if !b.usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER) {
            return refuse(format!(
                "host geometry buffer {i} lacks STORAGE_BUFFER usage (the pass reads it \
                 from a compute shader)"
            ));
        }
        if b.size > max_range || b.size % 4 != 0 || b.size == 0 {
            return refuse(format!(
                "host geometry buffer {i} is {} bytes: a non-zero multiple of 4 up to the \
                 device's maxStorageBufferRange ({max_range})",
                b.size
            ));
        }
    }
    table.clear();
    let mut first = 0u64;
    for (k, d) in geometry.draws.iter().enumerate() {
        let bad = |what: &str| GpuError::Unsupported(format!("host draw {k}: {what}"));
        let buffer = |i: usize| {
            geometry
                .buffers
                .get(i)
                .ok_or_else(|| bad(&format!("buffer {i}, of {} given", geometry.buffers.len())))
        };
        if d.vertex_format != vk::Format::R32G32B32_SFLOAT {
            return Err(bad(&format!(
                "position format {:?}: the pass reads R32G32B32_SFLOAT",
                d.vertex_format
            )));
        }
        if d.vertex_offset % 4 != 0 || d.vertex_stride % 4 != 0 || d.vertex_stride < 12 {
            return Err(bad(&format!(
                "vertex offset {} and stride {}: multiples of 4, the stride at least 12",
                d.vertex_offset, d.vertex_stride
            )));
        }
        if d.vertex_count == 0 {
            return Err(bad("no vertices"));
        }
        let vertices = buffer(d.vertex_buffer)?;
        let vertex_end = d.vertex_offset + d.vertex_stride * (u64::from(d.vertex_count) - 1) + 12;
        if vertex_end > vertices.size {
            return Err(bad(&format!(
                "{} vertices at offset {} and stride {} end at byte {vertex_end}, past \
                 buffer {}'s {} bytes",
                d.vertex_count, d.vertex_offset, d.vertex_stride, d.vertex_buffer, vertices.size
            )));
        }
        let corners = 3 * u64::from(d.triangle_count);
        let (index_slot, index_offset, index_bytes) = match d.indices {
            None => {
                if corners > u64::from(d.vertex_count) {
                    return Err(bad(&format!(
                        "{} triangles without indices need {corners} vertices, it has {}",
                        d.triangle_count, d.vertex_count
                    )));
                }
                (NO_INDICES, 0, 0)
            }
            Some(ix) => {
                let size = match ix.index_type {
                    vk::IndexType::UINT16 => 2,
                    vk::IndexType::UINT32 => 4,
                    other => return Err(bad(&format!("index type {other:?}: UINT16 or UINT32"))),
                };
                let indices = buffer(ix.buffer)?;
                let end = ix.offset + corners * size;
                if ix.offset % size != 0 || end > indices.size {
                    return Err(bad(&format!(
                        "{corners} indices of {size} bytes at offset {} end at byte {end}: \
                         the offset a multiple of {size}, the end within buffer {}'s {} \
                         bytes",
                        ix.offset, ix.buffer, indices.size
                    )));
                }
                (ix.buffer as u32, (ix.offset / size) as u32, size as u32)
            }
        };
        let Some((rows, cofactor)) = fold_transform(d.transform, eye) else {
            return Err(bad("its transform does not round to finite f32"));
        };
        table.push(GpuDraw {
            row_x: rows[0],
            row_y: rows[1],
            row_z: rows[2],
            cofactor_x: cofactor[0],
            first_triangle: first as u32,
            cofactor_y: cofactor[1],
            triangle_count: d.triangle_count,
            cofactor_z: cofactor[2],
            vertex_slot: d.vertex_buffer as u32,
            vertex_offset: (d.vertex_offset / 4) as u32,
            vertex_stride: (d.vertex_stride / 4) as u32,
            vertex_count: d.vertex_count,
            index_slot,
            index_offset,
            index_bytes,
        });
        first += u64::from(d.triangle_count);
        if first >= u64::from(izb_contract::word::DEPTH_SURFACE) {
            return Err(bad("the draws' triangles reach the G-buffer's id limit"));
        }
    }
    Ok(first as u32)
}

/// Records the step: one thread per triangle, then a barrier before the
/// passes that read the triangles.
pub fn gather_draws(rec: &Recorder, kernels: &Kernels, triangles: u32) {
    rec.begin_label("gather_draws");
    rec.dispatch_linear(&kernels.gather_draws, triangles);
    rec.barrier();
    rec.end_label();
}

/// Makes the host's last writes of `buffers` visible to the pass's
/// compute-shader reads.
///
/// # Safety
/// `cmd` is recording, and each buffer's `written_by` is truthful.
pub unsafe fn acquire(device: &ash::Device, cmd: vk::CommandBuffer, buffers: &[HostBuffer]) {
    let mut src_stage = vk::PipelineStageFlags::empty();
    let mut src_access = vk::AccessFlags::empty();
    for b in buffers {
        src_stage |= b.written_by.0;
        src_access |= b.written_by.1;
    }
    if src_stage.is_empty() {
        return;
    }
    let barrier = [vk::MemoryBarrier::default()
        .src_access_mask(src_access)
        .dst_access_mask(vk::AccessFlags::SHADER_READ)];
    // SAFETY: the caller's promise; `barrier` outlives the call.
    unsafe {
        device.cmd_pipeline_barrier(
            cmd,
            src_stage,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::DependencyFlags::empty(),
            &barrier,
            &[],
            &[],
        );
    }
}
