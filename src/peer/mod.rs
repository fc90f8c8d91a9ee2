//! Peers the IZB is measured against in `izb bench`: what a user would run
//! instead to get the same 32 samples per pixel.
//!
//! - [`embree`] (cargo feature `embree`, Debian's `libembree-dev`): Intel
//!   Embree 3 tracing the 32 µQuad sample rays of every shadow-tested
//!   pixel with occlusion queries, the `rt32-embree` method.

#[cfg(feature = "embree")]
pub mod embree;
