//! GPU pass 3, `evaluate` (`shaders/evaluate.comp`): per shadow-tested
//! pixel, the frustum-triangle test (paper-notes/frustum-test.md) against every candidate of
//! the cells under its µQuad and the overflow list, in 8×8 tiles with
//! cooperative shared-memory batches ([Compute IZB]) — the twin of
//! [`crate::cpu::evaluate::evaluate`]. Sample mode (1, 32 LUT, 32 exact)
//! comes from `FrameParams::mode`; the LUT is the build-time table.

use super::{Kernels, Recorder};

/// Records the pass.
pub fn evaluate(rec: &Recorder, kernels: &Kernels, size: [u32; 2]) {
    rec.begin_label("evaluate");
    rec.dispatch_pixels(&kernels.evaluate, size);
    rec.barrier();
    rec.end_label();
}
