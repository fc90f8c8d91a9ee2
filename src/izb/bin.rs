//! Pass 2, `bin`: triangles into the light-space grid by counting sort
//! (seed 000): count per cell, exclusive prefix sum, scatter of triangle
//! ids. The light-view vertex cache is written once here; triangles that
//! span more than `max_span` cells on an axis go to an overflow list that
//! every pixel tests, so one huge ground triangle does not fill thousands
//! of cells.

use super::light_setup::{LightSetup, Projection};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Default for [`bin`]'s `max_span`: larger triangles go to the overflow list.
pub const DEFAULT_MAX_SPAN: u32 = 32;

/// Cell rectangles are grown by this fraction of a cell on every side,
/// far above the `f32` rounding of a light NDC coordinate (~1e-4 cell on a
/// 1024-cell grid), so rounding never drops a triangle from a cell its
/// shadow touches.
pub const CELL_PADDING: f32 = 1.0 / 64.0;

/// Where one triangle went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Not binned: its shadow cannot reach any receiver.
    Culled,
    /// In the overflow list.
    Overflow,
    /// In the cells `[x0, x1] × [y0, y1]` (inclusive).
    Cells { x0: u32, y0: u32, x1: u32, y1: u32 },
}

/// Counters of the bin pass.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BinStats {
    pub triangles: usize,
    pub binned: usize,
    pub overflow: usize,
    pub culled: usize,
    /// Total (cell, triangle) entries written by the scatter.
    pub cell_entries: usize,
    pub max_span: u32,
}

/// The binned grid.
pub struct Bins {
    /// Light-view vertices per triangle id (written once).
    pub vertex_cache: Vec<[Vec3; 3]>,
    pub placement: Vec<Placement>,
    /// Exclusive prefix sum of the per-cell counts; `cells + 1` entries.
    pub cell_start: Vec<u32>,
    /// Triangle ids, cell after cell.
    pub cell_triangles: Vec<u32>,
    pub overflow: Vec<u32>,
    pub stats: BinStats,
}

impl Bins {
    /// Triangle ids binned in cell (x, y).
    #[inline]
    pub fn cell(&self, setup: &LightSetup, x: u32, y: u32) -> &[u32] {
        let c = (y * setup.cells[0] + x) as usize;
        &self.cell_triangles[self.cell_start[c] as usize..self.cell_start[c + 1] as usize]
    }
}

/// Inclusive integer cell range covered by the continuous grid-space box
/// `[lo, hi]`, grown by [`CELL_PADDING`], or `None` if it misses the grid.
pub fn cell_range(setup: &LightSetup, lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    let (w, h) = (setup.cells[0] as f32, setup.cells[1] as f32);
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

fn place(setup: &LightSetup, tri: &[Vec3; 3], max_span: u32) -> Placement {
    if setup.grid_disabled {
        return Placement::Overflow;
    }
    let ndc = match setup.projection {
        Projection::Orthographic => tri.map(|v| Vec2::new(v.x, v.y)),
        Projection::Perspective => {
            let in_front = tri.iter().filter(|v| v.z > 0.0).count();
            match in_front {
                0 => return Placement::Culled, // wholly behind the light
                3 => tri.map(|v| Vec2::new(v.x / v.z, v.y / v.z)),
                _ => return Placement::Overflow, // crosses the light's plane
            }
        }
    };
    let g = ndc.map(|n| setup.grid_coords(n));
    let lo = g[0].min(g[1]).min(g[2]);
    let hi = g[0].max(g[1]).max(g[2]);
    match cell_range(setup, lo, hi) {
        None => Placement::Culled,
        Some([x0, y0, x1, y1]) if x1 - x0 < max_span && y1 - y0 < max_span => {
            Placement::Cells { x0, y0, x1, y1 }
        }
        Some(_) => Placement::Overflow,
    }
}

/// Bins eye-relative `f32` triangles (`triangles[id]`) into the grid.
/// With the `outside_bounds` skip off, triangles that miss the grid go to
/// the overflow list instead of being culled.
pub fn bin(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    max_span: u32,
    skips: super::Skips,
) -> Bins {
    let vertex_cache: Vec<[Vec3; 3]> = triangles
        .par_iter()
        .map(|t| t.map(|v| setup.to_light_view(v)))
        .collect();
    let placement: Vec<Placement> = vertex_cache
        .par_iter()
        .map(|t| match place(setup, t, max_span) {
            Placement::Culled if !skips.outside_bounds => Placement::Overflow,
            p => p,
        })
        .collect();
    let cells = (setup.cells[0] * setup.cells[1]) as usize;
    // Count.
    let mut counts = vec![0u32; cells + 1];
    let mut stats = BinStats {
        triangles: triangles.len(),
        max_span,
        ..Default::default()
    };
    let mut overflow = Vec::new();
    for (id, p) in placement.iter().enumerate() {
        match *p {
            Placement::Culled => stats.culled += 1,
            Placement::Overflow => overflow.push(id as u32),
            Placement::Cells { x0, y0, x1, y1 } => {
                stats.binned += 1;
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        counts[(y * setup.cells[0] + x) as usize] += 1;
                    }
                }
            }
        }
    }
    stats.overflow = overflow.len();
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
    let mut cell_triangles = vec![0u32; sum as usize];
    for (id, p) in placement.iter().enumerate() {
        if let Placement::Cells { x0, y0, x1, y1 } = *p {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let c = (y * setup.cells[0] + x) as usize;
                    cell_triangles[cursor[c] as usize] = id as u32;
                    cursor[c] += 1;
                }
            }
        }
    }
    Bins {
        vertex_cache,
        placement,
        cell_start,
        cell_triangles,
        overflow,
        stats,
    }
}
