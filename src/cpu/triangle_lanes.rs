//! The bin's per-triangle arithmetic, [`LANES`] triangles at a time: each
//! vertex taken to light view, its light NDC and its level-0 grid
//! coordinates in one cascade's grid, and its level-0 cell range. The
//! bin's placement pass and its entries pass both start from these
//! (`placement::placements`, `bin::block_entries`).
//!
//! One triangle at a time this was most of the placement pass, and a
//! sixth of the entries pass: courtyard's 877 k triangles, taken to light
//! view twice per frame, at 960×540 (`paper-notes/performance.md`,
//! session 40).
//!
//! Bit for bit the one-triangle code, as in `light_setup::receiver_lanes`:
//! each lane performs [`LightSetup::to_light_view`] (`glam`'s
//! `Mat3 · Vec3` as `(x_axis·x + y_axis·y) + z_axis·z`), [`LightSetup::ndc`]
//! and [`CascadeGrid::grid_coords`] in their order, without fused
//! multiply-adds. A lane that a point light does not have wholly in front
//! (some vertex at `z ≤ 0`) is computed and flagged; the bin places it
//! one triangle at a time, as before. The kernels are one Rust loop over
//! the lanes, compiled plain, with AVX2 and with AVX-512F ([`SimdPath`]);
//! a unit test below and `tests/simd_paths.rs` hold every path to the
//! one-triangle functions.

use super::footprint::cell_range;
use super::light_setup::{CascadeGrid, LightSetup, Projection};
use super::penumbra::ndc_pad_in_cells;
use super::simd::{Kernel, SimdPath};
use glam::{Mat3, Vec2, Vec3};

/// Triangles per kernel call.
pub const LANES: usize = 16;

/// Per lane, a triangle's light-view vertices and, where it has light NDC,
/// their level-0 grid coordinates; `[vertex][axis][lane]`.
#[derive(Clone, Copy)]
pub struct TriangleLanes {
    view: [[[f32; LANES]; 3]; 3],
    grid: [[[f32; LANES]; 2]; 3],
    /// Every vertex has light NDC: always under a directional light, all
    /// three at `z > 0` under a point light.
    in_front: [bool; LANES],
    /// Where `level_0`, the level-0 cell range `[x0, y0, x1, y1]` of the
    /// triangle's box ([`level_and_rect`](super::footprint::level_and_rect) without a pad).
    rect: [[u32; LANES]; 4],
    /// In front, and placed at level 0 by [`level_and_rect`](super::footprint::level_and_rect) without a
    /// pad: its range meets the grid and holds at most `level_cells`
    /// cells (or level 0 is the only one).
    level_0: [bool; LANES],
}

impl Default for TriangleLanes {
    fn default() -> Self {
        TriangleLanes {
            view: [[[0.0; LANES]; 3]; 3],
            grid: [[[0.0; LANES]; 2]; 3],
            in_front: [false; LANES],
            rect: [[0; LANES]; 4],
            level_0: [false; LANES],
        }
    }
}

impl TriangleLanes {
    /// Lane `l`'s light-view vertices, [`LightSetup::to_light_view`]'s.
    #[inline]
    pub fn light_view(&self, l: usize) -> [Vec3; 3] {
        let v = &self.view;
        [0, 1, 2].map(|i| Vec3::new(v[i][0][l], v[i][1][l], v[i][2][l]))
    }

    /// Lane `l`'s level-0 grid coordinates (each vertex's
    /// [`CascadeGrid::grid_coords`] of its light NDC), or `None` where a
    /// point light does not have the whole triangle in front of it.
    #[inline]
    pub fn grid_coords(&self, l: usize) -> Option<[Vec2; 3]> {
        let g = &self.grid;
        self.in_front[l].then(|| [0, 1, 2].map(|i| Vec2::new(g[i][0][l], g[i][1][l])))
    }

    /// Lane `l`'s level-0 placement without a pad: its cell range there,
    /// or `None` where [`level_and_rect`](super::footprint::level_and_rect) would search coarser levels or
    /// find none, or the lane has no grid coordinates.
    #[inline]
    pub fn level_0_rect(&self, l: usize) -> Option<[u32; 4]> {
        let r = &self.rect;
        self.level_0[l].then(|| [r[0][l], r[1][l], r[2][l], r[3][l]])
    }

    /// Fills the first `tris.len()` lanes (at most [`LANES`]) from the
    /// eye-relative triangles `tris`, with grid coordinates in `grid`; a
    /// full chunk runs on the `simd` path ([`SimdPath::dispatch`]).
    pub fn fill(
        &mut self,
        setup: &LightSetup,
        grid: &CascadeGrid,
        simd: SimdPath,
        tris: &[[Vec3; 3]],
    ) {
        let frame = Frame {
            rotation: &setup.rotation,
            origin: setup.origin,
            grid,
        };
        let lanes = tris.len();
        assert!(lanes <= LANES, "at most {LANES} triangles per call");
        let perspective = setup.projection == Projection::Perspective;
        match (lanes == LANES, perspective) {
            (true, false) => simd.dispatch(FillKernel::<false> { frame, tris }, self),
            (true, true) => simd.dispatch(FillKernel::<true> { frame, tris }, self),
            (false, false) => fill::<false>(frame, tris, self, lanes),
            (false, true) => fill::<true>(frame, tris, self, lanes),
        }
    }
}

/// What the kernels read of the light setup.
#[derive(Clone, Copy)]
struct Frame<'a> {
    rotation: &'a Mat3,
    origin: Vec3,
    grid: &'a CascadeGrid,
}

/// [`fill`]'s arguments over all [`LANES`], as a [`Kernel`].
struct FillKernel<'a, const PERSPECTIVE: bool> {
    frame: Frame<'a>,
    tris: &'a [[Vec3; 3]],
}

impl<const PERSPECTIVE: bool> Kernel for FillKernel<'_, PERSPECTIVE> {
    type Out = TriangleLanes;
    type Output = ();
    #[inline(always)]
    fn run(self, out: &mut TriangleLanes) {
        fill::<PERSPECTIVE>(self.frame, self.tris, out, LANES)
    }
}

/// The first `lanes` lanes of [`TriangleLanes`] (all [`LANES`], a
/// constant, where the loop is to be vectorised). `PERSPECTIVE`: a point
/// light's NDC, `x / z` and `y / z`, taken in every lane and flagged where
/// some `z ≤ 0`.
#[inline(always)]
fn fill<const PERSPECTIVE: bool>(
    Frame {
        rotation,
        origin,
        grid,
    }: Frame<'_>,
    tris: &[[Vec3; 3]],
    out: &mut TriangleLanes,
    lanes: usize,
) {
    let tris = &tris[..lanes];
    let pad = ndc_pad_in_cells(grid, 0.0);
    let single_level = grid.levels <= 1;
    // No level-0 area overflows `u32` on such a grid (every grid today:
    // `GridRequest::cells` caps a side at 4096).
    let small_grid = grid.cells[0] <= 4096 && grid.cells[1] <= 4096;
    let level_cells = grid.level_cells.max(1);
    for (l, tri) in tris.iter().enumerate() {
        let mut in_front = true;
        let mut g = [Vec2::ZERO; 3];
        for (i, &p) in tri.iter().enumerate() {
            let v = *rotation * (p - origin);
            [out.view[i][0][l], out.view[i][1][l], out.view[i][2][l]] = [v.x, v.y, v.z];
            let ndc = if PERSPECTIVE {
                in_front &= v.z > 0.0;
                Vec2::new(v.x / v.z, v.y / v.z)
            } else {
                Vec2::new(v.x, v.y)
            };
            g[i] = grid.grid_coords(ndc);
            [out.grid[i][0][l], out.grid[i][1][l]] = [g[i].x, g[i].y];
        }
        out.in_front[l] = in_front;
        // `level_and_rect`'s first step.
        let lo = g[0].min(g[1]).min(g[2]) - pad;
        let hi = g[0].max(g[1]).max(g[2]) + pad;
        let range = cell_range(grid, lo, hi);
        let [x0, y0, x1, y1] = range.unwrap_or([0, 0, 0, 0]);
        [
            out.rect[0][l],
            out.rect[1][l],
            out.rect[2][l],
            out.rect[3][l],
        ] = [x0, y0, x1, y1];
        let area = (x1 - x0 + 1).wrapping_mul(y1 - y0 + 1);
        let fits = single_level || area <= level_cells;
        out.level_0[l] = in_front && small_grid && range.is_some() && fits;
    }
}

// The scene's G-buffer (ray-cast) comes with the `cli` feature.
#[cfg(all(test, feature = "cli"))]
mod tests {
    use super::*;
    use crate::cpu::test_random::XorShift;
    use crate::cpu::{eye_relative_f32, light_setup, CascadeCount, GridRequest};

    /// Every path, on full and partial chunks, under a directional light
    /// (one and three cascades) and a point light among the triangles
    /// (some wholly or partly behind it), against the one-triangle
    /// functions, bit for bit.
    #[test]
    fn every_path_matches_the_one_triangle_code() {
        let mut checked = [0usize; 2];
        for (point, cascades) in [(false, 1), (false, 3), (true, 1)] {
            let mut scene = crate::scene::load("default")
                .and_then(|s| s.with_resolution([160, 90]))
                .expect("a procedural scene");
            if point {
                let target = scene.camera.target;
                scene.light = crate::scene::Light::Point {
                    position: target + glam::DVec3::new(20.0, 60.0, 10.0),
                };
            }
            let bvh = crate::bvh::SceneBvh::build(&scene);
            let g = crate::gbuffer::gbuffer(&scene, &bvh);
            let request = GridRequest {
                cells: None,
                level_cells: None,
                cascades: CascadeCount::Fixed(cascades),
                split_lambda: 1.0,
                simd: SimdPath::detected(),
            };
            let setup = light_setup(&scene, &g, request);
            assert!(!setup.grid_disabled && setup.cascades[0].cells[0] > 1);
            assert_eq!(setup.projection == Projection::Perspective, point);
            // The scene's triangles, then some around the light's origin.
            let mut rng = XorShift::new(0x07a1_a9e5);
            let origin = setup.origin;
            let mut near =
                || origin + 8.0 * Vec3::new(rng.unit_f32(), rng.unit_f32(), rng.unit_f32()) - 4.0;
            let mut tris = eye_relative_f32(&scene);
            tris.extend((0..LANES * 3 + 7).map(|_| [near(), near(), near()]));
            for grid in &setup.cascades {
                for simd in SimdPath::ALL {
                    let mut lanes = TriangleLanes::default();
                    for chunk in tris.chunks(LANES) {
                        lanes.fill(&setup, grid, simd, chunk);
                        for (l, tri) in chunk.iter().enumerate() {
                            let view = tri.map(|v| setup.to_light_view(v));
                            let bits = |v: [Vec3; 3]| v.map(|p| p.to_array().map(f32::to_bits));
                            assert_eq!(bits(lanes.light_view(l)), bits(view), "{simd:?} lane {l}");
                            let ndc = view.map(|v| setup.ndc(v));
                            let want = ndc
                                .iter()
                                .all(Option::is_some)
                                .then(|| ndc.map(|n| grid.grid_coords(n.unwrap())));
                            let got = lanes.grid_coords(l);
                            let grid_bits = |g: Option<[Vec2; 3]>| {
                                g.map(|g| g.map(|p| p.to_array().map(f32::to_bits)))
                            };
                            assert_eq!(grid_bits(got), grid_bits(want), "{simd:?} lane {l}");
                            checked[usize::from(got.is_some())] += 1;
                        }
                    }
                }
            }
        }
        // Both kinds of lane, every path, five grids.
        assert!(checked[1] >= 5 * 3 * 1000, "{checked:?} triangles checked");
        assert!(
            checked[0] >= 3,
            "{checked:?}: no lane behind the point light"
        );
    }
}
