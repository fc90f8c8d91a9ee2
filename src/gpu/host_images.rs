//! The host's images a frame of the shadow pass reads or writes, and the
//! state contract around them (issue 29's point 2): the visibility buffer,
//! or the depth and the normal, in; the masks and the lit fraction out. The host declares each
//! image — what it is and the layout, stage and access its last write
//! left it in — and the pass records the one barrier that makes that write
//! visible to its compute shader and moves the image into the layout it
//! reads it in, as FidelityFX FSR2's dispatch takes resources whose current
//! state the host declares, and kajiya's render graph imports an image
//! with its access at import.
//!
//! The contract, per frame and image:
//! - before: the image in [`HostImage::layout`], the host's last access
//!   of it in the stage and access of [`HostImage::written_by`]
//!   (submitted earlier on the same queue, or earlier in the same command
//!   buffer): for an input its last write, for an output its last read or
//!   write (an output's contents are discarded: `UNDEFINED` is allowed);
//! - during: an input read by compute shaders (`COMPUTE_SHADER`,
//!   `SHADER_READ`), an output written by them (`COMPUTE_SHADER`,
//!   `SHADER_WRITE`), every pixel of it;
//! - after: in [`HostImage::layout_after`] — an input
//!   `SHADER_READ_ONLY_OPTIMAL`, or left as given when given `GENERAL`
//!   or (a depth image) `DEPTH_STENCIL_READ_ONLY_OPTIMAL` or
//!   `DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL`, so a host may keep
//!   depth-testing against it read-only; an output `GENERAL`. The host's next access needs a barrier from the
//!   pass's scope above (a layout transition out of it is one).
//!
//! Descriptors: one set per frame slot (set `HOST_SET`), allocated once
//! from a pool of their own and written when the slot records, when the
//! slot's previous frame is known done — so a host may hand a different
//! image each frame (a swapchain-sized ring, a resized target) without
//! any allocation.

use super::context::DeviceShared;
use super::pipeline::BindingLayout;
use super::shared::host_image;
use super::GpuError;
use ash::vk;
use std::sync::Arc;

/// One of the host's images as a frame reads it: what it is and the
/// state the host leaves it in before the frame.
#[derive(Clone, Copy, Debug)]
pub struct HostImage {
    pub image: vk::Image,
    /// A 2D view of the image's first mip level and array layer, in
    /// `format`, with the colour aspect (a depth image's: the depth
    /// aspect alone).
    pub view: vk::ImageView,
    pub format: vk::Format,
    pub extent: [u32; 2],
    /// The usage the image was created with (the pass samples it:
    /// `SAMPLED`).
    pub usage: vk::ImageUsageFlags,
    /// The sample count it was created with: `TYPE_1`, or for a pass made
    /// for a multisampled visibility buffer
    /// (`GBufferInput::MultisampledVisibility`) that count (one bound
    /// where the pass reads another would be undefined: refused by name).
    pub samples: vk::SampleCountFlags,
    /// Its layout when the frame's commands start executing.
    pub layout: vk::ImageLayout,
    /// The stage and access of the host's last write before the frame:
    /// the source scope of the pass's barrier. Empty flags: nothing to
    /// wait for (already visible to compute-shader reads).
    pub written_by: (vk::PipelineStageFlags, vk::AccessFlags),
}

/// The host's images of one frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameImages {
    /// In: per pixel the scene triangle it sees (`R32_UINT`, sampled),
    /// with the pass's `GBufferInput::Visibility` and only then; per
    /// sample, unresolved, with `GBufferInput::MultisampledVisibility`.
    pub visibility: Option<HostImage>,
    /// In: the host's depth (with the pass's `GBufferInput::DepthNormal`
    /// and only then): one of [`DEPTH_FORMATS`], sampled.
    pub depth: Option<HostImage>,
    /// In: the host's geometric normal per pixel (with the depth): world
    /// axes in x, y, z, either facing, unit length or near it (the pass
    /// normalises); one of [`NORMAL_FORMATS`], sampled.
    pub normal: Option<HostImage>,
    /// Out: the masks (`R32_UINT`; `R32G32_UINT` with two mask halves),
    /// a storage image.
    pub masks: Option<HostImage>,
    /// Out: the lit fraction (`R16_UNORM` or `R8_UNORM`), a storage image:
    /// 1 − hidden / samples where shadow-tested, 0 on a surface facing
    /// away from the light, 1 where no surface is seen.
    pub lit_fraction: Option<HostImage>,
}

/// The depth formats the pass reads (the depth aspect of the combined
/// ones).
pub const DEPTH_FORMATS: [vk::Format; 4] = [
    vk::Format::D32_SFLOAT,
    vk::Format::D24_UNORM_S8_UINT,
    vk::Format::X8_D24_UNORM_PACK32,
    vk::Format::D32_SFLOAT_S8_UINT,
];

/// The normal formats the pass reads: float or snorm, x, y, z in the
/// first three channels.
pub const NORMAL_FORMATS: [vk::Format; 3] = [
    vk::Format::R32G32B32A32_SFLOAT,
    vk::Format::R16G16B16A16_SFLOAT,
    vk::Format::R16G16B16A16_SNORM,
];

/// Which input images a frame gives the pass's G-buffer producer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputImages {
    /// None (the pass casts its own rays).
    None,
    /// A visibility buffer of this many samples a pixel.
    Visibility(vk::SampleCountFlags),
    /// A depth and a normal.
    DepthNormal,
}

/// The aspects a barrier on an image of `format` names: depth and stencil
/// for a combined format (every aspect changes layout together), depth for
/// a depth-only one, else colour.
pub fn format_aspects(format: vk::Format) -> vk::ImageAspectFlags {
    match format {
        vk::Format::D32_SFLOAT | vk::Format::X8_D24_UNORM_PACK32 => vk::ImageAspectFlags::DEPTH,
        vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT => {
            vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
        }
        _ => vk::ImageAspectFlags::COLOR,
    }
}

/// Whether the pass reads or writes an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageUse {
    Read,
    Write,
}

impl HostImage {
    /// The layout a frame leaves an input in (and reads it in): the one
    /// given when it is `GENERAL` or, for a depth image, a depth
    /// read-only layout; else `SHADER_READ_ONLY_OPTIMAL`.
    pub fn layout_after(&self) -> vk::ImageLayout {
        let depth_read_only = [
            vk::ImageLayout::DEPTH_STENCIL_READ_ONLY_OPTIMAL,
            vk::ImageLayout::DEPTH_READ_ONLY_STENCIL_ATTACHMENT_OPTIMAL,
        ];
        let is_depth = DEPTH_FORMATS.contains(&self.format);
        if self.layout == vk::ImageLayout::GENERAL
            || (is_depth && depth_read_only.contains(&self.layout))
        {
            self.layout
        } else {
            vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL
        }
    }

    /// The aspects a barrier on the image names ([`format_aspects`]).
    pub fn aspects(&self) -> vk::ImageAspectFlags {
        format_aspects(self.format)
    }

    /// The layout a frame leaves the image in for `usage`: an output is
    /// written as a storage image, in `GENERAL`.
    pub fn layout_after_use(&self, usage: ImageUse) -> vk::ImageLayout {
        match usage {
            ImageUse::Read => self.layout_after(),
            ImageUse::Write => vk::ImageLayout::GENERAL,
        }
    }

    /// Checks the image for `usage`: one of `formats` (`format_why` says
    /// what they mean), the pass's resolution, the usage flag the pass
    /// needs, non-null handles, and for an input a layout that keeps its
    /// contents (an output's are replaced). `what` names it in the error.
    fn check(
        &self,
        what: &str,
        usage: ImageUse,
        (formats, format_why): (&[vk::Format], &str),
        resolution: [u32; 2],
        samples: vk::SampleCountFlags,
    ) -> Result<(), GpuError> {
        let (flag, how) = match usage {
            ImageUse::Read => (vk::ImageUsageFlags::SAMPLED, "reads it with texelFetch"),
            ImageUse::Write => (vk::ImageUsageFlags::STORAGE, "writes it with imageStore"),
        };
        let problem = if !formats.contains(&self.format) {
            Some(format!(
                "its format is {:?}; it must be {formats:?}{format_why}",
                self.format
            ))
        } else if self.extent != resolution {
            Some(format!(
                "it is {}x{}; the pass renders {}x{}",
                self.extent[0], self.extent[1], resolution[0], resolution[1]
            ))
        } else if self.samples != samples {
            Some(format!(
                "it has {:?} samples a pixel; the pass was made for {samples:?} (a \
                 multisampled visibility buffer is GBufferInput::MultisampledVisibility; \
                 depth, normal and outputs are single-sampled)",
                self.samples
            ))
        } else if !self.usage.contains(flag) {
            Some(format!(
                "its usage {:?} lacks {flag:?} (the pass {how})",
                self.usage
            ))
        } else if usage == ImageUse::Read
            && matches!(
                self.layout,
                vk::ImageLayout::UNDEFINED | vk::ImageLayout::PREINITIALIZED
            )
        {
            Some(format!(
                "its layout is {:?}: a transition from it discards the contents",
                self.layout
            ))
        } else if self.image == vk::Image::null() || self.view == vk::ImageView::null() {
            Some("its image or view is a null handle".into())
        } else {
            None
        };
        match problem {
            Some(p) => Err(GpuError::Unsupported(format!(
                "the host's {what} image cannot be {}: {p}",
                if usage == ImageUse::Read {
                    "read"
                } else {
                    "written"
                }
            ))),
            None => Ok(()),
        }
    }

    /// Checks the declaration of a visibility buffer for a `resolution`
    /// image of `samples` samples a pixel: `R32_UINT`, the same size and
    /// sample count, sampled usage, contents defined.
    pub fn check_visibility(
        &self,
        resolution: [u32; 2],
        samples: vk::SampleCountFlags,
    ) -> Result<(), GpuError> {
        let why = format!(
            " (per pixel a triangle id, {:#x} for none)",
            izb_contract::word::NO_HIT
        );
        let formats = (&[vk::Format::R32_UINT][..], why.as_str());
        self.check("visibility", ImageUse::Read, formats, resolution, samples)
    }
}

/// A named error for an input the pass was not made for, or lacks.
fn input_mismatch(made_for: InputImages, what: &str, given: bool) -> GpuError {
    GpuError::Unsupported(format!(
        "the pass was made for the {made_for:?} G-buffer input, and the frame {} a {what}",
        if given { "gives" } else { "lacks" }
    ))
}

impl FrameImages {
    /// Checks a frame's images for a pass whose G-buffer producer reads
    /// `input` (a visibility buffer of its sample count, depth + normal, or
    /// none), renders `resolution` and keeps `mask_halves` mask halves;
    /// each problem named.
    pub fn check(
        &self,
        input: InputImages,
        resolution: [u32; 2],
        mask_halves: usize,
    ) -> Result<(), GpuError> {
        let wanted = [
            (
                "visibility buffer",
                self.visibility,
                matches!(input, InputImages::Visibility(_)),
            ),
            ("depth image", self.depth, input == InputImages::DepthNormal),
            (
                "normal image",
                self.normal,
                input == InputImages::DepthNormal,
            ),
        ];
        for (what, given, wants) in wanted {
            if given.is_some() != wants {
                return Err(input_mismatch(input, what, given.is_some()));
            }
        }
        if let (Some(v), InputImages::Visibility(samples)) = (&self.visibility, input) {
            v.check_visibility(resolution, samples)?;
        }
        let one = vk::SampleCountFlags::TYPE_1;
        if let Some(d) = &self.depth {
            let why = " (its depth aspect: the view must have that aspect alone)";
            d.check(
                "depth",
                ImageUse::Read,
                (&DEPTH_FORMATS, why),
                resolution,
                one,
            )?;
        }
        if let Some(n) = &self.normal {
            let why = " (x, y, z in the first three channels)";
            n.check(
                "normal",
                ImageUse::Read,
                (&NORMAL_FORMATS, why),
                resolution,
                one,
            )?;
        }
        if let Some(m) = &self.masks {
            let format = if mask_halves == 2 {
                vk::Format::R32G32_UINT
            } else {
                vk::Format::R32_UINT
            };
            m.check("masks", ImageUse::Write, (&[format], ""), resolution, one)?;
        }
        if let Some(l) = &self.lit_fraction {
            let formats = [vk::Format::R16_UNORM, vk::Format::R8_UNORM];
            let formats = (&formats[..], "");
            l.check("lit fraction", ImageUse::Write, formats, resolution, one)?;
        }
        Ok(())
    }
}

/// Records the barrier before a frame uses `image`: the host's last
/// access made available and the image moved from its declared layout to
/// the one it is used in ([`HostImage::layout_after_use`]), visible to
/// compute-shader reads or writes.
///
/// # Safety
/// `cmd` is a command buffer of `device` in the recording state;
/// `image` is a live image of that device declared truthfully (its
/// layout when this barrier executes is `image.layout`).
pub(crate) unsafe fn acquire(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    image: &HostImage,
    usage: ImageUse,
) {
    let (mut src_stage, src_access) = image.written_by;
    if src_stage.is_empty() {
        src_stage = vk::PipelineStageFlags::TOP_OF_PIPE;
    }
    let dst_access = match usage {
        ImageUse::Read => vk::AccessFlags::SHADER_READ,
        ImageUse::Write => vk::AccessFlags::SHADER_WRITE,
    };
    let barrier = [vk::ImageMemoryBarrier::default()
        .src_access_mask(src_access)
        .dst_access_mask(dst_access)
        .old_layout(image.layout)
        .new_layout(image.layout_after_use(usage))
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image.image)
        .subresource_range(
            vk::ImageSubresourceRange::default()
                .aspect_mask(image.aspects())
                .level_count(1)
                .layer_count(1),
        )];
    // SAFETY: the caller's promise; `barrier` outlives the call.
    unsafe {
        device.cmd_pipeline_barrier(
            cmd,
            src_stage,
            vk::PipelineStageFlags::COMPUTE_SHADER,
            vk::DependencyFlags::empty(),
            &[],
            &[],
            &barrier,
        );
    }
}

/// One host-image descriptor set (`HOST_SET`) per frame slot, from a pool
/// made for exactly them; all freed on drop.
pub(crate) struct HostImageSets {
    shared: Arc<DeviceShared>,
    pool: vk::DescriptorPool,
    sets: Vec<vk::DescriptorSet>,
}

impl HostImageSets {
    /// Allocates `slots` sets.
    pub fn new(
        shared: &Arc<DeviceShared>,
        layout: &BindingLayout,
        slots: usize,
    ) -> Result<Self, GpuError> {
        shared.count_allocation(super::context::Allocation::DescriptorSet);
        let device = &shared.device;
        let slots_u32 = slots as u32;
        let sizes = [
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::SAMPLED_IMAGE)
                .descriptor_count(3 * slots_u32),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_IMAGE)
                .descriptor_count(2 * slots_u32),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(host_image::GEOMETRY_SLOTS * slots_u32),
        ];
        let info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(slots as u32)
            .pool_sizes(&sizes);
        // SAFETY: `info` and its pool sizes outlive the call.
        let pool = unsafe { device.create_descriptor_pool(&info, None) }.map_err(GpuError::vk)?;
        let layouts = vec![layout.host_images_layout; slots];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        // SAFETY: `pool` was created above for exactly these sets.
        match unsafe { device.allocate_descriptor_sets(&alloc) } {
            Ok(sets) => Ok(HostImageSets {
                shared: shared.clone(),
                pool,
                sets,
            }),
            Err(e) => {
                // SAFETY: created above; its allocation failed, so nothing uses it.
                unsafe { device.destroy_descriptor_pool(pool, None) };
                Err(GpuError::vk(e))
            }
        }
    }

    /// Points slot `slot`'s set at `images` (those present; a binding
    /// left unwritten is never used by the frame's dispatches).
    ///
    /// # Safety
    /// No submitted frame that binds slot `slot`'s set is pending, and
    /// every view in `images` is a live view of this device's.
    pub unsafe fn write(&self, slot: usize, images: &FrameImages) {
        let bound = [
            (host_image::VISIBILITY, images.visibility, ImageUse::Read),
            (host_image::MASKS, images.masks, ImageUse::Write),
            (host_image::LIT, images.lit_fraction, ImageUse::Write),
            (host_image::DEPTH, images.depth, ImageUse::Read),
            (host_image::NORMAL, images.normal, ImageUse::Read),
        ];
        let infos: Vec<(u32, [vk::DescriptorImageInfo; 1], ImageUse)> = bound
            .iter()
            .filter_map(|&(binding, image, usage)| {
                let image = image?;
                let info = vk::DescriptorImageInfo::default()
                    .image_view(image.view)
                    .image_layout(image.layout_after_use(usage));
                Some((binding, [info], usage))
            })
            .collect();
        let writes: Vec<vk::WriteDescriptorSet> = infos
            .iter()
            .map(|(binding, info, usage)| {
                let kind = match usage {
                    ImageUse::Read => vk::DescriptorType::SAMPLED_IMAGE,
                    ImageUse::Write => vk::DescriptorType::STORAGE_IMAGE,
                };
                vk::WriteDescriptorSet::default()
                    .dst_set(self.sets[slot])
                    .dst_binding(*binding)
                    .descriptor_type(kind)
                    .image_info(info)
            })
            .collect();
        // SAFETY: the caller's promise: the set is not in use.
        unsafe { self.shared.device.update_descriptor_sets(&writes, &[]) };
    }

    /// Points slot `slot`'s `HOST_GEOMETRY` array at `buffers` (at most
    /// `GEOMETRY_SLOTS`, at least one), whole; the slots past them repeat
    /// the first (the shader names every slot, so each must be valid).
    ///
    /// # Safety
    /// No submitted frame that binds slot `slot`'s set is pending, and
    /// every buffer is a live buffer of this device's made with
    /// `STORAGE_BUFFER` usage.
    pub unsafe fn write_geometry(&self, slot: usize, buffers: &[vk::Buffer]) {
        // Every frame records this: a fixed array, nothing on the heap.
        let infos: [vk::DescriptorBufferInfo; host_image::GEOMETRY_SLOTS as usize] =
            std::array::from_fn(|k| {
                vk::DescriptorBufferInfo::default()
                    .buffer(*buffers.get(k).unwrap_or(&buffers[0]))
                    .range(vk::WHOLE_SIZE)
            });
        let write = vk::WriteDescriptorSet::default()
            .dst_set(self.sets[slot])
            .dst_binding(host_image::GEOMETRY)
            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
            .buffer_info(&infos);
        // SAFETY: the caller's promise: the set is not in use.
        unsafe { self.shared.device.update_descriptor_sets(&[write], &[]) };
    }

    /// Slot `slot`'s set (binding it is `unsafe`, as every recording is).
    pub fn handle(&self, slot: usize) -> vk::DescriptorSet {
        self.sets[slot]
    }
}

impl Drop for HostImageSets {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        // SAFETY: the pass that owns the sets is dropped with the GPU idle
        // for its frames (its documented contract), so no pending command
        // buffer binds them (a poisoned device returns above).
        unsafe { self.shared.device.destroy_descriptor_pool(self.pool, None) };
    }
}
