//! The receivers' registration arithmetic for the `behind_receivers`
//! cull ([`super::receivers::cell_receivers`]), [`LANES`] consecutive
//! G-buffer entries at a time, under one cascade: each receiver's
//! light-view key, its µQuad's grid box and reach box, and on every
//! wanted pyramid level its cell range and reach. What is left per
//! receiver is writing the cells.
//!
//! One receiver at a time this arithmetic was four fifths of the
//! registration: courtyard at 1920×1080 registered its 1.7 M receivers
//! in 48 ms on two threads, 39 of them without writing a cell
//! (`paper-notes/performance.md`, session 40).
//!
//! Bit for bit the one-receiver code, as in `light_setup::receiver_lanes`:
//! each lane performs [`LightSetup::to_light_view`], [`receiver_key`],
//! [`MicroquadBoxes::grid_box`], [`reach_box`](super::receivers::reach_box), and per level the scaled
//! [`cell_range_in`] and [`receiver_reach`], in their order, without fused
//! multiply-adds. The kernels are Rust loops over the lanes, compiled
//! plain, with AVX2 and with AVX-512F ([`SimdPath`]); a unit test below
//! and `tests/simd_paths.rs` hold every path to the one-receiver code.

use super::footprint::cell_range_in;
use super::light_setup::{CascadeGrid, LightSetup, Projection};
use super::receivers::{receiver_key, receiver_reach};
use super::simd::{Kernel, SimdPath};
#[cfg(doc)]
use crate::cpu::light_setup::MicroquadBoxes;
use glam::{Vec2, Vec3};

/// G-buffer entries per kernel call.
pub const LANES: usize = 16;

/// A pyramid has at most this many levels (a level mask is a `u32`).
const MAX_LEVELS: usize = 32;

/// One wanted level of the receivers' cascade: its index, its scale
/// (2⁻ˡ) and its sides in cells.
pub type WantedLevel = (u32, f32, [u32; 2]);

/// Per lane, a receiver's registration: its key, and on each wanted level
/// (in the order given, up to the first its box misses) its cell range
/// `[x0, y0, x1, y1]` and reach.
pub struct RegistrationLanes {
    pub key: [f32; LANES],
    range: [[[u32; LANES]; 4]; MAX_LEVELS],
    reach: [[u32; LANES]; MAX_LEVELS],
    hit: [[bool; LANES]; MAX_LEVELS],
}

impl Default for RegistrationLanes {
    fn default() -> Self {
        RegistrationLanes {
            key: [0.0; LANES],
            range: [[[0; LANES]; 4]; MAX_LEVELS],
            reach: [[0; LANES]; MAX_LEVELS],
            hit: [[false; LANES]; MAX_LEVELS],
        }
    }
}

impl RegistrationLanes {
    /// Lane `l`'s cell range and reach on the `w`-th wanted level, or
    /// `None` where its box misses that level (and so every coarser one
    /// after it: the registration stops there).
    #[inline]
    pub fn level(&self, w: usize, l: usize) -> Option<([u32; 4], u32)> {
        let r = &self.range[w];
        self.hit[w][l].then(|| ([r[0][l], r[1][l], r[2][l], r[3][l]], self.reach[w][l]))
    }

    /// Fills the first `position.len()` lanes (at most [`LANES`]) for the
    /// receivers at eye-relative `position` with µQuad light-NDC boxes
    /// `ndc`, all in `grid`, on `levels` (at most 32); a full chunk runs
    /// on the `simd` path ([`SimdPath::dispatch`]).
    pub fn fill(
        &mut self,
        (setup, grid): (&LightSetup, &CascadeGrid),
        simd: SimdPath,
        (position, ndc): (&[Vec3], &[(Vec2, Vec2)]),
        levels: &[WantedLevel],
    ) {
        let lanes = position.len();
        assert!(lanes <= LANES && ndc.len() == lanes && levels.len() <= MAX_LEVELS);
        let frame = Frame {
            setup,
            grid,
            levels,
        };
        let perspective = setup.projection == Projection::Perspective;
        let quads = (position, ndc);
        match (lanes == LANES, perspective) {
            (true, false) => simd.dispatch(FillKernel::<false> { frame, quads }, self),
            (true, true) => simd.dispatch(FillKernel::<true> { frame, quads }, self),
            (false, false) => fill::<false>(frame, quads, self, lanes),
            (false, true) => fill::<true>(frame, quads, self, lanes),
        }
    }
}

/// What the kernels read of the light setup.
#[derive(Clone, Copy)]
struct Frame<'a> {
    setup: &'a LightSetup,
    grid: &'a CascadeGrid,
    levels: &'a [WantedLevel],
}

type Quads<'a> = (&'a [Vec3], &'a [(Vec2, Vec2)]);

/// [`fill`]'s arguments over all [`LANES`], as a [`Kernel`].
struct FillKernel<'a, const PERSPECTIVE: bool> {
    frame: Frame<'a>,
    quads: Quads<'a>,
}

impl<const PERSPECTIVE: bool> Kernel for FillKernel<'_, PERSPECTIVE> {
    type Out = RegistrationLanes;
    type Output = ();
    #[inline(always)]
    fn run(self, out: &mut RegistrationLanes) {
        fill::<PERSPECTIVE>(self.frame, self.quads, out, LANES)
    }
}

/// The first `lanes` lanes of [`RegistrationLanes`] (all [`LANES`], a
/// constant, where the loops are to be vectorised). `PERSPECTIVE`: a point
/// light's NDC of P, `x / z` and `y / z`, taken in every lane and left out
/// of the reach box where `z ≤ 0`, as [`reach_box`](super::receivers::reach_box) does.
#[inline(always)]
fn fill<const PERSPECTIVE: bool>(
    frame: Frame<'_>,
    (position, ndc): Quads<'_>,
    out: &mut RegistrationLanes,
    lanes: usize,
) {
    let Frame {
        setup,
        grid,
        levels,
    } = frame;
    let (position, ndc) = (&position[..lanes], &ndc[..lanes]);
    let mut boxes = [[Vec2::ZERO; 4]; LANES];
    for l in 0..lanes {
        // `MicroquadBoxes::grid_box`.
        let (lo, hi) = (grid.grid_coords(ndc[l].0), grid.grid_coords(ndc[l].1));
        // `LightSetup::to_light_view`.
        let p = setup.rotation * (position[l] - setup.origin);
        out.key[l] = receiver_key(setup.projection, p);
        // `reach_box`, its NDC of P taken in every lane.
        let (n, has_ndc) = if PERSPECTIVE {
            (Vec2::new(p.x / p.z, p.y / p.z), p.z > 0.0)
        } else {
            (Vec2::new(p.x, p.y), true)
        };
        let centre = grid.grid_coords(n);
        let (reach_lo, reach_hi) = if has_ndc {
            (lo.min(centre), hi.max(centre))
        } else {
            (lo, hi)
        };
        boxes[l] = [lo, hi, reach_lo, reach_hi];
    }
    for (w, &(_, s, dims)) in levels.iter().enumerate() {
        // Every lane, those past `lanes` on zero boxes: a loop of a
        // constant length.
        level_lanes(
            (dims, s),
            &boxes,
            (&mut out.range[w], &mut out.reach[w], &mut out.hit[w]),
        );
    }
}

/// One level's cell ranges, reaches and hits of the lanes' `boxes` (grid
/// box, reach box), the level's sides `dims` and scale `s`.
#[inline(always)]
fn level_lanes(
    (dims, s): ([u32; 2], f32),
    boxes: &[[Vec2; 4]; LANES],
    (range, reach, hit): (
        &mut [[u32; LANES]; 4],
        &mut [u32; LANES],
        &mut [bool; LANES],
    ),
) {
    for l in 0..LANES {
        let [lo, hi, reach_lo, reach_hi] = boxes[l];
        let r = cell_range_in(dims, lo * s, hi * s);
        let [x0, y0, x1, y1] = r.unwrap_or([0; 4]);
        [range[0][l], range[1][l], range[2][l], range[3][l]] = [x0, y0, x1, y1];
        reach[l] = receiver_reach(reach_lo * s, reach_hi * s);
        hit[l] = r.is_some();
    }
}

// The scene's G-buffer (ray-cast) comes with the `cli` feature.
#[cfg(all(test, feature = "cli"))]
mod tests {
    use super::*;
    use crate::cpu::light_setup::level_scale;
    use crate::cpu::{light_setup, CascadeCount, GridRequest, Skips};

    /// [`RegistrationLanes::fill`]'s one-receiver counterpart, as
    /// `cell_receivers` computed it: the key, then the range and reach on each
    /// level up to the first the box misses.
    fn one_receiver(
        (setup, grid): (&LightSetup, &CascadeGrid),
        (position, ndc): (Vec3, (Vec2, Vec2)),
        levels: &[WantedLevel],
    ) -> (f32, Vec<([u32; 4], u32)>) {
        let (lo, hi) = (grid.grid_coords(ndc.0), grid.grid_coords(ndc.1));
        let p = setup.to_light_view(position);
        let (reach_lo, reach_hi) = crate::cpu::receivers::reach_box(setup, grid, p, (lo, hi));
        let mut out = Vec::new();
        for &(_, s, dims) in levels {
            let Some(range) = cell_range_in(dims, lo * s, hi * s) else {
                break;
            };
            out.push((range, receiver_reach(reach_lo * s, reach_hi * s)));
        }
        (receiver_key(setup.projection, p), out)
    }

    /// Every path, on full and partial chunks, under a directional and a
    /// point light, on every level of the pyramid, against the
    /// one-receiver code, bit for bit.
    #[test]
    fn every_path_matches_the_one_receiver_code() {
        let (mut receivers, mut levels_hit) = (0usize, 0usize);
        for point in [false, true] {
            let mut scene = crate::scene::load("default")
                .and_then(|s| s.with_resolution([200, 120]))
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
                cells: Some(300),
                // Small, so that the pyramid keeps its coarse levels.
                level_cells: Some(16),
                cascades: CascadeCount::Fixed(1),
                split_lambda: 1.0,
                simd: SimdPath::detected(),
            };
            let setup = light_setup(&scene, &g, request);
            assert!(!setup.grid_disabled && setup.cascades[0].cells[0] > 1);
            let grid = &setup.cascades[0];
            let boxes = setup.microquad_boxes(&g, Skips::ALL);
            let levels: Vec<WantedLevel> = (0..grid.levels)
                .map(|l| (l, level_scale(l), grid.level_dims(l)))
                .collect();
            assert!(levels.len() >= 5, "{} levels", levels.len());
            for simd in SimdPath::ALL {
                let mut lanes = RegistrationLanes::default();
                let n = g.flags.len();
                for first in (0..n).step_by(LANES) {
                    let c = first..(first + LANES).min(n);
                    let quads = (&g.position[c.clone()], &boxes.ndc[c.clone()]);
                    lanes.fill((&setup, grid), simd, quads, &levels);
                    for (l, i) in c.enumerate() {
                        if g.flags[i] & crate::gbuffer::flags::SHADOW_TESTED == 0 {
                            continue;
                        }
                        let (key, want) =
                            one_receiver((&setup, grid), (g.position[i], boxes.ndc[i]), &levels);
                        assert_eq!(lanes.key[l].to_bits(), key.to_bits(), "{simd:?} {i}");
                        let got: Vec<_> =
                            (0..levels.len()).map_while(|w| lanes.level(w, l)).collect();
                        assert_eq!(got, want, "{simd:?} receiver {i}");
                        receivers += 1;
                        levels_hit += got.len();
                    }
                }
            }
        }
        assert!(receivers >= 2 * 3 * 10_000, "{receivers} receivers checked");
        assert!(
            levels_hit >= 4 * receivers,
            "{levels_hit} levels for {receivers}"
        );
    }
}
