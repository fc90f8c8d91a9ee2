//! The host's visibility-buffer pass on the rasteriser, as an engine
//! draws one: its own render pass, pipeline and framebuffers over images
//! it owns, the scene's triangles from its own vertex and index buffers,
//! drawn with izb's visibility shaders and push constants
//! (`izb::gpu::visibility_raster`). The colour attachments are left in
//! `COLOR_ATTACHMENT_OPTIMAL`, written at `COLOR_ATTACHMENT_OUTPUT`, and
//! the depth in `DEPTH_STENCIL_ATTACHMENT_OPTIMAL`, written at
//! `LATE_FRAGMENT_TESTS`: what the host declares to the shadow pass.
//! With `--msaa N` the visibility buffer and depth have N samples a pixel
//! and are not resolved (integer ids cannot be averaged): the pass reads
//! every sample. With
//! a depth + normal G-buffer the pass also writes the geometric normal
//! (`depth_normal_raster.frag`) and keeps the depth, in the host's chosen
//! format and convention.

use crate::host_device::HostGpu;
use crate::targets::HostDepth;
use ash::vk;
use gpu_allocator::vulkan::Allocation;
use gpu_allocator::MemoryLocation;
use izb::gpu::host_images::format_aspects;
use izb::gpu::visibility_raster::{
    VisibilityView, DEPTH_NORMAL_FRAGMENT_SPIRV, DEPTH_NORMAL_VERTEX_SPIRV, FRAGMENT_SPIRV,
    VERTEX_SPIRV,
};

/// An image of the host's with its view and memory.
pub struct OwnedImage {
    pub image: vk::Image,
    /// The view a shader reads (a depth image's: its depth aspect alone).
    pub view: vk::ImageView,
    /// The view a framebuffer binds: every aspect of the format (the
    /// same view but for a combined depth-stencil format).
    pub attachment_view: vk::ImageView,
    pub format: vk::Format,
    pub usage: vk::ImageUsageFlags,
    /// Samples a pixel (`TYPE_1` but for a multisampled raster's targets).
    pub samples: vk::SampleCountFlags,
    allocation: Option<Allocation>,
}

impl OwnedImage {
    pub fn new(
        gpu: &HostGpu,
        name: &str,
        extent: [u32; 2],
        format: vk::Format,
        usage: vk::ImageUsageFlags,
    ) -> Self {
        Self::with_samples(
            gpu,
            name,
            extent,
            format,
            usage,
            vk::SampleCountFlags::TYPE_1,
        )
    }

    /// [`Self::new`] with `samples` samples a pixel.
    pub fn with_samples(
        gpu: &HostGpu,
        name: &str,
        extent: [u32; 2],
        format: vk::Format,
        usage: vk::ImageUsageFlags,
        samples: vk::SampleCountFlags,
    ) -> Self {
        let aspects = format_aspects(format);
        let aspect = if aspects.contains(vk::ImageAspectFlags::DEPTH) {
            vk::ImageAspectFlags::DEPTH
        } else {
            aspects
        };
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(samples)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let device = &gpu.device;
        // SAFETY: `info` is complete; the image is destroyed in `destroy`.
        let image = unsafe { device.create_image(&info, None) }.expect("an image");
        // SAFETY: `image` is live.
        let requirements = unsafe { device.get_image_memory_requirements(image) };
        let allocation = gpu.allocate(name, requirements, MemoryLocation::GpuOnly, false);
        // SAFETY: fresh memory of the image's requirements, bound once.
        unsafe { device.bind_image_memory(image, allocation.memory(), allocation.offset()) }
            .expect("image memory");
        let make_view = |aspect| {
            let view_info = vk::ImageViewCreateInfo::default()
                .image(image)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(format)
                .subresource_range(whole(aspect));
            // SAFETY: `image` is live and bound.
            unsafe { device.create_image_view(&view_info, None) }.expect("a view")
        };
        let view = make_view(aspect);
        let attachment_view = if aspect == aspects {
            view
        } else {
            make_view(aspects)
        };
        OwnedImage {
            image,
            view,
            attachment_view,
            format,
            usage,
            samples,
            allocation: Some(allocation),
        }
    }

    /// Frees the image; no work that uses it is executing.
    pub fn destroy(&mut self, gpu: &HostGpu) {
        // SAFETY: the caller's promise; each handle is destroyed once.
        unsafe {
            if self.attachment_view != self.view {
                gpu.device.destroy_image_view(self.attachment_view, None);
            }
            gpu.device.destroy_image_view(self.view, None);
            gpu.device.destroy_image(self.image, None);
        }
        if let Some(a) = self.allocation.take() {
            gpu.free(a);
        }
    }
}

/// A colour or depth image's whole subresource range.
pub fn whole(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange::default()
        .aspect_mask(aspect)
        .level_count(1)
        .layer_count(1)
}

/// A host-visible buffer of the host's with its memory: written by the
/// host (`CpuToGpu`) or read back (`GpuToCpu`).
pub struct OwnedBuffer {
    pub buffer: vk::Buffer,
    allocation: Option<Allocation>,
}

impl OwnedBuffer {
    pub fn new(
        gpu: &HostGpu,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Self {
        let info = vk::BufferCreateInfo::default().size(size).usage(usage);
        // SAFETY: `info` is complete; destroyed in `destroy`.
        let buffer = unsafe { gpu.device.create_buffer(&info, None) }.expect("a buffer");
        // SAFETY: `buffer` is live.
        let requirements = unsafe { gpu.device.get_buffer_memory_requirements(buffer) };
        let allocation = gpu.allocate(name, requirements, location, true);
        // SAFETY: fresh memory of the buffer's requirements, bound once.
        unsafe {
            gpu.device
                .bind_buffer_memory(buffer, allocation.memory(), allocation.offset())
        }
        .expect("buffer memory");
        OwnedBuffer {
            buffer,
            allocation: Some(allocation),
        }
    }

    /// The buffer's mapped bytes.
    pub fn bytes(&mut self) -> &mut [u8] {
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .expect("a mapped buffer")
    }

    /// Frees the buffer; no work that uses it is executing.
    pub fn destroy(&mut self, gpu: &HostGpu) {
        // SAFETY: the caller's promise.
        unsafe { gpu.device.destroy_buffer(self.buffer, None) };
        if let Some(a) = self.allocation.take() {
            gpu.free(a);
        }
    }
}

/// The raster pass: a render pass with an `R32_UINT` colour attachment
/// (the visibility buffer), with a depth + normal G-buffer an
/// `R32G32B32A32_SFLOAT` one (the normal), and a depth attachment (`D32`
/// under reverse Z, or the G-buffer's format and convention); its
/// pipeline, and one framebuffer per frame slot.
pub struct VisibilityRaster {
    render_pass: vk::RenderPass,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    framebuffers: Vec<vk::Framebuffer>,
    extent: [u32; 2],
    /// The depth clear value: 0 under reverse Z, 1 under standard Z.
    depth_clear: f32,
    draws_normal: bool,
}

impl VisibilityRaster {
    /// The pass drawing into `targets`' (visibility, normal, depth) images
    /// of `samples` samples a pixel; `depth`: the depth + normal
    /// G-buffer's format and convention.
    pub fn new(
        gpu: &HostGpu,
        extent: [u32; 2],
        targets: &[(&OwnedImage, Option<&OwnedImage>, &OwnedImage)],
        depth: Option<HostDepth>,
        samples: vk::SampleCountFlags,
    ) -> Self {
        let device = &gpu.device;
        let draws_normal = depth.is_some();
        let reversed = depth.is_none_or(|d| d.convention.reversed);
        let colour_attachment = |format| {
            vk::AttachmentDescription::default()
                .format(format)
                .samples(samples)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .initial_layout(vk::ImageLayout::UNDEFINED)
                .final_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
        };
        let mut attachments = vec![colour_attachment(vk::Format::R32_UINT)];
        if draws_normal {
            attachments.push(colour_attachment(vk::Format::R32G32B32A32_SFLOAT));
        }
        // The depth is kept for the pass only with a depth + normal G-buffer.
        let depth_store = if draws_normal {
            vk::AttachmentStoreOp::STORE
        } else {
            vk::AttachmentStoreOp::DONT_CARE
        };
        attachments.push(
            vk::AttachmentDescription::default()
                .format(depth.map_or(vk::Format::D32_SFLOAT, |d| d.format))
                .samples(samples)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(depth_store)
                .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
                .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
                .initial_layout(vk::ImageLayout::UNDEFINED)
                .final_layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL),
        );
        let colour: Vec<vk::AttachmentReference> = (0..attachments.len() as u32 - 1)
            .map(|a| {
                vk::AttachmentReference::default()
                    .attachment(a)
                    .layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
            })
            .collect();
        let depth_ref = vk::AttachmentReference::default()
            .attachment(attachments.len() as u32 - 1)
            .layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL);
        let subpass = [vk::SubpassDescription::default()
            .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
            .color_attachments(&colour)
            .depth_stencil_attachment(&depth_ref)];
        // The previous frame's shadow pass read the colour attachment in
        // compute shaders (the frame before on this slot, and the barrier
        // at the pass's start orders nothing before the clear): wait for
        // those reads before writing; depth's own previous writes too.
        let dependencies = [vk::SubpassDependency::default()
            .src_subpass(vk::SUBPASS_EXTERNAL)
            .dst_subpass(0)
            .src_stage_mask(
                vk::PipelineStageFlags::COMPUTE_SHADER
                    | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS
                    | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            )
            .src_access_mask(
                vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE
                    | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            )
            .dst_stage_mask(
                vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS
                    | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS
                    | vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            )
            .dst_access_mask(
                vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE
                    | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
                    | vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
            )];
        let info = vk::RenderPassCreateInfo::default()
            .attachments(&attachments)
            .subpasses(&subpass)
            .dependencies(&dependencies);
        // SAFETY: `info` and its arrays outlive the call.
        let render_pass = unsafe { device.create_render_pass(&info, None) }.expect("render pass");
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT)
            .size(size_of::<VisibilityView>() as u32)];
        let layout_info = vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges);
        // SAFETY: as above.
        let layout = unsafe { device.create_pipeline_layout(&layout_info, None) }.expect("layout");
        let shape = (draws_normal, reversed, samples);
        let pipeline = pipeline(gpu, (render_pass, layout), extent, shape);
        let framebuffers = targets
            .iter()
            .map(|(visibility, normal, depth)| {
                let mut views = vec![visibility.view];
                views.extend(normal.map(|n| n.view));
                views.push(depth.attachment_view);
                let info = vk::FramebufferCreateInfo::default()
                    .render_pass(render_pass)
                    .attachments(&views)
                    .width(extent[0])
                    .height(extent[1])
                    .layers(1);
                // SAFETY: the views are live and match the attachments.
                unsafe { device.create_framebuffer(&info, None) }.expect("framebuffer")
            })
            .collect();
        VisibilityRaster {
            render_pass,
            layout,
            pipeline,
            framebuffers,
            extent,
            depth_clear: if reversed { 0.0 } else { 1.0 },
            draws_normal,
        }
    }

    /// Records the draw of `triangles` indexed triangles into slot
    /// `slot`'s targets.
    ///
    /// # Safety
    /// `cmd` is recording; the buffers and the slot's images are live
    /// until it has executed, and the slot's previous frame is done.
    pub unsafe fn record(
        &self,
        gpu: &HostGpu,
        cmd: vk::CommandBuffer,
        slot: usize,
        (vertices, indices, triangles): (vk::Buffer, vk::Buffer, u32),
        view: &VisibilityView,
    ) {
        let mut clear = vec![vk::ClearValue {
            color: vk::ClearColorValue {
                uint32: [u32::MAX; 4],
            },
        }];
        if self.draws_normal {
            clear.push(vk::ClearValue {
                color: vk::ClearColorValue { float32: [0.0; 4] },
            });
        }
        clear.push(vk::ClearValue {
            depth_stencil: vk::ClearDepthStencilValue {
                depth: self.depth_clear,
                stencil: 0,
            },
        });
        let begin = vk::RenderPassBeginInfo::default()
            .render_pass(self.render_pass)
            .framebuffer(self.framebuffers[slot])
            .render_area(vk::Rect2D::default().extent(vk::Extent2D {
                width: self.extent[0],
                height: self.extent[1],
            }))
            .clear_values(&clear);
        let d = &gpu.device;
        let stages = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
        // SAFETY: the caller's promise; every handle is live.
        unsafe {
            d.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE);
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
            d.cmd_push_constants(cmd, self.layout, stages, 0, bytemuck::bytes_of(view));
            d.cmd_bind_vertex_buffers(cmd, 0, &[vertices], &[0]);
            d.cmd_bind_index_buffer(cmd, indices, 0, vk::IndexType::UINT32);
            d.cmd_draw_indexed(cmd, triangles * 3, 1, 0, 0, 0);
            d.cmd_end_render_pass(cmd);
        }
    }

    /// Frees the pass; no work that uses it is executing.
    pub fn destroy(&mut self, gpu: &HostGpu) {
        let d = &gpu.device;
        // SAFETY: the caller's promise; each handle is destroyed once.
        unsafe {
            for f in self.framebuffers.drain(..) {
                d.destroy_framebuffer(f, None);
            }
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// The graphics pipeline: positions at location 0, no culling (the pass
/// shadow-tests back faces too: it flips their normal), depth `GREATER`
/// under reverse Z and `LESS` under standard Z; with `draws_normal` the
/// depth + normal fragment shader and two colour attachments.
fn pipeline(
    gpu: &HostGpu,
    (render_pass, layout): (vk::RenderPass, vk::PipelineLayout),
    extent: [u32; 2],
    (draws_normal, reversed, samples): (bool, bool, vk::SampleCountFlags),
) -> vk::Pipeline {
    let d = &gpu.device;
    let module = |bytes: &[u8]| {
        let words = ash::util::read_spv(&mut std::io::Cursor::new(bytes)).expect("SPIR-V");
        let info = vk::ShaderModuleCreateInfo::default().code(&words);
        // SAFETY: `words` is whole SPIR-V compiled by izb's build script.
        unsafe { d.create_shader_module(&info, None) }.expect("shader module")
    };
    let (vertex, fragment) = if draws_normal {
        (DEPTH_NORMAL_VERTEX_SPIRV, DEPTH_NORMAL_FRAGMENT_SPIRV)
    } else {
        (VERTEX_SPIRV, FRAGMENT_SPIRV)
    };
    let (vert, frag) = (module(vertex), module(fragment));
    let stages = [
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::VERTEX)
            .module(vert)
            .name(c"main"),
        vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::FRAGMENT)
            .module(frag)
            .name(c"main"),
    ];
    let bindings = [vk::VertexInputBindingDescription::default()
        .binding(0)
        .stride(12)
        .input_rate(vk::VertexInputRate::VERTEX)];
    let attributes = [vk::VertexInputAttributeDescription::default()
        .location(0)
        .binding(0)
        .format(vk::Format::R32G32B32_SFLOAT)];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
        .vertex_binding_descriptions(&bindings)
        .vertex_attribute_descriptions(&attributes);
    let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewports = [vk::Viewport {
        x: 0.0,
        y: 0.0,
        width: extent[0] as f32,
        height: extent[1] as f32,
        min_depth: 0.0,
        max_depth: 1.0,
    }];
    let scissors = [vk::Rect2D::default().extent(vk::Extent2D {
        width: extent[0],
        height: extent[1],
    })];
    let viewport = vk::PipelineViewportStateCreateInfo::default()
        .viewports(&viewports)
        .scissors(&scissors);
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .line_width(1.0);
    // A multisampled target gets each sample's own coverage and depth test
    // (not sample shading: the fragment's id is the same for every sample
    // it covers).
    let multisample =
        vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(samples);
    let depth = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(true)
        .depth_write_enable(true)
        .depth_compare_op(if reversed {
            vk::CompareOp::GREATER
        } else {
            vk::CompareOp::LESS
        });
    // Without the independentBlend feature every attachment's state is the
    // same: all channels written (an R32_UINT target has only R).
    let write_all = vk::PipelineColorBlendAttachmentState::default()
        .color_write_mask(vk::ColorComponentFlags::RGBA);
    let blend_attachments = vec![write_all; if draws_normal { 2 } else { 1 }];
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
    let info = [vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&assembly)
        .viewport_state(&viewport)
        .rasterization_state(&raster)
        .multisample_state(&multisample)
        .depth_stencil_state(&depth)
        .color_blend_state(&blend)
        .layout(layout)
        .render_pass(render_pass)
        .subpass(0)];
    // SAFETY: every state the info points to outlives the call.
    let pipeline = unsafe { d.create_graphics_pipelines(vk::PipelineCache::null(), &info, None) }
        .map_err(|(_, e)| e)
        .expect("the visibility pipeline")[0];
    // SAFETY: the pipeline holds what it needs of the modules.
    unsafe {
        d.destroy_shader_module(vert, None);
        d.destroy_shader_module(frag, None);
    }
    pipeline
}
