//! The light-space boxes of the receivers' µQuads: per pixel and per edge
//! surface, projected once per frame, for the whole image where the bin's
//! receiver registration needs them (then evaluate reads them too), else
//! band by band in evaluate; with edge surfaces under a point-like light,
//! only the part of a µQuad its samples span.

use super::receiver_lanes::{corner_boxes, CornerBoxes, LANES};
use super::{CascadeGrid, LightSetup};
use crate::cpu::Skips;
use crate::gbuffer::GBuffer;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::ops::Range;

impl LightSetup {
    /// Light-NDC bounding box of the µQuad (centre `p`, axes `ex`, `ey`,
    /// eye-relative): the box of its projected corners, which holds the
    /// projection of every point of the µQuad, its centre included. A
    /// corner not in front of a point light is left out (`f32::min`
    /// ignores NaN); then the grid is disabled and the box unused.
    #[inline]
    pub fn microquad_ndc_box(&self, p: Vec3, ex: Vec3, ey: Vec3) -> (Vec2, Vec2) {
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for c in microquad_corners(p, ex, ey) {
            let n = self.ndc(self.to_light_view(c)).unwrap_or(Vec2::NAN);
            lo = lo.min(n);
            hi = hi.max(n);
        }
        (lo, hi)
    }

    /// Grid-space bounding box, in `grid`, of the µQuad: the grid
    /// coordinates of [`Self::microquad_ndc_box`]. Bit for bit the box of
    /// the four corners' grid coordinates (what `light_view.glsl`
    /// computes): [`CascadeGrid::grid_coords`] subtracts, divides and
    /// multiplies by positive numbers, each rounded monotonically, so it
    /// commutes with min and max.
    pub fn microquad_grid_box(
        &self,
        grid: &CascadeGrid,
        p: Vec3,
        ex: Vec3,
        ey: Vec3,
    ) -> (Vec2, Vec2) {
        let (lo, hi) = self.microquad_ndc_box(p, ex, ey);
        (grid.grid_coords(lo), grid.grid_coords(hi))
    }

    /// [`Self::microquad_ndc_box`] of every receiver of `g` (`skips`
    /// decides which pixels are: [`crate::cpu::is_receiver`]), computed once
    /// per frame for the bin's receiver registration and evaluate.
    pub fn microquad_boxes(&self, g: &GBuffer, skips: Skips) -> MicroquadBoxes {
        self.receiver_boxes(g, skips, false)
    }

    /// [`Self::microquad_boxes`] where an edge pixel's surface covers only
    /// some of the µQuad samples ([`GBuffer::edges`]): its box is that of
    /// the part of the µQuad its own samples span (`covered_only`, under a
    /// point-like light, where each bit is a µQuad sample's line toward
    /// the light). Every triangle able to shadow one of them projects over
    /// that part, so the candidates stay complete; fewer cells are visited.
    pub fn receiver_boxes(&self, g: &GBuffer, skips: Skips, covered_only: bool) -> MicroquadBoxes {
        // Covered boxes are those of half 0's samples, the only half under
        // a point-like light.
        let edges = g.edges.as_deref().filter(|_| covered_only);
        let layer = |e: &crate::gbuffer::edge_surfaces::EdgeSurfaces, coverage| {
            Box::new(MicroquadBoxes {
                ndc: self.boxes_of(&e.surfaces, skips, coverage),
                edges: None,
                edges_high: None,
            })
        };
        MicroquadBoxes {
            ndc: self.boxes_of(g, skips, edges.map(|e| &e.centre_coverage[..])),
            edges: g
                .edges
                .as_deref()
                .map(|e| layer(e, edges.map(|e| &e.coverage[..]))),
            edges_high: g.edges_high.as_deref().map(|e| layer(e, None)),
        }
    }

    fn boxes_of(&self, g: &GBuffer, skips: Skips, coverage: Option<&[u32]>) -> Vec<(Vec2, Vec2)> {
        let receiver_flags = crate::cpu::receiver_flags(skips);
        let n = g.flags.len();
        let mut boxes = Vec::with_capacity(n);
        boxes.spare_capacity_mut()[..n]
            .par_chunks_mut(LANES)
            .enumerate()
            .with_min_len(256)
            .for_each_init(ChunkQuads::default, |lanes, (chunk, out)| {
                let c = chunk * LANES..chunk * LANES + out.len();
                lanes.receiver_boxes(self, g, c, coverage, receiver_flags, |l, b| {
                    out[l].write(b);
                });
            });
        // SAFETY: the chunks cover the first `n` slots, and
        // `receiver_boxes` hands every lane of a chunk to the write above.
        unsafe { boxes.set_len(n) };
        boxes
    }
}

/// One chunk's µQuads where some are covered sub-rectangles, and its
/// boxes: reused chunk after chunk.
#[derive(Default)]
struct ChunkQuads {
    quads: ([Vec3; LANES], [Vec3; LANES], [Vec3; LANES]),
    boxes: CornerBoxes,
}

impl ChunkQuads {
    /// The boxes of `g`'s entries `c` (at most [`LANES`]) into
    /// `self.boxes`, non-receivers' too, on the setup's SIMD path.
    fn project(
        &mut self,
        setup: &LightSetup,
        g: &GBuffer,
        c: Range<usize>,
        coverage: Option<&[u32]>,
    ) {
        let mut quads = (
            &g.position[c.clone()],
            &g.axis_x[c.clone()],
            &g.axis_y[c.clone()],
        );
        // An edge pixel's surface that covers only some samples: the
        // sub-rectangle they span, as a µQuad of its own.
        let covered = coverage.map(|cov| &cov[c.clone()]);
        if covered.is_some_and(|cov| cov.iter().any(|&c| c != u32::MAX && c != 0)) {
            let pattern = crate::lut::sample_pattern();
            let (p, ex, ey) = &mut self.quads;
            for (l, &c) in covered.into_iter().flatten().enumerate() {
                let quad = (quads.0[l], quads.1[l], quads.2[l]);
                (p[l], ex[l], ey[l]) = covered_quad(pattern, quad, c);
            }
            let len = c.len();
            quads = (&p[..len], &ex[..len], &ey[..len]);
        }
        corner_boxes(setup, setup.simd, quads, &mut self.boxes);
    }

    /// Hands `write` each lane's box of `g`'s entries `c` (at most
    /// [`LANES`]): NaN where the entry is not a receiver
    /// (`receiver_flags`). A chunk without receivers (sky, back faces)
    /// is not projected.
    fn receiver_boxes(
        &mut self,
        setup: &LightSetup,
        g: &GBuffer,
        c: Range<usize>,
        coverage: Option<&[u32]>,
        receiver_flags: u32,
        mut write: impl FnMut(usize, (Vec2, Vec2)),
    ) {
        let flags = &g.flags[c.clone()];
        let any = flags.iter().any(|f| f & receiver_flags != 0);
        if any {
            self.project(setup, g, c, coverage);
        }
        for (l, f) in flags.iter().enumerate() {
            write(
                l,
                if any && f & receiver_flags != 0 {
                    self.boxes.ndc_box(l)
                } else {
                    (Vec2::NAN, Vec2::NAN)
                },
            );
        }
    }
}

/// The boxes of the band of entries evaluate is in, projected together
/// as [`LightSetup::receiver_boxes`] projects them, before the band's
/// pixels are evaluated ([`ReceiverBoxes::PerBand`]).
#[derive(Default)]
pub struct BandBoxes {
    first: usize,
    ndc: Vec<(Vec2, Vec2)>,
    lanes: ChunkQuads,
}

/// Per pixel, the light-NDC box of its µQuad
/// ([`LightSetup::microquad_ndc_box`]; NaN for pixels that are not
/// receivers): the µQuad projection the bin's cull and evaluate both
/// need, so the four corners are projected once per frame, not once per
/// pass.
pub struct MicroquadBoxes {
    pub ndc: Vec<(Vec2, Vec2)>,
    /// The boxes of the G-buffer's edge surfaces ([`GBuffer::edges`],
    /// [`GBuffer::edges_high`]).
    pub edges: Option<Box<MicroquadBoxes>>,
    pub edges_high: Option<Box<MicroquadBoxes>>,
}

impl MicroquadBoxes {
    /// The boxes of each of [`GBuffer::layers`], in its order.
    pub fn layers(&self) -> impl Iterator<Item = &MicroquadBoxes> {
        std::iter::once(self)
            .chain(self.edges.as_deref())
            .chain(self.edges_high.as_deref())
    }

    /// Pixel `i`'s box in `grid`'s coordinates
    /// ([`LightSetup::microquad_grid_box`]).
    #[inline]
    pub fn grid_box(&self, grid: &CascadeGrid, i: usize) -> (Vec2, Vec2) {
        let (lo, hi) = self.ndc[i];
        (grid.grid_coords(lo), grid.grid_coords(hi))
    }
}

/// Where evaluate finds each receiver's µQuad box.
#[derive(Clone, Copy)]
pub enum ReceiverBoxes<'a> {
    /// Projected for the whole layer before evaluate: the bin's cull
    /// needed them ([`LightSetup::receiver_boxes`]).
    Stored(&'a MicroquadBoxes),
    /// Projected by evaluate band by band ([`BandBoxes`]), with the
    /// kernels and arithmetic of [`LightSetup::receiver_boxes`]
    /// (`covered_only` as there), just before the band's pixels read the
    /// same µQuads. Where no cull needs the boxes first, a stored layer
    /// was a pass of its own over the G-buffer, bound by memory: 10–13 ms
    /// of tablefan's and grazing's 1080p frame for 16 bytes a pixel
    /// written and read back; a band's boxes stay in cache. (Projecting
    /// each run of sixteen as the pixel loop reached it cost evaluate
    /// twice what the pass had.)
    PerBand { covered_only: bool },
}

impl ReceiverBoxes<'_> {
    /// Projects the boxes of `g`'s entries `band` into `out` where they
    /// are not stored; `receiver_flags` as [`crate::cpu::receiver_flags`].
    pub fn project_band(
        self,
        setup: &LightSetup,
        g: &GBuffer,
        band: Range<usize>,
        coverage: Option<&[u32]>,
        receiver_flags: u32,
        out: &mut BandBoxes,
    ) {
        let ReceiverBoxes::PerBand { covered_only } = self else {
            return;
        };
        let coverage = coverage.filter(|_| covered_only);
        out.first = band.start;
        out.ndc.clear();
        let BandBoxes { ndc, lanes, .. } = out;
        for first in band.clone().step_by(LANES) {
            let c = first..(first + LANES).min(band.end);
            lanes.receiver_boxes(setup, g, c, coverage, receiver_flags, |_, b| {
                ndc.push(b);
            });
        }
    }

    /// Receiver `i`'s box, from `band` where not stored.
    #[inline]
    pub fn ndc_box(self, i: usize, band: &BandBoxes) -> (Vec2, Vec2) {
        match self {
            ReceiverBoxes::Stored(boxes) => boxes.ndc[i],
            ReceiverBoxes::PerBand { .. } => band.ndc[i - band.first],
        }
    }

    /// The boxes of one of the layer's edge-surface layers
    /// (`MicroquadBoxes::edges` or `edges_high`): none where stored boxes
    /// lack it.
    pub fn layer(self, pick: fn(&MicroquadBoxes) -> Option<&MicroquadBoxes>) -> Option<Self> {
        match self {
            ReceiverBoxes::Stored(boxes) => pick(boxes).map(ReceiverBoxes::Stored),
            per_band => Some(per_band),
        }
    }
}

/// Sample offsets' margin around a covered sub-rectangle, in µQuad units:
/// its corners are not samples, so rounding at a corner cannot drop one.
/// The GPU's `receiver_grid_box` grows it by the same margin.
const COVERED_MARGIN: f32 = izb_contract::tolerance::COVERED_MARGIN;

/// The µQuad (centre, axes) of the sub-rectangle spanned by the samples
/// `coverage` marks when they are some but not all, else `quad` itself.
#[inline]
fn covered_quad(
    pattern: &[[f32; 2]; 32],
    quad: (Vec3, Vec3, Vec3),
    coverage: u32,
) -> (Vec3, Vec3, Vec3) {
    let (p, ex, ey) = quad;
    if coverage == u32::MAX || coverage == 0 {
        return quad;
    }
    let (lo, hi) = covered_rectangle(pattern, coverage);
    let centre = (lo + hi) * 0.5 - Vec2::splat(0.5);
    let size = hi - lo;
    (p + centre.x * ex + centre.y * ey, ex * size.x, ey * size.y)
}

/// The rectangle of µQuad offsets (in [0, 1]²) spanned by the samples of
/// `pattern` that `coverage` marks, grown by [`COVERED_MARGIN`].
fn covered_rectangle(pattern: &[[f32; 2]; 32], coverage: u32) -> (Vec2, Vec2) {
    let (mut lo, mut hi) = (Vec2::ONE, Vec2::ZERO);
    // The marked samples in increasing order, without a branch per sample
    // (one that mispredicted about half the time: courtyard's 374 k edge
    // surfaces at 1080p took 11 ms, now 7).
    let mut rest = coverage;
    while rest != 0 {
        let s = Vec2::from(pattern[rest.trailing_zeros() as usize]);
        lo = lo.min(s);
        hi = hi.max(s);
        rest &= rest - 1;
    }
    (
        (lo - COVERED_MARGIN).max(Vec2::ZERO),
        (hi + COVERED_MARGIN).min(Vec2::ONE),
    )
}

/// The four corners of a pixel's µQuad, eye-relative.
pub fn microquad_corners(p: Vec3, ex: Vec3, ey: Vec3) -> [Vec3; 4] {
    let (hx, hy) = (ex * 0.5, ey * 0.5);
    [p - hx - hy, p + hx - hy, p + hx + hy, p - hx + hy]
}
