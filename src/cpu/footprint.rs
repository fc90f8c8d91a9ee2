//! A triangle's light-space footprint in a cascade's grid pyramid: which
//! level it is binned at, its cell rectangle there, and which cells of
//! that rectangle its projection really touches.
//!
//! Two things bound the work a pixel does (issue 13, after Wyman et al.
//! 2016 and Kalojanov et al. 2011, who size cells by local density):
//! - **A pyramid instead of an overflow list.** Each triangle goes to the
//!   finest level where its padded bounding rectangle holds at most
//!   [`CascadeGrid::level_cells`] cells; a pixel visits the cells under
//!   its µQuad on every non-empty level. A long wall or slat that used to
//!   overflow (and be tested by every pixel of the frame) is now tested
//!   only by pixels within about one coarse cell of it.
//! - **Exact conservative overlap.** Within its rectangle a triangle is
//!   listed only in cells whose padded box its projection touches
//!   (separating axes: the rectangle settles the box's own axes, the
//!   three edge normals are tested here), so a long diagonal sliver costs
//!   O(length) entries, not O(length²).
//!
//! Both are exact: the grid still offers every triangle whose projection
//! comes within [`CELL_PADDING`] of a cell under the µQuad
//! (`tests/izb_grid.rs` checks it against brute force).

use super::light_setup::{level_scale, CascadeGrid};
use glam::Vec2;

/// Cell boxes are grown by this fraction of a cell on every side,
/// far above the `f32` rounding of a light NDC coordinate (~1e-4 cell on a
/// 1024-cell grid), so rounding never drops a triangle from a cell its
/// shadow touches.
pub const CELL_PADDING: f32 = izb_contract::tolerance::CELL_PADDING;

/// Relative bound on the `f32` rounding of an edge function evaluated at a
/// cell corner (2⁻¹⁸ ≈ 32 ε₃₂, for four roundings of products and
/// differences): a cell is dropped only when it lies outside an edge by
/// more than this times |edge|₁ · |corner − vertex|₁, on top of the padding.
pub const TOUCH_ROUNDING: f32 = izb_contract::tolerance::TOUCH_ROUNDING;

/// A projected triangle whose doubled area is at most this fraction of
/// |e₀|₁·|e₁|₁ (2⁻¹⁶) is treated as a segment whose orientation rounding
/// may flip: it is listed in every cell of its rectangle. (A 1 mm wire ten
/// metres long has ~1e-4, above it.)
pub const SLIVER_RATIO: f32 = izb_contract::tolerance::SLIVER_RATIO;

/// Inclusive integer cell range of a `dims` grid covered by the continuous
/// box `[lo, hi]` (in that grid's cells), grown by [`CELL_PADDING`], or
/// `None` if it misses the grid (always for a grid without cells).
pub fn cell_range_in(dims: [u32; 2], lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    let (w, h) = (dims[0] as f32, dims[1] as f32);
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

/// [`cell_range_in`] level 0 of `grid`.
pub fn cell_range(grid: &CascadeGrid, lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    cell_range_in(grid.cells, lo, hi)
}

/// The cell range at pyramid level `level` of a box given in level-0 grid
/// coordinates.
pub fn cell_range_at(grid: &CascadeGrid, level: u32, lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    let s = level_scale(level);
    cell_range_in(grid.level_dims(level), lo * s, hi * s)
}

/// Cells in an inclusive range.
#[inline]
pub fn range_area(r: [u32; 4]) -> u64 {
    u64::from(r[2] - r[0] + 1) * u64::from(r[3] - r[1] + 1)
}

/// A triangle's projection in one pyramid level's grid coordinates, with
/// the rectangle it is binned in there.
#[derive(Clone, Copy, Debug)]
pub struct Footprint {
    pub level: u32,
    pub rect: [u32; 4],
    /// Vertices in this level's grid coordinates.
    v: [Vec2; 3],
    /// +1 or −1: the side of each edge the triangle lies on; 0 for a
    /// sliver (every cell of the rectangle counts as touched).
    orientation: f32,
    /// The penumbra it may cast (an area light, [`penumbra_pad`]), in
    /// this level's cells along x and y: every cell box is grown by it,
    /// so the triangle is listed where its projection grown by that box
    /// (a superset of the disk of its penumbra) touches.
    pad: Vec2,
}

/// Where a triangle whose vertices have level-0 grid coordinates `g` is
/// binned in `grid`: `None` when its padded box misses level 0 (it can
/// shadow no receiver of the cascade), else the finest level whose
/// rectangle holds at most `grid.level_cells` cells (the 1×1 top always
/// does). `pad` (level-0 cells along x and y; zero for a point-like
/// light) grows the projection by the penumbra the triangle may cast.
pub fn footprint(grid: &CascadeGrid, g: [Vec2; 3], pad: Vec2) -> Option<Footprint> {
    let lo = g[0].min(g[1]).min(g[2]) - pad;
    let hi = g[0].max(g[1]).max(g[2]) + pad;
    cell_range(grid, lo, hi)?;
    let top = grid.levels.saturating_sub(1);
    let limit = u64::from(grid.level_cells.max(1));
    let (level, rect) = (0..grid.levels)
        .filter_map(|l| cell_range_at(grid, l, lo, hi).map(|r| (l, r)))
        .find(|&(l, r)| l == top || range_area(r) <= limit)?;
    let v = g.map(|p| p * level_scale(level));
    let (d1, d2) = (v[1] - v[0], v[2] - v[0]);
    let winding = d1.x * d2.y - d1.y * d2.x;
    let scale = (d1.x.abs() + d1.y.abs()) * (d2.x.abs() + d2.y.abs());
    let orientation = if winding.abs() > SLIVER_RATIO * scale {
        winding.signum()
    } else {
        0.0
    };
    Some(Footprint {
        level,
        rect,
        v,
        orientation,
        pad: pad * level_scale(level),
    })
}

impl Footprint {
    /// Whether the triangle's projection touches the padded box of cell
    /// (`x`, `y`) of its level (false outside its rectangle): no edge has
    /// every corner of the box outside it by more than its rounding.
    /// Conservative, never exact-critical beyond that: a touched cell
    /// that the triangle misses only costs a test.
    #[inline]
    pub fn touches(&self, x: i64, y: i64) -> bool {
        self.touches_grown(x, y, self.pad + CELL_PADDING)
    }

    /// [`Self::touches`] with the cell box grown by `grow` (this level's
    /// cells along x and y) instead of the pad and [`CELL_PADDING`].
    #[inline]
    pub fn touches_grown(&self, x: i64, y: i64, grow: Vec2) -> bool {
        let [x0, y0, x1, y1] = self.rect.map(i64::from);
        if x < x0 || x > x1 || y < y0 || y > y1 {
            return false;
        }
        if self.orientation == 0.0 {
            return true;
        }
        let (lo_x, lo_y) = (x as f32 - grow.x, y as f32 - grow.y);
        let (hi_x, hi_y) = (x as f32 + 1.0 + grow.x, y as f32 + 1.0 + grow.y);
        let corners = [(lo_x, lo_y), (hi_x, lo_y), (hi_x, hi_y), (lo_x, hi_y)];
        (0..3).all(|k| {
            let (a, b) = (self.v[k], self.v[(k + 1) % 3]);
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            let mut inside = f32::NEG_INFINITY;
            let mut reach = 0.0f32;
            for (qx, qy) in corners {
                let (rx, ry) = (qx - a.x, qy - a.y);
                let e = self.orientation * (dx * ry - dy * rx);
                inside = inside.max(e);
                reach = reach.max(rx.abs() + ry.abs());
            }
            inside >= -(TOUCH_ROUNDING * (dx.abs() + dy.abs()) * reach)
        })
    }
}
