//! The `behind-receivers` skip (Wyman et al. 2015, §5.4, exact): per cell of every
//! pyramid level, how far the farthest receiver able to test a triangle
//! there lies from the light, and the test that drops a triangle whose
//! plane no such receiver can lie beyond (then the per-pixel depth test
//! fails for all of them). Used by [`super::bin::bin`]; the GPU twin is
//! `STEP_RECEIVERS` and `behind_receivers` in `shaders/bin.comp`.

use super::footprint::{cell_range_in, CELL_PADDING};
use super::light_setup::{
    level_scale, CascadeGrid, LevelCells, LightSetup, MicroquadBoxes, Projection,
};
use super::{is_receiver, Skips};
use crate::gbuffer::GBuffer;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// What the `behind_receivers` skip knows of each cell (of every cascade,
/// indexed like the cell arrays): how far from the light the farthest µQuad
/// centre P of the receivers whose µQuad touches the cell lies, and how
/// many cells those centres may lie away from it.
pub struct CellReceivers {
    /// The farthest receiver as a lowest value: a directional light's
    /// lowest light-view z, a point light's lowest −z (z: depth along its
    /// axis, [`receiver_key`]); +∞ where no receiver touches the cell.
    pub z_min: Vec<f32>,
    pub reach: Vec<u32>,
    /// Each cell grown by its reach and [`CELL_PADDING`], in light NDC, as
    /// `[lo, hi]`: the box [`TriangleCull::behind`] tests every triangle
    /// touching the cell against ([`cull_box`]), computed once per cell
    /// rather than once per (triangle, cell) pair (engine at 960×540: 472 k
    /// calls for 14 725 cells). Unset (zero) where no receiver touches the cell.
    pub cull_box: Vec<[Vec2; 2]>,
    pub projection: Projection,
}

/// The value a receiver at light-view `p` registers in
/// [`CellReceivers::z_min`]: z for a directional light (+z toward it), −z
/// for a point light (z its depth), so the lowest is the farthest.
#[inline]
pub fn receiver_key(projection: Projection, p: Vec3) -> f32 {
    match projection {
        Projection::Orthographic => p.z,
        Projection::Perspective => -p.z,
    }
}

impl CellReceivers {
    fn empty(cells: usize, projection: Projection) -> CellReceivers {
        CellReceivers {
            z_min: vec![f32::INFINITY; cells],
            reach: vec![0; cells],
            cull_box: Vec::new(),
            projection,
        }
    }

    fn merge(mut self, other: CellReceivers) -> CellReceivers {
        for (c, (z, r)) in other.z_min.into_iter().zip(other.reach).enumerate() {
            self.z_min[c] = self.z_min[c].min(z);
            self.reach[c] = self.reach[c].max(r);
        }
        self
    }
}

/// [`CellReceivers`] of the receivers of `g` (`None` for a disabled
/// grid), their µQuads' boxes taken from `boxes`, on each level of each
/// receiver's own cascade's pyramid that `levels` (per cascade, bit l =
/// level l) names; `level_cells` is [`LightSetup::level_tables`]. At level
/// l a receiver's µQuad box and reach are those of level 0 scaled by 2⁻ˡ.
/// Cells of other levels stay empty (the bin never reads them).
pub fn cell_receivers(
    setup: &LightSetup,
    g: &GBuffer,
    boxes: &MicroquadBoxes,
    skips: Skips,
    levels: &[u32],
    level_cells: &[Vec<LevelCells>],
) -> Option<CellReceivers> {
    if setup.grid_disabled {
        return None;
    }
    let projection = setup.projection;
    let cells = setup.total_cells();
    // One partial array per thread, merged once: a split per 64 k pixels
    // would allocate and merge a whole pyramid's arrays each time. Split
    // over the receivers, not the pixels: the sky rows at the top of an
    // image would leave one thread with most of the work (measured at
    // 1080p: deckchair 0.079 → 0.042 s, the threads finishing together).
    // Every receiver of every layer: the pixels' centre surfaces, then the
    // edge pixels' extra surfaces (`GBuffer::layers`).
    let layers: Vec<(&GBuffer, &MicroquadBoxes)> = g.layers().zip(boxes.layers()).collect();
    // Blocks of entries with their receiver counts, then runs of blocks
    // holding equal shares of the receivers, one per thread.
    let blocks: Vec<(usize, std::ops::Range<usize>, usize)> = layers
        .iter()
        .enumerate()
        .flat_map(|(l, (g, _))| {
            let n = g.flags.len();
            (0..n.div_ceil(RECEIVER_BLOCK))
                .into_par_iter()
                .map(move |b| {
                    let range = b * RECEIVER_BLOCK..((b + 1) * RECEIVER_BLOCK).min(n);
                    let count = g.flags[range.clone()]
                        .iter()
                        .filter(|&&f| is_receiver(f, skips))
                        .count();
                    (l, range, count)
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let total: usize = blocks.iter().map(|b| b.2).sum();
    let per_thread = total.div_ceil(rayon::current_num_threads()).max(1);
    let mut shares: Vec<&[(usize, std::ops::Range<usize>, usize)]> = Vec::new();
    let (mut first, mut sum) = (0, 0);
    for (b, block) in blocks.iter().enumerate() {
        sum += block.2;
        if sum >= per_thread || b + 1 == blocks.len() {
            shares.push(&blocks[first..=b]);
            (first, sum) = (b + 1, 0);
        }
    }
    // Per cascade, the levels to register on, finest first, with their
    // scale and sides.
    let wanted_levels: Vec<Vec<(u32, f32, [u32; 2])>> = setup
        .cascades
        .iter()
        .zip(levels)
        .map(|(grid, wanted)| {
            (0..grid.levels)
                .filter(|l| wanted & (1 << l) != 0)
                .map(|l| (l, level_scale(l), grid.level_dims(l)))
                .collect()
        })
        .collect();
    let receivers = shares
        .into_par_iter()
        .map(|share| {
            let mut out = CellReceivers::empty(cells, projection);
            let receivers = share.iter().flat_map(|(l, range, _)| {
                range
                    .clone()
                    .filter(|&i| is_receiver(layers[*l].0.flags[i], skips))
                    .map(|i| (*l, i))
            });
            for (l, i) in receivers {
                let (g, boxes) = layers[l];
                let k = setup.cascade_of(g.position[i]);
                let grid = &setup.cascades[k];
                let (lo, hi) = boxes.grid_box(grid, i);
                let p = setup.to_light_view(g.position[i]);
                let z = receiver_key(projection, p);
                let (reach_lo, reach_hi) = reach_box(setup, grid, p, (lo, hi));
                for &(level, s, dims) in &wanted_levels[k] {
                    let (lo, hi) = (lo * s, hi * s);
                    // `cell_range_at`, its level's scale and sides read
                    // from the table.
                    let Some(range) = cell_range_in(dims, lo, hi) else {
                        break;
                    };
                    let reach = receiver_reach(reach_lo * s, reach_hi * s);
                    let [x0, y0, x1, y1] = range;
                    let cells = level_cells[k][level as usize];
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            let c = cells.index(x, y);
                            out.z_min[c] = out.z_min[c].min(z);
                            out.reach[c] = out.reach[c].max(reach);
                        }
                    }
                }
            }
            out
        })
        .reduce(
            || CellReceivers::empty(cells, projection),
            CellReceivers::merge,
        );
    Some(receivers.with_cull_boxes(setup, &wanted_levels, level_cells))
}

impl CellReceivers {
    /// Fills [`Self::cull_box`] for the cells of `wanted_levels` (per
    /// cascade: level, scale, sides) that a receiver touches.
    fn with_cull_boxes(
        mut self,
        setup: &LightSetup,
        wanted_levels: &[Vec<(u32, f32, [u32; 2])>],
        level_cells: &[Vec<LevelCells>],
    ) -> CellReceivers {
        let mut boxes = vec![[Vec2::ZERO; 2]; self.z_min.len()];
        for (k, grid) in setup.cascades.iter().enumerate() {
            for &(level, _, [w, h]) in &wanted_levels[k] {
                let cells = level_cells[k][level as usize];
                let range = cells.start..cells.start + (w * h) as usize;
                let row_len = w.max(1) as usize;
                boxes[range.clone()]
                    .par_chunks_mut(row_len)
                    .zip(self.z_min[range.clone()].par_chunks(row_len))
                    .zip(self.reach[range].par_chunks(row_len))
                    .enumerate()
                    .for_each(|(y, ((row, z_min), reach))| {
                        for (x, b) in row.iter_mut().enumerate() {
                            if z_min[x] != f32::INFINITY {
                                *b = cull_box(grid, level, (x as u32, y as u32), reach[x]);
                            }
                        }
                    });
            }
        }
        self.cull_box = boxes;
        self
    }
}

/// Cell (`x`, `y`) of level `level` of `grid`, grown by `reach` cells and
/// [`CELL_PADDING`], in light NDC, as `[lo, hi]`: the box whose pyramid
/// (point light) or column (directional) [`TriangleCull::behind`] tests.
#[inline]
pub fn cull_box(grid: &CascadeGrid, level: u32, (x, y): (u32, u32), reach: u32) -> [Vec2; 2] {
    let r = reach as f32 + CELL_PADDING;
    // Level-l grid coordinates to level 0: times 2^l, exact.
    let up = (1u32 << level) as f32;
    let (g_lo, g_hi) = (
        Vec2::new(x as f32 - r, y as f32 - r) * up,
        Vec2::new(x as f32 + 1.0 + r, y as f32 + 1.0 + r) * up,
    );
    [grid.ndc_of_grid(g_lo), grid.ndc_of_grid(g_hi)]
}

/// Entries per block when the receivers are shared out between threads.
const RECEIVER_BLOCK: usize = 4096;

/// The box whose larger side gives a receiver's reach: its µQuad's grid
/// box `[lo, hi]` (`grid`'s level 0) and its µQuad centre P (light view
/// `p`), where the depth test is taken. The two differ where the box spans
/// only the part of the µQuad an edge surface's samples cover
/// ([`LightSetup::receiver_boxes`]): P can then lie cells away from it
/// (ficus at 1920×1080: an edge surface's P 2.5 cells beyond its box
/// grown by the box's reach), and the cull's box must still hold it.
/// `shaders/bin.comp`'s `STEP_RECEIVERS` is the GPU twin.
#[inline]
pub fn reach_box(
    setup: &LightSetup,
    grid: &CascadeGrid,
    p: Vec3,
    (lo, hi): (Vec2, Vec2),
) -> (Vec2, Vec2) {
    match setup.ndc(p) {
        Some(n) => {
            let centre = grid.grid_coords(n);
            (lo.min(centre), hi.max(centre))
        }
        None => (lo, hi),
    }
}

/// How many cells a receiver's µQuad centre may lie from a cell its grid
/// box touches, given its [`reach_box`] `[lo, hi]` (at that cell's level):
/// the larger side, rounded up, plus one for the cell itself and the
/// padding.
#[inline]
pub fn receiver_reach(lo: Vec2, hi: Vec2) -> u32 {
    ((hi - lo).max_element().ceil() as u32).saturating_add(1)
}

/// Relative margin of [`behind_receivers`] (2⁻¹⁰), about 10⁴ times the
/// `f32` rounding of the depth test it must agree with.
pub const BEHIND_MARGIN: f32 = izb_contract::tolerance::BEHIND_MARGIN;

/// Whether triangle `tri` (light view) is behind every receiver that can
/// test it in cell (`x`, `y`) of level `level` of `grid` (index `c` in the
/// cell arrays): no µQuad centre P
/// of those receivers can lie beyond its plane, seen from the light. Then
/// the per-pixel depth test ([`crate::frustum::may_shadow`]: P beyond the
/// plane, away from the light, by more than a tolerance) fails for each of
/// them and the cell need not list the triangle. A cell no receiver
/// touches never needs a list. Where the P can be: over the cell grown by
/// their reach (light NDC), no farther from the light than the farthest.
/// - Directional light (+z toward it): a box with z ≥ the lowest z; the
///   plane's height is linear in x, y, so it is below the box's floor when
///   it is below at the four corners.
/// - Point light (at the origin, z its depth): the pyramid from the light
///   through the grown cell down to the largest depth; the light is on its
///   own side of the plane, so the pyramid is when its four base corners
///   are.
pub fn behind_receivers(
    grid: &CascadeGrid,
    receivers: &CellReceivers,
    tri: &[Vec3; 3],
    level: u32,
    c: usize,
    (x, y): (u32, u32),
    light_radius: f32,
) -> bool {
    TriangleCull::new(tri, receivers.projection, light_radius).behind(
        grid,
        receivers,
        level,
        c,
        (x, y),
    )
}

/// What [`behind_receivers`] computes of the triangle alone, once for
/// every cell of its rectangle (the same values, so the same verdicts).
pub struct TriangleCull<'a> {
    tri: &'a [Vec3; 3],
    projection: Projection,
    /// Under an area light: every light sample on the receivers' side of
    /// the plane ([`beyond_every_light_sample`]); else `true`.
    light_side: bool,
    plane: PlaneParts,
}

/// The plane's parts of [`plane_below_box`] and [`plane_beyond_pyramid`].
enum PlaneParts {
    /// Directional; `None`: seen edge-on.
    Below(Option<UpwardPlane>),
    /// Point light.
    Beyond(PointPlane),
}

/// A directional light's triangle: its upward normal, |n| / n_z, and its
/// xy and z bounds.
#[derive(Clone, Copy)]
struct UpwardPlane {
    n: Vec3,
    slope: f32,
    xy: (Vec2, Vec2),
    z: (f32, f32),
}

/// A point light's triangle: its normal, the light's side (`None`: the
/// light in the plane, or NaN), |n|, and the bounds of the triangle and
/// the light (the origin).
#[derive(Clone, Copy)]
struct PointPlane {
    n: Vec3,
    side: Option<f32>,
    length: f32,
    bounds: (Vec3, Vec3),
}

impl<'a> TriangleCull<'a> {
    /// The triangle's parts of the test, under a light of `light_radius`.
    pub fn new(tri: &'a [Vec3; 3], projection: Projection, light_radius: f32) -> Self {
        let light_side = if light_radius > 0.0 {
            beyond_every_light_sample(tri, projection, light_radius)
        } else {
            true // a point-like light (or NaN, as before: not checked)
        };
        let plane = match projection {
            Projection::Orthographic => PlaneParts::Below(upward_normal(tri).map(|n| {
                let xy = [tri[1], tri[2]]
                    .iter()
                    .fold((tri[0].truncate(), tri[0].truncate()), |(lo, hi), v| {
                        (lo.min(v.truncate()), hi.max(v.truncate()))
                    });
                let z = (
                    tri[0].z.min(tri[1].z).min(tri[2].z),
                    tri[0].z.max(tri[1].z).max(tri[2].z),
                );
                UpwardPlane {
                    n,
                    slope: n.length() / n.z,
                    xy,
                    z,
                }
            })),
            Projection::Perspective => {
                let a = tri[0];
                let n = (tri[1] - a).cross(tri[2] - a);
                // The light's side: sign of n · (light − a), the light at
                // the origin.
                let light_side = -n.dot(a);
                let side = (light_side != 0.0).then(|| light_side.signum());
                let bounds = tri.iter().fold((Vec3::ZERO, Vec3::ZERO), |(lo, hi), p| {
                    (lo.min(*p), hi.max(*p))
                });
                PlaneParts::Beyond(PointPlane {
                    n,
                    side,
                    length: n.length(),
                    bounds,
                })
            }
        };
        TriangleCull {
            tri,
            projection,
            light_side,
            plane,
        }
    }

    /// [`behind_receivers`] in cell (`x`, `y`) of level `level` (index `c`).
    #[inline]
    pub fn behind(
        &self,
        grid: &CascadeGrid,
        receivers: &CellReceivers,
        level: u32,
        c: usize,
        (x, y): (u32, u32),
    ) -> bool {
        let z_min = receivers.z_min[c];
        if z_min == f32::INFINITY {
            return true;
        }
        if !self.light_side {
            return false;
        }
        let [lo, hi] = receivers.cull_box[c];
        debug_assert_eq!([lo, hi], cull_box(grid, level, (x, y), receivers.reach[c]));
        debug_assert_eq!(self.projection, receivers.projection);
        match &self.plane {
            PlaneParts::Below(parts) => plane_below_box(self.tri, parts, lo, hi, z_min),
            PlaneParts::Beyond(parts) => plane_beyond_pyramid(self.tri, parts, lo, hi, -z_min),
        }
    }
}

/// Under an area light the cull also needs every light sample on the
/// receivers' side of the plane, seen along every ray: a receiver above
/// a steep plane can still see part of the light's disk through it.
/// - Directional light of angular radius r (`light_radius` = tan r): a
///   ray toward any sample never descends toward the plane when the
///   plane's upward unit normal has n̂_z ≥ sin r.
/// - Sphere light of radius R at the origin: every sample lies on the
///   light's (and the receivers') side when the plane is farther than R
///   from the centre; a segment between two points of one half-space
///   stays in it.
///
/// With a margin of [`BEHIND_MARGIN`], far above the `f32` rounding.
fn beyond_every_light_sample(tri: &[Vec3; 3], projection: Projection, light_radius: f32) -> bool {
    let grow = 1.0 + BEHIND_MARGIN;
    match projection {
        Projection::Orthographic => upward_normal(tri).is_some_and(|n| {
            let sin_r = light_radius / (1.0 + light_radius * light_radius).sqrt();
            n.z > sin_r * grow * n.length()
        }),
        Projection::Perspective => {
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
            n.dot(tri[0]).abs() > light_radius * grow * n.length()
        }
    }
}

/// Directional [`behind_receivers`]: the plane of `tri` below the box
/// `[lo, hi]` × [`z_min`, ∞) by a margin.
fn plane_below_box(
    tri: &[Vec3; 3],
    parts: &Option<UpwardPlane>,
    lo: Vec2,
    hi: Vec2,
    z_min: f32,
) -> bool {
    let Some(UpwardPlane {
        n,
        slope,
        xy: (xy_lo, xy_hi),
        z: (tri_z_lo, tri_z_hi),
    }) = *parts
    else {
        return false;
    };
    let plane_max = highest_plane_height(n, tri[0], lo, hi);
    if plane_max.partial_cmp(&z_min) != Some(std::cmp::Ordering::Less) {
        // Not below the floor (or NaN): the margin is never negative, so
        // the answer is no without it, the usual one (most triangles rise
        // above their cells' floor).
        return false;
    }
    // Size of the whole configuration, for the margin.
    let (box_lo, box_hi) = (lo.min(xy_lo), hi.max(xy_hi));
    let (z_lo, z_hi) = (z_min.min(tri_z_lo), z_min.max(tri_z_hi));
    // Against a bound of the margin without the square root first
    // ([`length_bound`]; a larger sum, a larger product, a lower
    // difference), the same verdict where the plane clears it.
    if let Some(bound) = length_bound((box_hi - box_lo).extend(0.0)) {
        if plane_max < z_min - BEHIND_MARGIN * (bound + (z_hi - z_lo)) * slope {
            return true;
        }
    }
    let size = (box_hi - box_lo).length() + (z_hi - z_lo);
    let margin = BEHIND_MARGIN * size * slope;
    plane_max < z_min - margin
}

/// The height over `q` of the plane through `a` with upward normal `n`.
#[inline]
pub(super) fn plane_height(n: Vec3, a: Vec3, q: Vec2) -> f32 {
    a.z - (n.x * (q.x - a.x) + n.y * (q.y - a.y)) / n.z
}

/// [`highest_corner_height`] at one corner. With n_z > 0 and every
/// rounded step monotone, the corner against the normal's x and y is the
/// highest of the four rounded heights, bit for bit. A non-finite height
/// there (an overflow, which a NaN at another corner would carry there)
/// asks all four. (`shaders/bin_placement.glsl` takes the four corners'
/// largest, the same value.)
#[inline]
fn highest_plane_height(n: Vec3, a: Vec3, lo: Vec2, hi: Vec2) -> f32 {
    let highest = Vec2::new(
        if n.x >= 0.0 { lo.x } else { hi.x },
        if n.y >= 0.0 { lo.y } else { hi.y },
    );
    match plane_height(n, a, highest) {
        h if h.is_finite() => h,
        _ => highest_corner_height(n, a, lo, hi),
    }
}

/// The highest [`plane_height`] at the four corners of `[lo, hi]`: how
/// [`plane_below_box`] is defined.
fn highest_corner_height(n: Vec3, a: Vec3, lo: Vec2, hi: Vec2) -> f32 {
    let height = |q: Vec2| plane_height(n, a, q);
    height(lo)
        .max(height(Vec2::new(hi.x, lo.y)))
        .max(height(hi))
        .max(height(Vec2::new(lo.x, hi.y)))
}

/// Point-light [`behind_receivers`]: the four corners at depth `depth` of
/// the pyramid from the light (the origin) through the NDC rectangle
/// `[lo, hi]` lie on the light's side of `tri`'s plane by a margin.
fn plane_beyond_pyramid(
    tri: &[Vec3; 3],
    parts: &PointPlane,
    lo: Vec2,
    hi: Vec2,
    depth: f32,
) -> bool {
    let PointPlane {
        n,
        side,
        length,
        bounds: (tri_lo, tri_hi),
    } = *parts;
    let Some(side) = side else {
        return false; // the light in the plane (or NaN): no side to keep
    };
    let a = tri[0];
    let corners = [
        Vec3::new(lo.x * depth, lo.y * depth, depth),
        Vec3::new(hi.x * depth, lo.y * depth, depth),
        Vec3::new(hi.x * depth, hi.y * depth, depth),
        Vec3::new(lo.x * depth, hi.y * depth, depth),
    ];
    let beyond = corners.map(|q| side * n.dot(q - a));
    // The margin is never negative (or it is NaN, which no value exceeds):
    // a corner on the plane or behind it answers no without it, the usual
    // answer where the cull does not drop the triangle.
    if !beyond.iter().all(|&b| b > 0.0) {
        return false;
    }
    // Size of the whole configuration (light, corners, triangle).
    let (mut box_lo, mut box_hi) = (tri_lo, tri_hi);
    for p in &corners {
        box_lo = box_lo.min(*p);
        box_hi = box_hi.max(*p);
    }
    let size = box_hi - box_lo;
    // Most corners clear the margin by far: against a bound of it without
    // the square root first, the same verdict.
    if let Some(bound) = length_bound(size) {
        if beyond.iter().all(|&b| b > BEHIND_MARGIN * bound * length) {
            return true;
        }
    }
    let margin = BEHIND_MARGIN * size.length() * length;
    beyond.iter().all(|&b| b > margin)
}

/// A bound on `size.length()` as `f32` rounds it, never below it, for a
/// box of sides `size` (non-negative), without the square root: |size|₁
/// grown by 2⁻¹⁰ (|·|₂ ≤ |·|₁, and the roundings of the two differ by a
/// few ulps). A margin computed from it by the same products is never
/// below the one computed from the length: each rounded product is
/// monotone. `None` where the squares could overflow (sides near 10¹⁹),
/// or for NaN.
#[inline]
fn length_bound(size: Vec3) -> Option<f32> {
    let l1 = (size.x + size.y + size.z) * (1.0 + 1.0 / 1024.0);
    (l1 < 1.0e18).then_some(l1)
}

/// The normal of light-view triangle `tri` turned toward the light (+z),
/// or `None` when the light sees it edge-on (or it is NaN): then it has no
/// height function z(x, y).
pub(super) fn upward_normal(tri: &[Vec3; 3]) -> Option<Vec3> {
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    let n = if n.z < 0.0 { -n } else { n };
    (n.z > 0.0).then_some(n)
}

#[cfg(test)]
mod tests;
