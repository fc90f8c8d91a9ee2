//! Sample-distribution cascades (Lauritzen et al. 2011, Wyman et al. 2015, §6.4):
//! the shadow-tested pixels are split by view depth into 1–4 cascades, and
//! each cascade gets its own light-space grid fitted to its own pixels'
//! µQuads (see [`mod@crate::cpu::light_setup`]).
//!
//! Why an IZB wants them: a pixel's µQuad grows with its view depth, so one
//! grid sized for the average pixel puts hundreds of far pixels in one cell
//! and spreads a near pixel's µQuad over many cells (each one more list to
//! walk). A cascade whose pixels span a view-depth ratio of at most
//! [`AUTO_MAX_DEPTH_RATIO`] keeps the µQuad size within that ratio inside
//! its grid. (Measured, they do not pay below that on our scenes: see the
//! constant.)
//!
//! Exactness does not depend on the split: every cascade shares one
//! light-view frame (rotation and origin), so a pixel's light-view
//! coordinates, and with them every triangle test, are bit-for-bit the same
//! whichever cascade it lands in; only the grid it looks its candidates up
//! in differs, and every grid offers every triangle that can shadow it.
//! The GPU twin computes the same expressions in `f32` (`light_setup.comp`,
//! `STEP_FRAME` and `STEP_GRID`); a driver's `pow` may round differently,
//! which can move a pixel at a split into the next cascade and change the
//! counters, never a mask.

use izb_contract::tolerance::MIN_CASCADE_CELLS;
use std::fmt;

/// Most cascades a frame may have.
pub const MAX_CASCADES: usize = izb_contract::size::MAX_CASCADES as usize;

/// `auto` uses the fewest cascades (up to [`MAX_CASCADES`]) whose
/// logarithmic splits keep each cascade's far/near view-depth ratio at or
/// below this. Measured (CPU twin, 240×135, candidates per pixel, 1 vs 4
/// cascades at the same cell budget): 0.85–2.1× on every scene we have
/// (view-depth ratios 1.9–9.5; city 0.85×, grazing 1.21×, courtyard
/// 2.07×), because the far cascade's grid is coarse over a wide
/// light-space area and triangles near a split are listed in both grids
/// (`paper-notes/skipping-work.md`). So `auto` keeps one grid up to a
/// ratio of 16 and splits only deeper views, where one grid's cells must
/// serve µQuads more than 16× apart in size.
pub const AUTO_MAX_DEPTH_RATIO: f32 = izb_contract::tolerance::AUTO_MAX_DEPTH_RATIO;

/// How many cascades to use (`--cascades auto|1..4`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum CascadeCount {
    /// As few as the view-depth range needs ([`cascade_count`]).
    #[default]
    Auto,
    /// Exactly this many (1..=4).
    Fixed(u32),
}

impl CascadeCount {
    /// Parses `auto` or a count in 1..=4.
    pub fn parse(text: &str) -> Result<CascadeCount, String> {
        match text.trim() {
            "auto" => Ok(CascadeCount::Auto),
            t => match t.parse::<u32>() {
                Ok(n) if (1..=MAX_CASCADES as u32).contains(&n) => Ok(CascadeCount::Fixed(n)),
                _ => Err(format!(
                    "cascades must be `auto` or 1..={MAX_CASCADES}, not `{t}`"
                )),
            },
        }
    }

    /// `FrameParams::cascades`: 0 for auto.
    pub fn code(self) -> u32 {
        match self {
            CascadeCount::Auto => 0,
            CascadeCount::Fixed(n) => n,
        }
    }
}

impl fmt::Display for CascadeCount {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CascadeCount::Auto => f.write_str("auto"),
            CascadeCount::Fixed(n) => write!(f, "{n}"),
        }
    }
}

impl serde::Serialize for CascadeCount {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// Cascades for view depths `[near, far]` of the shadow-tested pixels:
/// `Fixed(n)` gives n; `Auto` the smallest K ≤ [`MAX_CASCADES`] with
/// far ≤ near · 4^K (compared exactly: multiplying by 4 is exact in `f32`,
/// so both backends agree).
pub fn cascade_count(requested: CascadeCount, near: f32, far: f32) -> u32 {
    match requested {
        CascadeCount::Fixed(n) => n.clamp(1, MAX_CASCADES as u32),
        CascadeCount::Auto => {
            let mut k = 1;
            let mut reach = near * AUTO_MAX_DEPTH_RATIO;
            while k < MAX_CASCADES as u32 && far > reach {
                k += 1;
                reach *= AUTO_MAX_DEPTH_RATIO;
            }
            k
        }
    }
}

/// Upper view depth of each of `count` cascades over `[near, far]`: the
/// practical split scheme, `λ` times the logarithmic split plus `1 − λ`
/// times the uniform one (`λ` = 1: purely logarithmic, which gives every
/// cascade the same far/near ratio). The last used cascade and the unused
/// slots are +∞, so every pixel lands in a cascade.
pub fn split_depths(near: f32, far: f32, count: u32, lambda: f32) -> [f32; MAX_CASCADES] {
    let mut upper = [f32::INFINITY; MAX_CASCADES];
    for (k, u) in upper.iter_mut().enumerate().take(count as usize - 1) {
        let s = (k + 1) as f32 / count as f32;
        let log = near * (far / near).powf(s);
        let uniform = near + (far - near) * s;
        *u = lambda * log + (1.0 - lambda) * uniform;
    }
    upper
}

/// The cascade of a pixel at view depth `depth`: the first whose upper
/// split is at or beyond it.
#[inline]
pub fn cascade_of_depth(upper: &[f32; MAX_CASCADES], depth: f32) -> usize {
    upper
        .iter()
        .position(|&u| depth <= u)
        .unwrap_or(MAX_CASCADES - 1)
}

/// Longest side a grid may have (cells): a 4096-cell side is finer than a
/// pixel's µQuad up to 4K images, and it bounds the pyramid's rim of
/// rounded-up cells that the GPU cell arrays are sized for
/// ([`max_total_cells`]).
pub const MAX_GRID_SIDE: u32 = izb_contract::size::MAX_GRID_SIDE;

/// Cells along x and y of a cascade's grid over a light-NDC `extent`: the
/// frame's cell budget `side²` (`side` from all receivers and triangles,
/// [`crate::cpu::light_setup::default_grid_side`], or `--cells`) shared between
/// the cascades in proportion to their receivers (at least 64 cells each),
/// with square cells in NDC. Sides are rounded down, so a grid never holds
/// more than its share and all grids together at most `side² + 64 ·
/// cascades` cells — what the GPU sizes its cell arrays for
/// ([`max_total_cells`]). Filling the budget whatever the aspect ratio
/// matters: a grid sized by its longer side alone gave `grazing` (a long,
/// thin light-space footprint) 49 receivers per cell instead of ~4.
pub fn cascade_cells(
    side: u32,
    receivers: usize,
    all_receivers: usize,
    count: u32,
    extent: glam::Vec2,
) -> [u32; 2] {
    let budget = side as f32 * side as f32;
    let target = if count <= 1 || all_receivers == 0 {
        budget
    } else {
        (budget * (receivers as f32 / all_receivers as f32)).max(MIN_CASCADE_CELLS)
    };
    let cell = (extent.x * extent.y / target).sqrt();
    if cell.is_nan() || cell <= 0.0 {
        return [1, 1];
    }
    // The shorter side first: rounding it up to one cell must not let the
    // longer side overspend the target.
    let max = MAX_GRID_SIDE as f32;
    let (short, long) = if extent.x <= extent.y {
        (extent.x, extent.y)
    } else {
        (extent.y, extent.x)
    };
    let n_short = ((short / cell).floor().min(max) as u32).max(1);
    let n_long = ((long / cell)
        .floor()
        .min((target / n_short as f32).floor())
        .min(max) as u32)
        .max(1);
    if extent.x <= extent.y {
        [n_short, n_long]
    } else {
        [n_long, n_short]
    }
}

/// The most cells all cascades' pyramids may need for a frame whose
/// single-cascade side is `side`: what the cell arrays are sized for.
/// Level 0 of all grids holds at most `side² + 64 · cascades` cells
/// ([`cascade_cells`]); the levels of a `w × h` grid add at most
/// `Σ (w/2^l + 1)(h/2^l + 1) ≤ wh/3 + 2(w + h) + levels` more.
pub fn max_total_cells(side: u32) -> u64 {
    let level0 = u64::from(side) * u64::from(side) + MIN_CASCADE_CELLS as u64 * MAX_CASCADES as u64;
    let per_grid_rim = 4 * u64::from(MAX_GRID_SIDE) + 2 * 32;
    level0 + level0.div_ceil(3) + MAX_CASCADES as u64 * per_grid_rim
}

/// Cells a triangle's rectangle may hold at the pyramid level it is
/// binned at (Wyman et al. 2016 and [Compute IZB] bin each triangle into every
/// cell it covers up to a threshold and list the rest globally; a pyramid
/// has no global list: a triangle too large for one level goes to the next,
/// coarser one, where it covers about a quarter as many cells). Its
/// rectangle then holds at most this many cells, so binning costs at most
/// this many entries per triangle, while a pixel visits one small cell
/// range per level. Larger values keep big triangles on finer levels, where
/// fewer pixels share their cells: measured at 1920×1080 (CPU, shadow
/// seconds, tests per pixel), 64 → 1024 takes courtyard 1.71 → 1.32 s
/// (64.6 → 29.2 tests), engine 0.22 → 0.14 s (35.8 → 12.0), wires 1.01 →
/// 0.51 s. 1024 → 16384 (session 22, once the bin's cull and the GPU's
/// subgroup-wide walk of big rectangles were in): a pixel visits every
/// level that holds a triangle, and a few hundred big triangles kept four
/// coarse levels busy. Courtyard's pixels visit 3.5 levels instead of
/// 5.8, its bin and evaluate take 0.91 s instead of 0.96, deckchair's
/// evaluate 0.087 s instead of 0.122, `default`'s bin and evaluate 0.18 s
/// instead of 0.23, for about 5 % more entries; masks are unchanged
/// (`paper-notes/performance.md`).
pub const DEFAULT_LEVEL_CELLS: u32 = izb_contract::word::DEFAULT_LEVEL_CELLS;

/// What the frame chose, for the report.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct CascadeChoice {
    pub requested: CascadeCount,
    pub count: u32,
    /// View depth range of the shadow-tested pixels.
    pub view_depth: [f32; 2],
    /// `far / near` of that range.
    pub depth_ratio: f32,
    /// Largest far/near ratio of one cascade (logarithmic splits).
    pub ratio_per_cascade: f32,
    pub split_lambda: f32,
    /// Why this many, in words.
    pub reason: String,
}

impl CascadeChoice {
    pub fn new(requested: CascadeCount, near: f32, far: f32, lambda: f32) -> CascadeChoice {
        let count = cascade_count(requested, near, far);
        let depth_ratio = far / near;
        let ratio_per_cascade = depth_ratio.powf(1.0 / count as f32);
        let reason = match requested {
            CascadeCount::Fixed(n) => format!("{n} requested"),
            CascadeCount::Auto if count == 1 => format!(
                "view depth ratio {depth_ratio:.2} ≤ {AUTO_MAX_DEPTH_RATIO}: one grid suffices"
            ),
            CascadeCount::Auto if depth_ratio > AUTO_MAX_DEPTH_RATIO.powi(count as i32) => {
                format!(
                    "view depth ratio {depth_ratio:.1} needs more than {MAX_CASCADES} cascades of \
                     ratio ≤ {AUTO_MAX_DEPTH_RATIO}: capped at {MAX_CASCADES} (ratio \
                     {ratio_per_cascade:.1} each)"
                )
            }
            CascadeCount::Auto => format!(
                "view depth ratio {depth_ratio:.1}: {count} cascades keep each one's ratio at \
                 {ratio_per_cascade:.2} ≤ {AUTO_MAX_DEPTH_RATIO}"
            ),
        };
        CascadeChoice {
            requested,
            count,
            view_depth: [near, far],
            depth_ratio,
            ratio_per_cascade,
            split_lambda: lambda,
            reason,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_count_follows_the_depth_ratio() {
        let auto = CascadeCount::Auto;
        assert_eq!(cascade_count(auto, 1.0, 16.0), 1);
        assert_eq!(cascade_count(auto, 1.0, 16.001), 2);
        assert_eq!(cascade_count(auto, 2.0, 32.0), 1);
        assert_eq!(cascade_count(auto, 1.0, 300.0), 3);
        assert_eq!(cascade_count(auto, 1.0, 1e6), 4);
        assert_eq!(cascade_count(CascadeCount::Fixed(3), 1.0, 1.0), 3);
    }

    #[test]
    fn log_splits_give_equal_ratios_and_cover_every_depth() {
        let upper = split_depths(1.0, 64.0, 3, 1.0);
        approx::assert_relative_eq!(upper[0], 4.0, max_relative = 1e-6);
        approx::assert_relative_eq!(upper[1], 16.0, max_relative = 1e-6);
        assert_eq!(upper[2], f32::INFINITY);
        assert_eq!(cascade_of_depth(&upper, 1.0), 0);
        assert_eq!(cascade_of_depth(&upper, 4.5), 1);
        assert_eq!(cascade_of_depth(&upper, 64.0), 2);
        assert_eq!(cascade_of_depth(&upper, f32::MAX), 2);
        let uniform = split_depths(1.0, 64.0, 3, 0.0);
        approx::assert_relative_eq!(uniform[0], 22.0, max_relative = 1e-6);
    }

    #[test]
    fn count_parses_and_rejects() {
        assert_eq!(CascadeCount::parse("auto"), Ok(CascadeCount::Auto));
        assert_eq!(CascadeCount::parse("2"), Ok(CascadeCount::Fixed(2)));
        assert!(CascadeCount::parse("0").is_err());
        assert!(CascadeCount::parse("5").is_err());
    }
}
