//! A pass for one view: the batch `render`'s (`izb render --backend
//! vulkan`, `izb bench`), whose eye never moves, holds the scene's
//! eye-relative vertices and a BVH built around that eye, and lets the
//! bin's lists reuse the BVH's memory (`layout.rs` says why). The BVH is
//! therefore copied in again at each frame's start from host memory
//! ([`RestagedBvh`]); the camera and the image size stay the pass's.

use super::layout::ResidentLayout;
use super::{GBufferInput, ShadowPass, ShadowPassConfig};
use crate::gpu::context::DeviceShared;
use crate::gpu::frame::GpuRenderer;
use crate::gpu::frame_inputs::SceneUpload;
use crate::gpu::frame_memory::frame_buffer_descs;
use crate::gpu::resources::GpuBuffer;
use crate::gpu::shared::{binding, BINDING_COUNT};
use crate::gpu::GpuError;
use crate::scene::Scene;
use ash::vk;
use std::sync::Arc;

/// The BVH's nodes and leaf slots in host-visible buffers, copied into
/// the device buffers the bin's lists share with them at each frame's
/// start.
pub(super) struct RestagedBvh {
    nodes: GpuBuffer,
    prims: GpuBuffer,
}

impl RestagedBvh {
    /// The staged BVH of `layout` where its buffers are shared (`at`, each
    /// binding's buffer), else none.
    pub(super) fn new(
        shared: &Arc<DeviceShared>,
        layout: &ResidentLayout,
        at: &[usize; BINDING_COUNT as usize],
    ) -> Result<Option<Self>, GpuError> {
        let shares = |a: u32, b: u32| at[a as usize] == at[b as usize];
        let shared_lists = shares(binding::BVH_NODES, binding::CELL_TRIANGLES)
            || shares(binding::BVH_PRIMS, binding::OVERFLOW);
        if !shared_lists || layout.bvh.nodes.is_empty() {
            return Ok(None);
        }
        Ok(Some(RestagedBvh {
            nodes: GpuBuffer::staging(shared, bytemuck::cast_slice(&layout.bvh.nodes))?,
            prims: GpuBuffer::staging(shared, bytemuck::cast_slice(&layout.bvh.prims))?,
        }))
    }

    /// Records the copies into the pass's BVH buffers (`buffer`: each
    /// binding's).
    ///
    /// # Safety
    /// `cmd` is recording outside a render pass, after a barrier that ends
    /// every earlier access to the BVH's buffers, and the pass (with
    /// these buffers) outlives its execution.
    pub(super) unsafe fn record(
        &self,
        device: &ash::Device,
        cmd: vk::CommandBuffer,
        buffer: impl Fn(u32) -> vk::Buffer,
    ) {
        for (staged, b) in [
            (&self.nodes, binding::BVH_NODES),
            (&self.prims, binding::BVH_PRIMS),
        ] {
            let region = [vk::BufferCopy::default().size(staged.size())];
            // SAFETY: the caller's promise; each device buffer is at
            // least its staged copy's size (sized from the same BVH).
            unsafe { device.cmd_copy_buffer(cmd, staged.buffer, buffer(b), &region) };
        }
    }

    /// Bytes of host-visible memory it holds.
    pub(super) fn bytes(&self) -> u64 {
        self.nodes.size() + self.prims.size()
    }
}

impl<'r> ShadowPass<'r> {
    /// Makes the pass for `scene`'s view only, with its own ray-cast
    /// G-buffer (`config.gbuffer` is [`GBufferInput::RayCast`]): the batch
    /// `render`'s. Its frames must keep the scene's camera and size.
    pub(crate) fn for_one_view(
        renderer: &'r GpuRenderer,
        scene: Scene,
        config: ShadowPassConfig,
    ) -> Result<Self, GpuError> {
        if config.gbuffer != GBufferInput::RayCast {
            return Err(GpuError::Unsupported(format!(
                "a pass for one view casts its own G-buffer, not {:?}",
                config.gbuffer
            )));
        }
        let upload = SceneUpload::new(&scene);
        Self::make(renderer, scene, config, None, None, Some(upload))
    }

    /// Bytes of the BVH's nodes the pass holds (0 without a ray cast).
    pub(super) fn bvh_node_bytes(&self) -> u64 {
        frame_buffer_descs(&self.sizes)[binding::BVH_NODES as usize].size
    }

    /// Whether the pass is for its scene's view only.
    pub(super) fn is_one_view(&self) -> bool {
        self.one_view
    }

    /// The pass's device buffers, each once (a pass for one view binds
    /// some twice).
    pub(super) fn distinct_buffers(&self) -> Vec<Arc<GpuBuffer>> {
        let mut distinct: Vec<Arc<GpuBuffer>> = Vec::with_capacity(self.buffers.len());
        for b in &self.buffers {
            if !distinct.iter().any(|d| Arc::ptr_eq(d, b)) {
                distinct.push(b.clone());
            }
        }
        distinct
    }
}
