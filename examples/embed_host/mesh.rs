//! The host's mesh: the scene's triangles as an indexed vertex buffer in
//! host-visible memory, as the raster and the pass both read it.

use crate::host_device::HostGpu;
use crate::raster::OwnedBuffer;
use ash::vk;
use glam::{DVec3, Vec3};
use gpu_allocator::MemoryLocation;
use izb::scene::Scene;
use std::collections::HashMap;

/// The scene's triangles as the host's indexed mesh: distinct vertices
/// relative to `origin`, rounded to f32, and three indices a triangle in
/// the scene's order (so `gl_PrimitiveID` is the scene's triangle id).
pub fn indexed_mesh(scene: &Scene, origin: DVec3) -> (Vec<Vec3>, Vec<u32>) {
    let mut at: HashMap<[u64; 3], u32> = HashMap::new();
    let mut vertices = Vec::new();
    let mut indices = Vec::with_capacity(scene.triangles.len() * 3);
    for t in scene.triangles.iter() {
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

/// A host-visible buffer holding `bytes`.
pub fn host_buffer(
    gpu: &HostGpu,
    name: &str,
    bytes: &[u8],
    usage: vk::BufferUsageFlags,
) -> OwnedBuffer {
    let size = bytes.len().max(4) as u64;
    let mut buffer = OwnedBuffer::new(gpu, name, size, usage, MemoryLocation::CpuToGpu);
    buffer.bytes()[..bytes.len()].copy_from_slice(bytes);
    buffer
}
