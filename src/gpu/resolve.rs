//! GPU pass 4, `resolve` (`shaders/resolve.comp`): lit fraction from the
//! mask and the shaded image — the twin of [`crate::cpu::resolve`] and
//! [`crate::output::shade_pixel`].

use super::{Kernels, Recorder};

/// Records the pass.
pub fn resolve(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("resolve");
    rec.dispatch_pixels(&kernels.resolve, size);
    rec.barrier();
    rec.end_label();
}
