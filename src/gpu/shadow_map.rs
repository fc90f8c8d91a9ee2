//! The shadow-map baseline on the GPU (`shaders/shadow_map.comp`,
//! `shaders/shadow_lookup.comp`): the twins of
//! [`crate::baseline::shadow_map::shadow_map`] and
//! [`crate::baseline::shadow_map::shadow_lookup`], run after the IZB's own
//! G-buffer and light-setup passes in a frame of their own
//! ([`super::frame::GpuRenderer::render_shadow_map`]).

use super::{Kernels, Recorder};

/// Most workgroups along x (the Vulkan minimum of
/// `maxComputeWorkGroupCount[0]`); more triangles go on in y.
const MAX_GROUPS_X: u32 = 65_535;

/// Records the raster pass: one 64-invocation workgroup per triangle.
pub fn shadow_map(rec: &Recorder, kernels: &Kernels, triangles: u32) {
    rec.begin_label("shadow_map");
    let x = triangles.clamp(1, MAX_GROUPS_X);
    rec.dispatch(&kernels.shadow_map, [x, triangles.div_ceil(x).max(1), 1]);
    rec.barrier();
    rec.end_label();
}

/// Records the lookup pass: one invocation per pixel.
pub fn shadow_lookup(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("shadow_lookup");
    rec.dispatch_pixels(&kernels.shadow_lookup, size);
    rec.barrier();
    rec.end_label();
}
