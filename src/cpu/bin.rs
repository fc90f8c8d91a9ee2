//! Pass 2, `bin`: triangles into the light-space grid pyramids by
//! counting sort ([Compute IZB]): count per cell, exclusive prefix sum, scatter
//! of triangle ids. Each triangle is placed in every cascade its shadow
//! reaches, at the pyramid level where its rectangle holds at most
//! `level_cells` cells, and listed only in the cells of that rectangle its
//! projection touches ([`super::footprint`]). The overflow list remains
//! for what has no footprint: triangles crossing a point light's image
//! plane, and every triangle when the grid is disabled.

use super::counting_sort::{sort_into_cells, BlockEntry, CellLists};
use super::footprint::Footprint;
pub use super::footprint::{cell_range, cell_range_at, CELL_PADDING};
use super::light_setup::{CascadeGrid, LevelCells, LightSetup, MicroquadBoxes, Projection};
pub use super::penumbra::{ndc_pad_in_cells, penumbra_pad, penumbra_reaches_cell};
use super::placement::{lane_footprint, placements};
pub use super::placement::{place, Placement};
pub use super::receiver_cull::behind_receivers;
use super::receiver_cull::TriangleCull;
pub use super::receivers::{cell_receivers, CellReceivers};
pub use super::shadow_map_cover::cover_floor;
use super::shadow_map_cover::set_cover_floors;
use super::triangle_lanes::{TriangleLanes, LANES};
use super::{ReceiverCull, Skips};
use crate::cascades::MAX_CASCADES;
use crate::gbuffer::GBuffer;
use glam::Vec3;
use rayon::prelude::*;
use std::cell::OnceCell;

/// One entry of a cell's list: the triangle and whether it does *not*
/// touch the cell to the left / below (at the same level). A pixel tests
/// the entry in cell (`x`, `y`) of its range `[px0, px1] × [py0, py1]`
/// when it is at the range's left column or the left cell lacks the
/// triangle, and likewise below. At least once: in the lowest row of the
/// range where the triangle touches a cell, take the leftmost such cell;
/// its left and lower neighbours within the range lack the triangle. At
/// most once for a triangle whose touched cells within the range form a
/// rectangle; a thin diagonal can be tested twice (a staircase of cells),
/// which ORs the same mask again. The GPU packs both bits above the 28-bit
/// id.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CellEntry {
    pub id: u32,
    pub first_column: bool,
    pub first_row: bool,
}

impl CellEntry {
    /// Whether a pixel whose cell range at this level starts at (`px0`,
    /// `py0`) tests this entry in cell (`x`, `y`).
    #[inline]
    pub fn tested_in(&self, x: u32, y: u32, px0: u32, py0: u32) -> bool {
        (self.first_column || x == px0) && (self.first_row || y == py0)
    }

    /// The entry of triangle `id` in cell (`x`, `y`) of its footprint.
    pub fn new(id: u32, f: &Footprint, x: u32, y: u32) -> CellEntry {
        let (x, y) = (i64::from(x), i64::from(y));
        CellEntry {
            id,
            first_column: !f.touches(x - 1, y),
            first_row: !f.touches(x, y - 1),
        }
    }
}

/// An overflow-list entry: a triangle and the cascades (bit k = cascade k)
/// whose pixels must all test it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct OverflowEntry {
    id: u32,
    cascades: u8,
}

/// Counters of the bin pass. With several cascades a triangle is placed
/// once per cascade: `binned` counts (triangle, cascade) placements in
/// cells, `overflow` the triangles that overflow in at least one cascade,
/// `culled` the triangles placed in none.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BinStats {
    pub triangles: usize,
    pub binned: usize,
    pub overflow: usize,
    pub culled: usize,
    /// Total (cell, triangle) entries written by the scatter.
    pub cell_entries: usize,
    /// Cells of binned triangles' rectangles their projection does not
    /// touch (not listed: the exact overlap test).
    pub cells_untouched: usize,
    /// Binned placements per pyramid level (index = level).
    pub per_level: Vec<usize>,
    /// (cell, triangle) entries the `behind_receivers` skip dropped.
    pub entries_behind_receivers: usize,
    /// Binned placements dropped from every cell they cover.
    pub triangles_behind_receivers: usize,
    /// (cell, triangle) entries an area light's per-cell penumbra bound
    /// dropped ([`penumbra_reaches_cell`]).
    pub entries_outside_penumbra: usize,
    /// Cells with a cover triangle (the conservative shadow map).
    pub covered_cells: usize,
    /// The densest cascade's placed rectangles: their cells per cell of
    /// their level, summed over its levels ([`ReceiverCull::WhereDense`]).
    pub rectangle_cells_per_cell: f64,
    /// Whether the receivers were registered and the `behind_receivers`
    /// skip taken.
    pub receivers_culled_against: bool,
    /// The mean length of the cell list an entry sits in (Σ len² / Σ len
    /// over the cells; 0 where the vertex cache was not asked for).
    pub list_length_per_entry: f64,
    /// Bytes of the vertex cache ([`Bins::cache_vertices`]; 0 without):
    /// 40 per entry (a key and nine floats) and a little padding.
    pub vertex_cache_bytes: usize,
}

/// The binned grids of every cascade, back to back. Cells hold triangle
/// ids into the eye-relative triangle buffer, which `evaluate` reads as it
/// is: its frustum test runs in eye space, so there is no light-view copy
/// to cache ([Compute IZB]'s vertex cache saves the evaluate pass a fetch,
/// skin and transform chain; this crate's input is already flat
/// eye-relative `f32` triangles, the very vertices the test needs).
pub struct Bins {
    /// `placement[cascade][id]`.
    pub placement: Vec<Vec<Placement>>,
    /// Exclusive prefix sum of the per-cell counts; `cells + 1` entries.
    pub cell_start: Vec<u32>,
    /// Cell entries, cell after cell.
    pub cell_triangles: Vec<CellEntry>,
    /// Per cascade, its overflow list: the triangles every pixel of the
    /// cascade tests, as the entries of one more cell that is tested whole
    /// (both `first_` flags set), so evaluate walks it like the others.
    pub overflow: Vec<Vec<CellEntry>>,
    /// Per cascade, bit l set when pyramid level l holds a placement: the
    /// levels a pixel visits.
    pub levels: Vec<u32>,
    /// Per cascade, each level's place in the cell arrays
    /// ([`CascadeGrid::level_table`]).
    pub level_cells: Vec<Vec<LevelCells>>,
    /// Per cell, the conservative shadow map: the triangle whose shadow
    /// covers the whole cell with the highest floor ([`cover_floor`]), or
    /// [`NO_COVER`]. Only filled with the `shadow_map` skip.
    pub cover: Vec<u32>,
    /// The cell lists' vertex cache, when written ([`Bins::cache_vertices`]).
    pub vertices: Option<super::cell_vertices::CellVertices>,
    pub stats: BinStats,
}

impl Drop for Bins {
    /// The cell lists' memory goes to the next frame's sort.
    fn drop(&mut self) {
        super::counting_sort::keep_lists(std::mem::take(&mut self.cell_triangles));
    }
}

/// [`Bins::cover`] of a cell no triangle covers.
pub const NO_COVER: u32 = izb_contract::word::NO_COVER;

impl Bins {
    /// Entries of cell (x, y) of pyramid level `level` of `grid`.
    #[inline]
    pub fn cell(&self, grid: &CascadeGrid, level: u32, x: u32, y: u32) -> &[CellEntry] {
        self.cell_at(grid.cell_index_at(level, x, y))
    }

    /// Entries of the cell with index `c` in the cell arrays.
    #[inline]
    pub fn cell_at(&self, c: usize) -> &[CellEntry] {
        self.cell_and_following(c).0
    }

    /// [`Self::cell_at`]'s entries, and every entry from its first on: the
    /// cells of a row follow one another (`LevelCells::index`), so a walk
    /// along the row reads on into the next cell's.
    #[inline]
    pub fn cell_and_following(&self, c: usize) -> (&[CellEntry], &[CellEntry]) {
        let following = &self.cell_triangles[self.cell_start[c] as usize..];
        let len = (self.cell_start[c + 1] - self.cell_start[c]) as usize;
        (&following[..len], following)
    }
}

/// The receivers (and µQuad boxes) the `behind_receivers` skip culls
/// against, and when to take it.
#[derive(Clone, Copy)]
pub struct CullAgainst<'a> {
    pub g: &'a GBuffer,
    /// The receivers' µQuad boxes: given, or projected by the bin once it
    /// takes the cull ([`LightSetup::receiver_boxes`] with
    /// `covered_only`), for evaluate to read after it. Where the cull is
    /// not taken, nothing projects them ahead of evaluate.
    pub boxes: &'a OnceCell<MicroquadBoxes>,
    pub covered_only: bool,
    pub when: ReceiverCull,
}

/// Bins eye-relative `f32` triangles (`triangles[id]`) into every
/// cascade's pyramid. With the `outside_bounds` skip off, triangles that
/// miss a grid go to that cascade's overflow list instead of being culled;
/// with `cull_behind` (the `behind_receivers` skip) a cell does not list
/// triangles that are behind all of its receivers, when `when` says it
/// pays; with the `shadow_map` skip (directional lights) each cell records
/// its cover triangle.
///
/// Placement and the per-cell tests run in parallel over blocks of
/// triangles; the counting sort itself (counts, prefix sum, scatter,
/// `cpu::counting_sort`) takes their entries in triangle order, so
/// every cell lists its ids in increasing order, as a stable GPU scatter
/// after a sort would.
pub fn bin(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    skips: Skips,
    cull_behind: Option<CullAgainst<'_>>,
) -> Bins {
    // Each triangle's placement only: its footprint (84 bytes with the
    // placement, 74 MB at courtyard's 877 k triangles) and its light-view
    // vertices are computed again where its entries are (courtyard 1080p
    // bin 0.244 → 0.226 s).
    let placed: Vec<Vec<Placement>> = setup
        .cascades
        .iter()
        .map(|grid| placements(setup, grid, triangles, skips))
        .collect();
    // The levels that hold placements: the only ones a pixel visits, and
    // the only ones whose receivers the cull needs.
    let (levels, rectangle_cells): (Vec<u32>, Vec<Vec<u64>>) = setup
        .cascades
        .iter()
        .zip(&placed)
        .map(|(grid, placed)| placed_levels(grid, placed))
        .unzip();
    let level_cells = setup.level_tables();
    // The densest cascade's rectangle cells per cell.
    let density = setup
        .cascades
        .iter()
        .zip(&rectangle_cells)
        .map(|(grid, cells)| grid.rectangle_cells_per_cell(cells))
        .fold(0.0, f64::max);
    let receivers = cull_behind
        .filter(|c| c.when.culls(setup.light_radius, density))
        .and_then(|c| {
            let boxes = c
                .boxes
                .get_or_init(|| setup.receiver_boxes(c.g, skips, c.covered_only));
            cell_receivers(setup, c.g, boxes, skips, &levels, &level_cells)
        });
    let covers = skips.shadow_map && setup.projection == Projection::Orthographic;
    let blocks: Vec<BlockEntries> = (0..triangles.len())
        .step_by(TRIANGLE_BLOCK)
        .collect::<Vec<_>>()
        .into_par_iter()
        // One job per block, as evaluate's bands (dense blocks cost more).
        .with_max_len(1)
        .map(|first| {
            let ids = first..(first + TRIANGLE_BLOCK).min(triangles.len());
            block_entries(setup, &placed, triangles, receivers.as_ref(), covers, ids)
        })
        .collect();
    let cells = setup.total_cells();
    let mut stats = BinStats {
        triangles: triangles.len(),
        rectangle_cells_per_cell: density,
        receivers_culled_against: receivers.is_some(),
        ..Default::default()
    };
    let mut overflow = Vec::new();
    for b in &blocks {
        overflow.extend_from_slice(&b.overflow);
        b.stats.add_to(&mut stats);
    }
    stats.overflow = overflow.len();
    let entries: Vec<&[BlockEntry]> = blocks.iter().map(|b| &b.entries[..]).collect();
    let CellLists {
        cell_start,
        cell_triangles,
        cover,
    } = sort_into_cells(&entries, cells);
    stats.covered_cells = cover.iter().filter(|&&c| c != NO_COVER).count();
    stats.cell_entries = cell_triangles.len();
    // Each cascade's overflow list, as the entries of a cell that every
    // pixel of the cascade tests whole.
    let overflow = (0..setup.cascades.len())
        .map(|k| {
            overflow
                .iter()
                .filter(|e| e.cascades & (1 << k) != 0)
                .map(|e| CellEntry {
                    id: e.id,
                    first_column: true,
                    first_row: true,
                })
                .collect()
        })
        .collect();
    Bins {
        placement: placed,
        cell_start,
        cell_triangles,
        overflow,
        levels,
        level_cells,
        cover,
        vertices: None,
        stats,
    }
}

/// Triangles per parallel block of the bin.
const TRIANGLE_BLOCK: usize = 1024;

/// What one block of triangles contributes to the bin, in triangle order:
/// (cell, entry, cover floor or −∞) per listed cell, overflow entries and
/// counters.
struct BlockEntries {
    entries: Vec<BlockEntry>,
    overflow: Vec<OverflowEntry>,
    stats: BinStats,
}

impl BinStats {
    /// Adds a block's counters (not its cell or cover totals, which the
    /// whole bin counts).
    fn add_to(&self, total: &mut BinStats) {
        total.binned += self.binned;
        total.culled += self.culled;
        total.cells_untouched += self.cells_untouched;
        total.entries_behind_receivers += self.entries_behind_receivers;
        total.triangles_behind_receivers += self.triangles_behind_receivers;
        total.entries_outside_penumbra += self.entries_outside_penumbra;
        if total.per_level.len() < self.per_level.len() {
            total.per_level.resize(self.per_level.len(), 0);
        }
        for (t, s) in total.per_level.iter_mut().zip(&self.per_level) {
            *t += s;
        }
    }
}

/// One cascade's placements, in one parallel pass: the levels that hold
/// one (bit l = level l) and the cells of their rectangles on each level.
fn placed_levels(grid: &CascadeGrid, placed: &[Placement]) -> (u32, Vec<u64>) {
    let levels = grid.levels as usize;
    let add = |(mask, mut cells): (u32, Vec<u64>), p: &Placement| {
        if let Some((level, [x0, y0, x1, y1])) = p.cells() {
            cells[level as usize] += u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1);
            return (mask | 1 << level, cells);
        }
        (mask, cells)
    };
    placed
        .par_iter()
        .with_min_len(TRIANGLE_BLOCK)
        .fold(|| (0, vec![0; levels]), add)
        .reduce(
            || (0, vec![0; levels]),
            |(a, mut x), (b, y)| {
                x.iter_mut().zip(&y).for_each(|(x, y)| *x += y);
                (a | b, x)
            },
        )
}

/// The entries of triangles `ids` in every cascade: each cell of its
/// rectangle its projection touches and the cull keeps.
fn block_entries(
    setup: &LightSetup,
    placed: &[Vec<Placement>],
    triangles: &[[Vec3; 3]],
    receivers: Option<&CellReceivers>,
    covers: bool,
    ids: std::ops::Range<usize>,
) -> BlockEntries {
    let (first, end) = (ids.start, ids.end);
    let mut out = BlockEntries {
        entries: Vec::new(),
        overflow: Vec::new(),
        stats: BinStats::default(),
    };
    let stats = &mut out.stats;
    let mut touched_above = Vec::new();
    // The block's triangles sixteen at a time, in each cascade: their
    // light-view vertices and grid coordinates, as the placement pass
    // computed them (`TriangleLanes`), not again one by one.
    let mut lanes = [TriangleLanes::default(); MAX_CASCADES];
    for id in ids {
        let l = (id - first) % LANES;
        if l == 0 {
            let chunk = &triangles[id..(id + LANES).min(end)];
            for (grid, lanes) in setup.cascades.iter().zip(&mut lanes) {
                lanes.fill(setup, grid, setup.simd, chunk);
            }
        }
        let mut overflows = 0u8;
        let mut placed_anywhere = false;
        for (k, grid) in setup.cascades.iter().enumerate() {
            let Some((level, rect)) = placed[k][id].cells() else {
                if placed[k][id] == Placement::Overflow {
                    overflows |= 1 << k;
                }
                continue;
            };
            let light_view = lanes[k].light_view(l);
            let f = lane_footprint(setup, grid, (&lanes[k], l), level, rect);
            placed_anywhere = true;
            stats.binned += 1;
            if stats.per_level.len() <= level as usize {
                stats.per_level.resize(level as usize + 1, 0);
            }
            stats.per_level[level as usize] += 1;
            let [x0, y0, x1, y1] = rect;
            let cells = grid.level(level);
            let first_entry = out.entries.len();
            let cull = receivers.map(|r| {
                let t = TriangleCull::new(&light_view, setup.projection, setup.light_radius);
                (r, t)
            });
            let mut listed = false;
            // Whether the cells left of and above each cell are touched
            // (`CellEntry::new`'s two questions), carried along the rows
            // rather than asked again: false outside the rectangle.
            touched_above.clear();
            touched_above.resize((x1 - x0 + 1) as usize, false);
            for y in y0..=y1 {
                // Cells outside the row's span are untouched
                // (`Footprint::row_span`): only the flags above them are
                // cleared.
                let (a, b) = f.row_span(i64::from(y));
                // As x in a..b (b ≥ a − 1: an empty span is a..a).
                let (a, b) = (a as u32, (b + 1) as u32);
                let span = (a - x0) as usize..(b - x0) as usize;
                stats.cells_untouched += touched_above.len() - span.len();
                touched_above[..span.start].fill(false);
                touched_above[span.end..].fill(false);
                let mut touched_left = false;
                let row = f.row(i64::from(y));
                for (x, above) in (a..b).zip(touched_above[span].iter_mut()) {
                    let touched = row.touches(i64::from(x));
                    debug_assert_eq!(touched, f.touches(i64::from(x), i64::from(y)));
                    let first = (!touched_left, !*above);
                    (touched_left, *above) = (touched, touched);
                    if !touched {
                        stats.cells_untouched += 1;
                        continue;
                    }
                    let c = cells.index(x, y);
                    if cull
                        .as_ref()
                        .is_some_and(|(r, t)| t.behind(grid, r, level, c, (x, y)))
                    {
                        stats.entries_behind_receivers += 1;
                        continue;
                    }
                    if receivers.is_some_and(|r| {
                        !penumbra_reaches_cell(setup, grid, r, &f, &light_view, c, x, y)
                    }) {
                        stats.entries_outside_penumbra += 1;
                        continue;
                    }
                    listed = true;
                    let entry = CellEntry {
                        id: id as u32,
                        first_column: first.0,
                        first_row: first.1,
                    };
                    debug_assert_eq!(entry, CellEntry::new(id as u32, &f, x, y));
                    out.entries.push((c as u32, entry, f32::NEG_INFINITY));
                }
            }
            stats.triangles_behind_receivers += !listed as usize;
            if covers {
                let entries = &mut out.entries[first_entry..];
                set_cover_floors(grid, &f, &light_view, cells, entries);
            }
        }
        if overflows != 0 {
            out.overflow.push(OverflowEntry {
                id: id as u32,
                cascades: overflows,
            });
        }
        stats.culled += (!placed_anywhere && overflows == 0) as usize;
    }
    out
}
