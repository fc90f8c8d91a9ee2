//! The CPU twin of the shadow pass's `export_images`
//! (`shaders/export_images.comp`): the masks and the lit fraction as the
//! host's images hold them.

use crate::gbuffer::{flags, GBuffer};

/// What the host's output images hold, row-major.
pub struct ExportedImages {
    /// Per pixel its mask halves' words (`R32_UINT`, or `R32G32_UINT`
    /// with two halves: low half first).
    pub masks: Vec<u32>,
    /// Per pixel the lit fraction as a `bits`-bit UNORM code.
    pub lit_fraction: Vec<u16>,
}

/// The images of masks `masks` (and `high`, empty with one half) over
/// G-buffer `g`, the lit fraction with `bits` bits (16 or 8): 1 −
/// hidden / samples where shadow-tested, 0 on a surface facing away from
/// the light (its geometry shadows it), 1 where no surface is seen.
/// Codes round to nearest; the GPU's UNORM conversion may pick the other
/// code at a tie (Vulkan spec, "Conversion from Floating-Point to
/// Normalized Fixed-Point": the rounding is the implementation's).
pub fn export_images(masks: &[u32], high: &[u32], g: &GBuffer, bits: u32) -> ExportedImages {
    let halves = 1 + usize::from(!high.is_empty());
    let mut words = Vec::with_capacity(masks.len() * halves);
    for (i, &m) in masks.iter().enumerate() {
        words.push(m);
        if halves == 2 {
            words.push(high[i]);
        }
    }
    let lit = super::resolve_halves(masks, high, g);
    let top = ((1u32 << bits) - 1) as f32;
    let lit_fraction = lit
        .iter()
        .zip(&g.flags)
        .map(|(&v, &f)| {
            let v = if f & flags::SHADOW_TESTED != 0 {
                v
            } else if f & flags::HIT != 0 {
                0.0
            } else {
                1.0
            };
            (v * top).round() as u16
        })
        .collect();
    ExportedImages {
        masks: words,
        lit_fraction,
    }
}
