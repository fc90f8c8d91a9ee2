//! The 32 light samples of soft shadows: points on the light's disk, in
//! the same (u, v) ∈ [0, 1)² frame as the pixel pattern, inside the disk
//! of radius ½ centred at (½, ½) (the frame [`crate::edge`]'s edge
//! functions use, so the same table generator serves both).
//!
//! A soft-shadow mask is the set of light samples a receiver point cannot
//! see; each occluder edge, projected from the receiver onto the light's
//! disk, is a straight line across it, so what matters is again how well
//! the fraction of samples on one side of a line matches the *disk's*
//! area on that side.

use crate::pattern::SamplePattern;
use crate::SAMPLES_PER_PIXEL;

/// Name of the light pattern the renderer uses.
pub const LIGHT_PATTERN_NAME: &str = "vogel_spiral";

/// The disk's radius in (u, v): the disk inscribed in the unit square.
pub const LIGHT_DISK_RADIUS: f64 = 0.5;

/// The light samples: a Vogel (golden-angle) spiral, sample i at radius
/// ½·√((i + ½)/32) and angle i·π(3 − √5): equal-area rings, no two
/// samples on one line through the centre.
pub fn light_pattern() -> SamplePattern {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    std::array::from_fn(|i| {
        let r = LIGHT_DISK_RADIUS * ((i as f64 + 0.5) / SAMPLES_PER_PIXEL as f64).sqrt();
        let a = i as f64 * golden_angle;
        [(0.5 + r * a.cos()) as f32, (0.5 + r * a.sin()) as f32]
    })
}
