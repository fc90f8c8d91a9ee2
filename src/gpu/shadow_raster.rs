//! The shadow map's raster pass on the hardware rasteriser, as engines
//! draw shadow maps: a depth-only render pass per cascade into a
//! D32_SFLOAT layer, fixed-function depth bias (`vkCmdSetDepthBias`),
//! depth clamp for a directional light's map, no fragment shader
//! (`shaders/shadow_map.vert`). The lookups stay compute: the layers are
//! copied into the `SHADOW_MAP` buffer, which `shadow_lookup` reads.
//! The CPU twin is [`crate::baseline::raster`] (its rules) inside
//! [`crate::baseline::shadow_map::shadow_map`].

use super::context::DeviceShared;
use super::pipeline::BindingLayout;
use super::{GpuError, Recorder};
use crate::baseline::raster::RasterBias;
use crate::cpu::light_setup::Projection;
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

/// The map's format: the float depth engines use for shadow maps.
pub const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

/// The render pass and the two pipelines of the raster pass.
pub struct ShadowRaster {
    shared: Arc<DeviceShared>,
    pub render_pass: vk::RenderPass,
    /// Directional light: orthographic, depth clamp on, LESS.
    orthographic: vk::Pipeline,
    /// Point light: perspective, reversed depth, GREATER, clipped at near.
    perspective: vk::Pipeline,
}

impl ShadowRaster {
    /// Builds the pass, or says why this device cannot draw it.
    pub fn new(shared: &Arc<DeviceShared>, layout: &BindingLayout) -> Result<Self, GpuError> {
        if let Some(why) = &shared.raster_missing {
            return Err(GpuError::Unsupported(why.clone()));
        }
        let needed =
            vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT | vk::FormatFeatureFlags::TRANSFER_SRC;
        require_format(
            shared,
            DEPTH_FORMAT,
            needed,
            "render D32_SFLOAT depth and copy it out",
        )?;
        let attachment = vk::AttachmentDescription::default()
            .format(DEPTH_FORMAT)
            .samples(vk::SampleCountFlags::TYPE_1)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .stencil_load_op(vk::AttachmentLoadOp::DONT_CARE)
            .stencil_store_op(vk::AttachmentStoreOp::DONT_CARE)
            .initial_layout(vk::ImageLayout::UNDEFINED)
            .final_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL);
        // Before: the previous repetition's copy has read the layer.
        let render_pass = depth_render_pass(
            shared,
            attachment,
            vk::AccessFlags::empty(),
            "shadow_map depth-only pass",
        )?;
        let mut raster = ShadowRaster {
            shared: shared.clone(),
            render_pass,
            orthographic: vk::Pipeline::null(),
            perspective: vk::Pipeline::null(),
        };
        let spirv = vertex_spirv("shadow_map")?;
        raster.orthographic = raster.pipeline(layout, spirv, Projection::Orthographic)?;
        raster.perspective = raster.pipeline(layout, spirv, Projection::Perspective)?;
        Ok(raster)
    }

    fn pipeline(
        &self,
        layout: &BindingLayout,
        spirv: &[u8],
        projection: Projection,
    ) -> Result<vk::Pipeline, GpuError> {
        let orthographic = projection == Projection::Orthographic;
        let desc = DepthPipelineDesc {
            name: if orthographic {
                "shadow_map (orthographic)"
            } else {
                "shadow_map (perspective)"
            },
            depth_clamp: orthographic,
            depth_bias: true,
            depth_write: true,
            compare: if orthographic {
                vk::CompareOp::LESS
            } else {
                vk::CompareOp::GREATER
            },
            stencil: None,
        };
        depth_pipeline(&self.shared, layout, self.render_pass, spirv, &desc)
    }
}

/// Whether this device renders and copies `format` with `features`, or
/// what it cannot do.
pub(super) fn require_format(
    shared: &DeviceShared,
    format: vk::Format,
    features: vk::FormatFeatureFlags,
    what: &str,
) -> Result<(), GpuError> {
    // SAFETY: `physical_device` belongs to this instance.
    let props = unsafe {
        shared
            .instance
            .get_physical_device_format_properties(shared.physical_device, format)
    };
    if props.optimal_tiling_features.contains(features) {
        Ok(())
    } else {
        Err(GpuError::Unsupported(format!("this device cannot {what}")))
    }
}

/// The one-subpass render pass of a depth(-stencil) pass over
/// `attachment`: a transfer before it (which wrote the attachment when
/// `transfer_access` says so, or only read it) comes first, and the copy
/// out after it sees what the tests wrote.
pub(super) fn depth_render_pass(
    shared: &DeviceShared,
    attachment: vk::AttachmentDescription,
    transfer_access: vk::AccessFlags,
    name: &str,
) -> Result<vk::RenderPass, GpuError> {
    let attachment = [attachment];
    let depth_ref = vk::AttachmentReference::default()
        .attachment(0)
        .layout(vk::ImageLayout::DEPTH_STENCIL_ATTACHMENT_OPTIMAL);
    let subpass = [vk::SubpassDescription::default()
        .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
        .depth_stencil_attachment(&depth_ref)];
    let tests =
        vk::PipelineStageFlags::EARLY_FRAGMENT_TESTS | vk::PipelineStageFlags::LATE_FRAGMENT_TESTS;
    let dependencies = [
        vk::SubpassDependency::default()
            .src_subpass(vk::SUBPASS_EXTERNAL)
            .dst_subpass(0)
            .src_stage_mask(vk::PipelineStageFlags::TRANSFER)
            .src_access_mask(transfer_access)
            .dst_stage_mask(tests)
            .dst_access_mask(
                vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_READ
                    | vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE,
            ),
        vk::SubpassDependency::default()
            .src_subpass(0)
            .dst_subpass(vk::SUBPASS_EXTERNAL)
            .src_stage_mask(tests)
            .src_access_mask(vk::AccessFlags::DEPTH_STENCIL_ATTACHMENT_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags::TRANSFER)
            .dst_access_mask(vk::AccessFlags::TRANSFER_READ),
    ];
    let info = vk::RenderPassCreateInfo::default()
        .attachments(&attachment)
        .subpasses(&subpass)
        .dependencies(&dependencies);
    // SAFETY: `info` and the arrays it points to outlive the call.
    let render_pass =
        unsafe { shared.device.create_render_pass(&info, None) }.map_err(GpuError::vk)?;
    shared.set_name(render_pass, name);
    Ok(render_pass)
}

/// The SPIR-V of vertex shader `name` (as `build.rs` compiled it).
pub(super) fn vertex_spirv(name: &str) -> Result<&'static [u8], GpuError> {
    super::SPIRV_MODULES
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, bytes)| *bytes)
        .ok_or_else(|| GpuError::Unsupported(format!("{name} was not compiled")))
}

/// What differs between the depth-only pipelines (the maps', the
/// volumes').
pub(super) struct DepthPipelineDesc {
    pub name: &'static str,
    pub depth_clamp: bool,
    pub depth_bias: bool,
    pub depth_write: bool,
    pub compare: vk::CompareOp,
    /// Front and back stencil operations, when the pass counts.
    pub stencil: Option<(vk::StencilOpState, vk::StencilOpState)>,
}

/// A graphics pipeline with one vertex shader (`spirv`), no vertex
/// buffers, no fragment shader, triangles unculled, viewport, scissor and
/// depth bias dynamic.
pub(super) fn depth_pipeline(
    shared: &DeviceShared,
    layout: &BindingLayout,
    render_pass: vk::RenderPass,
    spirv: &[u8],
    desc: &DepthPipelineDesc,
) -> Result<vk::Pipeline, GpuError> {
    let device = &shared.device;
    let words = super::pipeline::spirv_words(desc.name, spirv)?;
    let module_info = vk::ShaderModuleCreateInfo::default().code(&words);
    // SAFETY: `words` is whole SPIR-V words with its magic number
    // (`spirv_words`); `module_info` outlives the call.
    let module =
        unsafe { device.create_shader_module(&module_info, None) }.map_err(GpuError::vk)?;
    let stages = [vk::PipelineShaderStageCreateInfo::default()
        .stage(vk::ShaderStageFlags::VERTEX)
        .module(module)
        .name(c"main")];
    let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
    let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport = vk::PipelineViewportStateCreateInfo::default()
        .viewport_count(1)
        .scissor_count(1);
    let rasterization = vk::PipelineRasterizationStateCreateInfo::default()
        .depth_clamp_enable(desc.depth_clamp)
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(vk::CullModeFlags::NONE)
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .depth_bias_enable(desc.depth_bias)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let mut depth = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(true)
        .depth_write_enable(desc.depth_write)
        .depth_compare_op(desc.compare);
    if let Some((front, back)) = desc.stencil {
        depth = depth.stencil_test_enable(true).front(front).back(back);
    }
    let dynamic = [
        vk::DynamicState::VIEWPORT,
        vk::DynamicState::SCISSOR,
        vk::DynamicState::DEPTH_BIAS,
    ];
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic);
    let info = [vk::GraphicsPipelineCreateInfo::default()
        .stages(&stages)
        .vertex_input_state(&vertex_input)
        .input_assembly_state(&assembly)
        .viewport_state(&viewport)
        .rasterization_state(&rasterization)
        .multisample_state(&multisample)
        .depth_stencil_state(&depth)
        .dynamic_state(&dynamic)
        .layout(layout.pipeline_layout)
        .render_pass(render_pass)
        .subpass(0)];
    // SAFETY: every state struct, `module`, the layout and the render
    // pass are alive for the call.
    let pipeline =
        unsafe { device.create_graphics_pipelines(vk::PipelineCache::null(), &info, None) };
    // SAFETY: a pipeline keeps no reference to its module once created.
    unsafe { device.destroy_shader_module(module, None) };
    let pipeline = pipeline.map_err(|(_, e)| GpuError::vk(e))?[0];
    shared.set_name(pipeline, desc.name);
    Ok(pipeline)
}

impl Drop for ShadowRaster {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: frames wait for their fence, so no command buffer using
        // these is pending; destroying a null pipeline is a no-op.
        unsafe {
            let d = &self.shared.device;
            d.destroy_pipeline(self.orthographic, None);
            d.destroy_pipeline(self.perspective, None);
            d.destroy_render_pass(self.render_pass, None);
        }
    }
}

/// One frame's depth attachment for `render_pass`: an image with one
/// layer per map (the cascades) or one (the volumes' depth and stencil),
/// a view and a framebuffer per layer.
pub struct DepthAttachment {
    shared: Arc<DeviceShared>,
    pub image: vk::Image,
    allocation: Option<Allocation>,
    views: Vec<vk::ImageView>,
    pub framebuffers: Vec<vk::Framebuffer>,
    pub extent: [u32; 2],
    pub bytes: u64,
}

/// The shadow maps' depth layers.
pub type ShadowDepthTarget = DepthAttachment;

impl DepthAttachment {
    /// `side`² D32_SFLOAT layers for the maps' pass.
    pub fn new(
        shared: &Arc<DeviceShared>,
        raster: &ShadowRaster,
        side: u32,
        layers: u32,
    ) -> Result<Self, GpuError> {
        let usage =
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | vk::ImageUsageFlags::TRANSFER_SRC;
        let desc = (DEPTH_FORMAT, vk::ImageAspectFlags::DEPTH, usage);
        Self::with_format(
            shared,
            raster.render_pass,
            desc,
            [side, side],
            layers,
            "shadow_map depth layers",
        )
    }

    /// An attachment of `format` (whose `aspect` the views see) and
    /// `usage`, `extent` texels, `layers` layers, named `name`.
    pub(super) fn with_format(
        shared: &Arc<DeviceShared>,
        render_pass: vk::RenderPass,
        (format, aspect, usage): (vk::Format, vk::ImageAspectFlags, vk::ImageUsageFlags),
        extent: [u32; 2],
        layers: u32,
        name: &'static str,
    ) -> Result<Self, GpuError> {
        let l = &shared.limits;
        let largest = l
            .max_framebuffer_width
            .min(l.max_framebuffer_height)
            .min(l.max_image_dimension2_d)
            .min(l.max_viewport_dimensions[0])
            .min(l.max_viewport_dimensions[1]);
        if extent[0].max(extent[1]) > largest {
            return Err(GpuError::Unsupported(format!(
                "a {}×{} {name} is larger than this device's largest depth attachment ({largest}²)",
                extent[0], extent[1]
            )));
        }
        let device = &shared.device;
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(format)
            .extent(vk::Extent3D {
                width: extent[0],
                height: extent[1],
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(layers)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: `info` outlives the call.
        let image = unsafe { device.create_image(&info, None) }.map_err(GpuError::vk)?;
        shared.set_name(image, name);
        let mut target = DepthAttachment {
            shared: shared.clone(),
            image,
            allocation: None,
            views: Vec::new(),
            framebuffers: Vec::new(),
            extent,
            bytes: 0,
        };
        // SAFETY: `image` was just created on this device.
        let requirements = unsafe { device.get_image_memory_requirements(image) };
        let allocation = shared
            .allocator
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location: MemoryLocation::GpuOnly,
                linear: false,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| {
                GpuError::Allocation(format!("{name} ({} bytes): {e}", requirements.size))
            })?;
        target.bytes = requirements.size;
        // SAFETY: the allocation was made for this image's requirements and
        // the image is not bound yet.
        let bound =
            unsafe { device.bind_image_memory(image, allocation.memory(), allocation.offset()) };
        target.allocation = Some(allocation);
        bound.map_err(GpuError::vk)?;
        for layer in 0..layers {
            let range = vk::ImageSubresourceRange::default()
                .aspect_mask(aspect)
                .base_mip_level(0)
                .level_count(1)
                .base_array_layer(layer)
                .layer_count(1);
            let info = vk::ImageViewCreateInfo::default()
                .image(image)
                .view_type(vk::ImageViewType::TYPE_2D)
                .format(format)
                .subresource_range(range);
            // SAFETY: `image` is bound to memory; `info` outlives the call.
            let view = unsafe { device.create_image_view(&info, None) }.map_err(GpuError::vk)?;
            target.views.push(view);
            let attachments = [view];
            let info = vk::FramebufferCreateInfo::default()
                .render_pass(render_pass)
                .attachments(&attachments)
                .width(extent[0])
                .height(extent[1])
                .layers(1);
            // SAFETY: the view and the render pass are alive; `info`
            // outlives the call.
            let framebuffer =
                unsafe { device.create_framebuffer(&info, None) }.map_err(GpuError::vk)?;
            target.framebuffers.push(framebuffer);
        }
        Ok(target)
    }
}

impl Drop for DepthAttachment {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: dropped after the frame's fence wait (a poisoned device
        // returns above), so nothing uses the image, its views or
        // framebuffers.
        unsafe {
            let d = &self.shared.device;
            for &f in &self.framebuffers {
                d.destroy_framebuffer(f, None);
            }
            for &v in &self.views {
                d.destroy_image_view(v, None);
            }
            d.destroy_image(self.image, None);
        }
        if let Some(a) = self.allocation.take() {
            let mut allocator = self
                .shared
                .allocator
                .lock()
                .unwrap_or_else(|e| e.into_inner());
            // A failed free leaks device memory the device's drop reclaims.
            let _ = allocator.free(a);
        }
    }
}

/// The render area, viewport and clear value of a pass over a whole
/// `size` target, depth cleared to `depth`, stencil to 0.
pub(super) fn whole_target(
    size: [u32; 2],
    depth: f32,
) -> (vk::Rect2D, [vk::Viewport; 1], [vk::ClearValue; 1]) {
    let area = vk::Rect2D {
        offset: vk::Offset2D { x: 0, y: 0 },
        extent: vk::Extent2D {
            width: size[0],
            height: size[1],
        },
    };
    let viewport = [vk::Viewport {
        x: 0.0,
        y: 0.0,
        width: size[0] as f32,
        height: size[1] as f32,
        min_depth: 0.0,
        max_depth: 1.0,
    }];
    let clear = [vk::ClearValue {
        depth_stencil: vk::ClearDepthStencilValue { depth, stencil: 0 },
    }];
    (area, viewport, clear)
}

/// Records the raster pass: per cascade `k`, a depth-only render pass into
/// layer `k` drawing `triangles` triangles (instance `k`), then the copy of
/// every layer into `map_buffer`, cascade after cascade.
pub fn shadow_map(
    rec: &Recorder,
    raster: &ShadowRaster,
    target: &ShadowDepthTarget,
    map_buffer: vk::Buffer,
    triangles: u32,
    projection: Projection,
    bias: RasterBias,
) {
    rec.begin_label("shadow_map");
    let d = &rec.shared().device;
    let cmd = rec.cmd();
    let side = target.extent[0];
    let (pipeline, clear) = match projection {
        Projection::Orthographic => (raster.orthographic, 1.0),
        Projection::Perspective => (raster.perspective, 0.0),
    };
    let (area, viewport, clear) = whole_target([side, side], clear);
    // The light setup's compute writes (light state, cascades) are read
    // by the vertex shader.
    let to_vertex = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::SHADER_READ)];
    // SAFETY: `cmd` is recording (inside the frame's submission); the
    // pipeline, layout, set, render pass and framebuffers outlive the
    // frame's fence wait; every region stays inside the image and buffer.
    unsafe {
        d.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::VERTEX_SHADER,
            vk::DependencyFlags::empty(),
            &to_vertex,
            &[],
            &[],
        );
        for (k, &framebuffer) in target.framebuffers.iter().enumerate() {
            let begin = vk::RenderPassBeginInfo::default()
                .render_pass(raster.render_pass)
                .framebuffer(framebuffer)
                .render_area(area)
                .clear_values(&clear);
            d.cmd_begin_render_pass(cmd, &begin, vk::SubpassContents::INLINE);
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, pipeline);
            d.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::GRAPHICS,
                rec.binding().0,
                0,
                &[rec.binding().1],
                &[],
            );
            d.cmd_set_viewport(cmd, 0, &viewport);
            d.cmd_set_scissor(cmd, 0, &[area]);
            d.cmd_set_depth_bias(cmd, bias.constant_factor, 0.0, bias.slope_factor);
            d.cmd_draw(cmd, 3 * triangles, 1, 0, k as u32);
            d.cmd_end_render_pass(cmd);
        }
        let layer_bytes = u64::from(side) * u64::from(side) * 4;
        let regions: Vec<vk::BufferImageCopy> = (0..target.framebuffers.len() as u32)
            .map(|k| {
                vk::BufferImageCopy::default()
                    .buffer_offset(u64::from(k) * layer_bytes)
                    .buffer_row_length(side)
                    .buffer_image_height(side)
                    .image_subresource(
                        vk::ImageSubresourceLayers::default()
                            .aspect_mask(vk::ImageAspectFlags::DEPTH)
                            .mip_level(0)
                            .base_array_layer(k)
                            .layer_count(1),
                    )
                    .image_extent(vk::Extent3D {
                        width: side,
                        height: side,
                        depth: 1,
                    })
            })
            .collect();
        d.cmd_copy_image_to_buffer(
            cmd,
            target.image,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            map_buffer,
            &regions,
        );
    }
    rec.mark("shadow_map");
    rec.barrier();
    rec.end_label();
}
