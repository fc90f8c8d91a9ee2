//! The host's per-frame-slot render targets at one size: the raster's
//! visibility, depth and (for a depth + normal G-buffer) normal images,
//! the pass's mask and lit-fraction outputs, the host's shaded image, and
//! the raster and lighting passes drawing into them. A resize makes them
//! anew (as a swapchain's recreation does).

use crate::host_device::HostGpu;
use crate::lighting::{HostLighting, LightingImages};
use crate::raster::{OwnedImage, VisibilityRaster};
use ash::vk;
use izb::gbuffer::DepthConvention;
use izb::gpu::host_images::HostImage;

/// A depth + normal G-buffer the host draws for the pass: its depth
/// format and convention.
#[derive(Clone, Copy, Debug)]
pub struct HostDepth {
    pub format: vk::Format,
    pub convention: DepthConvention,
}

/// One frame slot's images: the raster's visibility and depth targets,
/// the pass's mask and lit-fraction outputs, the host's lighting's
/// output.
pub struct SlotImages {
    pub visibility: OwnedImage,
    pub depth: OwnedImage,
    /// The geometric normal (`R32G32B32A32_SFLOAT`), with a depth + normal
    /// G-buffer.
    pub normal: Option<OwnedImage>,
    pub masks: OwnedImage,
    pub lit: OwnedImage,
    /// The host's lighting (`R8G8B8A8_UNORM`, sRGB-encoded).
    pub shaded: OwnedImage,
}

impl SlotImages {
    /// What the host's lighting reads and writes.
    pub fn lighting(&self) -> LightingImages<'_> {
        LightingImages {
            visibility: &self.visibility,
            lit: &self.lit,
            shaded: &self.shaded,
        }
    }
}

/// Every slot's images and the passes that draw into them.
pub struct Targets {
    pub slots: Vec<SlotImages>,
    pub raster: VisibilityRaster,
    pub lighting: HostLighting,
    pub extent: [u32; 2],
}

impl Targets {
    /// `depth`: a depth + normal G-buffer for the pass (its depth sampled,
    /// a normal image drawn), else a visibility buffer and a `D32` depth
    /// the raster alone uses; `samples`: the visibility buffer's and
    /// depth's samples a pixel (`--msaa`). `mesh`: the vertex and index buffers the
    /// lighting reads.
    pub fn new(
        gpu: &HostGpu,
        extent: [u32; 2],
        frames_in_flight: usize,
        (depth, samples): (Option<HostDepth>, vk::SampleCountFlags),
        mesh: (vk::Buffer, vk::Buffer),
    ) -> Self {
        let sampled_colour = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_SRC;
        let storage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
        let slots: Vec<SlotImages> = (0..frames_in_flight)
            .map(|_| SlotImages {
                visibility: OwnedImage::with_samples(
                    gpu,
                    "visibility",
                    extent,
                    vk::Format::R32_UINT,
                    sampled_colour,
                    samples,
                ),
                depth: OwnedImage::with_samples(
                    gpu,
                    "depth",
                    extent,
                    depth.map_or(vk::Format::D32_SFLOAT, |d| d.format),
                    vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                        | depth.map_or(vk::ImageUsageFlags::empty(), |_| {
                            vk::ImageUsageFlags::SAMPLED
                        }),
                    samples,
                ),
                normal: depth.map(|_| {
                    let format = vk::Format::R32G32B32A32_SFLOAT;
                    OwnedImage::new(gpu, "normal", extent, format, sampled_colour)
                }),
                masks: OwnedImage::new(gpu, "masks", extent, vk::Format::R32_UINT, storage),
                // Written by izb's pass, sampled by the host's lighting.
                lit: OwnedImage::new(
                    gpu,
                    "lit",
                    extent,
                    vk::Format::R16_UNORM,
                    storage | vk::ImageUsageFlags::SAMPLED,
                ),
                shaded: OwnedImage::new(gpu, "shaded", extent, vk::Format::R8G8B8A8_UNORM, storage),
            })
            .collect();
        let targets: Vec<_> = slots
            .iter()
            .map(|s| (&s.visibility, s.normal.as_ref(), &s.depth))
            .collect();
        let raster = VisibilityRaster::new(gpu, extent, &targets, depth, samples);
        let images: Vec<_> = slots.iter().map(SlotImages::lighting).collect();
        let lighting = HostLighting::new(gpu, extent, &images, mesh);
        Targets {
            slots,
            raster,
            lighting,
            extent,
        }
    }

    /// Frees every image and the pass; no work that uses them executes.
    pub fn destroy(&mut self, gpu: &HostGpu) {
        self.raster.destroy(gpu);
        self.lighting.destroy(gpu);
        for s in &mut self.slots {
            let images = [
                &mut s.visibility,
                &mut s.depth,
                &mut s.masks,
                &mut s.lit,
                &mut s.shaded,
            ];
            for image in images {
                image.destroy(gpu);
            }
            if let Some(n) = &mut s.normal {
                n.destroy(gpu);
            }
        }
    }
}

/// `image` as the host declares it to the pass.
pub fn declared(
    image: &OwnedImage,
    extent: [u32; 2],
    layout: vk::ImageLayout,
    written_by: (vk::PipelineStageFlags, vk::AccessFlags),
) -> HostImage {
    HostImage {
        image: image.image,
        view: image.view,
        format: image.format,
        extent,
        usage: image.usage,
        samples: image.samples,
        layout,
        written_by,
    }
}
