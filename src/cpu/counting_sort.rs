//! The bin's counting sort ([Compute IZB]): per-cell counts (with each
//! cell's conservative shadow-map cover), the exclusive prefix sum, and
//! the scatter of the entries into cell order.
//!
//! The entries arrive as the bin's blocks made them, in triangle order,
//! and every cell lists its ids in that order, as a stable GPU scatter
//! after a sort would. The cells are split into one contiguous range per
//! thread; each thread reads every entry and keeps those of its range, in
//! the same order, so the counts, covers and lists are those of one
//! serial pass. The serial passes were a tenth of the bin on the small
//! scenes and a sixth on courtyard (random writes into the cell arrays);
//! split, each thread makes half of them and streams the entries twice.

use super::bin::{CellEntry, NO_COVER};
use super::spare::{reused, Spare};
use rayon::prelude::*;

/// The last frame's cell lists, their memory for the next frame's
/// ([`super::spare`]; handed back when its [`super::bin::Bins`] drops):
/// fresh, the sort filled all of it on one thread before the scatter
/// wrote it (courtyard at 960×540: 4.8 of the sort's 13.3 ms).
static SPARE_LISTS: Spare<Vec<CellEntry>> = Spare::new();

/// Keeps `lists` (a dropped [`super::bin::Bins`]'s) for the next sort.
pub(super) fn keep_lists(lists: Vec<CellEntry>) {
    SPARE_LISTS.keep(lists);
}

/// One entry of a block: (cell, entry, cover floor or −∞).
pub(super) type BlockEntry = (u32, CellEntry, f32);

/// The cell lists of the counting sort, and each cell's cover triangle.
pub(super) struct CellLists {
    /// Exclusive prefix sum of the per-cell counts; `cells + 1` entries.
    pub cell_start: Vec<u32>,
    /// Cell entries, cell after cell.
    pub cell_triangles: Vec<CellEntry>,
    /// Per cell, the triangle with the highest cover floor (ties to the
    /// lowest id), or [`NO_COVER`].
    pub cover: Vec<u32>,
}

/// Sorts the `blocks`' entries (every cell index below `cells`) into cell
/// lists.
pub(super) fn sort_into_cells(blocks: &[&[BlockEntry]], cells: usize) -> CellLists {
    let part = cells.div_ceil(rayon::current_num_threads().max(1)).max(1);
    // The entries of cells lo..lo + len, in block order, as (offset in
    // the range, entry, floor).
    let in_range = move |lo: usize, len: usize| {
        blocks
            .iter()
            .flat_map(|b| b.iter())
            .filter_map(move |&(c, entry, floor)| {
                let j = (c as usize).wrapping_sub(lo);
                (j < len).then_some((j, entry, floor))
            })
    };
    // Count (and the best cover floor per cell: highest wins, ties to the
    // lowest id, as ids arrive in increasing order).
    let mut counts = vec![0u32; cells];
    let mut cover = vec![NO_COVER; cells];
    counts
        .par_chunks_mut(part)
        .zip(cover.par_chunks_mut(part))
        .enumerate()
        .for_each(|(k, (counts, cover))| {
            let mut best_floor = vec![f32::NEG_INFINITY; counts.len()];
            for (j, entry, floor) in in_range(k * part, counts.len()) {
                counts[j] += 1;
                if floor > best_floor[j] {
                    best_floor[j] = floor;
                    cover[j] = entry.id;
                }
            }
        });
    // Exclusive prefix sum.
    let mut cell_start = Vec::with_capacity(cells + 1);
    let mut sum = 0u32;
    for c in &counts {
        cell_start.push(sum);
        sum += c;
    }
    cell_start.push(sum);
    // Scatter: each range's lists are one slice of the output, every
    // entry of which it writes.
    let spare = SPARE_LISTS.take().unwrap_or_default();
    let mut cell_triangles = reused(spare, sum as usize, CellEntry::default());
    let mut rest = &mut cell_triangles[..];
    let mut ranges = Vec::new();
    for lo in (0..cells).step_by(part) {
        let hi = (lo + part).min(cells);
        let len = (cell_start[hi] - cell_start[lo]) as usize;
        let (lists, tail) = rest.split_at_mut(len);
        ranges.push((lo, hi, lists));
        rest = tail;
    }
    ranges.into_par_iter().for_each(|(lo, hi, lists)| {
        let base = cell_start[lo];
        let mut cursor: Vec<u32> = cell_start[lo..hi].iter().map(|s| s - base).collect();
        for (j, entry, _) in in_range(lo, hi - lo) {
            lists[cursor[j] as usize] = entry;
            cursor[j] += 1;
        }
    });
    CellLists {
        cell_start,
        cell_triangles,
        cover,
    }
}
