//! The shadow pass's last step, `export_images`
//! (`shaders/export_images.comp`): the frame's masks and lit fraction
//! copied into the host's storage images — the twin of
//! [`crate::cpu::export_images`]. The pass's own results stay in its
//! storage buffers; these are the images a host's lighting pass samples,
//! under the contract of [`super::host_images`].

use super::host_images::FrameImages;
use super::{Kernels, Recorder};
use ash::vk;

/// Records one dispatch per output image in `images` (none without
/// outputs). The caller has bound the frame's host-image set and moved
/// the outputs to `GENERAL` (`host_images::acquire`); `images` passed
/// `FrameImages::check`, so the formats are the ones matched here.
pub fn export_images(
    rec: &Recorder,
    kernels: &Kernels,
    size: [u32; 2],
    images: &FrameImages,
    mask_halves: usize,
) {
    if images.masks.is_none() && images.lit_fraction.is_none() {
        return;
    }
    rec.begin_label("export_images");
    if images.masks.is_some() {
        let kernel = if mask_halves == 2 {
            &kernels.export_masks_paired
        } else {
            &kernels.export_masks
        };
        rec.dispatch_pixels(kernel, size);
    }
    if let Some(lit) = &images.lit_fraction {
        let kernel = if lit.format == vk::Format::R8_UNORM {
            &kernels.export_lit_r8
        } else {
            &kernels.export_lit_r16
        };
        rec.dispatch_pixels(kernel, size);
    }
    rec.end_label();
}
