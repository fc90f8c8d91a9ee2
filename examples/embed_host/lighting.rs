//! The host's own lighting pass, recorded after izb's shadow pass in the
//! same command buffer: a deferred renderer's compute lighting over its
//! visibility buffer that samples the lit fraction izb left
//! (`lighting.comp`). It is what the pass is for — the shadow mask
//! consumed by the host's shading, not izb's — and the image it writes
//! can be held against izb's own shaded image of the same frame (same
//! constants: `izb::output::{AMBIENT, DIFFUSE, SKY_RGB}`).
//!
//! State: the lit fraction is read in `GENERAL` after the pass's compute
//! writes; the visibility buffer in `SHADER_READ_ONLY_OPTIMAL`, where the
//! pass leaves it when it reads it (a visibility-buffer G-buffer), else
//! moved there from the raster's `COLOR_ATTACHMENT_OPTIMAL` here. The
//! shaded image is written in `GENERAL`.

use crate::host_device::HostGpu;
use crate::raster::{whole, OwnedImage};
use ash::vk;
use glam::DVec3;
use izb::gpu::shadow_pass::FrameView;
use izb::scene::Light;

/// The lighting shader's SPIR-V, compiled by izb's build script.
const LIGHTING_SPIRV: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/host_lighting.spv"));
/// The same over a multisampled visibility buffer (its sample 0).
const LIGHTING_MULTISAMPLED_SPIRV: &[u8] =
    include_bytes!(concat!(env!("OUT_DIR"), "/host_lighting_multisampled.spv"));

/// The lighting pass's push constants (`lighting.comp`'s `Lighting`,
/// scalar layout): every point relative to the mesh's origin.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct LightingView {
    eye: [f32; 3],
    width: u32,
    corner: [f32; 3],
    height: u32,
    dx: [f32; 3],
    light_is_point: u32,
    dy: [f32; 3],
    ambient: f32,
    light: [f32; 3],
    diffuse: f32,
    sky: [f32; 3],
}

/// `view`'s lighting parameters for an image of `extent`, for vertices
/// relative to `origin` (subtracted in `f64`).
pub fn lighting_view(view: &FrameView, extent: [u32; 2], origin: DVec3) -> LightingView {
    let frame = view.camera.frame(extent);
    let f32s = |v: DVec3| v.as_vec3().to_array();
    let (light, light_is_point) = match view.light {
        Light::Directional { direction } => (-direction.normalize(), 0),
        Light::Point { position } => (position - origin, 1),
    };
    LightingView {
        eye: f32s(view.camera.eye - origin),
        width: extent[0],
        corner: f32s(frame.direction(0.0, 0.0)),
        height: extent[1],
        dx: f32s(frame.direction_dx()),
        light_is_point,
        dy: f32s(frame.direction_dy()),
        ambient: izb::output::AMBIENT,
        light: f32s(light),
        diffuse: izb::output::DIFFUSE,
        sky: izb::output::SKY_RGB,
    }
}

/// One frame slot's images the lighting reads and writes.
pub struct LightingImages<'a> {
    pub visibility: &'a OwnedImage,
    pub lit: &'a OwnedImage,
    pub shaded: &'a OwnedImage,
}

/// The compute pipeline, its nearest-texel sampler and one descriptor
/// set per frame slot, written once (the slot's images and the mesh's
/// buffers do not change until the targets are made anew).
pub struct HostLighting {
    sampler: vk::Sampler,
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    pool: vk::DescriptorPool,
    sets: Vec<vk::DescriptorSet>,
    extent: [u32; 2],
}

impl HostLighting {
    /// The pass over `slots`' images, reading the mesh's `vertices`
    /// (`f32` triples) and `indices` (`u32`) as storage buffers.
    pub fn new(
        gpu: &HostGpu,
        extent: [u32; 2],
        slots: &[LightingImages],
        (vertices, indices): (vk::Buffer, vk::Buffer),
    ) -> Self {
        let d = &gpu.device;
        let sampler_info = vk::SamplerCreateInfo::default()
            .mag_filter(vk::Filter::NEAREST)
            .min_filter(vk::Filter::NEAREST)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_EDGE)
            .unnormalized_coordinates(false);
        // SAFETY: the device is live; destroyed in `destroy`.
        let sampler = unsafe { d.create_sampler(&sampler_info, None) }.expect("a sampler");
        let samplers = [sampler];
        let binding = |b: u32, ty: vk::DescriptorType| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b)
                .descriptor_type(ty)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
        };
        let sampled = vk::DescriptorType::COMBINED_IMAGE_SAMPLER;
        let storage = vk::DescriptorType::STORAGE_BUFFER;
        let bindings = [
            binding(0, sampled).immutable_samplers(&samplers),
            binding(1, sampled).immutable_samplers(&samplers),
            binding(2, vk::DescriptorType::STORAGE_IMAGE),
            binding(3, storage),
            binding(4, storage),
        ];
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        // SAFETY: as above.
        let set_layout =
            unsafe { d.create_descriptor_set_layout(&set_info, None) }.expect("a set layout");
        let push = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .size(std::mem::size_of::<LightingView>() as u32)];
        let set_layouts = [set_layout];
        let layout_info = vk::PipelineLayoutCreateInfo::default()
            .set_layouts(&set_layouts)
            .push_constant_ranges(&push);
        // SAFETY: as above.
        let layout = unsafe { d.create_pipeline_layout(&layout_info, None) }.expect("a layout");
        let multisampled = slots
            .first()
            .is_some_and(|s| s.visibility.samples != vk::SampleCountFlags::TYPE_1);
        let spirv = if multisampled {
            LIGHTING_MULTISAMPLED_SPIRV
        } else {
            LIGHTING_SPIRV
        };
        let words = ash::util::read_spv(&mut std::io::Cursor::new(spirv)).expect("SPIR-V");
        let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: `words` is whole SPIR-V compiled by izb's build script.
        let module = unsafe { d.create_shader_module(&module_info, None) }.expect("a module");
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(vk::ShaderStageFlags::COMPUTE)
                    .module(module)
                    .name(c"main"),
            )
            .layout(layout)];
        // SAFETY: the module and layout are live; the module is destroyed
        // once the pipeline holds what it needs of it.
        let pipeline = unsafe {
            let p = d.create_compute_pipelines(vk::PipelineCache::null(), &info, None);
            d.destroy_shader_module(module, None);
            p.map_err(|(_, e)| e).expect("the lighting pipeline")[0]
        };
        let n = slots.len() as u32;
        let sizes = [
            vk::DescriptorPoolSize::default()
                .ty(sampled)
                .descriptor_count(2 * n),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_IMAGE)
                .descriptor_count(n),
            vk::DescriptorPoolSize::default()
                .ty(storage)
                .descriptor_count(2 * n),
        ];
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(n)
            .pool_sizes(&sizes);
        // SAFETY: as above.
        let pool = unsafe { d.create_descriptor_pool(&pool_info, None) }.expect("a pool");
        let layouts = vec![set_layout; slots.len()];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        // SAFETY: the pool holds `n` sets of this layout.
        let sets = unsafe { d.allocate_descriptor_sets(&alloc) }.expect("descriptor sets");
        for (set, images) in sets.iter().zip(slots) {
            let image = |view, layout| {
                [vk::DescriptorImageInfo::default()
                    .image_view(view)
                    .image_layout(layout)]
            };
            let read_only = vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL;
            let general = vk::ImageLayout::GENERAL;
            let visibility = image(images.visibility.view, read_only);
            let lit = image(images.lit.view, general);
            let shaded = image(images.shaded.view, general);
            let buffer = |b| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(b)
                    .range(vk::WHOLE_SIZE)]
            };
            let (vertex_info, index_info) = (buffer(vertices), buffer(indices));
            let write = |b: u32, ty| {
                vk::WriteDescriptorSet::default()
                    .dst_set(*set)
                    .dst_binding(b)
                    .descriptor_type(ty)
            };
            let writes = [
                write(0, sampled).image_info(&visibility),
                write(1, sampled).image_info(&lit),
                write(2, vk::DescriptorType::STORAGE_IMAGE).image_info(&shaded),
                write(3, storage).buffer_info(&vertex_info),
                write(4, storage).buffer_info(&index_info),
            ];
            // SAFETY: the set is not in use by any frame (just made); the
            // views and buffers are live.
            unsafe { d.update_descriptor_sets(&writes, &[]) };
        }
        HostLighting {
            sampler,
            set_layout,
            layout,
            pipeline,
            pool,
            sets,
            extent,
        }
    }

    /// Records slot `slot`'s lighting after izb's pass: the barriers that
    /// make the pass's lit fraction (and, unless the pass read it, the
    /// raster's visibility buffer) visible, and the dispatch.
    /// `pass_read_visibility`: the pass left the visibility buffer in
    /// `SHADER_READ_ONLY_OPTIMAL` after its own barrier from the raster.
    ///
    /// # Safety
    /// `cmd` is recording, after this frame's raster and shadow pass into
    /// the slot's images; the slot's previous frame is done; the images
    /// and mesh buffers outlive the frame.
    pub unsafe fn record(
        &self,
        d: &ash::Device,
        cmd: vk::CommandBuffer,
        slot: usize,
        images: &LightingImages,
        pass_read_visibility: bool,
        view: &LightingView,
    ) {
        let barrier = |image: &OwnedImage, old, new, src, dst| {
            vk::ImageMemoryBarrier::default()
                .src_access_mask(src)
                .dst_access_mask(dst)
                .old_layout(old)
                .new_layout(new)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image.image)
                .subresource_range(whole(vk::ImageAspectFlags::COLOR))
        };
        let general = vk::ImageLayout::GENERAL;
        let mut barriers = vec![
            // izb's lit fraction: its compute write, read here.
            barrier(
                images.lit,
                general,
                general,
                vk::AccessFlags::SHADER_WRITE,
                vk::AccessFlags::SHADER_READ,
            ),
            // The shaded image: its last frame's contents are replaced
            // (that frame is done; the write after write needs only the
            // order, which the source stage gives).
            barrier(
                images.shaded,
                vk::ImageLayout::UNDEFINED,
                general,
                vk::AccessFlags::empty(),
                vk::AccessFlags::SHADER_WRITE,
            ),
        ];
        let mut source = vk::PipelineStageFlags::COMPUTE_SHADER;
        if !pass_read_visibility {
            barriers.push(barrier(
                images.visibility,
                vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
                vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
                vk::AccessFlags::SHADER_READ,
            ));
            source |= vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT;
        }
        let groups = self.extent.map(|n| n.div_ceil(8));
        // SAFETY: the caller's promise; the set is the slot's, written
        // once with live views and buffers.
        unsafe {
            d.cmd_pipeline_barrier(
                cmd,
                source,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::DependencyFlags::empty(),
                &[],
                &[],
                &barriers,
            );
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
            d.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.layout,
                0,
                &self.sets[slot..slot + 1],
                &[],
            );
            d.cmd_push_constants(
                cmd,
                self.layout,
                vk::ShaderStageFlags::COMPUTE,
                0,
                bytemuck::bytes_of(view),
            );
            d.cmd_dispatch(cmd, groups[0], groups[1], 1);
        }
    }

    /// Frees the pass; no work that uses it is executing.
    pub fn destroy(&mut self, gpu: &HostGpu) {
        let d = &gpu.device;
        // SAFETY: the caller's promise; each handle is destroyed once
        // (the sets with their pool).
        unsafe {
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_pool(self.pool, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
            d.destroy_sampler(self.sampler, None);
        }
        self.sets.clear();
    }
}

/// How the host's lighting of a frame compares with izb's own shaded
/// image of it (the same constants): per pixel, the largest difference of
/// any channel, in 8-bit codes.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct LightingComparison {
    pub pixels: usize,
    /// Pixels where some channel differs.
    pub differing: usize,
    /// The largest difference, in codes.
    pub max_difference: u8,
}

/// The host's `shaded` RGBA8 words against izb's RGB pixels.
pub fn compare_lighting(host: &[u32], izb: &[[u8; 3]]) -> LightingComparison {
    let mut c = LightingComparison {
        pixels: izb.len(),
        ..Default::default()
    };
    for (word, rgb) in host.iter().zip(izb) {
        let bytes = word.to_le_bytes();
        let most = (0..3).map(|k| bytes[k].abs_diff(rgb[k])).max().unwrap_or(0);
        c.differing += usize::from(most != 0);
        c.max_difference = c.max_difference.max(most);
    }
    c
}
