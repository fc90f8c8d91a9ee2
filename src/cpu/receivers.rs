//! The `behind-receivers` skip (Wyman et al. 2015, §5.4, exact): per cell of every
//! pyramid level, how far the farthest receiver able to test a triangle
//! there lies from the light, and the test that drops a triangle whose
//! plane no such receiver can lie beyond (then the per-pixel depth test
//! fails for all of them). Used by [`super::bin::bin`]; the GPU twin is
//! `STEP_RECEIVERS` and `behind_receivers` in `shaders/bin.comp`.

use super::footprint::{cell_range_at, CELL_PADDING};
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
    let list: Vec<(usize, usize)> = layers
        .iter()
        .enumerate()
        .flat_map(|(l, (g, _))| {
            (0..g.flags.len())
                .into_par_iter()
                .with_min_len(4096)
                .filter(|&i| is_receiver(g.flags[i], skips))
                .map(move |i| (l, i))
                .collect::<Vec<_>>()
        })
        .collect();
    let per_thread = list.len().div_ceil(rayon::current_num_threads()).max(1);
    let receivers = list
        .par_chunks(per_thread)
        .map(|chunk| {
            let mut out = CellReceivers::empty(cells, projection);
            for &(l, i) in chunk {
                let (g, boxes) = layers[l];
                let k = setup.cascade_of(g.position[i]);
                let grid = &setup.cascades[k];
                let wanted = levels[k];
                let (lo, hi) = boxes.grid_box(grid, i);
                let z = receiver_key(projection, setup.to_light_view(g.position[i]));
                for level in (0..grid.levels).filter(|l| wanted & (1 << l) != 0) {
                    let Some([x0, y0, x1, y1]) = cell_range_at(grid, level, lo, hi) else {
                        break;
                    };
                    let s = level_scale(level);
                    let reach = receiver_reach(lo * s, hi * s);
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
    Some(receivers)
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
#[allow(clippy::too_many_arguments)]
pub fn behind_receivers(
    grid: &CascadeGrid,
    receivers: &CellReceivers,
    tri: &[Vec3; 3],
    level: u32,
    c: usize,
    x: u32,
    y: u32,
    light_radius: f32,
) -> bool {
    let z_min = receivers.z_min[c];
    if z_min == f32::INFINITY {
        return true;
    }
    if light_radius > 0.0 && !beyond_every_light_sample(tri, receivers.projection, light_radius) {
        return false;
    }
    let r = receivers.reach[c] as f32 + CELL_PADDING;
    // Level-l grid coordinates to level 0: times 2^l, exact.
    let up = (1u32 << level) as f32;
    let (g_lo, g_hi) = (
        Vec2::new(x as f32 - r, y as f32 - r) * up,
        Vec2::new(x as f32 + 1.0 + r, y as f32 + 1.0 + r) * up,
    );
    let (lo, hi) = (grid.ndc_of_grid(g_lo), grid.ndc_of_grid(g_hi));
    match receivers.projection {
        Projection::Orthographic => plane_below_box(tri, lo, hi, z_min),
        Projection::Perspective => plane_beyond_pyramid(tri, lo, hi, -z_min),
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
fn plane_below_box(tri: &[Vec3; 3], lo: Vec2, hi: Vec2, z_min: f32) -> bool {
    let Some(n) = upward_normal(tri) else {
        return false;
    };
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

/// Point-light [`behind_receivers`]: the four corners at depth `depth` of
/// the pyramid from the light (the origin) through the NDC rectangle
/// `[lo, hi]` lie on the light's side of `tri`'s plane by a margin.
fn plane_beyond_pyramid(tri: &[Vec3; 3], lo: Vec2, hi: Vec2, depth: f32) -> bool {
    let a = tri[0];
    let n = (tri[1] - a).cross(tri[2] - a);
    // The light's side: sign of n · (light − a), the light at the origin.
    let light_side = -n.dot(a);
    if !(light_side != 0.0) {
        return false; // the light in the plane (or NaN): no side to keep
    }
    let side = light_side.signum();
    let corners = [
        Vec3::new(lo.x * depth, lo.y * depth, depth),
        Vec3::new(hi.x * depth, lo.y * depth, depth),
        Vec3::new(hi.x * depth, hi.y * depth, depth),
        Vec3::new(lo.x * depth, hi.y * depth, depth),
    ];
    // Size of the whole configuration (light, corners, triangle).
    let (mut box_lo, mut box_hi) = (Vec3::ZERO, Vec3::ZERO);
    for p in corners.iter().chain(tri) {
        box_lo = box_lo.min(*p);
        box_hi = box_hi.max(*p);
    }
    let margin = BEHIND_MARGIN * (box_hi - box_lo).length() * n.length();
    corners.iter().all(|&q| side * n.dot(q - a) > margin)
}

/// The normal of light-view triangle `tri` turned toward the light (+z),
/// or `None` when the light sees it edge-on (or it is NaN): then it has no
/// height function z(x, y).
pub(super) fn upward_normal(tri: &[Vec3; 3]) -> Option<Vec3> {
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    let n = if n.z < 0.0 { -n } else { n };
    (n.z > 0.0).then_some(n)
}
