//! GPU pass 2, `bin` (`shaders/bin.comp`): triangles into the light-space
//! grid pyramid by counting sort ([Compute IZB]) — each triangle placed on
//! its level from its light-view vertices and counted in the cells its
//! projection touches (the overflow list only for triangles crossing a
//! point light's image plane), an in-place prefix sum, a scatter by atomic
//! decrement — the twin of [`crate::cpu::bin::bin`].
//!
//! The cell list's size is only known after the prefix sum, inside the
//! frame. The host allocates a guess; the prefix sum compares the total
//! with it and raises `C_CAPACITY_EXCEEDED`, the scatter writes nothing past
//! the end, evaluate skips the incomplete grid, and the host reruns the
//! frame with the exact size ([`super::frame`]). Within a cell the order of
//! triangle ids depends on the atomics; masks do not (they are ORs).

use super::{Kernels, Recorder};

/// Records the pass over `triangles` triangles; with `pixels` (the
/// behind-receivers skip) it first gathers each cell's receivers
/// (`STEP_RECEIVERS`, [`crate::cpu::bin::cell_receivers`]).
pub fn bin(rec: &Recorder, kernels: &Kernels, triangles: u32, pixels: Option<u32>) {
    rec.begin_label("bin");
    if let Some(pixels) = pixels {
        rec.dispatch_linear(&kernels.bin_receivers, pixels);
        rec.barrier();
    }
    rec.dispatch_linear(&kernels.bin_count, triangles);
    rec.barrier();
    rec.dispatch(&kernels.bin_prefix_sum, [1, 1, 1]);
    rec.barrier();
    rec.dispatch_linear(&kernels.bin_scatter, triangles);
    rec.barrier();
    rec.end_label();
}
