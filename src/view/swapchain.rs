//! The swapchain with its views, framebuffers and present semaphores, and
//! the read-back of one presented image (a screenshot of the window).

use anyhow::{anyhow, Context, Result};
use ash::vk;

/// A swapchain and everything sized by it.
pub struct Swapchain {
    pub handle: vk::SwapchainKHR,
    pub images: Vec<vk::Image>,
    views: Vec<vk::ImageView>,
    pub framebuffers: Vec<vk::Framebuffer>,
    /// One per image: a present waits on the semaphore of its own image,
    /// so no semaphore is signalled again while a present may wait on it.
    pub render_finished: Vec<vk::Semaphore>,
    pub extent: vk::Extent2D,
    pub format: vk::Format,
}

impl Swapchain {
    /// A swapchain for `size` (clamped to what the surface allows),
    /// mailbox when offered (no wait for the display), else FIFO.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        device: &ash::Device,
        swapchain_fn: &ash::khr::swapchain::Device,
        surface_fn: &ash::khr::surface::Instance,
        physical: vk::PhysicalDevice,
        surface: vk::SurfaceKHR,
        format: vk::SurfaceFormatKHR,
        render_pass: vk::RenderPass,
        size: [u32; 2],
        old: Option<&Swapchain>,
    ) -> Result<Swapchain> {
        // SAFETY: the surface and physical device are live.
        let (caps, modes) = unsafe {
            (
                surface_fn.get_physical_device_surface_capabilities(physical, surface)?,
                surface_fn.get_physical_device_surface_present_modes(physical, surface)?,
            )
        };
        let extent = if caps.current_extent.width != u32::MAX {
            caps.current_extent
        } else {
            vk::Extent2D {
                width: size[0].clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: size[1].clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        };
        let mode = if modes.contains(&vk::PresentModeKHR::MAILBOX) {
            vk::PresentModeKHR::MAILBOX
        } else {
            vk::PresentModeKHR::FIFO
        };
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        // Screenshots copy out of the image: transfer source when allowed.
        let usage = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | (caps.supported_usage_flags & vk::ImageUsageFlags::TRANSFER_SRC);
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(surface)
            .min_image_count(count)
            .image_format(format.format)
            .image_color_space(format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(usage)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
            .present_mode(mode)
            .clipped(true)
            .old_swapchain(old.map_or(vk::SwapchainKHR::null(), |o| o.handle));
        // SAFETY: the create info and the old swapchain (retired by this
        // call, destroyed by the caller after it) are live.
        let handle = unsafe { swapchain_fn.create_swapchain(&info, None) }
            .context("vkCreateSwapchainKHR")?;
        let mut s = Swapchain {
            handle,
            images: Vec::new(),
            views: Vec::new(),
            framebuffers: Vec::new(),
            render_finished: Vec::new(),
            extent,
            format: format.format,
        };
        // SAFETY: the swapchain was just created; every view, framebuffer
        // and semaphore is created from live handles and owned by `s`,
        // which destroys them on the error path too.
        let filled: Result<()> = unsafe {
            (|| {
                s.images = swapchain_fn.get_swapchain_images(handle)?;
                for &image in &s.images {
                    let view = device.create_image_view(
                        &vk::ImageViewCreateInfo::default()
                            .image(image)
                            .view_type(vk::ImageViewType::TYPE_2D)
                            .format(format.format)
                            .subresource_range(color_range()),
                        None,
                    )?;
                    s.views.push(view);
                    let attachments = [view];
                    s.framebuffers.push(
                        device.create_framebuffer(
                            &vk::FramebufferCreateInfo::default()
                                .render_pass(render_pass)
                                .attachments(&attachments)
                                .width(extent.width)
                                .height(extent.height)
                                .layers(1),
                            None,
                        )?,
                    );
                    s.render_finished
                        .push(device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None)?);
                }
                Ok(())
            })()
        };
        match filled {
            Ok(()) => Ok(s),
            Err(e) => {
                s.destroy(device, swapchain_fn);
                Err(e)
            }
        }
    }

    /// Destroys everything; the device must be idle.
    pub fn destroy(self, device: &ash::Device, swapchain_fn: &ash::khr::swapchain::Device) {
        // SAFETY: the caller waited for the device; each handle is owned
        // here and destroyed once.
        unsafe {
            for &f in &self.framebuffers {
                device.destroy_framebuffer(f, None);
            }
            for &v in &self.views {
                device.destroy_image_view(v, None);
            }
            for &sem in &self.render_finished {
                device.destroy_semaphore(sem, None);
            }
            swapchain_fn.destroy_swapchain(self.handle, None);
        }
    }
}

fn color_range() -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: vk::ImageAspectFlags::COLOR,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// A host buffer a presented image is copied into.
pub struct Readback {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    extent: vk::Extent2D,
}

/// Records the copy of `image` (in `PRESENT_SRC` after the render pass)
/// into a new host-visible buffer, returning it to `PRESENT_SRC`.
pub fn record_readback(
    instance: &ash::Instance,
    device: &ash::Device,
    physical: vk::PhysicalDevice,
    cmd: vk::CommandBuffer,
    image: vk::Image,
    extent: vk::Extent2D,
) -> Result<Readback> {
    let size = u64::from(extent.width) * u64::from(extent.height) * 4;
    // SAFETY: plain creation and binding on the live device; `cmd` is
    // recording; the barriers' arrays outlive the calls.
    unsafe {
        let buffer = device.create_buffer(
            &vk::BufferCreateInfo::default()
                .size(size)
                .usage(vk::BufferUsageFlags::TRANSFER_DST),
            None,
        )?;
        let needs = device.get_buffer_memory_requirements(buffer);
        let props = instance.get_physical_device_memory_properties(physical);
        let wanted = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let Some(type_index) = (0..props.memory_type_count).find(|&t| {
            needs.memory_type_bits & (1 << t) != 0
                && props.memory_types[t as usize]
                    .property_flags
                    .contains(wanted)
        }) else {
            device.destroy_buffer(buffer, None);
            return Err(anyhow!("no host-visible memory for the screenshot"));
        };
        let memory = match device.allocate_memory(
            &vk::MemoryAllocateInfo::default()
                .allocation_size(needs.size)
                .memory_type_index(type_index),
            None,
        ) {
            Ok(m) => m,
            Err(e) => {
                device.destroy_buffer(buffer, None);
                return Err(e.into());
            }
        };
        device.bind_buffer_memory(buffer, memory, 0)?;
        let to_transfer = [vk::ImageMemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)
            .dst_access_mask(vk::AccessFlags::TRANSFER_READ)
            .old_layout(vk::ImageLayout::PRESENT_SRC_KHR)
            .new_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image)
            .subresource_range(color_range())];
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
            vk::PipelineStageFlags::TRANSFER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &to_transfer,
        );
        let region = [vk::BufferImageCopy::default()
            .image_subresource(vk::ImageSubresourceLayers {
                aspect_mask: vk::ImageAspectFlags::COLOR,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            })
            .image_extent(vk::Extent3D {
                width: extent.width,
                height: extent.height,
                depth: 1,
            })];
        device.cmd_copy_image_to_buffer(
            cmd,
            image,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
            buffer,
            &region,
        );
        let to_present = [vk::ImageMemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_READ)
            .dst_access_mask(vk::AccessFlags::empty())
            .old_layout(vk::ImageLayout::TRANSFER_SRC_OPTIMAL)
            .new_layout(vk::ImageLayout::PRESENT_SRC_KHR)
            .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
            .image(image)
            .subresource_range(color_range())];
        let host = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(vk::AccessFlags::HOST_READ)];
        device.cmd_pipeline_barrier(
            cmd,
            vk::PipelineStageFlags::TRANSFER,
            vk::PipelineStageFlags::BOTTOM_OF_PIPE | vk::PipelineStageFlags::HOST,
            vk::DependencyFlags::empty(),
            &host,
            &[],
            &to_present,
        );
        Ok(Readback {
            buffer,
            memory,
            extent,
        })
    }
}

impl Readback {
    /// After the frame's fence: the image as RGBA8 rows, and the buffer freed.
    pub fn finish(self, device: &ash::Device, format: vk::Format) -> Result<Vec<u8>> {
        let len = self.extent.width as usize * self.extent.height as usize * 4;
        // SAFETY: the copy finished (the caller waited for the fence); the
        // memory is host-visible and coherent, mapped once and unmapped
        // before it is freed with its buffer.
        let mut rgba = unsafe {
            let ptr = device.map_memory(self.memory, 0, len as u64, vk::MemoryMapFlags::empty())?;
            let bytes = std::slice::from_raw_parts(ptr as *const u8, len).to_vec();
            device.unmap_memory(self.memory);
            device.destroy_buffer(self.buffer, None);
            device.free_memory(self.memory, None);
            bytes
        };
        if format == vk::Format::B8G8R8A8_UNORM {
            for px in rgba.chunks_exact_mut(4) {
                px.swap(0, 2);
            }
        }
        Ok(rgba)
    }

    pub fn size(&self) -> [u32; 2] {
        [self.extent.width, self.extent.height]
    }
}
