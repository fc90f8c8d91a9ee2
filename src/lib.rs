//! # izb
//!
//! Analytic, antialiased hard shadows with a compute irregular z-buffer
//! (IZB), and the ray-traced ground truth they are measured against.
//!
//! Module map (README, Layout): [`scene`] loads glTF, scene specs and procedural
//! scenes; [`gbuffer`] computes primary visibility with µQuad footprints;
//! [`reference`] traces supersampled ground truth; [`izb`] is the CPU
//! irregular z-buffer and [`gpu`] its Vulkan twin; [`output`] writes images
//! and reports atomically; [`baseline`] holds the shadow maps the IZB is
//! measured against.

pub mod baseline;
pub mod bench;
pub mod bvh;
pub mod cascades;
pub mod cli;
pub mod cpu;
pub mod frustum;
pub mod gbuffer;
pub mod gpu;
pub mod lut;
pub mod metrics;
pub mod output;
pub mod peer;
pub mod reference;
pub mod report;
pub mod scene;
pub mod settings;
pub mod skips;

/// Visibility samples per pixel: one bit each in a `u32` occlusion mask.
pub const SAMPLES_PER_PIXEL: usize = izb_lut::SAMPLES_PER_PIXEL;
