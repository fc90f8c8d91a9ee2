//! The light setup's two passes over the shadow-tested receivers — the
//! eye-relative bounds and view-depth range, then each cascade's light-NDC
//! bounds of the µQuads' corners — in parallel: minima, maxima and counts
//! do not depend on how the receivers are grouped, so the setup is the
//! one a single pass finds (courtyard at 1080p: 2 M receivers, about
//! 100 ms on one thread). Only a zero bound's sign could follow the
//! grouping (`f32::min` of −0 and +0), and every use of a bound compares
//! it or adds to it, where the two zeros act alike; NaN never wins a
//! `min` or `max` in any order.

use super::{microquad_corners, LightSetup};
use crate::cascades::MAX_CASCADES;
use crate::gbuffer::{flags, GBuffer};
use glam::{Vec2, Vec3};
use rayon::prelude::*;

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

    #[inline]
    fn add(&mut self, p: Vec3, view_forward: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
        let d = p.dot(view_forward);
        self.near = self.near.min(d);
        self.far = self.far.max(d);
        self.count += 1;
    }

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

/// Folds `add` over the shadow-tested entries of every layer of `g` in
/// parallel, in blocks of [`MIN_JOB`] entries, each block into its own
/// accumulator (a plain loop on a local value: the accumulators are too
/// large to pass by value per receiver), merged with `merge`.
fn fold_tested<B: Copy + Send + Sync>(
    g: &GBuffer,
    empty: B,
    add: impl Fn(&mut B, &GBuffer, usize) + Sync,
    merge: impl Fn(B, B) -> B + Sync,
) -> B {
    // The pixels' centre surfaces and the edge pixels' extra surfaces,
    // whose µQuads the grids must hold too.
    g.layers()
        .map(|g| {
            let n = g.flags.len();
            (0..n.div_ceil(MIN_JOB))
                .into_par_iter()
                .map(|block| {
                    let mut b = empty;
                    for i in block * MIN_JOB..((block + 1) * MIN_JOB).min(n) {
                        if g.flags[i] & flags::SHADOW_TESTED != 0 {
                            add(&mut b, g, i);
                        }
                    }
                    b
                })
                .reduce(|| empty, &merge)
        })
        .fold(empty, &merge)
}

/// [`ViewBounds`] of the shadow-tested receivers of `g`.
pub(super) fn view_bounds(g: &GBuffer, view_forward: Vec3) -> ViewBounds {
    fold_tested(
        g,
        ViewBounds::EMPTY,
        |b, g, i| b.add(g.position[i], view_forward),
        ViewBounds::merge,
    )
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
/// light view, `cascade_of` their P's cascade.
pub(super) fn light_bounds(
    g: &GBuffer,
    setup: &LightSetup,
    cascade_of: impl Fn(Vec3) -> usize + Sync,
) -> LightBounds {
    let add = |b: &mut LightBounds, g: &GBuffer, i: usize| {
        let p = g.position[i];
        let k = cascade_of(p);
        b.receivers[k] += 1;
        for corner in microquad_corners(p, g.axis_x[i], g.axis_y[i]) {
            let p = setup.to_light_view(corner);
            b.zmin = b.zmin.min(p.z);
            b.zmax = b.zmax.max(p.z);
            match setup.ndc(p) {
                Some(n) => {
                    b.nmin[k] = b.nmin[k].min(n);
                    b.nmax[k] = b.nmax[k].max(n);
                }
                None => b.no_ndc = true,
            }
        }
    };
    fold_tested(g, LightBounds::EMPTY, add, LightBounds::merge)
}
