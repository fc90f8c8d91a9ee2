//! The host's per-frame-slot render targets at one size: the raster's
//! visibility and depth images, the pass's mask and lit-fraction outputs,
//! and the visibility pass drawing into them. A resize makes them anew
//! (as a swapchain's recreation does).

use crate::host_device::HostGpu;
use crate::raster::{OwnedImage, VisibilityRaster};
use ash::vk;

/// One frame slot's images: the raster's visibility and depth targets,
/// the pass's mask and lit-fraction outputs.
pub struct SlotImages {
    pub visibility: OwnedImage,
    pub depth: OwnedImage,
    pub masks: OwnedImage,
    pub lit: OwnedImage,
}

/// Every slot's images and the pass that draws into them.
pub struct Targets {
    pub slots: Vec<SlotImages>,
    pub raster: VisibilityRaster,
    pub extent: [u32; 2],
}

impl Targets {
    pub fn new(gpu: &HostGpu, extent: [u32; 2], frames_in_flight: usize) -> Self {
        let sampled_colour = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_SRC;
        let storage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
        let slots: Vec<SlotImages> = (0..frames_in_flight)
            .map(|_| SlotImages {
                visibility: OwnedImage::new(
                    gpu,
                    "visibility",
                    extent,
                    vk::Format::R32_UINT,
                    sampled_colour,
                ),
                depth: OwnedImage::new(
                    gpu,
                    "depth",
                    extent,
                    vk::Format::D32_SFLOAT,
                    vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
                ),
                masks: OwnedImage::new(gpu, "masks", extent, vk::Format::R32_UINT, storage),
                lit: OwnedImage::new(gpu, "lit", extent, vk::Format::R16_UNORM, storage),
            })
            .collect();
        let targets: Vec<_> = slots.iter().map(|s| (&s.visibility, &s.depth)).collect();
        let raster = VisibilityRaster::new(gpu, extent, &targets);
        Targets {
            slots,
            raster,
            extent,
        }
    }

    /// Frees every image and the pass; no work that uses them executes.
    pub fn destroy(&mut self, gpu: &HostGpu) {
        self.raster.destroy(gpu);
        for s in &mut self.slots {
            for image in [&mut s.visibility, &mut s.depth, &mut s.masks, &mut s.lit] {
                image.destroy(gpu);
            }
        }
    }
}
