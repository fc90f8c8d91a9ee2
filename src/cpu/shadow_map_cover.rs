//! The conservative shadow map's test (Tokuyoshi 2018, [Compute IZB]),
//! which the bin runs on every cell it lists a triangle in under a
//! directional light: each cell keeps the triangle whose shadow covers it
//! whole with the highest floor, and `evaluate` tests that one first.

use super::light_setup::CascadeGrid;
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
