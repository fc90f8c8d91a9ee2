//! The conservative shadow map's test (Tokuyoshi 2018, [Compute IZB]),
//! which the bin runs, behind a cheap gate, on the cells it lists a
//! triangle in under a directional light: each cell keeps the triangle
//! whose shadow covers it whole with the highest floor, and `evaluate`
//! tests that one first.

use super::counting_sort::BlockEntry;
use super::footprint::Footprint;
use super::light_setup::{CascadeGrid, LevelCells};
use super::receiver_cull::{plane_height, upward_normal};
use glam::{Vec2, Vec3};

/// The conservative shadow map's test (Tokuyoshi 2018, [Compute IZB], made a
/// candidate filter instead of a verdict): when triangle `tri` (light view,
/// directional light) covers all of cell (`x`, `y`) of level `level` of
/// `grid` — the cell's
/// four corners inside its light-space projection — the lowest height of
/// its plane over the cell; else `None`. A receiver in that cell below
/// this floor is likely to lie wholly in the triangle's shadow. Nothing
/// here has to be exact: `evaluate` only tests the best cover triangle
/// first with the ordinary test and stops when that alone fills the mask.
pub fn cover_floor(grid: &CascadeGrid, tri: &[Vec3; 3], level: u32, x: u32, y: u32) -> Option<f32> {
    cover_floor_below(grid, tri, upward_normal(tri)?, level, x, y)
}

/// [`cover_floor`] with the triangle's [`upward_normal`] `n` computed
/// once for all the cells it is listed in.
pub(super) fn cover_floor_below(
    grid: &CascadeGrid,
    tri: &[Vec3; 3],
    n: Vec3,
    level: u32,
    x: u32,
    y: u32,
) -> Option<f32> {
    let up = (1u32 << level) as f32;
    let corners = [
        Vec2::new(x as f32, y as f32),
        Vec2::new(x as f32 + 1.0, y as f32),
        Vec2::new(x as f32 + 1.0, y as f32 + 1.0),
        Vec2::new(x as f32, y as f32 + 1.0),
    ]
    .map(|g| grid.ndc_of_grid(g * up));
    let v = tri.map(|p| p.truncate());
    // Inside: on the same side of every edge as the third vertex.
    let winding = (v[1] - v[0]).perp_dot(v[2] - v[0]);
    let inside =
        |q: Vec2| (0..3).all(|k| winding * (v[(k + 1) % 3] - v[k]).perp_dot(q - v[k]) > 0.0);
    if !corners.iter().all(|&q| inside(q)) {
        return None;
    }
    let a = tri[0];
    Some(
        corners
            .iter()
            .map(|&q| plane_height(n, a, q))
            .fold(f32::INFINITY, f32::min),
    )
}

/// Sets the cover floor ([`cover_floor_below`]) of each of one triangle's
/// `entries`, its listed cells of level `cells` of `grid` (footprint `f`,
/// light view `tri`), where it covers the cell whole; the others stay at
/// −∞. Out of the bin's loop over the cells: most triangles stop at the
/// gate's first test, and the loop without the cover's state runs as it
/// does with covers off (engine 960×540, where covers are off: bin
/// 15.5 → 17.5 ms with the gate inside the loop).
pub(super) fn set_cover_floors(
    grid: &CascadeGrid,
    f: &Footprint,
    tri: &[Vec3; 3],
    cells: LevelCells,
    entries: &mut [BlockEntry],
) {
    let Some(n) = upward_normal(tri) else {
        return;
    };
    let gate = CoverGate::new(f);
    if gate.verdict == GateVerdict::NoCell {
        return;
    }
    let w = cells.dims[0] as usize;
    // The row's gate is set up again for every entry on purpose: kept
    // across a row's entries (an `Option` carried through the loop) it
    // cost ficus's 1080p bin 33–34 → 35–36.5 ms on one thread (session 37).
    for (c, _, floor) in entries {
        let i = *c as usize - cells.start;
        let (x, y) = ((i % w) as u32, (i / w) as u32);
        if gate.row(y).may_cover(x) {
            if let Some(h) = cover_floor_below(grid, tri, n, f.level, x, y) {
                *floor = h;
            }
        }
    }
}

/// A necessary condition for [`cover_floor_below`], cheap enough to ask of
/// every cell a triangle is listed in: the cell shrunk by
/// [`GATE_SHRINK`] on every side lies inside the triangle's footprint
/// (grid coordinates, the footprint's own arithmetic). Where the triangle
/// covers a cell whole, the shrunk cell is inside every edge by
/// `GATE_SHRINK` · |edge|₁, far above the rounding that separates the
/// footprint's grid coordinates from the cover test's NDC ones; so the
/// gate never turns away a cell the cover test would take, and the covers
/// are the same with it as without (`the_gate_keeps_every_covered_cell`
/// holds the gate against the test cell by cell). Most listed cells fail
/// it (ficus at 1080p: 6.7 k of 662 k pass, 6.4 k of them covered).
#[derive(Clone, Copy)]
pub(super) struct CoverGate {
    v: [Vec2; 3],
    orientation: f32,
    verdict: GateVerdict,
}

/// Whether [`CoverGate`] decides cell by cell.
#[derive(Clone, Copy, PartialEq)]
enum GateVerdict {
    /// A triangle too thin to hold a shrunk cell.
    NoCell,
    /// A sliver, or coordinates too large for the margin to hold: every
    /// cell goes on to the cover test.
    EveryCell,
    ByEdges,
}

/// How far the gate shrinks a cell on every side (cells): 8× the rounding
/// of an edge value at coordinates below [`GATE_COORDINATE`].
const GATE_SHRINK: f32 = 1.0 / 16.0;

/// Grid coordinates (vertices and cells, at the footprint's level) below
/// which the gate's margin holds: an edge value there rounds by at most
/// about 4 · 2⁻²⁴ · 2¹⁵ · |edge|₁ = 2⁻⁷ · |edge|₁.
const GATE_COORDINATE: f32 = 16_384.0;

impl CoverGate {
    /// The gate of footprint `f`'s cells. A triangle too thin to hold any
    /// shrunk cell passes none: a triangle that holds a square holds the
    /// square's inscribed disc, so its inradius 2A / P is at least half
    /// the square's side (with P ≥ P₁ / √2, P₁ the perimeter in
    /// |dx| + |dy|, no square root is needed).
    pub(super) fn new(f: &Footprint) -> CoverGate {
        let (v, orientation) = f.projection();
        let [_, _, x1, y1] = f.rect;
        let tame = v.iter().all(|p| p.abs().max_element() < GATE_COORDINATE)
            && (x1.max(y1) as f32) < GATE_COORDINATE;
        let verdict = if orientation == 0.0 || !tame {
            GateVerdict::EveryCell
        } else {
            let twice_area = (v[1] - v[0]).perp_dot(v[2] - v[0]).abs();
            let perimeter_l1: f32 = (0..3)
                .map(|k| (v[(k + 1) % 3] - v[k]).abs().element_sum())
                .sum();
            let half_side = 0.5 - GATE_SHRINK;
            if twice_area * std::f32::consts::SQRT_2 < half_side * perimeter_l1 {
                GateVerdict::NoCell
            } else {
                GateVerdict::ByEdges
            }
        };
        CoverGate {
            v,
            orientation,
            verdict,
        }
    }

    /// The gate along row `y` of the footprint's level.
    #[inline]
    pub(super) fn row(&self, y: u32) -> CoverGateRow {
        let (lo_y, hi_y) = (y as f32 + GATE_SHRINK, y as f32 + 1.0 - GATE_SHRINK);
        let o = self.orientation;
        let edges = std::array::from_fn(|k| {
            let (a, b) = (self.v[k], self.v[(k + 1) % 3]);
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            // The shrunk cell's corner least inside the edge: its value
            // o · (dx · (qy − a.y) − dy · (qx − a.x)) is lowest there.
            let qy = if o * dx >= 0.0 { lo_y } else { hi_y };
            GateEdge {
                y_term: dx * (qy - a.y),
                dy,
                a_x: a.x,
                high_x: o * dy >= 0.0,
            }
        });
        CoverGateRow {
            orientation: o,
            verdict: self.verdict,
            edges,
        }
    }
}

/// [`CoverGate`] along one row.
pub(super) struct CoverGateRow {
    orientation: f32,
    verdict: GateVerdict,
    edges: [GateEdge; 3],
}

/// One edge of [`CoverGateRow`]: its value at a cell's least-inside
/// corner is `orientation · (y_term − dy · (qx − a_x))`.
#[derive(Clone, Copy)]
struct GateEdge {
    y_term: f32,
    dy: f32,
    a_x: f32,
    /// The least-inside corner's x is the shrunk cell's high side.
    high_x: bool,
}

impl CoverGateRow {
    /// Whether cell `x` of the row may be covered whole (false: the cover
    /// test would find it is not).
    #[inline]
    pub(super) fn may_cover(&self, x: u32) -> bool {
        match self.verdict {
            GateVerdict::NoCell => false,
            GateVerdict::EveryCell => true,
            GateVerdict::ByEdges => {
                let (lo_x, hi_x) = (x as f32 + GATE_SHRINK, x as f32 + 1.0 - GATE_SHRINK);
                self.edges.iter().all(|e| {
                    let qx = if e.high_x { hi_x } else { lo_x };
                    self.orientation * (e.y_term - e.dy * (qx - e.a_x)) >= 0.0
                })
            }
        }
    }
}

// On real scenes, whose G-buffer is ray cast (the `cli` feature).
#[cfg(all(test, feature = "cli"))]
mod tests;
