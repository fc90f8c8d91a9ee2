//! The test host's own geometry for the shadow pass's host-geometry input
//! (`ShadowPass::with_host_geometry`): a scene's triangles kept as three
//! meshes in object space — `u32` indices into interleaved positions
//! (stride 24, offset 16) placed by a turn, `u16` indices at an odd
//! half-word offset into packed positions placed by a mirrored, scaled
//! turn, and unindexed positions placed by the identity — in three device
//! buffers the host copies into in each frame's command buffer.

use super::shadow_pass::HostTestImage;
use ash::vk;
use glam::{DAffine3, DMat3, DQuat, DVec3};
use izb::gpu::gather_draws::{FrameGeometry, HostBuffer, HostDraw, HostIndices};
use izb::gpu::host_images::FrameImages;
use izb::gpu::resources::{BufferDesc, GpuBuffer};
use izb::gpu::shadow_pass::{FrameView, ShadowPass};
use izb::gpu::{GpuError, GpuRenderer};
use izb::scene::Scene;
use std::collections::HashMap;

/// The host's meshes: each buffer's words and the draws over them.
pub struct HostMeshes {
    pub words: Vec<Vec<u32>>,
    pub draws: Vec<HostDraw>,
}

/// Object-space positions of `world` under `transform`, each distinct
/// world vertex once, and the triangles' indices into them.
fn object_mesh(world: &[[DVec3; 3]], transform: DAffine3) -> (Vec<[f32; 3]>, Vec<u32>) {
    let inverse = transform.inverse();
    let mut index: HashMap<[u64; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for t in world {
        for v in t {
            let i = *index
                .entry(v.to_array().map(f64::to_bits))
                .or_insert_with(|| {
                    positions.push(inverse.transform_point3(*v).as_vec3().to_array());
                    positions.len() as u32 - 1
                });
            indices.push(i);
        }
    }
    (positions, indices)
}

pub fn host_meshes(scene: &Scene) -> HostMeshes {
    let n = scene.triangles.len();
    let chunks = [
        &scene.triangles[..n / 3],
        &scene.triangles[n / 3..2 * n / 3],
        &scene.triangles[2 * n / 3..],
    ];
    let turn = DAffine3::from_mat3_translation(
        DMat3::from_quat(DQuat::from_rotation_y(0.6)),
        DVec3::new(3.0, 0.5, -2.0),
    );
    let mirrored = DAffine3::from_mat3_translation(
        DMat3::from_quat(DQuat::from_rotation_x(-0.3))
            * DMat3::from_diagonal(DVec3::new(-2.0, 0.5, 1.5)),
        DVec3::new(-4.0, 1.0, 6.0),
    );
    let (p0, i0) = object_mesh(chunks[0], turn);
    let (p1, i1) = object_mesh(chunks[1], mirrored);
    assert!(p1.len() < 1 << 16, "u16 indices");
    // Buffer 0: four words, then per vertex its position and 3 words.
    let mut b0 = vec![0x7FC0_0000u32; 4];
    for p in &p0 {
        b0.extend(p.map(f32::to_bits));
        b0.extend([0xFFFF_FFFF; 3]);
    }
    // Buffer 1: mesh 1 packed, then mesh 2's unindexed corners.
    let mut b1: Vec<u32> = p1.iter().flat_map(|p| p.map(f32::to_bits)).collect();
    let unindexed_offset = 4 * b1.len() as u64;
    for t in chunks[2] {
        for v in t {
            b1.extend(v.as_vec3().to_array().map(f32::to_bits));
        }
    }
    // Buffer 2: mesh 0's u32 indices, a half word, mesh 1's u16 indices.
    let mut bytes: Vec<u8> = i0.iter().flat_map(|i| i.to_le_bytes()).collect();
    bytes.extend([0xAB, 0xCD]);
    let u16_offset = bytes.len() as u64;
    bytes.extend(i1.iter().flat_map(|&i| (i as u16).to_le_bytes()));
    bytes.resize(bytes.len().next_multiple_of(4), 0);
    let b2: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
    let draw = |vertex_buffer,
                vertex_offset,
                vertex_stride,
                vertex_count: usize,
                indices,
                t: &[_],
                transform| HostDraw {
        vertex_buffer,
        vertex_offset,
        vertex_stride,
        vertex_format: vk::Format::R32G32B32_SFLOAT,
        vertex_count: vertex_count as u32,
        indices,
        triangle_count: t.len() as u32,
        transform,
    };
    let indices = |offset, index_type| {
        Some(HostIndices {
            buffer: 2,
            offset,
            index_type,
        })
    };
    HostMeshes {
        words: vec![b0, b1, b2],
        draws: vec![
            draw(
                0,
                16,
                24,
                p0.len(),
                indices(0, vk::IndexType::UINT32),
                chunks[0],
                turn,
            ),
            draw(
                1,
                0,
                12,
                p1.len(),
                indices(u16_offset, vk::IndexType::UINT16),
                chunks[1],
                mirrored,
            ),
            draw(
                1,
                unindexed_offset,
                12,
                3 * chunks[2].len(),
                None,
                chunks[2],
                DAffine3::IDENTITY,
            ),
        ],
    }
}

/// The host's device buffers of `meshes` and their staging copies.
pub struct HostBuffers {
    device: Vec<GpuBuffer>,
    staging: Vec<GpuBuffer>,
}

impl HostBuffers {
    pub fn new(r: &GpuRenderer, meshes: &HostMeshes) -> Self {
        let shared = &r.context.shared;
        let device = meshes
            .words
            .iter()
            .map(|w| {
                GpuBuffer::new(
                    shared,
                    BufferDesc::device("host", "host_geometry", 4 * w.len() as u64),
                )
                .unwrap()
            })
            .collect();
        let staging = meshes
            .words
            .iter()
            .map(|w| GpuBuffer::staging(shared, bytemuck::cast_slice(w)).unwrap())
            .collect();
        HostBuffers { device, staging }
    }

    /// The buffers as a frame declares them, last written by `written_by`.
    pub fn declared(
        &self,
        written_by: (vk::PipelineStageFlags, vk::AccessFlags),
    ) -> Vec<HostBuffer> {
        self.device
            .iter()
            .map(|b| HostBuffer {
                buffer: b.buffer,
                size: b.desc.size,
                usage: vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::TRANSFER_DST,
                written_by,
            })
            .collect()
    }

    /// Records the copies into the device buffers after the previous
    /// frame's reads (the contract's write-after-read barrier).
    ///
    /// # Safety
    /// `cmd` is recording on the buffers' device.
    pub unsafe fn record_fill(
        &self,
        device: &ash::Device,
        cmd: vk::CommandBuffer,
    ) -> Vec<HostBuffer> {
        let barrier = [vk::MemoryBarrier::default()];
        // SAFETY: the caller's promise; the buffers outlive the frame.
        unsafe {
            device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &barrier,
                &[],
                &[],
            );
            for (from, to) in self.staging.iter().zip(&self.device) {
                let region = [vk::BufferCopy::default().size(from.desc.size)];
                device.cmd_copy_buffer(cmd, from.buffer, to.buffer, &region);
            }
        }
        self.declared((
            vk::PipelineStageFlags::TRANSFER,
            vk::AccessFlags::TRANSFER_WRITE,
        ))
    }
}

/// Frame `k`: the host's buffers and visibility ids copied in, then the
/// pass recorded with `draws`, in one command buffer; the buffers and
/// sets made while recording.
#[allow(clippy::too_many_arguments)]
pub fn run_geometry_frame(
    r: &GpuRenderer,
    pass: &mut ShadowPass,
    image: &mut HostTestImage,
    buffers: &HostBuffers,
    k: usize,
    view: &FrameView,
    ids: &[u32],
    draws: &[HostDraw],
) -> Result<[u64; 2], GpuError> {
    let shared = &r.context.shared;
    let staging = GpuBuffer::staging(shared, bytemuck::cast_slice(ids))?;
    let slot = k % pass.frames_in_flight();
    let mut made = [0; 2];
    let record = |cmd| {
        // SAFETY: `cmd` is recording; the staging buffers outlive the
        // submission, which the call waits for.
        let (declared_image, declared_buffers) = unsafe {
            (
                image.record_fill(cmd, &staging),
                buffers.record_fill(&shared.device, cmd),
            )
        };
        let view = FrameView {
            images: FrameImages {
                visibility: Some(declared_image),
                ..view.images
            },
            ..*view
        };
        let geometry = FrameGeometry {
            buffers: &declared_buffers,
            draws,
        };
        let before = shared.allocations();
        // SAFETY: as in `run_frame`; the image and buffers live until the
        // wait and are declared as the commands above leave them.
        let recorded = unsafe { pass.record_host_geometry(cmd, slot, &view, &geometry) };
        let after = shared.allocations();
        made = [after[0] - before[0], after[1] - before[1]];
        recorded
    };
    // SAFETY: the pass, the image and the buffers outlive the call, which
    // waits.
    unsafe { r.context.submit_and_wait(record) }?;
    Ok(made)
}
