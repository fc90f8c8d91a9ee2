//! The host's multisampled visibility buffer read back, for the CPU twin
//! (a check outside the measured frames, after the frame was waited for):
//! a multisampled image cannot be copied to a buffer, so a compute shader
//! of the host's (`multisampled_ids.comp`) fetches every sample into one.
//! Its pipeline is made and destroyed around the one dispatch.

use crate::host_device::HostGpu;
use crate::raster::{OwnedBuffer, OwnedImage};
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The read-back shader's SPIR-V, compiled by izb's build script.
const SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/host_multisampled_ids.spv"));

/// Every sample of `image` (`R32_UINT`, `extent`, its `samples`), in
/// `SHADER_READ_ONLY_OPTIMAL` after a compute shader's read of it (the
/// pass's): `ids[(y * w + x) * N + s]`.
///
/// # Safety
/// `image` is a live `R32_UINT` image of this device with more than one
/// sample, in `SHADER_READ_ONLY_OPTIMAL`, its last write made visible to
/// compute-shader reads (the pass's barrier did); nothing that uses it is
/// executing; `pool` is this device's and used by this thread only.
pub unsafe fn read_back_samples(
    gpu: &HostGpu,
    pool: vk::CommandPool,
    image: &OwnedImage,
    extent: [u32; 2],
) -> Vec<u32> {
    let d = &gpu.device;
    let samples = image.samples.as_raw();
    let count = extent[0] as u64 * extent[1] as u64 * u64::from(samples);
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let mut out = OwnedBuffer::new(gpu, "ids", count * 4, usage, MemoryLocation::GpuToCpu);
    let binding = |b: u32, ty| {
        vk::DescriptorSetLayoutBinding::default()
            .binding(b)
            .descriptor_type(ty)
            .descriptor_count(1)
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
    };
    let bindings = [
        binding(0, vk::DescriptorType::SAMPLED_IMAGE),
        binding(1, vk::DescriptorType::STORAGE_BUFFER),
    ];
    let push = [vk::PushConstantRange::default()
        .stage_flags(vk::ShaderStageFlags::COMPUTE)
        .size(12)];
    let words = ash::util::read_spv(&mut std::io::Cursor::new(SPIRV)).expect("SPIR-V");
    let sizes = [
        vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::SAMPLED_IMAGE)
            .descriptor_count(1),
        vk::DescriptorPoolSize::default()
            .ty(vk::DescriptorType::STORAGE_BUFFER)
            .descriptor_count(1),
    ];
    // SAFETY: the caller's promise; every object made here is destroyed
    // below, after the wait.
    unsafe {
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        let set_layout = d.create_descriptor_set_layout(&set_info, None).unwrap();
        let set_layouts = [set_layout];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&push);
        let layout = d.create_pipeline_layout(&layout_info, None).unwrap();
        let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
        let module = d.create_shader_module(&module_info, None).unwrap();
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout)];
        let pipeline = d
            .create_compute_pipelines(vk::PipelineCache::null(), &info, None)
            .map_err(|(_, e)| e)
            .unwrap()[0];
        d.destroy_shader_module(module, None);
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        let descriptors = d.create_descriptor_pool(&pool_info, None).unwrap();
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(descriptors)
            .set_layouts(&set_layouts);
        let set = d.allocate_descriptor_sets(&alloc).unwrap()[0];
        let image_info = [vk::DescriptorImageInfo::default()
            .image_view(image.view)
            .image_layout(vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL)];
        let buffer_info = [vk::DescriptorBufferInfo::default()
            .buffer(out.buffer)
            .range(vk::WHOLE_SIZE)];
        let writes = [
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(0)
                .descriptor_type(vk::DescriptorType::SAMPLED_IMAGE)
                .image_info(&image_info),
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(1)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .buffer_info(&buffer_info),
        ];
        d.update_descriptor_sets(&writes, &[]);

        let record = |cmd| {
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
            let point = vk::PipelineBindPoint::COMPUTE;
            d.cmd_bind_descriptor_sets(cmd, point, layout, 0, &[set], &[]);
            let size = [extent[0], extent[1], samples];
            let stage = vk::ShaderStageFlags::COMPUTE;
            d.cmd_push_constants(cmd, layout, stage, 0, bytemuck::cast_slice(&size));
            d.cmd_dispatch(cmd, extent[0].div_ceil(8), extent[1].div_ceil(8), 1);
            let to_host = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ)];
            d.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::HOST,
                vk::DependencyFlags::empty(),
                &to_host,
                &[],
                &[],
            );
        };
        gpu.submit_once(pool, record);
        d.destroy_descriptor_pool(descriptors, None);
        d.destroy_pipeline(pipeline, None);
        d.destroy_pipeline_layout(layout, None);
        d.destroy_descriptor_set_layout(set_layout, None);
    }
    let ids = bytemuck::pod_collect_to_vec(out.bytes());
    out.destroy(gpu);
    ids
}
