//! Where the bin puts a triangle in one cascade's grid pyramid
//! ([`Placement`]): culled, in the overflow list, or at the finest level
//! where its rectangle holds at most `level_cells` cells, with its
//! [`Footprint`] there. The bin's first pass places every triangle
//! [`LANES`] at a time ([`TriangleLanes`]); its second computes each
//! placed triangle's footprint again rather than keeping it.

use super::footprint::{level_and_rect, Footprint};
use super::light_setup::{CascadeGrid, LightSetup, Projection};
use super::penumbra::{ndc_pad_in_cells, penumbra_pad};
use super::triangle_lanes::{TriangleLanes, LANES};
use super::Skips;
use glam::{Vec2, Vec3};
use rayon::prelude::*;

/// Where one triangle went in one cascade's grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Placement {
    /// Not binned: its shadow cannot reach any receiver of the cascade.
    Culled,
    /// In the overflow list.
    Overflow,
    /// At pyramid level `level`, in the cells of `[x0, x1] × [y0, y1]`
    /// (inclusive) that its projection touches.
    Cells {
        level: u32,
        x0: u32,
        y0: u32,
        x1: u32,
        y1: u32,
    },
}

impl Placement {
    /// In the cells of `rect` (`[x0, y0, x1, y1]`) at level `level`.
    fn of_cells(level: u32, [x0, y0, x1, y1]: [u32; 4]) -> Placement {
        Placement::Cells {
            level,
            x0,
            y0,
            x1,
            y1,
        }
    }

    /// The level and rectangle (`[x0, y0, x1, y1]`) of a placement in
    /// cells.
    pub fn cells(&self) -> Option<(u32, [u32; 4])> {
        match *self {
            Placement::Cells {
                level,
                x0,
                y0,
                x1,
                y1,
            } => Some((level, [x0, y0, x1, y1])),
            _ => None,
        }
    }
}

/// Light NDC of a light-view triangle's vertices: `Err` with its placement
/// when it has none (wholly behind a point light: culled; crossing its
/// image plane: overflow).
fn triangle_ndc(setup: &LightSetup, tri: &[Vec3; 3]) -> Result<[Vec2; 3], Placement> {
    match setup.projection {
        Projection::Orthographic => Ok(tri.map(|v| Vec2::new(v.x, v.y))),
        Projection::Perspective => match tri.iter().filter(|v| v.z > 0.0).count() {
            // A sphere light's samples reach z = −R behind its image plane:
            // a segment from a receiver to one of them passes there.
            0 if tri.iter().any(|v| v.z > -setup.light_radius) => Err(Placement::Overflow),
            0 => Err(Placement::Culled),
            3 => Ok(tri.map(|v| Vec2::new(v.x / v.z, v.y / v.z))),
            _ => Err(Placement::Overflow),
        },
    }
}

/// Where triangle `tri` (light view) goes in `grid`, and its footprint
/// there when it is binned in cells.
pub fn place(
    setup: &LightSetup,
    grid: &CascadeGrid,
    tri: &[Vec3; 3],
) -> (Placement, Option<Footprint>) {
    let p = placement(setup, grid, tri);
    let f = p
        .cells()
        .map(|(level, rect)| placed_footprint(setup, grid, tri, level, rect));
    (p, f)
}

/// [`place`]'s placement alone, without the footprint's edges (the
/// bin's first pass, which keeps only this).
fn placement(setup: &LightSetup, grid: &CascadeGrid, tri: &[Vec3; 3]) -> Placement {
    if setup.grid_disabled {
        return Placement::Overflow;
    }
    match grid_coords_and_pad(setup, grid, tri) {
        Ok((g, pad)) => match level_and_rect(grid, g, pad) {
            None => Placement::Culled,
            Some((level, rect)) => Placement::of_cells(level, rect),
        },
        Err(p) => p,
    }
}

/// A triangle's level-0 grid coordinates and penumbra pad (cells) in
/// `grid`, or the placement it gets without them.
fn grid_coords_and_pad(
    setup: &LightSetup,
    grid: &CascadeGrid,
    tri: &[Vec3; 3],
) -> Result<([Vec2; 3], Vec2), Placement> {
    let ndc = triangle_ndc(setup, tri)?;
    let pad = penumbra_pad(setup, tri, &ndc).ok_or(Placement::Overflow)?;
    Ok((
        ndc.map(|n| grid.grid_coords(n)),
        ndc_pad_in_cells(grid, pad),
    ))
}

/// The footprint [`place`] found for a triangle it placed at `level` in
/// `rect`, computed again from its vertices without the level search.
fn placed_footprint(
    setup: &LightSetup,
    grid: &CascadeGrid,
    tri: &[Vec3; 3],
    level: u32,
    rect: [u32; 4],
) -> Footprint {
    match grid_coords_and_pad(setup, grid, tri) {
        Ok((g, pad)) => Footprint::at_level(level, rect, g, pad),
        Err(_) => unreachable!("a placed triangle has grid coordinates"),
    }
}

/// Every triangle's placement in `grid`, [`LANES`] triangles at a time
/// ([`TriangleLanes`]); with the `outside_bounds` skip off, a triangle
/// that misses the grid overflows instead of being culled.
pub(super) fn placements(
    setup: &LightSetup,
    grid: &CascadeGrid,
    triangles: &[[Vec3; 3]],
    skips: Skips,
) -> Vec<Placement> {
    let n = triangles.len();
    let mut placed = Vec::with_capacity(n);
    placed.spare_capacity_mut()[..n]
        .par_chunks_mut(LANES)
        .zip(triangles.par_chunks(LANES))
        .with_min_len(64)
        .for_each_init(TriangleLanes::default, |lanes, (out, tris)| {
            lanes.fill(setup, grid, setup.simd, tris);
            for (l, slot) in out.iter_mut().enumerate() {
                slot.write(match lane_placement(setup, grid, lanes, l) {
                    Placement::Culled if !skips.outside_bounds => Placement::Overflow,
                    p => p,
                });
            }
        });
    // SAFETY: the chunks cover the first `n` slots, and each writes every
    // one of its slots.
    unsafe { placed.set_len(n) };
    placed
}

/// [`placement`] of the triangle in lane `l` of `lanes` (filled for
/// `grid`): from the lanes' grid coordinates where it has them and casts no
/// penumbra, else from its light-view vertices, one triangle at a time.
#[inline]
fn lane_placement(
    setup: &LightSetup,
    grid: &CascadeGrid,
    lanes: &TriangleLanes,
    l: usize,
) -> Placement {
    // The lanes' range and grid coordinates hold without a penumbra pad
    // (`penumbra_pad` is 0 without a light radius).
    if setup.grid_disabled || setup.light_radius != 0.0 {
        return placement(setup, grid, &lanes.light_view(l));
    }
    if let Some(rect) = lanes.level_0_rect(l) {
        return Placement::of_cells(0, rect);
    }
    match lanes.grid_coords(l) {
        Some(g) => match level_and_rect(grid, g, ndc_pad_in_cells(grid, 0.0)) {
            None => Placement::Culled,
            Some((level, rect)) => Placement::of_cells(level, rect),
        },
        None => placement(setup, grid, &lanes.light_view(l)),
    }
}

/// The footprint of the triangle in lane `l` of `lanes` (filled for
/// `grid`), placed at `level` in `rect`: [`placed_footprint`]'s, from the
/// lanes' grid coordinates where it has them and casts no penumbra.
#[inline]
pub(super) fn lane_footprint(
    setup: &LightSetup,
    grid: &CascadeGrid,
    (lanes, l): (&TriangleLanes, usize),
    level: u32,
    rect: [u32; 4],
) -> Footprint {
    match lanes.grid_coords(l) {
        // `penumbra_pad` is 0 without a light radius.
        Some(g) if setup.light_radius == 0.0 => {
            Footprint::at_level(level, rect, g, ndc_pad_in_cells(grid, 0.0))
        }
        _ => placed_footprint(setup, grid, &lanes.light_view(l), level, rect),
    }
}
