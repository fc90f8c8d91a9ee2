//! Peers the IZB is measured against in `izb bench`: what a user would run
//! instead to get the same 32 samples per pixel.
//!
//! - [`shadow_rays`]: the 32 µQuad sample rays of every shadow-tested
//!   pixel as plain shadow rays, the `rt32-rays` method: a compute pass on
//!   Vulkan (BVH traversal without ray-tracing hardware), its CPU twin
//!   here;
//! - `embree` (cargo feature `embree`, Debian's `libembree-dev`): Intel
//!   Embree 3 tracing the same rays with occlusion queries, the
//!   `rt32-embree` method.

#[cfg(feature = "embree")]
pub mod embree;
pub mod shadow_rays;
