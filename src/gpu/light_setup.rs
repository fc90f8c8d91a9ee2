//! GPU pass 1, `light_setup` (`shaders/light_setup.comp`): the light-view
//! frame and the grid fitted to the shadow-tested µQuads, computed by
//! reductions on the GPU (no read-back inside the frame) — the twin of
//! [`mod@crate::cpu::light_setup`].
//!
//! Four dispatches: receiver bounds (atomic min/max of order-preserving
//! float bits), the light frame (1 thread), the µQuads' light-NDC extent,
//! and the grid size (1 thread).

use super::{Kernels, Recorder};

/// Records the pass.
pub fn light_setup(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("light_setup");
    rec.dispatch_pixels(&kernels.light_setup_receivers, size);
    rec.barrier();
    rec.dispatch(&kernels.light_setup_frame, [1, 1, 1]);
    rec.barrier();
    rec.dispatch_pixels(&kernels.light_setup_extent, size);
    rec.barrier();
    rec.dispatch(&kernels.light_setup_grid, [1, 1, 1]);
    rec.barrier();
    rec.end_label();
}
