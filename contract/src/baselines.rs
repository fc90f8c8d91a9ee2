//! What the seed baselines' Rust and GLSL share (the filtered maps'
//! codes and parameters, contact shadows' march, the shadow volumes'
//! corners), rendered into `contract.glsl` by [`crate::glsl_header`]
//! with the rest of the contract.

use crate::macros::shared_constants;

shared_constants! {
    /// The filtered shadow maps (`MAP_FILTER_*`): their
    /// `FrameParams::map_filter` codes (PCF sizes are odd and ≥ 3, one tap
    /// is 0, PCSS 1) and the blur's reach.
    pub mod filtered: u32 as Uint, prefix "MAP_FILTER_" {
        /// Variance shadow maps (Donnelly & Lauritzen 2006).
        VSM = 2;
        /// Moment shadow maps, four moments, Hamburger reconstruction
        /// (Peters & Klein 2015).
        MSM = 4;
        /// Exponential shadow maps (Annen et al. 2008), one moment (an
        /// even code, as odd ones are PCF sizes).
        ESM = 6;
        /// Taps on each side of the centre of the separable blur: a 9²
        /// Gaussian (binomial weights C(8, i)/256), the filter of
        /// Peters 2017's compute blur.
        BLUR_RADIUS = 4;
    }
}

shared_constants! {
    /// Screen-space contact shadows (`crate::baseline::contact`).
    pub mod contact: u32 as Uint, prefix "CONTACT_" {
        /// Steps of the march toward the light.
        STEPS = 16;
    }
}

shared_constants! {
    /// The filtered maps' reconstruction parameters (`MAP_FILTER_*`).
    pub mod filtered_params: f32 as Float, prefix "MAP_FILTER_" {
        /// Light-bleeding reduction of VSM (Lauritzen 2007): Chebyshev
        /// bounds below this are cut to 0 and the rest rescaled to [0, 1].
        BLEEDING_CUT = 0.2;
        /// MSM's moment bias α: the moments move this share of the way
        /// toward (½, ½, ½, ½) (Peters & Klein 2015 bias them so to keep
        /// the Hankel matrix positive definite under rounding; the value
        /// is ours, for unquantised `f32` moments: about 250 units in the
        /// last place of a flat receiver's second moment near ¼. A tenth
        /// of it left the Cholesky pivots so near 0 that lavapipe's
        /// divisions, not always correctly rounded, moved results 0.022
        /// from the CPU twin's; see `paper-notes/baselines.md`).
        MOMENT_BIAS = 3.0e-5;
        /// ESM's exponent c (Annen et al. 2008 use 80 with 32-bit
        /// floats; larger is sharper and leaks less): the map keeps
        /// `exp(c·(u − 1))` ∈ [e⁻⁷², 1], and at 72 even a blurred texel's
        /// smallest share, e⁻⁷² / 256², stays a normal float (> 2⁻¹²⁶),
        /// so a GPU that flushes subnormals stores what the CPU does.
        ESM_EXPONENT = 72.0;
    }
}

/// A caster's shadow volume as 8 triangles (24 vertices, no index
/// buffer): corners 0–2 are the triangle turned to face the light (the
/// light cap), 3–5 the same vertices extruded away from the light (the
/// dark cap, reversed), then the three side quads, each edge walked
/// opposite to its neighbour face so the volume is closed and
/// consistently oriented (`izb::baseline::volumes`,
/// `shaders/shadow_volume.vert`).
pub const VOLUME_CORNERS: [u32; 24] = [
    0, 1, 2, 3, 5, 4, 1, 0, 3, 1, 3, 4, 2, 1, 4, 2, 4, 5, 0, 2, 5, 0, 5, 3,
];
