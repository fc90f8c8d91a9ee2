//! Compute pipelines. Every pass binds the same descriptor set — one
//! storage buffer per binding of `shaders/common.glsl` — so one
//! [`BindingLayout`] serves all [`ComputeKernel`]s, and a frame writes its
//! buffers into one [`DescriptorSet`]. All three free their Vulkan objects
//! on drop.

use super::context::DeviceShared;
use super::resources::GpuBuffer;
use super::GpuError;
use ash::vk;
use std::sync::Arc;

/// The descriptor set layouts and pipeline layout shared by every pass:
/// set 0, the frame's storage buffers; set 1 (`HOST_SET`), the host's
/// images the shadow pass reads (`super::host_images`), which only
/// `gbuffer_from_visibility` uses — a pipeline that does not use a set
/// needs nothing bound there, so the batch frame binds set 0 alone.
pub struct BindingLayout {
    shared: Arc<DeviceShared>,
    pub set_layout: vk::DescriptorSetLayout,
    pub host_images_layout: vk::DescriptorSetLayout,
    pub pipeline_layout: vk::PipelineLayout,
}

impl BindingLayout {
    pub fn new(shared: &Arc<DeviceShared>) -> Result<Self, GpuError> {
        // The pass's set and the host geometry's array, all storage
        // buffers one compute stage may see.
        let storage_buffers =
            super::shared::BINDING_COUNT + super::shared::host_image::GEOMETRY_SLOTS;
        let limit = shared.limits.max_per_stage_descriptor_storage_buffers;
        if limit < storage_buffers {
            return Err(GpuError::Unsupported(format!(
                "this device lets a shader stage see {limit} storage buffers; the passes' \
                 layout has {storage_buffers} (maxPerStageDescriptorStorageBuffers)"
            )));
        }
        let bindings: Vec<vk::DescriptorSetLayoutBinding> = (0..super::shared::BINDING_COUNT)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    // The shadow map's depth-only pass reads the frame,
                    // the triangles and the light state in its vertex shader.
                    .stage_flags(vk::ShaderStageFlags::COMPUTE | vk::ShaderStageFlags::VERTEX)
            })
            .collect();
        let device = &shared.device;
        let create = |bindings: &[vk::DescriptorSetLayoutBinding]| {
            let info = vk::DescriptorSetLayoutCreateInfo::default().bindings(bindings);
            // SAFETY: `info` and the bindings it points to outlive the call.
            unsafe { device.create_descriptor_set_layout(&info, None) }.map_err(GpuError::vk)
        };
        let set_layout = create(&bindings)?;
        use super::shared::host_image;
        let host_binding = |binding, kind| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(binding)
                .descriptor_type(kind)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
        };
        let host_bindings = [
            host_binding(host_image::VISIBILITY, vk::DescriptorType::SAMPLED_IMAGE),
            host_binding(host_image::MASKS, vk::DescriptorType::STORAGE_IMAGE),
            host_binding(host_image::LIT, vk::DescriptorType::STORAGE_IMAGE),
            host_binding(host_image::DEPTH, vk::DescriptorType::SAMPLED_IMAGE),
            host_binding(host_image::NORMAL, vk::DescriptorType::SAMPLED_IMAGE),
            host_binding(host_image::GEOMETRY, vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(host_image::GEOMETRY_SLOTS),
        ];
        const _: () = assert!(host_image::BINDING_COUNT == 6);
        let host_images_layout = match create(&host_bindings) {
            Ok(l) => l,
            Err(e) => {
                // SAFETY: created above, used by nothing yet.
                unsafe { device.destroy_descriptor_set_layout(set_layout, None) };
                return Err(e);
            }
        };
        const _: () = assert!(super::shared::host_image::SET == 1);
        let layouts = [set_layout, host_images_layout];
        let info = vk::PipelineLayoutCreateInfo::default().set_layouts(&layouts);
        // SAFETY: both set layouts were created just above on this device.
        let pipeline_layout = match unsafe { device.create_pipeline_layout(&info, None) } {
            Ok(l) => l,
            Err(e) => {
                // SAFETY: created above, used by nothing (the pipeline layout failed).
                unsafe {
                    device.destroy_descriptor_set_layout(set_layout, None);
                    device.destroy_descriptor_set_layout(host_images_layout, None);
                }
                return Err(GpuError::vk(e));
            }
        };
        Ok(BindingLayout {
            shared: shared.clone(),
            set_layout,
            host_images_layout,
            pipeline_layout,
        })
    }
}

impl Drop for BindingLayout {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: every pipeline and descriptor set made with this layout
        // holds the layout alive through the renderer (its fields drop the
        // kernels first) and no frame is in flight: frames wait for their
        // fence, and a poisoned device returns above.
        unsafe {
            let d = &self.shared.device;
            d.destroy_pipeline_layout(self.pipeline_layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_descriptor_set_layout(self.host_images_layout, None);
        }
    }
}

/// One compute shader as a pipeline.
pub struct ComputeKernel {
    shared: Arc<DeviceShared>,
    pub name: &'static str,
    pub pipeline: vk::Pipeline,
}

impl ComputeKernel {
    /// Builds the pipeline from SPIR-V bytes (as `build.rs` wrote them).
    pub fn new(
        shared: &Arc<DeviceShared>,
        layout: &BindingLayout,
        name: &'static str,
        spirv: &[u8],
    ) -> Result<Self, GpuError> {
        let words = spirv_words(name, spirv)?;
        let device = &shared.device;
        let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
        let module =
            // SAFETY: `words` is whole SPIR-V words with its magic number
            // (`spirv_words`); `module_info` outlives the call.
            unsafe { device.create_shader_module(&module_info, None) }.map_err(GpuError::vk)?;
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout.pipeline_layout)];
        let pipeline =
            // SAFETY: `module` and `layout` are alive; `info` outlives the call.
            unsafe { device.create_compute_pipelines(vk::PipelineCache::null(), &info, None) };
        // SAFETY: a pipeline keeps no reference to its module once created.
        unsafe { device.destroy_shader_module(module, None) };
        let pipeline = pipeline.map_err(|(_, e)| GpuError::vk(e))?[0];
        shared.set_name(pipeline, name);
        Ok(ComputeKernel {
            shared: shared.clone(),
            name,
            pipeline,
        })
    }
}

/// SPIR-V bytes as the words a shader module takes: a whole number of
/// words starting with the magic number, else an error naming the module
/// (an earlier version cut a partial last word off silently).
pub fn spirv_words(name: &str, spirv: &[u8]) -> Result<Vec<u32>, GpuError> {
    ash::util::read_spv(&mut std::io::Cursor::new(spirv))
        .map_err(|e| GpuError::Unsupported(format!("shader `{name}` is not SPIR-V: {e}")))
}

impl Drop for ComputeKernel {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: frames wait for their fence before returning, so no command
        // buffer using the pipeline is pending (a poisoned device returns above).
        unsafe { self.shared.device.destroy_pipeline(self.pipeline, None) };
    }
}

/// A descriptor pool holding the one set a frame binds, and the buffers
/// the set points at: they live as long as the set, whatever order their
/// owners drop in.
pub struct DescriptorSet {
    shared: Arc<DeviceShared>,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
    _buffers: [Arc<GpuBuffer>; BINDINGS],
}

/// Bindings of the set (`shared::BINDING_COUNT`).
const BINDINGS: usize = super::shared::BINDING_COUNT as usize;

impl DescriptorSet {
    /// Allocates the set and points binding `b` at `buffers[b]`.
    pub fn new(
        shared: &Arc<DeviceShared>,
        layout: &BindingLayout,
        buffers: [Arc<GpuBuffer>; BINDINGS],
    ) -> Result<Self, GpuError> {
        shared.count_allocation(super::context::Allocation::DescriptorSet);
        let device = &shared.device;
        let sizes = [vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::STORAGE_BUFFER)
            .descriptor_count(super::shared::BINDING_COUNT)];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        // SAFETY: `info` and its pool sizes outlive the call.
        let pool = unsafe { device.create_descriptor_pool(&info, None) }.map_err(GpuError::vk)?;
        let layouts = [layout.set_layout];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        // SAFETY: `pool` was created above for exactly this one set.
        let set = match unsafe { device.allocate_descriptor_sets(&alloc) } {
            Ok(s) => s[0],
            Err(e) => {
                // SAFETY: created above; its allocation failed, so nothing uses it.
                unsafe { device.destroy_descriptor_pool(pool, None) };
                return Err(GpuError::vk(e));
            }
        };
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|b| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(b.buffer)
                    .offset(0)
                    .range(vk::WHOLE_SIZE)]
            })
            .collect();
        let writes: Vec<vk::WriteDescriptorSet> = infos
            .iter()
            .enumerate()
            .map(|(b, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(b as u32)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        // SAFETY: the set is not bound yet; the set holds every buffer
        // until it is destroyed.
        unsafe { device.update_descriptor_sets(&writes, &[]) };
        Ok(DescriptorSet {
            shared: shared.clone(),
            pool,
            set,
            _buffers: buffers,
        })
    }

    /// The set's handle (binding it is `unsafe`, as every recording is).
    pub fn handle(&self) -> vk::DescriptorSet {
        self.set
    }
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: dropped after the frame's fence wait, so no command buffer
        // using the set is pending (a poisoned device returns above).
        unsafe { self.shared.device.destroy_descriptor_pool(self.pool, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::resources::BufferDesc;

    /// The set holds the buffers it points at: dropping their other
    /// owners first frees nothing (an earlier version relied on the
    /// frame's declaration order).
    #[test]
    fn a_descriptor_set_keeps_its_buffers() {
        let Some(context) = crate::gpu::context::test_context() else {
            return;
        };
        let shared = &context.shared;
        let layout = BindingLayout::new(shared).unwrap();
        let buffers: Vec<Arc<GpuBuffer>> = (0..BINDINGS)
            .map(|_| {
                let desc = BufferDesc::device("test", "bound", 16);
                Arc::new(GpuBuffer::new(shared, desc).unwrap())
            })
            .collect();
        let watch: Vec<_> = buffers.iter().map(Arc::downgrade).collect();
        let set = DescriptorSet::new(shared, &layout, std::array::from_fn(|b| buffers[b].clone()))
            .unwrap();
        drop(buffers);
        assert_eq!(
            watch.iter().filter(|w| w.upgrade().is_some()).count(),
            BINDINGS
        );
        drop(set);
        assert_eq!(watch.iter().filter(|w| w.upgrade().is_some()).count(), 0);
    }

    #[test]
    fn spirv_of_partial_words_or_without_its_magic_is_refused() {
        let (_, bytes) = super::super::SPIRV_MODULES[0];
        let words = spirv_words("gbuffer", bytes).unwrap();
        assert_eq!(words.len() * 4, bytes.len());
        let cut = spirv_words("gbuffer", &bytes[..bytes.len() - 1]).unwrap_err();
        assert!(cut.to_string().contains("`gbuffer`"), "{cut}");
        let mut wrong = bytes.to_vec();
        wrong[0] ^= 1;
        assert!(spirv_words("gbuffer", &wrong).is_err());
        assert!(spirv_words("empty", &[]).is_err());
    }
}
