//! The edge-visibility lookup table (Wyman et al. 2015, §4, paper-notes/frustum-test.md): a 2-D table
//! over (angle, signed distance) of the edge line, each cell the 32-bit
//! mask of samples on the inside of the line through the cell centre.

use crate::edge::{
    exact_mask, inside_area, line_mask, random_crossing_line, signed_distance, ALL_SAMPLES,
    HALF_DIAGONAL,
};
use crate::rng::SplitMix64;
use crate::{SamplePattern, SAMPLES_PER_PIXEL};
use std::f64::consts::{PI, SQRT_2, TAU};
use std::fmt;

/// Default angle resolution, chosen by measurement (`paper-notes/edge-lut.md`).
pub const DEFAULT_ANGLES: u32 = 128;
/// Default distance resolution, chosen by measurement (`paper-notes/edge-lut.md`).
pub const DEFAULT_DISTANCES: u32 = 128;

/// Largest accepted resolution on either axis (a 4096 × 4096 table is
/// already 64 MiB).
pub const MAX_RESOLUTION: u32 = 4096;

/// `b"IZBL"` read as a little-endian u32: first word of [`EdgeLut::to_bytes`].
pub const LUT_MAGIC: u32 = u32::from_le_bytes(*b"IZBL");

/// Bytes before the masks in [`EdgeLut::to_bytes`]: magic, angles, distances.
pub const LUT_HEADER_BYTES: usize = 12;

/// Allowance, in µQuad side lengths, for the f32 arithmetic of
/// [`EdgeLut::lookup`] on top of the exact-arithmetic bound of
/// [`EdgeLut::misclassification_bound`].
///
/// The proof assumes θ and d exact. In f32, `atan2` (≤ 2 ulp), the
/// normalisation α/√(β²+γ²) (4 roundings) and the index products
/// `(θ+π)·A/2π`, `(d+√2/2)·D/√2` (relative error a few 2⁻²⁴ on values up to
/// A or D, i.e. a few 2⁻²⁴·2π rad and 2⁻²⁴·√2 in d) move the cell boundary by
/// at most ~3·10⁻⁶ rad in θ and ~10⁻⁶ in d; the f32 constant √2/2 used for
/// saturation is 1.2·10⁻⁸ below √2/2; rounding f64 inputs to f32 adds
/// ~2·10⁻⁷. Together below 4·10⁻⁶·|s−c| + 2·10⁻⁶ < 5·10⁻⁶; this constant
/// leaves a factor 2 (the tests report the largest excess actually met).
/// A GPU lookup needs its own allowance, measured on the device: Vulkan
/// 1.0's precision appendix leaves the trigonometric functions' precision
/// undefined (later versions only bound `atan` loosely), and allows 2.5 ulp
/// for division and an inverse-square-root-based `sqrt`.
pub const LOOKUP_SLACK: f64 = 1e-5;

/// Which table cell (or constant) an edge maps to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LutCell {
    /// Saturated: the line misses the µQuad or (β, γ) vanishes.
    Constant(u32),
    /// Row `angle` ∈ [0, A), column `distance` ∈ [0, D).
    Cell { angle: u32, distance: u32 },
}

/// An edge LUT: `angles` rows (θ) × `distances` columns (d), row-major
/// (`masks[angle * distances + distance]`).
///
/// Cell (i, j) covers θ ∈ [−π + iΔθ, −π + (i+1)Δθ) and
/// d ∈ [−√2/2 + jΔd, −√2/2 + (j+1)Δd), Δθ = 2π/A, Δd = √2/D, and stores
/// the mask of the samples s with g_c(s) = d_c + cos θ_c·(u−½) + sin θ_c·(v−½) ≥ 0
/// at its centre (θ_c, d_c).
///
/// # Misclassification bound
///
/// Claim: for an edge with exact line (θ, d), a sample s = (u, v) whose
/// LUT bit differs from its exact bit satisfies
///
/// ```text
/// |g(s)| ≤ Δd/2 + (Δθ/2)·|s − c|,   g(s) = d + cos θ·x + sin θ·y,
/// ```
///
/// x = u − ½, y = v − ½, |s − c| = √(x² + y²) (c the µQuad centre).
///
/// Proof. *Unsaturated* (|d| < √2/2): the lookup picks the cell containing
/// (θ, d) (θ modulo 2π), so |d − d_c| ≤ Δd/2 and |θ − θ_c| ≤ Δθ/2. Then
///
/// ```text
/// |g(s) − g_c(s)| ≤ |d − d_c| + |cos θ − cos θ_c|·|x| + |sin θ − sin θ_c|·|y|.
/// ```
///
/// The vector (cos θ − cos θ_c, sin θ − sin θ_c) is the chord between two
/// points of the unit circle, of length 2|sin((θ − θ_c)/2)| ≤ |θ − θ_c|;
/// by Cauchy–Schwarz |a|·|x| + |b|·|y| ≤ |(a, b)|·|(x, y)|, hence
/// |cos θ − cos θ_c|·|x| + |sin θ − sin θ_c|·|y| ≤ |θ − θ_c|·√(x² + y²), and
/// |g(s) − g_c(s)| ≤ Δd/2 + (Δθ/2)·|s − c|. The bits differ only if g(s)
/// and g_c(s) lie on different sides of 0 (one ≥ 0, the other < 0), which
/// needs |g(s)| ≤ |g(s) − g_c(s)|. *Saturated* (|d| ≥ √2/2): every point
/// of the square has |cos θ·x + sin θ·y| ≤ |s − c| ≤ √2/2, so g(s) has the
/// sign of d (or is 0): the constant answer is exact except on g(s) = 0,
/// which satisfies the bound. ∎
///
/// This is the bound of the exact arithmetic; [`LOOKUP_SLACK`] covers the
/// f32 arithmetic of [`EdgeLut::lookup`]. (The chord gives the slightly
/// tighter 2 sin(Δθ/4) in place of Δθ/2; the difference is < 0.1 % for
/// A ≥ 32 and not worth the less obvious form.)
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EdgeLut {
    pub angles: u32,
    pub distances: u32,
    pub masks: Vec<u32>,
}

/// Why [`EdgeLut::from_bytes`] refused its input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LutDecodeError {
    TooShort { len: usize },
    BadMagic { found: u32 },
    BadResolution { angles: u32, distances: u32 },
    WrongLength { expected: usize, found: usize },
}

impl fmt::Display for LutDecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::TooShort { len } => write!(
                f,
                "edge LUT file has {len} bytes, shorter than its {LUT_HEADER_BYTES}-byte header"
            ),
            Self::BadMagic { found } => write!(
                f,
                "edge LUT file starts with {found:#010x}, not the magic \"IZBL\""
            ),
            Self::BadResolution { angles, distances } => {
                write!(
                    f,
                    "edge LUT resolution {angles}x{distances} outside 1..={MAX_RESOLUTION}"
                )
            }
            Self::WrongLength { expected, found } => write!(
                f,
                "edge LUT file has {found} bytes, its header says {expected}"
            ),
        }
    }
}

impl std::error::Error for LutDecodeError {}

impl EdgeLut {
    /// Builds the table for `pattern`: each cell stores the exact mask of
    /// the line through its centre (θ_c, d_c). Panics unless both
    /// resolutions are in 1..=[`MAX_RESOLUTION`].
    pub fn generate(angles: u32, distances: u32, pattern: &SamplePattern) -> Self {
        assert!(
            (1..=MAX_RESOLUTION).contains(&angles) && (1..=MAX_RESOLUTION).contains(&distances),
            "edge LUT resolution {angles}x{distances} outside 1..={MAX_RESOLUTION}"
        );
        let mut lut = Self {
            angles,
            distances,
            masks: Vec::with_capacity(angles as usize * distances as usize),
        };
        for angle in 0..angles {
            for distance in 0..distances {
                let (theta, d) = lut.cell_centre(angle, distance);
                lut.masks.push(line_mask(theta, d, pattern));
            }
        }
        lut
    }

    /// Δθ = 2π/A.
    pub fn angle_step(&self) -> f64 {
        TAU / f64::from(self.angles)
    }

    /// Δd = √2/D (the distance axis spans [−√2/2, √2/2]).
    pub fn distance_step(&self) -> f64 {
        SQRT_2 / f64::from(self.distances)
    }

    /// Centre (θ_c, d_c) of cell (`angle`, `distance`).
    pub fn cell_centre(&self, angle: u32, distance: u32) -> (f64, f64) {
        (
            -PI + (f64::from(angle) + 0.5) * self.angle_step(),
            -HALF_DIAGONAL + (f64::from(distance) + 0.5) * self.distance_step(),
        )
    }

    /// f32 constant A/(2π) of the angle index (pass this exact value to a
    /// shader).
    pub fn angle_scale_f32(&self) -> f32 {
        (f64::from(self.angles) / TAU) as f32
    }

    /// f32 constant D/√2 of the distance index (pass this exact value to a
    /// shader).
    pub fn distance_scale_f32(&self) -> f32 {
        (f64::from(self.distances) / SQRT_2) as f32
    }

    /// The cell an edge f = α + β(u−½) + γ(v−½) maps to, in f32 exactly as
    /// a shader computes it:
    ///
    /// ```glsl
    /// const float HALF_DIAGONAL = 0.70710677;   // f32(√2/2)
    /// const float PI = 3.14159274;              // f32(π)
    /// // ANGLE_SCALE = f32(A / 2π), DIST_SCALE = f32(D / √2): angle_scale_f32(), distance_scale_f32()
    /// uint edge_mask(float alpha, float beta, float gamma) {
    ///     float r = sqrt(beta * beta + gamma * gamma);
    ///     if (!(abs(alpha) < HALF_DIAGONAL * r))          // saturated, (β,γ) ≈ 0, or NaN
    ///         return (alpha >= 0.0 && r >= 0.0) ? 0xFFFFFFFFu : 0u;
    ///     float d = alpha / r;                             // in (−√2/2, √2/2)
    ///     int ti = int(floor((atan(gamma, beta) + PI) * ANGLE_SCALE));
    ///     ti = ti >= A ? ti - A : max(ti, 0);              // θ = π wraps to row 0
    ///     int di = clamp(int(floor((d + HALF_DIAGONAL) * DIST_SCALE)), 0, D - 1);
    ///     return masks[ti * D + di];
    /// }
    /// ```
    ///
    /// The saturation test compares |α| with (√2/2)·r instead of dividing
    /// first, so r = 0 or r tiny against |α| never reaches the division. It
    /// also routes NaN inputs to "none inside", as [`crate::exact_mask_f32`].
    /// Correct normalisation needs β² + γ² within f32 range
    /// (|β|, |γ| ≲ 10¹⁸ and not both ≲ 10⁻¹⁹). The renderer's edges grow
    /// with the cube of the scene's scale under a point light, so it scales
    /// each by a power of two first (`izb::frustum::normalised_edge`, exact).
    pub fn cell(&self, alpha: f32, beta: f32, gamma: f32) -> LutCell {
        const HALF_DIAGONAL_F32: f32 = std::f32::consts::FRAC_1_SQRT_2;
        const PI_F32: f32 = std::f32::consts::PI;
        let r = (beta * beta + gamma * gamma).sqrt();
        // False for NaN too, which then takes the constant branch.
        let line_may_cut_the_square = alpha.abs() < HALF_DIAGONAL_F32 * r;
        if !line_may_cut_the_square {
            let inside = alpha >= 0.0 && r >= 0.0;
            return LutCell::Constant(if inside { ALL_SAMPLES } else { 0 });
        }
        let d = alpha / r;
        let (rows, columns) = (self.angles as i32, self.distances as i32);
        let angle = ((gamma.atan2(beta) + PI_F32) * self.angle_scale_f32()).floor() as i32;
        let angle = if angle >= rows {
            angle - rows
        } else {
            angle.max(0)
        };
        let distance = (((d + HALF_DIAGONAL_F32) * self.distance_scale_f32()).floor() as i32)
            .clamp(0, columns - 1);
        LutCell::Cell {
            angle: angle as u32,
            distance: distance as u32,
        }
    }

    /// The LUT's mask for edge f = α + β(u−½) + γ(v−½) (bit set = inside,
    /// f ≥ 0): [`Self::cell`], then one table read.
    pub fn lookup(&self, alpha: f32, beta: f32, gamma: f32) -> u32 {
        self.cell_mask(self.cell(alpha, beta, gamma))
    }

    /// The mask of a cell [`Self::cell`] returned (one table read, or the
    /// saturated constant).
    #[inline]
    pub fn cell_mask(&self, cell: LutCell) -> u32 {
        match cell {
            LutCell::Constant(mask) => mask,
            LutCell::Cell { angle, distance } => {
                self.masks[(angle * self.distances + distance) as usize]
            }
        }
    }

    /// The proven bound Δd/2 + (Δθ/2)·|s − c| on |g(s)| for a sample the
    /// LUT misclassifies (see the type's documentation), in µQuad side
    /// lengths, exact arithmetic (add [`LOOKUP_SLACK`] for [`Self::lookup`]).
    pub fn misclassification_bound(&self, sample: [f32; 2]) -> f64 {
        let (x, y) = (f64::from(sample[0]) - 0.5, f64::from(sample[1]) - 0.5);
        0.5 * self.distance_step() + 0.5 * self.angle_step() * x.hypot(y)
    }

    /// Compares [`Self::lookup`] of the f32-rounded edge with the f64
    /// exact mask of the edge itself, sample by sample.
    pub fn compare_with_exact(
        &self,
        alpha: f64,
        beta: f64,
        gamma: f64,
        pattern: &SamplePattern,
    ) -> EdgeComparison {
        let lut_mask = self.lookup(alpha as f32, beta as f32, gamma as f32);
        let exact = exact_mask(alpha, beta, gamma, pattern);
        let mut comparison = EdgeComparison {
            lut_mask,
            exact_mask: exact,
            worst_distance: 0.0,
            worst_excess: f64::NEG_INFINITY,
            worst_bound_ratio: 0.0,
        };
        let mut mismatched = lut_mask ^ exact;
        while mismatched != 0 {
            let i = mismatched.trailing_zeros() as usize;
            mismatched &= mismatched - 1;
            let distance = signed_distance(alpha, beta, gamma, pattern[i]).abs();
            let bound = self.misclassification_bound(pattern[i]);
            comparison.worst_distance = comparison.worst_distance.max(distance);
            comparison.worst_excess = comparison.worst_excess.max(distance - bound);
            comparison.worst_bound_ratio = comparison.worst_bound_ratio.max(distance / bound);
        }
        comparison
    }

    /// True when every sample the LUT gets wrong for this edge lies within
    /// the proven bound (plus [`LOOKUP_SLACK`]) of the edge line.
    pub fn lut_error_within_bound(
        &self,
        alpha: f64,
        beta: f64,
        gamma: f64,
        pattern: &SamplePattern,
    ) -> bool {
        self.compare_with_exact(alpha, beta, gamma, pattern)
            .within_bound()
    }

    /// Table size in bytes (masks only).
    pub fn table_bytes(&self) -> usize {
        self.masks.len() * std::mem::size_of::<u32>()
    }

    /// Serialises as little-endian u32 words: magic `"IZBL"`, angles,
    /// distances, then the A·D masks row-major. The masks start at byte
    /// [`LUT_HEADER_BYTES`], so a GPU upload can take the slice from there.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = Vec::with_capacity(LUT_HEADER_BYTES + self.table_bytes());
        for word in [LUT_MAGIC, self.angles, self.distances]
            .iter()
            .chain(&self.masks)
        {
            bytes.extend_from_slice(&word.to_le_bytes());
        }
        bytes
    }

    /// Inverse of [`Self::to_bytes`].
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, LutDecodeError> {
        if bytes.len() < LUT_HEADER_BYTES {
            return Err(LutDecodeError::TooShort { len: bytes.len() });
        }
        let word =
            |k: usize| u32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().expect("4 bytes"));
        if word(0) != LUT_MAGIC {
            return Err(LutDecodeError::BadMagic { found: word(0) });
        }
        let (angles, distances) = (word(1), word(2));
        if !(1..=MAX_RESOLUTION).contains(&angles) || !(1..=MAX_RESOLUTION).contains(&distances) {
            return Err(LutDecodeError::BadResolution { angles, distances });
        }
        let cells = angles as usize * distances as usize;
        let expected = LUT_HEADER_BYTES + 4 * cells;
        if bytes.len() != expected {
            return Err(LutDecodeError::WrongLength {
                expected,
                found: bytes.len(),
            });
        }
        Ok(Self {
            angles,
            distances,
            masks: (3..3 + cells).map(word).collect(),
        })
    }
}

/// One edge, LUT against exact ([`EdgeLut::compare_with_exact`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EdgeComparison {
    pub lut_mask: u32,
    pub exact_mask: u32,
    /// Largest exact |g(s)| over the misclassified samples (0 if none).
    pub worst_distance: f64,
    /// Largest |g(s)| − bound(s) over the misclassified samples (−∞ if none).
    pub worst_excess: f64,
    /// Largest |g(s)| / bound(s) over the misclassified samples (0 if none).
    pub worst_bound_ratio: f64,
}

impl EdgeComparison {
    /// Misclassified samples.
    pub fn mismatched(&self) -> u32 {
        self.lut_mask ^ self.exact_mask
    }

    /// Every misclassified sample within bound + [`LOOKUP_SLACK`].
    pub fn within_bound(&self) -> bool {
        self.worst_excess <= LOOKUP_SLACK
    }
}

/// Seed of the random edges of [`lut_statistics`].
const STATISTICS_SEED: u64 = 0x0E06_E1A7_0002_0004;

/// Accuracy of a LUT against the exact classifier ([`lut_statistics`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LutStats {
    pub angles: u32,
    pub distances: u32,
    /// Size of the masks in bytes.
    pub table_bytes: usize,
    /// Random edges measured.
    pub lines: usize,
    /// Misclassified samples / (lines · 32).
    pub mismatch_rate: f64,
    /// Fraction of edges with at least one misclassified sample.
    pub lines_with_mismatch: f64,
    /// RMS over edges of (popcount(LUT) − popcount(exact)) / 32: the
    /// coverage error the table adds to one edge.
    pub coverage_rms_error: f64,
    /// RMS over edges of popcount(LUT)/32 − inside area: the coverage error
    /// of LUT mode on one straight edge (pattern error and table error).
    pub lut_coverage_rms: f64,
    /// The same for the exact classifier: the pattern's own error on the
    /// same edges, the floor any table can reach.
    pub exact_coverage_rms: f64,
    /// Largest exact |g(s)| of a misclassified sample, in µQuad sides.
    pub worst_misclassified_distance: f64,
    /// Largest |g(s)| / bound(s) of a misclassified sample (≤ 1 up to
    /// [`LOOKUP_SLACK`]).
    pub worst_bound_ratio: f64,
    /// Largest |g(s)| − bound(s) met (≤ [`LOOKUP_SLACK`]).
    pub worst_bound_excess: f64,
    /// Misclassified samples beyond bound + [`LOOKUP_SLACK`]: 0 if the
    /// proof and the implementation agree.
    pub bound_violations: usize,
    /// The bound at the pattern's sample farthest from the centre.
    pub max_bound: f64,
}

impl fmt::Display for LutStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "edge LUT {} angles x {} distances ({} bytes)",
            self.angles, self.distances, self.table_bytes
        )?;
        writeln!(f, "  random edges crossing the pixel:  {}", self.lines)?;
        writeln!(
            f,
            "  sample mismatch rate vs exact:    {:.4e}",
            self.mismatch_rate
        )?;
        writeln!(
            f,
            "  edges with any mismatch:          {:.4}",
            self.lines_with_mismatch
        )?;
        writeln!(
            f,
            "  coverage RMS, LUT vs exact:       {:.4e}",
            self.coverage_rms_error
        )?;
        writeln!(
            f,
            "  coverage RMS vs area, LUT/exact:  {:.4e} / {:.4e}",
            self.lut_coverage_rms, self.exact_coverage_rms
        )?;
        writeln!(
            f,
            "  worst misclassified distance:     {:.4e} (bound <= {:.4e})",
            self.worst_misclassified_distance, self.max_bound
        )?;
        writeln!(
            f,
            "  worst distance / bound:           {:.4}",
            self.worst_bound_ratio
        )?;
        write!(
            f,
            "  samples beyond the bound:         {}",
            self.bound_violations
        )
    }
}

/// Measures `lut` against [`exact_mask`] on `lines` random edges crossing
/// the pixel (uniform angle, uniform offset over the crossing offsets; the
/// same distribution as [`crate::coverage_error`]). Each edge gets a random
/// scale |(β, γ)| log-uniform in [10⁻³, 10³], so the f32 normalisation of
/// [`EdgeLut::lookup`] is exercised too; the exact mask and g(s) are
/// computed in f64. Deterministic.
pub fn lut_statistics(lut: &EdgeLut, pattern: &SamplePattern, lines: usize) -> LutStats {
    lut_statistics_over(
        lut,
        pattern,
        lines,
        STATISTICS_SEED,
        random_crossing_line,
        inside_area,
    )
}

/// [`lut_statistics`] over a family of lines: `random_line` draws
/// (θ, d) from the seeded generator, `area(θ, d)` is the share of the
/// sampled domain on the inside (the pixel's square, or the light's disk:
/// `crate::light::light_lut_statistics`).
pub(crate) fn lut_statistics_over(
    lut: &EdgeLut,
    pattern: &SamplePattern,
    lines: usize,
    seed: u64,
    mut random_line: impl FnMut(&mut SplitMix64) -> (f64, f64),
    area: impl Fn(f64, f64) -> f64,
) -> LutStats {
    let mut rng = SplitMix64::new(seed);
    let mut stats = LutStats {
        angles: lut.angles,
        distances: lut.distances,
        table_bytes: lut.table_bytes(),
        lines,
        mismatch_rate: 0.0,
        lines_with_mismatch: 0.0,
        coverage_rms_error: 0.0,
        lut_coverage_rms: 0.0,
        exact_coverage_rms: 0.0,
        worst_misclassified_distance: 0.0,
        worst_bound_ratio: 0.0,
        worst_bound_excess: f64::NEG_INFINITY,
        bound_violations: 0,
        max_bound: pattern
            .iter()
            .map(|&s| lut.misclassification_bound(s))
            .fold(0.0, f64::max),
    };
    let (mut mismatched_samples, mut mismatched_lines, mut coverage_sq) = (0u64, 0u64, 0.0f64);
    let (mut lut_area_sq, mut exact_area_sq) = (0.0f64, 0.0f64);
    let fraction = |mask: u32| f64::from(mask.count_ones()) / SAMPLES_PER_PIXEL as f64;
    for _ in 0..lines {
        let (theta, distance) = random_line(&mut rng);
        let scale = 10f64.powf(6.0 * rng.next_f64() - 3.0);
        // Round to f32 first so that exact and LUT judge the same edge.
        let [alpha, beta, gamma] = [scale * distance, scale * theta.cos(), scale * theta.sin()]
            .map(|x| f64::from(x as f32));
        let comparison = lut.compare_with_exact(alpha, beta, gamma, pattern);
        let area = area(theta, distance);
        lut_area_sq += (fraction(comparison.lut_mask) - area).powi(2);
        exact_area_sq += (fraction(comparison.exact_mask) - area).powi(2);
        let mismatched = comparison.mismatched();
        if mismatched == 0 {
            continue;
        }
        mismatched_samples += u64::from(mismatched.count_ones());
        mismatched_lines += 1;
        let coverage = fraction(comparison.lut_mask) - fraction(comparison.exact_mask);
        coverage_sq += coverage * coverage;
        stats.worst_misclassified_distance = stats
            .worst_misclassified_distance
            .max(comparison.worst_distance);
        stats.worst_bound_ratio = stats.worst_bound_ratio.max(comparison.worst_bound_ratio);
        stats.worst_bound_excess = stats.worst_bound_excess.max(comparison.worst_excess);
        if !comparison.within_bound() {
            let mut rest = mismatched;
            while rest != 0 {
                let i = rest.trailing_zeros() as usize;
                rest &= rest - 1;
                let g = signed_distance(alpha, beta, gamma, pattern[i]).abs();
                if g - lut.misclassification_bound(pattern[i]) > LOOKUP_SLACK {
                    stats.bound_violations += 1;
                }
            }
        }
    }
    let n = lines.max(1) as f64;
    stats.mismatch_rate = mismatched_samples as f64 / (n * SAMPLES_PER_PIXEL as f64);
    stats.lines_with_mismatch = mismatched_lines as f64 / n;
    stats.coverage_rms_error = (coverage_sq / n).sqrt();
    stats.lut_coverage_rms = (lut_area_sq / n).sqrt();
    stats.exact_coverage_rms = (exact_area_sq / n).sqrt();
    stats
}

#[cfg(test)]
mod tests;
