//! # izb
//!
//! Analytic, antialiased hard shadows with a compute irregular z-buffer
//! (IZB), and the ray-traced ground truth they are measured against.
//!
//! Module map (README, Layout), each layer importing only those below it:
//! [`scene`] loads glTF, scene specs and procedural scenes; [`bvh`] casts
//! rays; [`gbuffer`] computes primary visibility with µQuad footprints;
//! [`frustum`] is the shadow rule (depth test, edge functions);
//! [`settings`], [`cascades`] and [`skips`] are what both backends take;
//! [`cpu`] is the irregular z-buffer on the CPU and [`gpu`] its Vulkan
//! twin (sharing `izb-contract` with the shaders); [`mod@reference`] traces
//! the ground truth; [`baseline`] holds the shadow maps and [`peer`] the
//! ray tracers the IZB is measured against; [`mod@bench`], [`report`],
//! [`view`] (the interactive window) and [`cli`] run and show it all;
//! [`output`] writes files atomically.

pub mod baseline;
#[cfg(feature = "cli")]
pub mod bench;
#[cfg(feature = "cli")]
pub mod bvh;
pub mod cascades;
#[cfg(feature = "cli")]
pub mod cli;
pub mod cpu;
pub mod frustum;
pub mod gbuffer;
pub mod gpu;
pub mod lut;
#[cfg(feature = "cli")]
pub mod metrics;
#[cfg(feature = "cli")]
pub mod output;
#[cfg(feature = "cli")]
pub mod peer;
#[cfg(feature = "cli")]
pub mod reference;
#[cfg(feature = "cli")]
pub mod report;
pub mod scene;
pub mod settings;
pub mod skips;
#[cfg(feature = "cli")]
pub mod thread_time;
#[cfg(feature = "cli")]
pub mod view;

/// Visibility samples per pixel: one bit each in a `u32` occlusion mask.
pub const SAMPLES_PER_PIXEL: usize = izb_lut::SAMPLES_PER_PIXEL;
