//! Pass 2, `bin`: triangles into the light-space grid by counting sort
//! (seed 000): count per cell, exclusive prefix sum, scatter of triangle
//! ids. The light-view vertex cache is written once here; triangles that
//! span more than `max_span` cells on an axis go to an overflow list that
//! every pixel tests, so one huge ground triangle does not fill thousands
//! of cells.

use super::light_setup::{LightSetup, Projection};
use super::{is_receiver, Skips};
use crate::gbuffer::GBuffer;
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
    /// (cell, triangle) entries the `behind_receivers` skip dropped.
    pub entries_behind_receivers: usize,
    /// Binned triangles dropped from every cell they cover.
    pub triangles_behind_receivers: usize,
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

/// What the `behind_receivers` skip knows of each cell: the lowest
/// light-view z (farthest from the light) of the µQuad centres P of the
/// receivers whose µQuad touches the cell, and how many cells those centres
/// may lie away from it.
pub struct CellReceivers {
    /// +∞ where no receiver touches the cell.
    pub z_min: Vec<f32>,
    pub reach: Vec<u32>,
}

/// [`CellReceivers`] of the receivers of `g` (directional lights only:
/// `None` for a point light or a disabled grid).
pub fn cell_receivers(setup: &LightSetup, g: &GBuffer, skips: Skips) -> Option<CellReceivers> {
    if setup.grid_disabled || setup.projection != Projection::Orthographic {
        return None;
    }
    let cells = (setup.cells[0] * setup.cells[1]) as usize;
    let mut out = CellReceivers {
        z_min: vec![f32::INFINITY; cells],
        reach: vec![0; cells],
    };
    for i in 0..g.flags.len() {
        if !is_receiver(g.flags[i], skips) {
            continue;
        }
        let (lo, hi) = setup.microquad_grid_box(g.position[i], g.axis_x[i], g.axis_y[i]);
        let Some([x0, y0, x1, y1]) = cell_range(setup, lo, hi) else {
            continue;
        };
        let z = setup.to_light_view(g.position[i]).z;
        let reach = receiver_reach(lo, hi);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let c = (y * setup.cells[0] + x) as usize;
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

/// Whether triangle `tri` (light view) is behind every receiver that can
/// test it in cell (`x`, `y`): its plane, over every place a µQuad centre P
/// of those receivers can be (the cell grown by their reach, z ≥ their
/// lowest z), stays farther from the light than P by a margin. Then the
/// per-pixel depth test ([`super::frustum::may_shadow`]: P beyond the
/// plane, away from the light) fails for each of them and the cell need not
/// list the triangle. The plane's height is linear in x, y, so its maximum
/// over the box is at a corner. Directional lights only (+z toward the
/// light); a cell no receiver touches never needs a list.
pub fn behind_receivers(
    setup: &LightSetup,
    receivers: &CellReceivers,
    tri: &[Vec3; 3],
    x: u32,
    y: u32,
) -> bool {
    let c = (y * setup.cells[0] + x) as usize;
    let z_min = receivers.z_min[c];
    if z_min == f32::INFINITY {
        return true;
    }
    let mut n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    if n.z < 0.0 {
        n = -n;
    }
    // Seen edge-on from the light (or NaN): no height function to bound.
    if n.z.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return false;
    }
    let r = receivers.reach[c] as f32 + CELL_PADDING;
    let (g_lo, g_hi) = (
        Vec2::new(x as f32 - r, y as f32 - r),
        Vec2::new(x as f32 + 1.0 + r, y as f32 + 1.0 + r),
    );
    let (lo, hi) = (setup.ndc_of_grid(g_lo), setup.ndc_of_grid(g_hi));
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

/// Bins eye-relative `f32` triangles (`triangles[id]`) into the grid.
/// With the `outside_bounds` skip off, triangles that miss the grid go to
/// the overflow list instead of being culled; with `receivers` (the
/// `behind_receivers` skip) a cell does not list triangles that are behind
/// all of its receivers.
pub fn bin(
    setup: &LightSetup,
    triangles: &[[Vec3; 3]],
    max_span: u32,
    skips: Skips,
    receivers: Option<&CellReceivers>,
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
    let lists = |id: usize, x: u32, y: u32| match receivers {
        Some(r) => !behind_receivers(setup, r, &vertex_cache[id], x, y),
        None => true,
    };
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
                let mut listed = false;
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        if lists(id, x, y) {
                            counts[(y * setup.cells[0] + x) as usize] += 1;
                            listed = true;
                        } else {
                            stats.entries_behind_receivers += 1;
                        }
                    }
                }
                stats.triangles_behind_receivers += !listed as usize;
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
                    if !lists(id, x, y) {
                        continue;
                    }
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
