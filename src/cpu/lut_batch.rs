//! The LUT's cells of the edges a survivor batch's masks need
//! ([`super::survivor_batch`]; lanes whose edges are certified to leave no
//! sample inside need none, [`super::empty_certificate`]), packed eight to
//! a vector: the normalisation, the saturation test, the distance column
//! and the angle row of [`izb_lut::EdgeLut::cell`] computed in SIMD
//! registers, then the floors and the table read only for the edges the
//! scalar mask loop asks for ([`LutCoordinates::mask`]), in its order.
//!
//! All of it is the scalar operations bit for bit but the angle. The row
//! is `floor((atan2f(γ, β) + π) · A/2π)` in `f32`, and libm's `atan2f`
//! has no SIMD twin whose bits are guaranteed. Here the angle comes from
//! a polynomial (Cephes' `atanf`, Moshier 1989: one range reduction to
//! |x| ≤ tan π/8, then a degree-9 odd polynomial; relative error ≤
//! 2·10⁻⁷), within about 10⁻⁶ rad of the true angle, as is libm's `f32`
//! result; scaled by A/2π ≈ 20, both lie within about 10⁻⁴ rows of the
//! exact row coordinate. Wherever the estimate lies farther than
//! `ROW_MARGIN` (2⁻⁹ rows) from a whole number both floors are the same
//! row; nearer (about half a percent of the edges, and every edge
//! parallel to a µQuad axis or diagonal), the cell is left to the scalar
//! `MaskRule::edge_mask`. So the masks equal the
//! scalar path's on every input (`a_batch_s_lut_masks_equal_the_scalar_
//! cells` below, and `tests/masks_unchanged.rs`).
//!
//! Measured (courtyard 960×540, 2 threads): evaluate 0.85 → 0.56 s, the
//! LUT's `atan2f`, floors and cell code having been a third of it
//! (`paper-notes/performance.md`).

use super::simd::{Kernel, SimdPath};
use super::survivor_batch::LANES;
use crate::frustum::normalised_edge;
use izb_lut::EdgeLut;

/// How far (in rows) the estimated row coordinate must lie from a whole
/// number for its floor to be libm's: about 20 times the two angles'
/// combined error at A = 128 rows (both ≲ 10⁻⁶ rad, × A/2π ≈ 20).
const ROW_MARGIN: f32 = 1.0 / 512.0;

/// Edges a batch can ask for: three per lane.
const SLOTS: usize = 3 * LANES;

/// Slots per chunk of the kernel: a batch's LUT edges are few (most lanes
/// are certified empty), so eight at a time, whatever the batch's width.
const CHUNK: usize = 8;

/// Per edge the lanes asked for (in slots, packed: `slot[k][lane]` says
/// where edge k of lane `lane` went), what the LUT's cell needs
/// ([`Self::mask`] finishes the cell where it is asked for).
pub struct LutCoordinates {
    slot: [[u8; LANES]; 3],
    /// The packed edges, kept from batch to batch: slots past those in
    /// use hold stale edges, whose coordinates are computed and never
    /// read (clearing them cost a store of 288 bytes per batch).
    packed: Packed,
    cells: Cells,
}

/// Per slot: whether the edge's line may cut the µQuad (else the mask is
/// constant), which constant, and the estimated row and exact column
/// coordinates.
struct Cells {
    /// 1 where the line may cut the µQuad (a `u32`, not a `bool`: LLVM
    /// vectorises the loop only so).
    cuts: [u32; SLOTS],
    /// The saturated mask: every sample or none.
    constant: [u32; SLOTS],
    /// The row's floor, and 0 where the estimate is too near a whole
    /// number (or NaN) to be sure of it, else 1.
    row: [f32; SLOTS],
    row_sure: [u32; SLOTS],
    /// The column coordinate's floor (exact).
    column: [f32; SLOTS],
}

impl Default for LutCoordinates {
    fn default() -> Self {
        LutCoordinates {
            slot: [[0; LANES]; 3],
            packed: [[0.0; SLOTS]; 3],
            cells: Cells {
                cuts: [0; SLOTS],
                constant: [0; SLOTS],
                row: [0.0; SLOTS],
                row_sure: [0; SLOTS],
                column: [0.0; SLOTS],
            },
        }
    }
}

impl LutCoordinates {
    /// Edge `k` of lane `l` (a lane [`lut_coordinates`] was asked for):
    /// its mask from `lut` and whether it was the saturation branch's, as
    /// [`izb_lut::EdgeLut::cell`] and [`izb_lut::EdgeLut::cell_mask`] give
    /// them; `None` where the row estimate lies too near a row boundary to
    /// be sure.
    #[inline]
    pub fn mask(&self, lut: &EdgeLut, k: usize, l: usize) -> Option<(u32, bool)> {
        let (i, cells) = (self.slot[k][l] as usize, &self.cells);
        if cells.cuts[i] == 0 {
            return Some((cells.constant[i], true));
        }
        if cells.row_sure[i] == 0 {
            return None;
        }
        let floor = cells.row[i];
        let (rows, columns) = (lut.angles as i32, lut.distances as i32);
        let angle = floor as i32;
        let angle = if angle >= rows {
            angle - rows
        } else {
            angle.max(0)
        };
        let distance = (cells.column[i] as i32).clamp(0, columns - 1);
        let index = (angle * columns + distance) as usize;
        Some((lut.masks[index], false))
    }
}

/// A batch's edges, `[k][component][lane]`
/// ([`super::survivor_batch::BatchTests::edges`]).
pub type BatchEdges = [[[f32; LANES]; 3]; 3];

/// The LUT coordinates of the edges of the lanes `wanted` marks, into
/// `out`: packed into slots first, so that a batch whose masks mostly
/// need no LUT (`super::empty_certificate`) computes one vector of edges
/// rather than three.
pub fn lut_coordinates(
    path: SimdPath,
    lut: &EdgeLut,
    edges: &BatchEdges,
    wanted: impl Fn(usize) -> bool,
    out: &mut LutCoordinates,
) {
    let mut used = 0;
    for l in (0..LANES).filter(|&l| wanted(l)) {
        for (k, edge) in edges.iter().enumerate() {
            for (component, values) in edge.iter().enumerate() {
                out.packed[component][used] = values[l];
            }
            out.slot[k][l] = used as u8;
            used += 1;
        }
    }
    let chunks = used.div_ceil(CHUNK);
    let kernel = CoordinateKernel {
        lut,
        packed: &out.packed,
        chunks,
    };
    path.dispatch(kernel, &mut out.cells);
}

/// Packed edges, `[component][slot]`.
type Packed = [[f32; SLOTS]; 3];

/// [`kernel`]'s arguments, as a [`Kernel`].
struct CoordinateKernel<'a> {
    lut: &'a EdgeLut,
    packed: &'a Packed,
    chunks: usize,
}

impl Kernel for CoordinateKernel<'_> {
    type Out = Cells;
    type Output = ();
    #[inline(always)]
    fn run(self, out: &mut Cells) {
        kernel(self.lut, self.packed, self.chunks, out)
    }
}

/// The coordinates of the first `chunks` × [`CHUNK`] slots:
/// `EdgeLut::cell`'s operations up to the floors, the edge scaled by
/// [`normalised_edge`], so that each loop is straight-line code over
/// slots.
#[inline(always)]
fn kernel(lut: &EdgeLut, packed: &Packed, chunks: usize, out: &mut Cells) {
    const HALF_DIAGONAL: f32 = std::f32::consts::FRAC_1_SQRT_2;
    let (angle_scale, distance_scale) = (lut.angle_scale_f32(), lut.distance_scale_f32());
    let [alphas, betas, gammas] = packed;
    for chunk in 0..chunks.min(SLOTS / CHUNK) {
        for l in chunk * CHUNK..(chunk + 1) * CHUNK {
            let [alpha, beta, gamma] = normalised_edge([alphas[l], betas[l], gammas[l]]);
            let r = (beta * beta + gamma * gamma).sqrt();
            out.cuts[l] = u32::from(alpha.abs() < HALF_DIAGONAL * r);
            let inside = (alpha >= 0.0) & (r >= 0.0);
            out.constant[l] = 0u32.wrapping_sub(u32::from(inside));
            out.column[l] = ((alpha / r + HALF_DIAGONAL) * distance_scale).floor();
            let row = (angle_estimate(beta, gamma) + std::f32::consts::PI) * angle_scale;
            let floor = row.floor();
            out.row[l] = floor;
            // False for NaN too.
            let sure = (row - floor).min(floor + 1.0 - row) > ROW_MARGIN;
            out.row_sure[l] = u32::from(sure);
        }
    }
}

/// atan2(y, x) within about 10⁻⁶ rad (Cephes' `atanf` on the octant's
/// ratio); NaN where both are 0 or either is NaN, whose lanes the
/// saturation branch decides.
#[inline(always)]
fn angle_estimate(x: f32, y: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    const TAN_PI_8: f32 = 0.414_213_57;
    let (ax, ay) = (x.abs(), y.abs());
    let q = ax.min(ay) / ax.max(ay);
    // q in [0, 1]: above tan π/8, atan q = π/4 + atan((q − 1)/(q + 1)).
    let reduced = q > TAN_PI_8;
    let z = if reduced { (q - 1.0) / (q + 1.0) } else { q };
    let z2 = z * z;
    let poly = ((8.053_744_5e-2 * z2 - 1.387_768_6e-1) * z2 + 1.997_771_1e-1) * z2 - 3.333_295e-1;
    let octant = poly * z2 * z + z + if reduced { FRAC_PI_4 } else { 0.0 };
    let first = if ay > ax { FRAC_PI_2 - octant } else { octant };
    let half = if x < 0.0 { PI - first } else { first };
    if y < 0.0 {
        -half
    } else {
        half
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frustum::normalised_edge;
    use izb_lut::LutCell;

    fn scalar(lut: &EdgeLut, e: [f32; 3]) -> (u32, bool) {
        let e = normalised_edge(e);
        let cell = lut.cell(e[0], e[1], e[2]);
        (lut.cell_mask(cell), matches!(cell, LutCell::Constant(_)))
    }

    /// Every known lane's mask and cheapness equal the scalar cell's, on
    /// random edges, edges along the µQuad's axes and diagonals, near the
    /// saturation boundary, tiny, huge, infinite and NaN; on every path
    /// this processor has; few lanes unknown.
    #[test]
    fn a_batch_s_lut_masks_equal_the_scalar_cells() {
        let lut = crate::lut::edge_lut();
        let mut random = crate::cpu::test_random::XorShift::new(0x2545_f491_4f6c_dd1d);
        let mut next = move || random.next_u64();
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            f32::MIN_POSITIVE,
            1e-30,
            3e38,
            -3e38,
            f32::INFINITY,
            f32::NAN,
        ];
        let mut edges = Vec::new();
        for _ in 0..400_000 {
            let r = next();
            let unit = |b: u64| (((r >> b) & 0xFFFF) as f32 / 32768.0) - 1.0;
            let (beta, gamma) = (unit(0), unit(16));
            let alpha = unit(32) * 0.8 * (beta * beta + gamma * gamma).sqrt();
            let scale = 2f32.powi(((r >> 48) % 64) as i32 - 32);
            edges.push([alpha * scale, beta * scale, gamma * scale]);
        }
        for a in special {
            for b in special {
                for c in special {
                    edges.push([a, b, c]);
                }
            }
        }
        // Directions on and beside every row boundary.
        for row in 0..=2 * lut.angles {
            let theta = row as f64 * std::f64::consts::PI / f64::from(lut.angles);
            for nudge in [-1e-6, 0.0, 1e-6] {
                let (s, c) = (theta + nudge).sin_cos();
                edges.push([0.1, c as f32, s as f32]);
            }
        }
        let paths = [SimdPath::Scalar, SimdPath::Avx2, SimdPath::Avx512];
        let mut checked = 0;
        let mut unknown = 0;
        for path in paths.map(SimdPath::or_supported) {
            for chunk in edges.chunks(3 * LANES) {
                let mut batch: BatchEdges = Default::default();
                for (i, e) in chunk.iter().enumerate() {
                    for c in 0..3 {
                        batch[i % 3][c][i / 3] = e[c];
                    }
                }
                let mut out = LutCoordinates::default();
                lut_coordinates(path, lut, &batch, |_| true, &mut out);
                for (i, e) in chunk.iter().enumerate() {
                    let (l, k) = (i / 3, i % 3);
                    match out.mask(lut, k, l) {
                        Some(got) => {
                            assert_eq!(got, scalar(lut, *e), "{path:?}: edge {e:?}");
                            checked += 1;
                        }
                        None => unknown += 1,
                    }
                }
            }
        }
        println!("{checked} edges known and equal to the scalar cells, {unknown} left to it");
        assert_eq!(checked + unknown, 3 * edges.len());
        assert!(
            unknown * 100 < checked,
            "{unknown} unknown of {checked} known"
        );
    }
}
