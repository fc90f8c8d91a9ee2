//! The viewer's window side of Vulkan: its own instance and device with a
//! surface, the swapchain and one render pass that egui draws into
//! (`egui-ash-renderer`), and the read-back of a presented image for
//! screenshots.
//!
//! The presentation device is separate from the compute device of
//! [`super::worker`] on purpose: the shadow frame runs on its own thread,
//! queue and device, so a frame that takes seconds on lavapipe never holds
//! the window's submissions (Vulkan queues are externally synchronised).

use super::swapchain::Swapchain;
use crate::gpu::context::{load_entry, messenger_info, VALIDATION_LAYER};
use anyhow::{anyhow, bail, Context, Result};
use ash::vk;
use egui_ash_renderer::{Options, RenderMode, Renderer};
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use std::sync::Mutex;
use winit::window::Window;

/// Why a frame was not drawn.
#[derive(Debug, PartialEq, Eq)]
pub enum Drawn {
    Presented,
    /// The window has no area (minimised) or the swapchain had to be
    /// rebuilt first; the next redraw draws.
    Skipped,
}

/// The window's Vulkan device, swapchain and UI renderer.
pub struct Presenter {
    // Dropped by hand in `Drop` (order matters); `Option` so the renderer
    // and swapchain go before the device.
    renderer: Option<Renderer<egui_ash_renderer::allocator::DefaultAllocator>>,
    swapchain: Option<Swapchain>,
    render_pass: vk::RenderPass,
    command_pool: vk::CommandPool,
    command_buffer: vk::CommandBuffer,
    frame_fence: vk::Fence,
    image_available: vk::Semaphore,
    /// Textures egui freed in the last frame: freed once its fence passed.
    textures_to_free: Vec<egui::TextureId>,
    pub(super) device: ash::Device,
    pub(super) queue: vk::Queue,
    pub(super) physical: vk::PhysicalDevice,
    swapchain_fn: ash::khr::swapchain::Device,
    surface_fn: ash::khr::surface::Instance,
    surface: vk::SurfaceKHR,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// The validation callback's list (boxed: the messenger points at it).
    messages: Box<Mutex<Vec<String>>>,
    pub(super) instance: ash::Instance,
    _entry: ash::Entry,
    /// The presenting device's name.
    pub device_name: String,
    /// The largest image side the device takes (egui's texture limit).
    pub max_image_side: u32,
}

impl Presenter {
    /// Opens a device that can present to `window`, with validation when
    /// `validation` (the layer's messages: [`Self::take_messages`]).
    pub fn new(window: &Window, validation: bool) -> Result<Presenter> {
        let entry = load_entry()?;
        let display = window.display_handle()?.as_raw();
        let handle = window.window_handle()?.as_raw();
        let mut extensions = ash_window::enumerate_required_extensions(display)
            .context("no Vulkan surface extension for this display")?
            .to_vec();
        let mut layers = Vec::new();
        if validation {
            layers.push(VALIDATION_LAYER.as_ptr());
            extensions.push(ash::ext::debug_utils::NAME.as_ptr());
        }
        let app = vk::ApplicationInfo::default()
            .application_name(c"izb view")
            .api_version(vk::API_VERSION_1_2);
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        // SAFETY: `info` and the name arrays it points to outlive the call.
        let instance = unsafe { entry.create_instance(&info, None) }
            .map_err(|e| anyhow!("vkCreateInstance with surface extensions failed: {e}"))?;
        let messages: Box<Mutex<Vec<String>>> = Box::default();
        let debug = validation
            .then(|| -> Result<_> {
                let debug = ash::ext::debug_utils::Instance::new(&entry, &instance);
                let info = messenger_info(&messages);
                // SAFETY: the user data is the boxed list, which `Presenter`
                // keeps until after the messenger is destroyed.
                let m = unsafe { debug.create_debug_utils_messenger(&info, None) }?;
                Ok((debug, m))
            })
            .transpose()?;
        let surface_fn = ash::khr::surface::Instance::new(&entry, &instance);
        // SAFETY: the handles come from a live window that outlives the
        // presenter (the app drops the presenter first).
        let surface =
            unsafe { ash_window::create_surface(&entry, &instance, display, handle, None) }
                .context("vkCreate*SurfaceKHR")?;
        let (physical, queue_family, device_name, max_image_side) =
            pick_device(&instance, &surface_fn, surface)?;
        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let device_extensions = [ash::khr::swapchain::NAME.as_ptr()];
        let device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&device_extensions);
        // SAFETY: `physical` comes from `instance`; the create info outlives the call.
        let device = unsafe { instance.create_device(physical, &device_info, None) }
            .context("vkCreateDevice (presentation)")?;
        // SAFETY: the device was created with one queue of this family.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let swapchain_fn = ash::khr::swapchain::Device::new(&instance, &device);
        // SAFETY: plain object creation on the live device.
        let (command_pool, command_buffer, frame_fence, image_available) = unsafe {
            let pool = device.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )?;
            let cmd = device.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(pool)
                    .command_buffer_count(1),
            )?[0];
            let fence = device.create_fence(
                &vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED),
                None,
            )?;
            let sem = device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None)?;
            (pool, cmd, fence, sem)
        };
        let mut presenter = Presenter {
            renderer: None,
            swapchain: None,
            render_pass: vk::RenderPass::null(),
            command_pool,
            command_buffer,
            frame_fence,
            image_available,
            textures_to_free: Vec::new(),
            device,
            queue,
            physical,
            swapchain_fn,
            surface_fn,
            surface,
            debug,
            messages,
            instance,
            _entry: entry,
            device_name,
            max_image_side,
        };
        let format = presenter.surface_format()?;
        presenter.render_pass = create_render_pass(&presenter.device, format.format)?;
        let size = window.inner_size();
        presenter.rebuild_swapchain([size.width, size.height])?;
        let renderer = Renderer::with_default_allocator(
            &presenter.instance,
            physical,
            presenter.device.clone(),
            RenderMode::RenderPass(presenter.render_pass),
            Options {
                in_flight_frames: 1,
                srgb_framebuffer: false,
                ..Default::default()
            },
        )
        .map_err(|e| anyhow!("egui renderer: {e}"))?;
        presenter.renderer = Some(renderer);
        Ok(presenter)
    }

    fn surface_format(&self) -> Result<vk::SurfaceFormatKHR> {
        // SAFETY: the surface and physical device are live.
        let formats = unsafe {
            self.surface_fn
                .get_physical_device_surface_formats(self.physical, self.surface)
        }?;
        // A UNORM target: egui's renderer then writes sRGB-encoded colours
        // itself, and the read-back bytes are the displayed ones.
        formats
            .iter()
            .find(|f| {
                matches!(
                    f.format,
                    vk::Format::B8G8R8A8_UNORM | vk::Format::R8G8B8A8_UNORM
                )
            })
            .copied()
            .ok_or_else(|| anyhow!("the surface offers no 8-bit UNORM format: {formats:?}"))
    }

    /// Rebuilds the swapchain for a window of `size` (a no-op size 0:
    /// minimised windows keep the old one until they come back).
    pub fn rebuild_swapchain(&mut self, size: [u32; 2]) -> Result<()> {
        if size[0] == 0 || size[1] == 0 {
            return Ok(());
        }
        // SAFETY: waiting for the device before destroying what it used.
        unsafe { self.device.device_wait_idle() }?;
        let format = self.surface_format()?;
        let old = self.swapchain.take();
        let new = Swapchain::new(
            &self.device,
            &self.swapchain_fn,
            &self.surface_fn,
            self.physical,
            self.surface,
            format,
            self.render_pass,
            size,
            old.as_ref(),
        );
        if let Some(old) = old {
            old.destroy(&self.device, &self.swapchain_fn);
        }
        self.swapchain = Some(new?);
        Ok(())
    }

    /// The swapchain's size, if one exists.
    pub fn extent(&self) -> Option<[u32; 2]> {
        self.swapchain
            .as_ref()
            .map(|s| [s.extent.width, s.extent.height])
    }

    /// Draws egui's `output` (textures, then shapes) into the next
    /// swapchain image and presents it. With `capture`, the presented image
    /// is also read back as RGBA8 (the screenshot's `window.png`).
    pub fn draw(
        &mut self,
        ctx: &egui::Context,
        output: egui::FullOutput,
        window_size: [u32; 2],
        capture: bool,
    ) -> Result<(Drawn, Option<image::RgbaImage>)> {
        if window_size[0] == 0 || window_size[1] == 0 {
            return Ok((Drawn::Skipped, None));
        }
        if self.extent() != Some(window_size) {
            self.rebuild_swapchain(window_size)?;
        }
        let device = self.device.clone();
        // SAFETY: the fence belongs to this device; one frame in flight.
        unsafe {
            device.wait_for_fences(&[self.frame_fence], true, u64::MAX)?;
        }
        let renderer = self.renderer.as_mut().context("renderer")?;
        for id in self.textures_to_free.drain(..) {
            renderer
                .free_texture(id)
                .map_err(|e| anyhow!("egui texture: {e}"))?;
        }
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                renderer
                    .set_texture(self.queue, self.command_pool, *id, delta)
                    .map_err(|e| anyhow!("egui texture upload: {e}"))?;
            }
        }
        self.textures_to_free = output.textures_delta.free.iter().copied().collect();
        let swapchain = self.swapchain.as_ref().context("swapchain")?;
        // SAFETY: the swapchain and semaphore are live; no fence.
        let acquired = unsafe {
            self.swapchain_fn.acquire_next_image(
                swapchain.handle,
                u64::MAX,
                self.image_available,
                vk::Fence::null(),
            )
        };
        let index = match acquired {
            Ok((i, _)) => i,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.rebuild_swapchain(window_size)?;
                return Ok((Drawn::Skipped, None));
            }
            Err(e) => bail!("vkAcquireNextImageKHR: {e}"),
        };
        let primitives = ctx.tessellate(output.shapes, output.pixels_per_point);
        let cmd = self.command_buffer;
        let image = swapchain.images[index as usize];
        let extent = swapchain.extent;
        // SAFETY: the command buffer is idle (fence waited above); every
        // handle recorded is live until the next fence wait.
        unsafe {
            device.reset_fences(&[self.frame_fence])?;
            device.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())?;
            device.begin_command_buffer(
                cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )?;
            let clear = [vk::ClearValue {
                color: vk::ClearColorValue {
                    float32: [0.08, 0.08, 0.09, 1.0],
                },
            }];
            device.cmd_begin_render_pass(
                cmd,
                &vk::RenderPassBeginInfo::default()
                    .render_pass(self.render_pass)
                    .framebuffer(swapchain.framebuffers[index as usize])
                    .render_area(vk::Rect2D {
                        offset: vk::Offset2D::default(),
                        extent,
                    })
                    .clear_values(&clear),
                vk::SubpassContents::INLINE,
            );
        }
        renderer
            .cmd_draw(cmd, extent, output.pixels_per_point, &primitives)
            .map_err(|e| anyhow!("egui draw: {e}"))?;
        // SAFETY: as above.
        unsafe { device.cmd_end_render_pass(cmd) };
        let readback = match capture {
            true => Some(super::swapchain::record_readback(
                &self.instance,
                &device,
                self.physical,
                cmd,
                image,
                extent,
            )?),
            false => None,
        };
        let render_finished = swapchain.render_finished[index as usize];
        // SAFETY: as above; the semaphores and fence are this device's.
        unsafe {
            device.end_command_buffer(cmd)?;
            let wait = [self.image_available];
            let stages = [vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT];
            let cmds = [cmd];
            let signal = [render_finished];
            let submit = vk::SubmitInfo::default()
                .wait_semaphores(&wait)
                .wait_dst_stage_mask(&stages)
                .command_buffers(&cmds)
                .signal_semaphores(&signal);
            device
                .queue_submit(self.queue, &[submit], self.frame_fence)
                .map_err(|e| match e {
                    vk::Result::ERROR_DEVICE_LOST => {
                        anyhow!("the presenting device was lost (driver reset)")
                    }
                    e => anyhow!("vkQueueSubmit: {e}"),
                })?;
        }
        let swapchains = [swapchain.handle];
        let indices = [index];
        let signal = [render_finished];
        let present = vk::PresentInfoKHR::default()
            .wait_semaphores(&signal)
            .swapchains(&swapchains)
            .image_indices(&indices);
        // SAFETY: the queue supports presentation to this surface (chosen so).
        let presented = unsafe { self.swapchain_fn.queue_present(self.queue, &present) };
        let screenshot = match readback {
            Some(readback) => {
                // SAFETY: waiting for the frame's own fence.
                unsafe { device.wait_for_fences(&[self.frame_fence], true, u64::MAX)? };
                let [w, h] = readback.size();
                let rgba = readback.finish(&device, swapchain.format)?;
                Some(image::RgbaImage::from_raw(w, h, rgba).context("screenshot size")?)
            }
            None => None,
        };
        match presented {
            Ok(false) => Ok((Drawn::Presented, screenshot)),
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => {
                self.rebuild_swapchain(window_size)?;
                Ok((Drawn::Presented, screenshot))
            }
            Err(e) => bail!("vkQueuePresentKHR: {e}"),
        }
    }

    /// Validation messages since the last call.
    pub fn take_messages(&self) -> Vec<String> {
        std::mem::take(&mut *self.messages.lock().unwrap_or_else(|e| e.into_inner()))
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        // SAFETY: after the idle wait nothing of this device is in flight;
        // each object is destroyed once, children before the device, the
        // surface and messenger before the instance.
        unsafe {
            let _ = self.device.device_wait_idle();
            if let Some(mut renderer) = self.renderer.take() {
                for id in std::mem::take(&mut self.textures_to_free) {
                    let _ = renderer.free_texture(id);
                }
                drop(renderer);
            }
            if let Some(s) = self.swapchain.take() {
                s.destroy(&self.device, &self.swapchain_fn);
            }
            self.device.destroy_render_pass(self.render_pass, None);
            self.device.destroy_semaphore(self.image_available, None);
            self.device.destroy_fence(self.frame_fence, None);
            self.device.destroy_command_pool(self.command_pool, None);
            self.device.destroy_device(None);
            self.surface_fn.destroy_surface(self.surface, None);
            if let Some((debug, messenger)) = &self.debug {
                debug.destroy_debug_utils_messenger(*messenger, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// The best device (discrete first, as `izb devices` ranks) with a
/// graphics queue that presents to `surface`: (device, queue family,
/// name, largest image side).
fn pick_device(
    instance: &ash::Instance,
    surface_fn: &ash::khr::surface::Instance,
    surface: vk::SurfaceKHR,
) -> Result<(vk::PhysicalDevice, u32, String, u32)> {
    // SAFETY: `instance` is live; each physical device comes from it.
    let physicals = unsafe { instance.enumerate_physical_devices() }?;
    let mut best: Option<(u32, vk::PhysicalDevice, u32, String, u32)> = None;
    for physical in physicals {
        // SAFETY: as above.
        let props = unsafe { instance.get_physical_device_properties(physical) };
        // SAFETY: as above.
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let family = (0..families.len() as u32).find(|&f| {
            families[f as usize]
                .queue_flags
                .contains(vk::QueueFlags::GRAPHICS)
                // SAFETY: as above; `f` indexes this device's families.
                && unsafe {
                    surface_fn.get_physical_device_surface_support(physical, f, surface)
                }
                .unwrap_or(false)
        });
        let Some(family) = family else { continue };
        let rank = match props.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => 0,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            vk::PhysicalDeviceType::CPU => 3,
            _ => 4,
        };
        let name = props
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let side = props.limits.max_image_dimension2_d;
        if best.as_ref().is_none_or(|(r, ..)| rank < *r) {
            best = Some((rank, physical, family, name, side));
        }
    }
    let (_, physical, family, name, side) =
        best.ok_or_else(|| anyhow!("no Vulkan device can present to this window"))?;
    Ok((physical, family, name, side))
}

fn create_render_pass(device: &ash::Device, format: vk::Format) -> Result<vk::RenderPass> {
    let attachments = [vk::AttachmentDescription::default()
        .format(format)
        .samples(vk::SampleCountFlags::TYPE_1)
        .load_op(vk::AttachmentLoadOp::CLEAR)
        .store_op(vk::AttachmentStoreOp::STORE)
        .initial_layout(vk::ImageLayout::UNDEFINED)
        .final_layout(vk::ImageLayout::PRESENT_SRC_KHR)];
    let color = [vk::AttachmentReference::default()
        .attachment(0)
        .layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)];
    let subpasses = [vk::SubpassDescription::default()
        .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)
        .color_attachments(&color)];
    // The acquire semaphore waits at colour output: the layout change
    // from UNDEFINED must wait there too.
    let dependencies = [vk::SubpassDependency::default()
        .src_subpass(vk::SUBPASS_EXTERNAL)
        .dst_subpass(0)
        .src_stage_mask(vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT)
        .dst_stage_mask(vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT)
        .dst_access_mask(vk::AccessFlags::COLOR_ATTACHMENT_WRITE)];
    let info = vk::RenderPassCreateInfo::default()
        .attachments(&attachments)
        .subpasses(&subpasses)
        .dependencies(&dependencies);
    // SAFETY: `info` and its arrays outlive the call.
    Ok(unsafe { device.create_render_pass(&info, None) }?)
}
