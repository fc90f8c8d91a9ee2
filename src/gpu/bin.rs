//! GPU pass 2, `bin` (`shaders/bin.comp`): triangles into the light-space
//! grid pyramid by counting sort ([Compute IZB]) — each triangle placed on
//! its level from its light-view vertices and counted in the cells its
//! projection touches (the overflow list only for triangles crossing a
//! point light's image plane), an in-place prefix sum (reduce, then scan,
//! over blocks of `SCAN_BLOCK_CELLS` cells), a scatter by atomic
//! decrement — the twin of [`crate::cpu::bin::bin`].
//!
//! The cell list's size is only known after the prefix sum, inside the
//! frame. The host allocates a guess; the prefix sum compares the total
//! with it and raises `C_CAPACITY_EXCEEDED`, the scatter writes nothing past
//! the end, evaluate skips the incomplete grid, and the host reruns the
//! frame with the exact size ([`super::frame`]). Within a cell the order of
//! triangle ids depends on the atomics; masks do not (they are ORs).

use super::{Kernels, Recorder};

/// Records the pass over `triangles` triangles and at most `max_cells`
/// cells; with `pixels` (the behind-receivers skip) it first gathers each
/// cell's receivers on the used levels (`STEP_RECEIVERS`,
/// [`crate::cpu::receivers::cell_receivers`]).
pub fn bin(rec: &Recorder, kernels: &Kernels, triangles: u32, max_cells: u64, pixels: Option<u32>) {
    rec.begin_label("bin");
    rec.dispatch_linear(&kernels.bin_levels, triangles);
    rec.barrier();
    if let Some(pixels) = pixels {
        rec.dispatch_linear(&kernels.bin_receivers, pixels);
        rec.barrier();
    }
    rec.dispatch_linear(&kernels.bin_count, triangles);
    rec.barrier();
    let blocks = super::frame_memory::scan_blocks(max_cells).max(1) as u32;
    rec.dispatch(&kernels.bin_scan_blocks, [blocks, 1, 1]);
    rec.barrier();
    rec.dispatch(&kernels.bin_scan_top, [1, 1, 1]);
    rec.barrier();
    rec.dispatch(&kernels.bin_scan_apply, [blocks, 1, 1]);
    rec.barrier();
    rec.dispatch_linear(&kernels.bin_scatter, triangles);
    rec.barrier();
    rec.end_label();
}
