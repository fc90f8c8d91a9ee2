//! The rest of the depth test and the edge functions, sixteen candidates at
//! a time: a pixel's candidates that pass the tangent-plane condition (a
//! third of courtyard's tests, two thirds of its evaluate time) wait in a
//! batch, and the batch computes for every lane whether P lies beyond the
//! triangle's plane ([`crate::frustum::beyond_triangle_plane`]), the
//! winding and the three side planes' edge functions
//! ([`crate::frustum::edge_function`]) in SIMD registers, and whether the
//! edges provably leave no sample inside ([`super::empty_certificate`]:
//! such a lane's mask is 0 without the LUT). The other masks are then
//! formed lane by lane, in the candidates' order, by the scalar code (the
//! LUT's cell, or the exact sample loop), so a mask fills — and the walk
//! stops — at the same candidate as one test at a time.
//!
//! Bit for bit the scalar test: each lane performs the scalar functions'
//! operations in their order (`glam`'s dot as `(x·x' + y·y') + z·z'`, its
//! cross product, the same `max3`, the power-of-two normalisation; no
//! fused multiply-add, which Rust never contracts), with the scalar code's
//! early returns as selects. The kernel is one Rust loop over the lanes,
//! compiled three times: plain (x86-64's SSE2), with AVX2 and with
//! AVX-512F enabled ([`SimdPath`]); LLVM vectorises each, and every path
//! gives the same floats.

use super::empty_certificate::no_sample_inside_lanes;
use super::mask_rule::MaskRule;
use super::simd::{Kernel, SimdPath};
use crate::frustum::{max3, LightRel, Vector, DEPTH_TOLERANCE_ROUNDING};
use glam::Vec3;

/// Candidates per batch: one AVX-512 register of `f32`, two of AVX2.
pub const LANES: usize = 16;

/// A batch of at most this many runs the kernel over these lanes alone.
pub const HALF: usize = LANES / 2;

/// What the walk had done when a candidate joined the batch: what the
/// counters are if the pixel's mask fills at that candidate.
#[derive(Clone, Copy, Default)]
pub struct WalkPoint {
    pub tests: u64,
    pub tangent_passed: u64,
    /// Cells and levels visited.
    pub walked: (u64, u64),
}

/// Up to [`LANES`] candidates above one pixel's tangent plane.
#[derive(Default)]
pub struct SurvivorBatch {
    pub len: usize,
    /// `t[v][axis][lane]`: vertex `v` minus P.
    t: [[[f32; LANES]; 3]; 3],
    height: [f32; LANES],
    pub point: [WalkPoint; LANES],
}

/// The batch's results, per lane.
#[derive(Default)]
pub struct BatchTests {
    /// P beyond the triangle's plane from the light (the depth test's
    /// second condition).
    pub beyond: [bool; LANES],
    /// [`crate::frustum::winding`].
    pub winding: [f32; LANES],
    /// `edges[k][component][lane]`: edge function `k`'s (α, β, γ),
    /// flipped by the winding.
    pub edges: super::lut_batch::BatchEdges,
    /// 1 where the edges provably leave no sample inside
    /// ([`super::empty_certificate`]), else 0 (a `u32`: LLVM vectorises
    /// the loop only so).
    pub no_sample_inside: [u32; LANES],
    /// With the LUT: the edges' cell coordinates ([`super::lut_batch`]).
    pub lut: super::lut_batch::LutCoordinates,
}

impl BatchTests {
    /// Lane `l`'s edge `k`.
    #[inline(always)]
    pub fn edge(&self, l: usize, k: usize) -> [f32; 3] {
        let e = &self.edges[k];
        [e[0][l], e[1][l], e[2][l]]
    }
}

impl SurvivorBatch {
    /// Adds a candidate (vertices minus P, its height above the tangent
    /// plane); returns whether the batch is now full.
    #[inline]
    pub fn push(&mut self, t: &[Vec3; 3], height: f32, point: WalkPoint) -> bool {
        let l = self.len;
        for (v, tv) in t.iter().enumerate() {
            self.t[v][0][l] = tv.x;
            self.t[v][1][l] = tv.y;
            self.t[v][2][l] = tv.z;
        }
        self.height[l] = height;
        self.point[l] = point;
        self.len += 1;
        self.len == LANES
    }

    /// Lane `l`'s vertices minus P.
    #[inline(always)]
    fn triangle(&self, l: usize) -> [Vec3; 3] {
        let t = &self.t;
        [0, 1, 2].map(|v| Vec3::new(t[v][0][l], t[v][1][l], t[v][2][l]))
    }

    /// The depth test's second condition, the winding, the edge
    /// functions and their certificate (each edge's mask erring by at most
    /// the rule's `certificate_reach`) of the batch's lanes, on the
    /// rule's instruction set, into `out` (lanes past `len` hold stale
    /// values).
    pub(super) fn test(
        &self,
        rule: &MaskRule,
        microquad_part: f32,
        light: LightRel<Vec3>,
        ex: Vec3,
        ey: Vec3,
        out: &mut BatchTests,
    ) {
        let frame = Frame {
            microquad_part,
            ex,
            ey,
            reach: rule.certificate_reach,
        };
        match light {
            LightRel::Toward(w) => self.kernel_on::<false>(rule.simd, &frame, w, out),
            LightRel::At(l) => self.kernel_on::<true>(rule.simd, &frame, l, out),
        }
    }

    /// [`Self::test`] on `simd`'s instruction set, as wide as
    /// [`kernel_width`] says for the batch's length.
    fn kernel_on<const POINT: bool>(
        &self,
        simd: SimdPath,
        frame: &Frame,
        light: Vec3,
        out: &mut BatchTests,
    ) {
        match kernel_width(self.len) {
            KernelWidth::EachAlone => kernel::<POINT>(self, frame, light, out, self.len),
            KernelWidth::Half => {
                let kernel = BatchKernel::<POINT, HALF> {
                    batch: self,
                    frame,
                    light,
                };
                simd.dispatch(kernel, out)
            }
            KernelWidth::Full => {
                let kernel = BatchKernel::<POINT, LANES> {
                    batch: self,
                    frame,
                    light,
                };
                simd.dispatch(kernel, out)
            }
        }
    }
}

/// The pixel's part of the test.
struct Frame {
    microquad_part: f32,
    ex: Vec3,
    ey: Vec3,
    /// How far an edge's mask may err ([`super::empty_certificate`]).
    reach: f32,
}

/// [`kernel`]'s arguments over `N` lanes ([`HALF`] or all [`LANES`]), as
/// a [`Kernel`].
struct BatchKernel<'a, const POINT: bool, const N: usize> {
    batch: &'a SurvivorBatch,
    frame: &'a Frame,
    light: Vec3,
}

impl<const POINT: bool, const N: usize> Kernel for BatchKernel<'_, POINT, N> {
    type Out = BatchTests;
    type Output = ();
    #[inline(always)]
    fn run(self, out: &mut BatchTests) {
        kernel::<POINT>(self.batch, self.frame, self.light, out, N)
    }
}

/// How wide a batch's kernel runs ([`kernel_width`]).
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum KernelWidth {
    /// Lane by lane, over the batch's candidates only: a pixel's last
    /// batch often holds one or two (city at 1080p: 1.2 lanes a batch),
    /// and a vector kernel would test all its lanes.
    EachAlone,
    /// Over [`HALF`] the lanes, the rest being empty (a pixel's last
    /// batch, and most of a scene's where survivors are few: engine at
    /// 1080p has 2.1 a pixel).
    Half,
    /// Over all [`LANES`].
    Full,
}

/// Batches of at most this many candidates are tested lane by lane.
const FEW_LANES: usize = 2;

/// The width of a batch of `len` candidates' kernel: the one place the
/// thresholds between the widths are stated.
fn kernel_width(len: usize) -> KernelWidth {
    match len {
        0..=FEW_LANES => KernelWidth::EachAlone,
        _ if len <= HALF => KernelWidth::Half,
        _ => KernelWidth::Full,
    }
}

/// The lanes a [`SurvivorBatch`] of `len` candidates has its kernel run
/// over: each alone, [`HALF`] or all [`LANES`].
pub fn lanes_issued(len: usize) -> usize {
    match kernel_width(len) {
        KernelWidth::EachAlone => len,
        KernelWidth::Half => HALF,
        KernelWidth::Full => LANES,
    }
}

/// The first `lanes` lanes' tests ([`LANES`] or [`HALF`], a constant,
/// where the loop is to be vectorised); `POINT`: `light` is the point light's
/// position minus P (`LightRel::At`), else the unit vector toward it.
#[inline(always)]
fn kernel<const POINT: bool>(
    b: &SurvivorBatch,
    f: &Frame,
    light: Vec3,
    out: &mut BatchTests,
    lanes: usize,
) {
    let rounding = <Vec3 as Vector>::from_f64(DEPTH_TOLERANCE_ROUNDING);
    // `side_plane_normal`.
    let side = |x: Vec3, y: Vec3| {
        if POINT {
            (x - light).cross(y - x)
        } else {
            (y - x).cross(light)
        }
    };
    for l in 0..lanes {
        let t = b.triangle(l);
        // `above_full_tolerance`.
        let reach = max3(t[0].length(), t[1].length(), t[2].length());
        let tolerance = f.microquad_part + rounding * reach;
        let above = b.height[l] > tolerance;
        // `beyond_triangle_plane`'s plane, oriented toward the light.
        let n = (t[1] - t[0]).cross(t[2] - t[0]).pow2_normalised();
        let facing = if POINT {
            n.dot(light - t[0])
        } else {
            n.dot(light)
        };
        let n = if facing > 0.0 { n } else { -n };
        out.beyond[l] = above & (facing != 0.0) & (n.dot(t[0]) > tolerance * n.length());
        // `winding` and `edge_function`.
        let w = side(t[0], t[1]).dot(t[2] - t[0]);
        out.winding[l] = w;
        for k in 0..3 {
            let (x, y) = (t[k], t[(k + 1) % 3]);
            let n = side(x, y);
            let n = if w < 0.0 { -n } else { n };
            let e = &mut out.edges[k];
            [e[0][l], e[1][l], e[2][l]] = [-(n.dot(x)), n.dot(f.ex), n.dot(f.ey)];
        }
    }
    no_sample_inside_lanes(&out.edges, f.reach, &mut out.no_sample_inside, lanes);
}
