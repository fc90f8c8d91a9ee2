//! Pass 2, `bin`: triangles into the light-space grids by counting sort
//! (seed 000): count per cell, exclusive prefix sum, scatter of triangle
//! ids. Each triangle is
//! placed in every cascade's grid its shadow reaches; one whose rectangle
//! holds more than the cascade's `overflow_cells` cells goes to the
//! overflow list that every pixel of that cascade tests, so one huge ground
//! triangle does not fill thousands of cells.

use super::light_setup::{CascadeGrid, LightSetup, Projection};
use super::{is_receiver, Skips};
use crate::gbuffer::GBuffer;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Cell rectangles are grown by this fraction of a cell on every side,
/// far above the `f32` rounding of a light NDC coordinate (~1e-4 cell on a
/// 1024-cell grid), so rounding never drops a triangle from a cell its
/// shadow touches.
pub const CELL_PADDING: f32 = 1.0 / 64.0;

/// Where one triangle went in one cascade's grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Not binned: its shadow cannot reach any receiver of the cascade.
    Culled,
    /// In the overflow list.
    Overflow,
    /// In the cells `[x0, x1] × [y0, y1]` (inclusive).
    Cells { x0: u32, y0: u32, x1: u32, y1: u32 },
}

/// One entry of a cell's list: the triangle and whether the cell is in the
/// first column / first row of the triangle's rectangle. A pixel whose
/// rectangle overlaps the triangle's in several cells tests it only in the
/// first cell of the overlap, `(max(tx0, px0), max(ty0, py0))`: for a cell
/// that lists the triangle, `x = max(tx0, px0)` holds exactly when
/// `x = tx0` or `x = px0` (x ≥ both there), so these two bits are all the
/// pixel needs of the triangle's rectangle — no per-triangle placement is
/// stored (the GPU packs them above the 28-bit id).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellEntry {
    pub id: u32,
    pub first_column: bool,
    pub first_row: bool,
}

impl CellEntry {
    /// Whether a pixel whose cell rectangle starts at (`px0`, `py0`) tests
    /// this entry in cell (`x`, `y`).
    #[inline]
    pub fn tested_in(&self, x: u32, y: u32, px0: u32, py0: u32) -> bool {
        (self.first_column || x == px0) && (self.first_row || y == py0)
    }
}

/// An overflow-list entry: a triangle and the cascades (bit k = cascade k)
/// whose pixels must all test it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OverflowEntry {
    pub id: u32,
    pub cascades: u8,
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
    /// (cell, triangle) entries the `behind_receivers` skip dropped.
    pub entries_behind_receivers: usize,
    /// Binned placements dropped from every cell they cover.
    pub triangles_behind_receivers: usize,
    /// Cells with a cover triangle (the conservative shadow map).
    pub covered_cells: usize,
}

/// The binned grids of every cascade, back to back. Cells hold triangle
/// ids into the eye-relative triangle buffer, which `evaluate` reads as it
/// is: its frustum test runs in eye space, so there is no light-view copy
/// to cache (seed 000's vertex cache saves the evaluate pass a fetch,
/// skin and transform chain; this crate's input is already flat
/// eye-relative `f32` triangles, the very vertices the test needs).
pub struct Bins {
    /// `placement[cascade][id]`.
    pub placement: Vec<Vec<Placement>>,
    /// Exclusive prefix sum of the per-cell counts; `cells + 1` entries.
    pub cell_start: Vec<u32>,
    /// Cell entries, cell after cell.
    pub cell_triangles: Vec<CellEntry>,
    pub overflow: Vec<OverflowEntry>,
    /// Per cell, the conservative shadow map: the triangle whose shadow
    /// covers the whole cell with the highest floor ([`cover_floor`]), or
    /// [`NO_COVER`]. Only filled with the `shadow_map` skip.
    pub cover: Vec<u32>,
    pub stats: BinStats,
}

/// [`Bins::cover`] of a cell no triangle covers.
pub const NO_COVER: u32 = u32::MAX;

impl Bins {
    /// Entries of cell (x, y) of `grid`.
    #[inline]
    pub fn cell(&self, grid: &CascadeGrid, x: u32, y: u32) -> &[CellEntry] {
        let c = grid.cell_index(x, y);
        &self.cell_triangles[self.cell_start[c] as usize..self.cell_start[c + 1] as usize]
    }
}

/// Inclusive integer cell range of `grid` covered by the continuous
/// grid-space box `[lo, hi]`, grown by [`CELL_PADDING`], or `None` if it
/// misses the grid (always for a grid without cells).
pub fn cell_range(grid: &CascadeGrid, lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    let (w, h) = (grid.cells[0] as f32, grid.cells[1] as f32);
    let (lo, hi) = (lo - CELL_PADDING, hi + CELL_PADDING);
    if hi.x < 0.0 || hi.y < 0.0 || lo.x >= w || lo.y >= h || lo.x.is_nan() || hi.x.is_nan() {
        return None;
    }
    let x0 = lo.x.max(0.0) as u32;
    let y0 = lo.y.max(0.0) as u32;
    let x1 = (hi.x.min(w - 1.0)) as u32;
    let y1 = (hi.y.min(h - 1.0)) as u32;
    Some([x0, y0, x1.max(x0), y1.max(y0)])
}

/// Light NDC of a light-view triangle's vertices: `Err` with its placement
/// when it has none (wholly behind a point light: culled; crossing its
/// image plane: overflow).
fn triangle_ndc(setup: &LightSetup, tri: &[Vec3; 3]) -> Result<[Vec2; 3], Placement> {
    match setup.projection {
        Projection::Orthographic => Ok(tri.map(|v| Vec2::new(v.x, v.y))),
        Projection::Perspective => match tri.iter().filter(|v| v.z > 0.0).count() {
            0 => Err(Placement::Culled),
            3 => Ok(tri.map(|v| Vec2::new(v.x / v.z, v.y / v.z))),
            _ => Err(Placement::Overflow),
        },
    }
}

/// Where triangle `tri` (light view) goes in `grid`.
pub fn place(setup: &LightSetup, grid: &CascadeGrid, tri: &[Vec3; 3]) -> Placement {
    if setup.grid_disabled {
        return Placement::Overflow;
    }
    let ndc = match triangle_ndc(setup, tri) {
        Ok(n) => n,
        Err(p) => return p,
    };
    let g = ndc.map(|n| grid.grid_coords(n));
    let lo = g[0].min(g[1]).min(g[2]);
    let hi = g[0].max(g[1]).max(g[2]);
    match cell_range(grid, lo, hi) {
        None => Placement::Culled,
        Some([x0, y0, x1, y1])
            if u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1)
                <= u64::from(grid.overflow_cells) =>
        {
            Placement::Cells { x0, y0, x1, y1 }
        }
        Some(_) => Placement::Overflow,
    }
}

/// What the `behind_receivers` skip knows of each cell (of every cascade,
/// indexed like the cell arrays): the lowest light-view z (farthest from
/// the light) of the µQuad centres P of the receivers whose µQuad touches
/// the cell, and how many cells those centres may lie away from it.
pub struct CellReceivers {
    /// +∞ where no receiver touches the cell.
    pub z_min: Vec<f32>,
    pub reach: Vec<u32>,
}

/// [`CellReceivers`] of the receivers of `g` (directional lights only:
/// `None` for a point light or a disabled grid). Each receiver counts in
/// its own cascade's grid.
pub fn cell_receivers(setup: &LightSetup, g: &GBuffer, skips: Skips) -> Option<CellReceivers> {
    if setup.grid_disabled || setup.projection != Projection::Orthographic {
        return None;
    }
    let cells = setup.total_cells();
    let mut out = CellReceivers {
        z_min: vec![f32::INFINITY; cells],
        reach: vec![0; cells],
    };
    for i in 0..g.flags.len() {
        if !is_receiver(g.flags[i], skips) {
            continue;
        }
        let grid = &setup.cascades[setup.cascade_of(g.position[i])];
        let (lo, hi) = setup.microquad_grid_box(grid, g.position[i], g.axis_x[i], g.axis_y[i]);
        let Some([x0, y0, x1, y1]) = cell_range(grid, lo, hi) else {
            continue;
        };
        let z = setup.to_light_view(g.position[i]).z;
        let reach = receiver_reach(lo, hi);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let c = grid.cell_index(x, y);
                out.z_min[c] = out.z_min[c].min(z);
                out.reach[c] = out.reach[c].max(reach);
            }
        }
    }
    Some(out)
}

/// How many cells the µQuad centre may lie from a cell its grid box
/// `[lo, hi]` touches: the box's larger side, rounded up, plus one for
/// the cell itself and the padding.
#[inline]
pub fn receiver_reach(lo: Vec2, hi: Vec2) -> u32 {
    ((hi - lo).max_element().ceil() as u32).saturating_add(1)
}

/// Relative margin of [`behind_receivers`] (2⁻¹⁰), about 10⁴ times the
/// `f32` rounding of the depth test it must agree with.
pub const BEHIND_MARGIN: f32 = 1.0 / 1024.0;

/// The normal of light-view triangle `tri` turned toward the light (+z),
/// or `None` when the light sees it edge-on (or it is NaN): then it has no
/// height function z(x, y).
fn upward_normal(tri: &[Vec3; 3]) -> Option<Vec3> {
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    let n = if n.z < 0.0 { -n } else { n };
    (n.z > 0.0).then_some(n)
}

/// Whether triangle `tri` (light view) is behind every receiver that can
/// test it in cell (`x`, `y`) of `grid`: its plane, over every place a
/// µQuad centre P of those receivers can be (the cell grown by their reach,
/// z ≥ their lowest z), stays farther from the light than P by a margin.
/// Then the per-pixel depth test ([`super::frustum::may_shadow`]: P beyond
/// the plane, away from the light) fails for each of them and the cell need
/// not list the triangle. The plane's height is linear in x, y, so its
/// maximum over the box is at a corner. Directional lights only (+z toward
/// the light); a cell no receiver touches never needs a list.
pub fn behind_receivers(
    grid: &CascadeGrid,
    receivers: &CellReceivers,
    tri: &[Vec3; 3],
    x: u32,
    y: u32,
) -> bool {
    let c = grid.cell_index(x, y);
    let z_min = receivers.z_min[c];
    if z_min == f32::INFINITY {
        return true;
    }
    let Some(n) = upward_normal(tri) else {
        return false;
    };
    let r = receivers.reach[c] as f32 + CELL_PADDING;
    let (g_lo, g_hi) = (
        Vec2::new(x as f32 - r, y as f32 - r),
        Vec2::new(x as f32 + 1.0 + r, y as f32 + 1.0 + r),
    );
    let (lo, hi) = (grid.ndc_of_grid(g_lo), grid.ndc_of_grid(g_hi));
    let a = tri[0];
    let height = |q: Vec2| a.z - (n.x * (q.x - a.x) + n.y * (q.y - a.y)) / n.z;
    let plane_max = height(lo)
        .max(height(Vec2::new(hi.x, lo.y)))
        .max(height(hi))
        .max(height(Vec2::new(lo.x, hi.y)));
    // Size of the whole configuration, for the margin.
    let box_lo = lo
        .min(a.truncate())
        .min(tri[1].truncate())
        .min(tri[2].truncate());
    let box_hi = hi
        .max(a.truncate())
        .max(tri[1].truncate())
        .max(tri[2].truncate());
    let z_lo = z_min.min(a.z).min(tri[1].z).min(tri[2].z);
    let z_hi = z_min.max(a.z).max(tri[1].z).max(tri[2].z);
    let size = (box_hi - box_lo).length() + (z_hi - z_lo);
    let margin = BEHIND_MARGIN * size * (n.length() / n.z);
    plane_max < z_min - margin
}

/// The conservative shadow map's test (Tokuyoshi 2018, seed 000, made a
/// candidate filter instead of a verdict): when triangle `tri` (light view,
/// directional light) covers all of cell (`x`, `y`) of `grid` — the cell's
/// four corners inside its light-space projection — the lowest height of
/// its plane over the cell; else `None`. A receiver in that cell below
/// this floor is likely to lie wholly in the triangle's shadow. Nothing
/// here has to be exact: `evaluate` only tests the best cover triangle
/// first with the ordinary test and stops when that alone fills the mask.
pub fn cover_floor(grid: &CascadeGrid, tri: &[Vec3; 3], x: u32, y: u32) -> Option<f32> {
    let n = upward_normal(tri)?;
    let corners = [
        Vec2::new(x as f32, y as f32),
        Vec2::new(x as f32 + 1.0, y as f32),
        Vec2::new(x as f32 + 1.0, y as f32 + 1.0),
        Vec2::new(x as f32, y as f32 + 1.0),
    ]
    .map(|g| grid.ndc_of_grid(g));
    let v = tri.map(|p| p.truncate());
    // Inside: on the same side of every edge as the third vertex.
    let winding = (v[1] - v[0]).perp_dot(v[2] - v[0]);
    let inside =
        |q: Vec2| (0..3).all(|k| winding * (v[(k + 1) % 3] - v[k]).perp_dot(q - v[k]) > 0.0);
    if !corners.iter().all(|&q| inside(q)) {
        return None;
    }
    let a = tri[0];
    let height = |q: Vec2| a.z - (n.x * (q.x - a.x) + n.y * (q.y - a.y)) / n.z;
    Some(
        corners
            .iter()
            .map(|&q| height(q))
            .fold(f32::INFINITY, f32::min),
    )
}

/// Bins eye-relative `f32` triangles (`triangles[id]`) into every
/// cascade's grid. With the `outside_bounds` skip off, triangles that miss
/// a grid go to that cascade's overflow list instead of being culled; with
/// `receivers` (the `behind_receivers` skip) a cell does not list
/// triangles that are behind all of its receivers; with the `shadow_map`
/// skip (directional lights) each cell records its cover triangle.
pub fn bin(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    skips: Skips,
    receivers: Option<&CellReceivers>,
) -> Bins {
    // Light-view vertices, for placing triangles only (the GPU recomputes
    // them in the scatter with the same arithmetic).
    let light_view: Vec<[Vec3; 3]> = triangles
        .par_iter()
        .map(|t| t.map(|v| setup.to_light_view(v)))
        .collect();
    let placement: Vec<Vec<Placement>> = setup
        .cascades
        .iter()
        .map(|grid| {
            light_view
                .par_iter()
                .map(|t| match place(setup, grid, t) {
                    Placement::Culled if !skips.outside_bounds => Placement::Overflow,
                    p => p,
                })
                .collect()
        })
        .collect();
    let cells = setup.total_cells();
    let lists = |grid: &CascadeGrid, id: usize, x: u32, y: u32| match receivers {
        Some(r) => !behind_receivers(grid, r, &light_view[id], x, y),
        None => true,
    };
    let covers = skips.shadow_map && setup.projection == Projection::Orthographic;
    // Count (and the best cover floor per cell).
    let mut counts = vec![0u32; cells + 1];
    let mut cover = vec![NO_COVER; cells];
    let mut best_floor = vec![f32::NEG_INFINITY; cells];
    let mut stats = BinStats {
        triangles: triangles.len(),
        ..Default::default()
    };
    let mut overflow = Vec::new();
    for id in 0..triangles.len() {
        let mut overflows = 0u8;
        let mut placed = false;
        for (k, grid) in setup.cascades.iter().enumerate() {
            match placement[k][id] {
                Placement::Culled => {}
                Placement::Overflow => overflows |= 1 << k,
                Placement::Cells { x0, y0, x1, y1 } => {
                    placed = true;
                    stats.binned += 1;
                    let mut listed = false;
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            if !lists(grid, id, x, y) {
                                stats.entries_behind_receivers += 1;
                                continue;
                            }
                            let c = grid.cell_index(x, y);
                            counts[c] += 1;
                            listed = true;
                            if let Some(floor) = covers
                                .then(|| cover_floor(grid, &light_view[id], x, y))
                                .flatten()
                            {
                                // Highest floor wins; ties go to the lowest id
                                // (ids arrive in increasing order).
                                if floor > best_floor[c] {
                                    best_floor[c] = floor;
                                    cover[c] = id as u32;
                                }
                            }
                        }
                    }
                    stats.triangles_behind_receivers += !listed as usize;
                }
            }
        }
        if overflows != 0 {
            overflow.push(OverflowEntry {
                id: id as u32,
                cascades: overflows,
            });
        }
        stats.culled += (!placed && overflows == 0) as usize;
    }
    stats.overflow = overflow.len();
    stats.covered_cells = cover.iter().filter(|&&c| c != NO_COVER).count();
    // Exclusive prefix sum.
    let mut cell_start = Vec::with_capacity(cells + 1);
    let mut sum = 0u32;
    for c in &counts[..cells] {
        cell_start.push(sum);
        sum += c;
    }
    cell_start.push(sum);
    stats.cell_entries = sum as usize;
    // Scatter (ids in increasing order within a cell, as a stable GPU
    // scatter after a sort would give).
    let mut cursor = cell_start.clone();
    let mut cell_triangles = vec![
        CellEntry {
            id: 0,
            first_column: false,
            first_row: false
        };
        sum as usize
    ];
    // Cascade after cascade: their cells are disjoint, so each cell still
    // receives its ids in increasing order.
    for (grid, placed) in setup.cascades.iter().zip(&placement) {
        for (id, &p) in placed.iter().enumerate() {
            if let Placement::Cells { x0, y0, x1, y1 } = p {
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        if !lists(grid, id, x, y) {
                            continue;
                        }
                        let c = grid.cell_index(x, y);
                        cell_triangles[cursor[c] as usize] = CellEntry {
                            id: id as u32,
                            first_column: x == x0,
                            first_row: y == y0,
                        };
                        cursor[c] += 1;
                    }
                }
            }
        }
    }
    Bins {
        placement,
        cell_start,
        cell_triangles,
        overflow,
        cover,
        stats,
    }
}
