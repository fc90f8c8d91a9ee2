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
#[inline]
pub fn cell_range_in(dims: [u32; 2], lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    let (w, h) = (dims[0] as f32, dims[1] as f32);
    let (lo, hi) = (lo - CELL_PADDING, hi + CELL_PADDING);
    // Without a branch before the end, so that the bin's loops over
    // sixteen lanes (`triangle_lanes`, `registration_lanes`) vectorise.
    let miss = (hi.x < 0.0) | (hi.y < 0.0) | (lo.x >= w) | (lo.y >= h);
    let miss = miss | lo.x.is_nan() | hi.x.is_nan();
    let x0 = as_u32(lo.x.max(0.0));
    let y0 = as_u32(lo.y.max(0.0));
    let x1 = as_u32(hi.x.min(w - 1.0));
    let y1 = as_u32(hi.y.min(h - 1.0));
    (!miss).then_some([x0, y0, x1.max(x0), y1.max(y0)])
}

/// `v as u32` for every `f32` (NaN and negatives 0, at least 2³² the
/// largest `u32`), in operations a loop over lanes vectorises: LLVM
/// turns the saturating cast into one scalar conversion per lane
/// (`vcvttss2si`), an unchecked one on clamped values into `vcvttps2udq`.
#[inline(always)]
pub fn as_u32(v: f32) -> u32 {
    // The largest `f32` below 2³².
    const BELOW_2_32: f32 = 4_294_967_040.0;
    // NaN → 0 (`max` ignores it), then within 0..=BELOW_2_32; `clamp`
    // would keep the NaN, which the unchecked cast must not see.
    #[allow(clippy::manual_clamp)]
    let clamped = v.max(0.0).min(BELOW_2_32);
    // SAFETY: `clamped` is finite and in 0..2³², so truncated it fits a
    // `u32`.
    let t: u32 = unsafe { clamped.to_int_unchecked() };
    if v >= 4_294_967_296.0 {
        u32::MAX
    } else {
        t
    }
}

/// [`cell_range_in`] level 0 of `grid`.
#[inline]
pub fn cell_range(grid: &CascadeGrid, lo: Vec2, hi: Vec2) -> Option<[u32; 4]> {
    cell_range_in(grid.cells, lo, hi)
}

/// The cell range at pyramid level `level` of a box given in level-0 grid
/// coordinates.
#[inline]
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
    /// Every vertex coordinate below [`TAME_COORDINATE`] in magnitude:
    /// with a cell's growth below it too, no edge's value or rounding
    /// bound can overflow at a cell of the rectangle (its cells are `u32`).
    tame: bool,
}

/// Vertex coordinates and cell growths (cells) below this keep every
/// value and rounding bound of [`Footprint::touches_grown`] finite (a
/// bound at most about 2⁻¹⁸ · 2⁴² · 2⁴³), so an edge value of at least
/// zero passes without its bound.
const TAME_COORDINATE: f32 = (1u64 << 40) as f32;

/// Where a triangle whose vertices have level-0 grid coordinates `g` is
/// binned in `grid`: `None` when its padded box misses level 0 (it can
/// shadow no receiver of the cascade), else the finest level whose
/// rectangle holds at most `grid.level_cells` cells (the 1×1 top always
/// does). `pad` (level-0 cells along x and y; zero for a point-like
/// light) grows the projection by the penumbra the triangle may cast.
pub fn footprint(grid: &CascadeGrid, g: [Vec2; 3], pad: Vec2) -> Option<Footprint> {
    let (level, rect) = level_and_rect(grid, g, pad)?;
    Some(Footprint::at_level(level, rect, g, pad))
}

/// [`footprint`]'s level and rectangle alone: all the bin's placement
/// pass keeps (the rest is computed again where the entries are).
pub fn level_and_rect(grid: &CascadeGrid, g: [Vec2; 3], pad: Vec2) -> Option<(u32, [u32; 4])> {
    let lo = g[0].min(g[1]).min(g[2]) - pad;
    let hi = g[0].max(g[1]).max(g[2]) + pad;
    let top = grid.levels.saturating_sub(1);
    let limit = u64::from(grid.level_cells.max(1));
    // Level 0's range is `cell_range_at(grid, 0, ..)` (its scale is 1):
    // most triangles stop there, and the search goes on above it. (A grid
    // without levels has no cells: its range is `None`.)
    let level_0 = cell_range(grid, lo, hi)?;
    if top == 0 || range_area(level_0) <= limit {
        return Some((0, level_0));
    }
    (1..grid.levels)
        .filter_map(|l| cell_range_at(grid, l, lo, hi).map(|r| (l, r)))
        .find(|&(l, r)| l == top || range_area(r) <= limit)
}

impl Footprint {
    /// The footprint [`footprint`] gives a triangle it places at `level`
    /// in `rect`, from the same `g` and `pad`, without searching the
    /// levels again (the bin's second look at a placed triangle).
    pub fn at_level(level: u32, rect: [u32; 4], g: [Vec2; 3], pad: Vec2) -> Footprint {
        let v = g.map(|p| p * level_scale(level));
        let (d1, d2) = (v[1] - v[0], v[2] - v[0]);
        let winding = d1.x * d2.y - d1.y * d2.x;
        let scale = (d1.x.abs() + d1.y.abs()) * (d2.x.abs() + d2.y.abs());
        let orientation = if winding.abs() > SLIVER_RATIO * scale {
            winding.signum()
        } else {
            0.0
        };
        let tame = v.iter().all(|p| p.abs().max_element() < TAME_COORDINATE);
        Footprint {
            level,
            rect,
            v,
            orientation,
            pad: pad * level_scale(level),
            tame,
        }
    }

    /// The vertices in this level's grid coordinates and their
    /// orientation (+1 or −1; 0 for a sliver).
    pub fn projection(&self) -> ([Vec2; 3], f32) {
        (self.v, self.orientation)
    }

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
        let [lo_x, lo_y, hi_x, hi_y] = match self.grown_cell(x, y, grow) {
            Ok(cell) => cell,
            Err(verdict) => return verdict,
        };
        let tame = self.tame && grow.max_element() < TAME_COORDINATE;
        (0..3).all(|k| {
            // The rounding bound is never positive, and finite here: a
            // value of at least zero passes without it (most edges of a
            // touched cell, and all but one of an untouched one's).
            if tame && self.edge_inside(k, [lo_x, lo_y, hi_x, hi_y]) >= 0.0 {
                return true;
            }
            self.edge_passes(k, [lo_x, lo_y, hi_x, hi_y])
        })
    }

    /// Whether the grown cell `cell` passes edge `k`: its value at the
    /// selected corner is not below its rounding bound.
    #[inline]
    fn edge_passes(&self, k: usize, cell: [f32; 4]) -> bool {
        let (inside, bound) = self.edge_at_corner(k, cell);
        if !(inside.is_finite() && bound.is_finite()) {
            // Only where a product overflowed (a NaN at another corner
            // needs two infinite products there, which the selected
            // corner's then has too): the corners one by one.
            let (a, b) = (self.v[k], self.v[(k + 1) % 3]);
            return edge_touches_by_corners(self.orientation, a, b, cell);
        }
        inside >= bound
    }

    /// The cells of row `y` of the rectangle that [`Self::touches`] can
    /// accept, as an inclusive range `(a, b)` (empty when `a > b`): every
    /// cell of the row outside it is untouched, bit for bit, so the bin
    /// asks `touches` only inside it. A wide rectangle is mostly empty
    /// where a long thin triangle crosses it diagonally (courtyard at
    /// 1920×1080: 5.2 M of the 5.5 M cells of its 1 382 rectangles over
    /// 1 024 cells).
    ///
    /// Along a row, an edge's value at the grown cell's selected corner
    /// (`touches_grown`) is monotone in x (each rounded step is), and its
    /// rounding bound is lowest at one of the row's two ends (the distance
    /// to the vertex is V-shaped in x, so the same holds rounded). A cell
    /// whose value is below that lowest bound fails the edge, and those
    /// cells are a prefix or a suffix of the row: found by bisection, a
    /// few evaluations per edge. Rows narrower than [`ROW_SPAN_MIN`] cells,
    /// slivers and rows with a value that is not finite keep every cell.
    pub fn row_span(&self, y: i64) -> (i64, i64) {
        let [x0, _, x1, _] = self.rect.map(i64::from);
        if x1 - x0 + 1 < ROW_SPAN_MIN || self.orientation == 0.0 {
            return (x0, x1);
        }
        let grow = self.pad + CELL_PADDING;
        let (mut a, mut b) = (x0, x1);
        for k in 0..3 {
            let edge = |x: i64| self.edge_at_corner(k, grown_corners(x, y, grow));
            let ((first, first_bound), (last, last_bound)) = (edge(x0), edge(x1));
            let lowest_bound = first_bound.min(last_bound);
            if !(first.is_finite() && last.is_finite() && lowest_bound.is_finite()) {
                return (x0, x1);
            }
            let fails = |x: i64| edge(x).0 < lowest_bound;
            if first <= last {
                // Rising along the row: the failing cells come first.
                a = partition_point(a, b, fails);
            } else {
                b = partition_point(a, b, |x| !fails(x)) - 1;
            }
            if a > b {
                break;
            }
        }
        (a, b)
    }

    /// Edge `k`'s value at the corner of the grown cell `[lo_x, lo_y, hi_x,
    /// hi_y]` deepest inside it, and the bound its rounding may reach
    /// there (a cell touches when the value is not below the bound).
    ///
    /// The corner is the one the edge's gradient o·(−dy, dx) points to,
    /// and the distance to the vertex the largest in |·|₁. Each rounded
    /// step (difference, product by a fixed factor, sum) is monotone, so
    /// these are the largest of the four corners' rounded values too: bit
    /// for bit the maxima over the corners
    /// ([`Self::touches_grown_by_corners`]), at a quarter of the work. The
    /// GPU twin (`shaders/bin_placement.glsl`) still evaluates the four
    /// corners, which gives the same verdict.
    #[inline(always)]
    fn edge_at_corner(&self, k: usize, cell: [f32; 4]) -> (f32, f32) {
        let [lo_x, lo_y, hi_x, hi_y] = cell;
        let (a, b) = (self.v[k], self.v[(k + 1) % 3]);
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let reach =
            (lo_x - a.x).abs().max((hi_x - a.x).abs()) + (lo_y - a.y).abs().max((hi_y - a.y).abs());
        (
            self.edge_inside(k, cell),
            -(TOUCH_ROUNDING * (dx.abs() + dy.abs()) * reach),
        )
    }

    /// [`Self::edge_at_corner`]'s value alone.
    #[inline(always)]
    fn edge_inside(&self, k: usize, [lo_x, lo_y, hi_x, hi_y]: [f32; 4]) -> f32 {
        let (a, b) = (self.v[k], self.v[(k + 1) % 3]);
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let qx = if self.orientation * dy <= 0.0 {
            hi_x
        } else {
            lo_x
        };
        let qy = if self.orientation * dx >= 0.0 {
            hi_y
        } else {
            lo_y
        };
        self.orientation * (dx * (qy - a.y) - dy * (qx - a.x))
    }

    /// [`Self::touches_grown`] as it is defined: every corner of the grown
    /// cell against every edge. The reference its corner selection is
    /// tested against.
    #[cfg(test)]
    pub fn touches_grown_by_corners(&self, x: i64, y: i64, grow: Vec2) -> bool {
        let cell = match self.grown_cell(x, y, grow) {
            Ok(cell) => cell,
            Err(verdict) => return verdict,
        };
        (0..3).all(|k| {
            edge_touches_by_corners(self.orientation, self.v[k], self.v[(k + 1) % 3], cell)
        })
    }

    /// Cell (`x`, `y`) grown by `grow`, as `[lo_x, lo_y, hi_x, hi_y]`, for
    /// the edge tests; `Err` with the verdict where they are not needed
    /// (outside the rectangle: untouched; a sliver: touched).
    #[inline]
    fn grown_cell(&self, x: i64, y: i64, grow: Vec2) -> Result<[f32; 4], bool> {
        let [x0, y0, x1, y1] = self.rect.map(i64::from);
        if x < x0 || x > x1 || y < y0 || y > y1 {
            return Err(false);
        }
        if self.orientation == 0.0 {
            return Err(true);
        }
        Ok(grown_corners(x, y, grow))
    }
}

/// [`Footprint::touches_grown`] along one row of the rectangle, for the
/// bin, which asks each cell of a row in turn: each edge's y term at its
/// selected corner, the same for every cell of the row, is computed once,
/// the same floats in the same order, so every verdict is
/// `touches_grown`'s bit for bit. (Its rounding bound, needed only where
/// the value is negative, is computed as `touches_grown` does.)
///
/// Why `touches_grown` is not simply `row_grown(y, grow).touches(x)`:
/// with a second caller, LLVM keeps [`FootprintRow::touches`] out of the
/// bin's loop (or, forced inline, lays the loop out worse), and engine's
/// entries stage at 960×540 takes 6–17 % longer on one thread (session
/// 33, four variants). The repeated early verdicts and edge formula are
/// held equal by `the_selected_corner_decides_like_every_corner`.
pub struct FootprintRow<'a> {
    f: &'a Footprint,
    /// The row is one of the rectangle's.
    in_rect: bool,
    grow: Vec2,
    /// The row's cells grown, along y.
    lo_y: f32,
    hi_y: f32,
    tame: bool,
    edges: [RowEdge; 3],
}

/// One edge's part of [`FootprintRow`]: its value at a cell's selected
/// corner is `orientation · (y_term − dy · (qx − a_x))`.
#[derive(Clone, Copy)]
struct RowEdge {
    /// dx · (qy − a.y), with qy the row's y the edge's gradient points to.
    y_term: f32,
    dy: f32,
    a_x: f32,
    /// The selected corner's x is the cell's high side.
    high_x: bool,
}

impl Footprint {
    /// [`Self::touches`] along row `y`.
    pub fn row(&self, y: i64) -> FootprintRow<'_> {
        self.row_grown(y, self.pad + CELL_PADDING)
    }

    /// [`Self::touches_grown`] along row `y`, cells grown by `grow`.
    pub fn row_grown(&self, y: i64, grow: Vec2) -> FootprintRow<'_> {
        let [_, y0, _, y1] = self.rect.map(i64::from);
        let [_, lo_y, _, hi_y] = grown_corners(0, y, grow);
        let edges = std::array::from_fn(|k| {
            let (a, b) = (self.v[k], self.v[(k + 1) % 3]);
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            // `edge_inside`'s corner.
            let qy = if self.orientation * dx >= 0.0 {
                hi_y
            } else {
                lo_y
            };
            RowEdge {
                y_term: dx * (qy - a.y),
                dy,
                a_x: a.x,
                high_x: self.orientation * dy <= 0.0,
            }
        });
        FootprintRow {
            f: self,
            in_rect: (y0..=y1).contains(&y),
            grow,
            lo_y,
            hi_y,
            tame: self.tame && grow.max_element() < TAME_COORDINATE,
            edges,
        }
    }
}

impl FootprintRow<'_> {
    /// [`Footprint::touches_grown`] of cell `x` of the row.
    #[inline]
    pub fn touches(&self, x: i64) -> bool {
        let f = self.f;
        // `grown_cell`'s verdicts: outside the rectangle, untouched; a
        // sliver, touched.
        let [x0, _, x1, _] = f.rect.map(i64::from);
        if x < x0 || x > x1 || !self.in_rect {
            return false;
        }
        if f.orientation == 0.0 {
            return true;
        }
        let [lo_x, _, hi_x, _] = grown_corners(x, 0, self.grow);
        let cell = [lo_x, self.lo_y, hi_x, self.hi_y];
        self.edges.iter().enumerate().all(|(k, e)| {
            let qx = if e.high_x { hi_x } else { lo_x };
            // `edge_inside`.
            let inside = f.orientation * (e.y_term - e.dy * (qx - e.a_x));
            if self.tame && inside >= 0.0 {
                return true;
            }
            f.edge_passes(k, cell)
        })
    }
}

/// Cell (`x`, `y`) grown by `grow`, as `[lo_x, lo_y, hi_x, hi_y]`.
#[inline(always)]
fn grown_corners(x: i64, y: i64, grow: Vec2) -> [f32; 4] {
    let (lo_x, lo_y) = (x as f32 - grow.x, y as f32 - grow.y);
    let (hi_x, hi_y) = (x as f32 + 1.0 + grow.x, y as f32 + 1.0 + grow.y);
    [lo_x, lo_y, hi_x, hi_y]
}

/// Rows of a rectangle narrower than this many cells are tested cell by
/// cell ([`Footprint::row_span`] would cost about as much as it saves).
pub const ROW_SPAN_MIN: i64 = 16;

/// The first x in `[a, b]` where `pred` is false, `pred` being true on a
/// prefix of the range and false after it (`b + 1` where it is true
/// throughout).
fn partition_point(mut a: i64, mut b: i64, pred: impl Fn(i64) -> bool) -> i64 {
    b += 1;
    while a < b {
        let mid = a + (b - a) / 2;
        if pred(mid) {
            a = mid + 1;
        } else {
            b = mid;
        }
    }
    a
}

/// Whether some corner of the box `[lo_x, lo_y, hi_x, hi_y]` lies inside
/// edge `a → b` (orientation `o`) or outside it within the rounding bound.
fn edge_touches_by_corners(o: f32, a: Vec2, b: Vec2, [lo_x, lo_y, hi_x, hi_y]: [f32; 4]) -> bool {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let corners = [(lo_x, lo_y), (hi_x, lo_y), (hi_x, hi_y), (lo_x, hi_y)];
    let mut inside = f32::NEG_INFINITY;
    let mut reach = 0.0f32;
    for (qx, qy) in corners {
        let (rx, ry) = (qx - a.x, qy - a.y);
        let e = o * (dx * ry - dy * rx);
        inside = inside.max(e);
        reach = reach.max(rx.abs() + ry.abs());
    }
    inside >= -(TOUCH_ROUNDING * (dx.abs() + dy.abs()) * reach)
}

#[cfg(test)]
mod tests;
