//! The light setup's per-receiver arithmetic, [`LANES`] consecutive
//! G-buffer entries at a time: the view bounds' minima and maxima, and
//! each µQuad's four corners taken to light view and light NDC (the
//! light bounds and [`LightSetup::microquad_ndc_box`]).
//!
//! One receiver at a time this was the per-pixel floor's largest part
//! outside evaluate: at 1920×1080 on `default` the view bounds took 8 ms,
//! the light bounds 15 and the µQuad boxes 14 of a 160 ms shadow pass
//! (2 threads), several times what reading the G-buffer costs.
//!
//! Bit for bit the one-receiver code, as in `survivor_batch`: each lane
//! performs [`microquad_corners`], [`LightSetup::to_light_view`]
//! (`glam`'s `Mat3 · Vec3` as `(x_axis·x + y_axis·y) + z_axis·z`) and
//! [`LightSetup::ndc`] in their order, without fused multiply-adds, and
//! `glam`'s `min`/`max` (`if a < b { a } else { b }`, what `minps` does)
//! and `f32::min`/`max` where those call them. A lane that is not a
//! receiver is computed and then left out by a select. The kernels are
//! one Rust loop over the lanes, compiled plain, with AVX2 and with
//! AVX-512F ([`SimdPath`]); `tests/simd_paths.rs` compares every path
//! with the one-receiver functions on the scenes' G-buffers.

use super::{microquad_corners, LightSetup, Projection};
use crate::cascades::MAX_CASCADES;
use crate::cpu::simd::{Kernel, SimdPath};
use crate::gbuffer::flags;
use glam::{Mat3, Vec2, Vec3};

/// G-buffer entries per kernel call.
pub const LANES: usize = 16;

/// Per lane, the light-NDC box of a µQuad's corners, as
/// [`LightSetup::microquad_ndc_box`] forms it (NaN where a corner has no
/// NDC, as there), the corners' light-view depth range, and whether a
/// corner had no NDC (at or behind a point light).
#[derive(Clone, Copy, Default)]
pub struct CornerBoxes {
    pub lo: [[f32; LANES]; 2],
    pub hi: [[f32; LANES]; 2],
    pub z_lo: [f32; LANES],
    pub z_hi: [f32; LANES],
    pub no_ndc: [u32; LANES],
}

impl CornerBoxes {
    /// Lane `l`'s box, `(lo, hi)`.
    #[inline]
    pub fn ndc_box(&self, l: usize) -> (Vec2, Vec2) {
        (
            Vec2::new(self.lo[0][l], self.lo[1][l]),
            Vec2::new(self.hi[0][l], self.hi[1][l]),
        )
    }
}

/// [`CornerBoxes`] of the µQuads `(p[l], ex[l], ey[l])`, `l < p.len()`
/// (at most [`LANES`]; a full chunk runs on the `simd` path,
/// [`SimdPath::dispatch`]).
pub(super) fn corner_boxes(
    setup: &LightSetup,
    simd: SimdPath,
    (p, ex, ey): (&[Vec3], &[Vec3], &[Vec3]),
    out: &mut CornerBoxes,
) {
    let frame = (&setup.rotation, setup.origin);
    let lanes = p.len();
    let perspective = setup.projection == Projection::Perspective;
    match (lanes == LANES, perspective) {
        (true, false) => simd.dispatch(
            CornerKernel::<false> {
                frame,
                quads: (p, ex, ey),
            },
            out,
        ),
        (true, true) => simd.dispatch(
            CornerKernel::<true> {
                frame,
                quads: (p, ex, ey),
            },
            out,
        ),
        (false, false) => corners::<false>(frame, (p, ex, ey), out, lanes),
        (false, true) => corners::<true>(frame, (p, ex, ey), out, lanes),
    }
}

/// [`corners`]' arguments over all [`LANES`], as a [`Kernel`].
struct CornerKernel<'a, const PERSPECTIVE: bool> {
    frame: (&'a Mat3, Vec3),
    quads: (&'a [Vec3], &'a [Vec3], &'a [Vec3]),
}

impl<const PERSPECTIVE: bool> Kernel for CornerKernel<'_, PERSPECTIVE> {
    type Out = CornerBoxes;
    type Output = ();
    #[inline(always)]
    fn run(self, out: &mut CornerBoxes) {
        corners::<PERSPECTIVE>(self.frame, self.quads, out, LANES)
    }
}

/// The first `lanes` lanes of [`CornerBoxes`] (all [`LANES`], a
/// constant, where the loop is to be vectorised). `PERSPECTIVE`: a point
/// light's NDC, where a corner needs `z > 0` (the division is taken in
/// every lane and its result dropped where that fails).
#[inline(always)]
fn corners<const PERSPECTIVE: bool>(
    (rotation, origin): (&Mat3, Vec3),
    (p, ex, ey): (&[Vec3], &[Vec3], &[Vec3]),
    out: &mut CornerBoxes,
    lanes: usize,
) {
    let (p, ex, ey) = (&p[..lanes], &ex[..lanes], &ey[..lanes]);
    for l in 0..lanes {
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        let (mut z_lo, mut z_hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut no_ndc = 0;
        for corner in microquad_corners(p[l], ex[l], ey[l]) {
            let v = *rotation * (corner - origin);
            z_lo = z_lo.min(v.z);
            z_hi = z_hi.max(v.z);
            let n = if PERSPECTIVE {
                let in_front = v.z > 0.0;
                no_ndc |= !in_front as u32;
                let n = Vec2::new(v.x / v.z, v.y / v.z);
                if in_front {
                    n
                } else {
                    Vec2::NAN
                }
            } else {
                Vec2::new(v.x, v.y)
            };
            lo = lo.min(n);
            hi = hi.max(n);
        }
        [out.lo[0][l], out.lo[1][l]] = [lo.x, lo.y];
        [out.hi[0][l], out.hi[1][l]] = [hi.x, hi.y];
        [out.z_lo[l], out.z_hi[l]] = [z_lo, z_hi];
        out.no_ndc[l] = no_ndc;
    }
}

/// Per lane, the running bounds of the receivers that lane has seen: the
/// view bounds' (`receiver_bounds::ViewBounds`), kept lane by lane over
/// a block of chunks and then folded.
#[derive(Clone, Copy)]
pub struct ViewLanes {
    pub lo: [[f32; LANES]; 3],
    pub hi: [[f32; LANES]; 3],
    pub near: [f32; LANES],
    pub far: [f32; LANES],
    pub count: [u32; LANES],
}

impl ViewLanes {
    pub const EMPTY: ViewLanes = ViewLanes {
        lo: [[f32::INFINITY; LANES]; 3],
        hi: [[f32::NEG_INFINITY; LANES]; 3],
        near: [f32::INFINITY; LANES],
        far: [f32::NEG_INFINITY; LANES],
        count: [0; LANES],
    };

    /// Adds the shadow-tested entries among `p` (flags `f`, at most
    /// [`LANES`]) to the lanes, `view_forward` the camera's direction.
    pub(super) fn add(&mut self, simd: SimdPath, p: &[Vec3], f: &[u32], view_forward: Vec3) {
        match p.len() == LANES {
            true => {
                let kernel = ViewKernel {
                    p,
                    f,
                    forward: view_forward,
                };
                simd.dispatch(kernel, self)
            }
            false => view(self, p, f, view_forward, p.len()),
        }
    }
}

/// [`view`]'s arguments over all [`LANES`], as a [`Kernel`].
struct ViewKernel<'a> {
    p: &'a [Vec3],
    f: &'a [u32],
    forward: Vec3,
}

impl Kernel for ViewKernel<'_> {
    type Out = ViewLanes;
    type Output = ();
    #[inline(always)]
    fn run(self, acc: &mut ViewLanes) {
        view(acc, self.p, self.f, self.forward, LANES)
    }
}

/// [`ViewLanes::add`] over the first `lanes` lanes: `ViewBounds::add`'s
/// operations where the entry is shadow-tested.
#[inline(always)]
fn view(acc: &mut ViewLanes, p: &[Vec3], f: &[u32], forward: Vec3, lanes: usize) {
    let (p, f) = (&p[..lanes], &f[..lanes]);
    for l in 0..lanes {
        let live = f[l] & flags::SHADOW_TESTED != 0;
        let q = p[l];
        let lo = Vec3::new(acc.lo[0][l], acc.lo[1][l], acc.lo[2][l]).min(q);
        let hi = Vec3::new(acc.hi[0][l], acc.hi[1][l], acc.hi[2][l]).max(q);
        let d = q.dot(forward);
        let (near, far) = (acc.near[l].min(d), acc.far[l].max(d));
        for a in 0..3 {
            acc.lo[a][l] = if live { lo[a] } else { acc.lo[a][l] };
            acc.hi[a][l] = if live { hi[a] } else { acc.hi[a][l] };
        }
        acc.near[l] = if live { near } else { acc.near[l] };
        acc.far[l] = if live { far } else { acc.far[l] };
        acc.count[l] += live as u32;
    }
}

/// A lane's cascade where it holds no shadow-tested receiver.
pub const NOT_TESTED: u32 = u32::MAX;

/// Per lane, the running light bounds (`receiver_bounds::LightBounds`) of
/// the receivers that lane has seen, per cascade.
#[derive(Clone, Copy)]
pub struct LightLanes {
    pub nmin: [[[f32; LANES]; 2]; MAX_CASCADES],
    pub nmax: [[[f32; LANES]; 2]; MAX_CASCADES],
    pub receivers: [[u32; LANES]; MAX_CASCADES],
    pub z_lo: [f32; LANES],
    pub z_hi: [f32; LANES],
    pub no_ndc: [u32; LANES],
}

impl LightLanes {
    pub const EMPTY: LightLanes = LightLanes {
        nmin: [[[f32::INFINITY; LANES]; 2]; MAX_CASCADES],
        nmax: [[[f32::NEG_INFINITY; LANES]; 2]; MAX_CASCADES],
        receivers: [[0; LANES]; MAX_CASCADES],
        z_lo: [f32::INFINITY; LANES],
        z_hi: [f32::NEG_INFINITY; LANES],
        no_ndc: [0; LANES],
    };

    /// Adds the lanes of `boxes` whose `cascade` is not [`NOT_TESTED`]
    /// (below `cascades`) to their cascade's bounds.
    pub(super) fn add(
        &mut self,
        simd: SimdPath,
        boxes: &CornerBoxes,
        cascade: &[u32; LANES],
        cascades: usize,
    ) {
        let kernel = LightKernel {
            boxes,
            cascade,
            cascades,
        };
        simd.dispatch(kernel, self)
    }
}

/// [`light`]'s arguments, as a [`Kernel`].
struct LightKernel<'a> {
    boxes: &'a CornerBoxes,
    cascade: &'a [u32; LANES],
    cascades: usize,
}

impl Kernel for LightKernel<'_> {
    type Out = LightLanes;
    type Output = ();
    #[inline(always)]
    fn run(self, acc: &mut LightLanes) {
        light(acc, self.boxes, self.cascade, self.cascades)
    }
}

/// [`LightLanes::add`]: `light_bounds`' operations per receiver, its
/// corners' depth range (`f32::min`, `max`) and NDC box (`glam`'s `min`,
/// `max`) folded into its cascade's lane. A box a corner without NDC made
/// NaN is folded too: the grid is then disabled and the bounds unused.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // a lane indexes eight arrays
fn light(acc: &mut LightLanes, b: &CornerBoxes, cascade: &[u32; LANES], cascades: usize) {
    for l in 0..LANES {
        let live = cascade[l] != NOT_TESTED;
        let (z_lo, z_hi) = (acc.z_lo[l].min(b.z_lo[l]), acc.z_hi[l].max(b.z_hi[l]));
        acc.z_lo[l] = if live { z_lo } else { acc.z_lo[l] };
        acc.z_hi[l] = if live { z_hi } else { acc.z_hi[l] };
        acc.no_ndc[l] |= if live { b.no_ndc[l] } else { 0 };
    }
    for k in 0..cascades.min(MAX_CASCADES) {
        for l in 0..LANES {
            let take = cascade[l] == k as u32;
            for a in 0..2 {
                let (lo, hi) = (acc.nmin[k][a][l], acc.nmax[k][a][l]);
                let (box_lo, box_hi) = (b.lo[a][l], b.hi[a][l]);
                // `glam`'s `Vec2::min`, `max`.
                let lo = if lo < box_lo { lo } else { box_lo };
                let hi = if hi > box_hi { hi } else { box_hi };
                acc.nmin[k][a][l] = if take { lo } else { acc.nmin[k][a][l] };
                acc.nmax[k][a][l] = if take { hi } else { acc.nmax[k][a][l] };
            }
            acc.receivers[k][l] += take as u32;
        }
    }
}
