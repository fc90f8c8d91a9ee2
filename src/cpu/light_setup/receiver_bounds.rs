//! The light setup's two passes over the shadow-tested receivers — the
//! eye-relative bounds and view-depth range, then each cascade's light-NDC
//! bounds of the µQuads' corners — in parallel, and sixteen entries at a
//! time within a block (`receiver_lanes`): minima, maxima and counts do
//! not depend on how the receivers are grouped, so the setup is the one a
//! single pass finds (courtyard at 1080p: 2 M receivers, about 100 ms on
//! one thread before either). Only a zero bound's sign could follow the
//! grouping (`min` of −0 and +0), and every use of a bound compares it or
//! adds to it, where the two zeros act alike. NaN never wins an
//! `f32::min` or `max` in any order; it reaches an NDC bound (`glam`'s
//! `min`, which keeps it) only from a corner without NDC, and that
//! disables the grid, whose bounds then go unused.

use super::receiver_lanes::{corner_boxes, CornerBoxes, LightLanes, ViewLanes, LANES, NOT_TESTED};
use super::LightSetup;
use crate::cascades::MAX_CASCADES;
use crate::cpu::simd::SimdPath;
use crate::gbuffer::{flags, GBuffer};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// Entries per parallel job.
const MIN_JOB: usize = 4096;

/// The receivers' eye-relative bounds and view-depth range.
#[derive(Clone, Copy)]
pub(super) struct ViewBounds {
    pub lo: Vec3,
    pub hi: Vec3,
    pub near: f32,
    pub far: f32,
    pub count: usize,
}

impl ViewBounds {
    const EMPTY: ViewBounds = ViewBounds {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
        near: f32::INFINITY,
        far: f32::NEG_INFINITY,
        count: 0,
    };

    fn merge(self, o: ViewBounds) -> ViewBounds {
        ViewBounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
            near: self.near.min(o.near),
            far: self.far.max(o.far),
            count: self.count + o.count,
        }
    }
}

/// Folds `block` over every layer of `g` in parallel, in blocks of
/// [`MIN_JOB`] entries, each block into its own accumulator (the lanes'
/// accumulators are too large to pass by value per chunk), merged with
/// `merge`.
fn fold_blocks<B: Copy + Send + Sync>(
    g: &GBuffer,
    empty: B,
    block: impl Fn(&GBuffer, Range<usize>) -> B + Sync,
    merge: impl Fn(B, B) -> B + Sync,
) -> B {
    // The pixels' centre surfaces and the edge pixels' extra surfaces,
    // whose µQuads the grids must hold too.
    g.layers()
        .map(|g| {
            let n = g.flags.len();
            (0..n.div_ceil(MIN_JOB))
                .into_par_iter()
                .map(|b| block(g, b * MIN_JOB..((b + 1) * MIN_JOB).min(n)))
                .reduce(|| empty, &merge)
        })
        .fold(empty, &merge)
}

/// The chunks of at most [`LANES`] entries of `range` in layer `g` that
/// hold a shadow-tested receiver (sky and back-facing pixels come in
/// runs: `engine` at 1080p has 315 k receivers among 2 M pixels).
fn chunks<'a>(g: &'a GBuffer, range: Range<usize>) -> impl Iterator<Item = Range<usize>> + 'a {
    let end = range.end;
    range
        .step_by(LANES)
        .map(move |start| start..(start + LANES).min(end))
        .filter(|c| {
            g.flags[c.clone()]
                .iter()
                .any(|f| f & flags::SHADOW_TESTED != 0)
        })
}

/// [`ViewBounds`] of the shadow-tested receivers of `g`.
pub(super) fn view_bounds(g: &GBuffer, view_forward: Vec3, simd: SimdPath) -> ViewBounds {
    let block = |g: &GBuffer, range: Range<usize>| {
        let mut lanes = ViewLanes::EMPTY;
        for c in chunks(g, range) {
            lanes.add(simd, &g.position[c.clone()], &g.flags[c], view_forward);
        }
        let mut b = ViewBounds::EMPTY;
        for l in 0..LANES {
            let lo = Vec3::new(lanes.lo[0][l], lanes.lo[1][l], lanes.lo[2][l]);
            let hi = Vec3::new(lanes.hi[0][l], lanes.hi[1][l], lanes.hi[2][l]);
            b = b.merge(ViewBounds {
                lo,
                hi,
                near: lanes.near[l],
                far: lanes.far[l],
                count: lanes.count[l] as usize,
            });
        }
        b
    };
    fold_blocks(g, ViewBounds::EMPTY, block, ViewBounds::merge)
}

/// Per cascade, the light-NDC bounds of its receivers' µQuad corners and
/// their count; the corners' light-view depth range; whether a corner had
/// no light NDC (at or behind a point light: no grid).
#[derive(Clone, Copy)]
pub(super) struct LightBounds {
    pub nmin: [Vec2; MAX_CASCADES],
    pub nmax: [Vec2; MAX_CASCADES],
    pub receivers: [usize; MAX_CASCADES],
    pub zmin: f32,
    pub zmax: f32,
    pub no_ndc: bool,
}

impl LightBounds {
    const EMPTY: LightBounds = LightBounds {
        nmin: [Vec2::splat(f32::INFINITY); MAX_CASCADES],
        nmax: [Vec2::splat(f32::NEG_INFINITY); MAX_CASCADES],
        receivers: [0; MAX_CASCADES],
        zmin: f32::INFINITY,
        zmax: f32::NEG_INFINITY,
        no_ndc: false,
    };

    fn merge(mut self, o: LightBounds) -> LightBounds {
        for k in 0..MAX_CASCADES {
            self.nmin[k] = self.nmin[k].min(o.nmin[k]);
            self.nmax[k] = self.nmax[k].max(o.nmax[k]);
            self.receivers[k] += o.receivers[k];
        }
        self.zmin = self.zmin.min(o.zmin);
        self.zmax = self.zmax.max(o.zmax);
        self.no_ndc |= o.no_ndc;
        self
    }
}

/// [`LightBounds`] of the shadow-tested receivers of `g` in `setup`'s
/// light view, `cascade_of` their P's cascade (of `cascades`).
pub(super) fn light_bounds(
    g: &GBuffer,
    setup: &LightSetup,
    simd: SimdPath,
    (cascades, cascade_of): (usize, impl Fn(Vec3) -> usize + Sync),
) -> LightBounds {
    let block = |g: &GBuffer, range: Range<usize>| {
        let mut lanes = LightLanes::EMPTY;
        let mut boxes = CornerBoxes::default();
        let mut cascade = [NOT_TESTED; LANES];
        for c in chunks(g, range) {
            let quads = (
                &g.position[c.clone()],
                &g.axis_x[c.clone()],
                &g.axis_y[c.clone()],
            );
            corner_boxes(setup, simd, quads, &mut boxes);
            cascade.fill(NOT_TESTED);
            for (l, i) in c.enumerate() {
                if g.flags[i] & flags::SHADOW_TESTED != 0 {
                    cascade[l] = if cascades == 1 {
                        0
                    } else {
                        cascade_of(g.position[i]) as u32
                    };
                }
            }
            lanes.add(simd, &boxes, &cascade, cascades);
        }
        let mut b = LightBounds::EMPTY;
        for l in 0..LANES {
            for k in 0..MAX_CASCADES {
                let nmin = Vec2::new(lanes.nmin[k][0][l], lanes.nmin[k][1][l]);
                let nmax = Vec2::new(lanes.nmax[k][0][l], lanes.nmax[k][1][l]);
                b.nmin[k] = b.nmin[k].min(nmin);
                b.nmax[k] = b.nmax[k].max(nmax);
                b.receivers[k] += lanes.receivers[k][l] as usize;
            }
            b.zmin = b.zmin.min(lanes.z_lo[l]);
            b.zmax = b.zmax.max(lanes.z_hi[l]);
            b.no_ndc |= lanes.no_ndc[l] != 0;
        }
        b
    };
    fold_blocks(g, LightBounds::EMPTY, block, LightBounds::merge)
}
