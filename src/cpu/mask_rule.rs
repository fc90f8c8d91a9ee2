//! How `evaluate` forms a triangle's mask from its edges: the sample
//! mode, the pattern, the LUT and the skips ([`MaskRule`]), and the AND of
//! a triangle's edge masks with its counters ([`and_of_edges`]).

use super::evaluate::FULL;
use super::simd::SimdPath;
use super::{SampleMode, Skips};
use crate::frustum::{exact_edge_mask, normalised_edge, saturated_edge};

/// How `evaluate` forms masks: the mode, the sample pattern, the LUT, and
/// the skips that shape the work.
#[derive(Clone, Copy)]
pub struct MaskRule<'a> {
    pub mode: SampleMode,
    pub pattern: &'a [[f32; 2]; 32],
    /// Paired modes: the µQuad sample each of `pattern`'s light samples is
    /// paired with (sample i with sample i).
    pub pair_pattern: &'a [[f32; 2]; 32],
    pub lut: &'a izb_lut::EdgeLut,
    pub skips: Skips,
    /// [`crate::frustum::pattern_radius`] of `pattern`.
    pub radius: f32,
    /// The samples are the light's (an area light, [`Self::for_light`]),
    /// not the µQuad's.
    pub light_samples: bool,
    /// How far the LUT's edge masks may err, in µQuad sides
    /// ([`super::empty_certificate::certificate_reach`]).
    pub certificate_reach: f32,
    /// The instruction set of the batched tests
    /// ([`super::survivor_batch`]): masks and counters are the same on
    /// every path.
    pub simd: SimdPath,
}

impl<'a> MaskRule<'a> {
    /// The µQuad's 32 samples and their LUT.
    pub fn new(mode: SampleMode, skips: Skips) -> MaskRule<'static> {
        Self::for_light(mode, skips, false)
    }

    /// The light's 32 samples and their LUT (soft shadows), or the
    /// µQuad's for a point-like light ([`crate::lut::tables_for`]).
    pub fn for_light(mode: SampleMode, skips: Skips, soft: bool) -> MaskRule<'static> {
        let (lut, pattern) = crate::lut::tables_for(soft);
        MaskRule {
            mode,
            pattern,
            pair_pattern: crate::lut::sample_pattern(),
            lut,
            skips,
            radius: crate::frustum::pattern_radius(pattern),
            certificate_reach: super::empty_certificate::certificate_reach(lut),
            light_samples: soft,
            simd: SimdPath::detected(),
        }
    }

    /// The rule of mask half `half` of a paired mode under an area light
    /// ([`crate::lut::paired_patterns`]: half 0 the light and µQuad
    /// patterns, as [`Self::for_light`] has them; half 1 `Paired64`'s
    /// samples 32–63).
    pub fn half(self, half: usize) -> MaskRule<'a> {
        let (pattern, pair_pattern) = crate::lut::paired_patterns(half);
        MaskRule {
            pattern,
            pair_pattern,
            radius: crate::frustum::pattern_radius(pattern),
            ..self
        }
    }

    /// The samples edge `e` keeps inside (bit set = inside), and whether
    /// the cheap path decided them: the line keeps every sample on one
    /// side. For the LUT that is exactly its own saturation branch; for
    /// exact evaluation [`saturated_edge`]; one sample is always cheap.
    #[inline]
    pub(super) fn edge_mask(&self, e: [f32; 3]) -> (u32, bool) {
        let e = normalised_edge(e);
        match self.mode {
            SampleMode::One => (if e[0] >= 0.0 { FULL } else { 0 }, true),
            SampleMode::Lut32 => {
                let cell = self.lut.cell(e[0], e[1], e[2]);
                let cheap = matches!(cell, izb_lut::LutCell::Constant(_));
                (self.lut.cell_mask(cell), cheap)
            }
            SampleMode::Exact32 | SampleMode::Paired32 | SampleMode::Paired64 => {
                match saturated_edge(e, self.radius) {
                    Some(mask) => (mask, true),
                    None => (exact_edge_mask(e, self.pattern), false),
                }
            }
        }
    }
}

/// Counters one pixel's triangle tests add to.
#[derive(Default)]
pub(super) struct TestCounters {
    pub(super) tangent_passed: u64,
    pub(super) depth_passed: u64,
    pub(super) saturated_masks: u64,
    pub(super) masks_nonempty: u64,
    /// Survivor batches tested, their lanes holding a candidate and the
    /// lanes their kernels ran over.
    pub(super) survivor_batches: u64,
    pub(super) survivor_lanes: u64,
    pub(super) survivor_lanes_issued: u64,
}

/// The AND of the masks of `count` edges (`edge(k)`, k < `count`), with
/// the counters: with the `saturated_edges` skip it stops at the first
/// edge that leaves no sample and counts the triangles no LUT read or
/// sample loop was needed for. Shared by the µQuad and the light-sample
/// tests.
#[inline]
pub(super) fn and_of_edges(
    rule: &MaskRule,
    count: usize,
    edge: impl Fn(usize) -> [f32; 3],
    counters: &mut TestCounters,
) -> u32 {
    and_of_edge_masks(rule, count, |k| rule.edge_mask(edge(k)), counters)
}

/// [`and_of_edges`] of the edges' masks and whether each was cheap
/// (`edge_mask(k)`, [`MaskRule::edge_mask`]'s pair).
#[inline]
pub(super) fn and_of_edge_masks(
    rule: &MaskRule,
    count: usize,
    edge_mask: impl Fn(usize) -> (u32, bool),
    counters: &mut TestCounters,
) -> u32 {
    let saturate = rule.skips.saturated_edges;
    let mut mask = FULL;
    let mut all_cheap = true;
    for k in 0..count {
        let (m, cheap) = edge_mask(k);
        mask &= m;
        all_cheap &= cheap;
        if mask == 0 && saturate {
            break;
        }
    }
    if saturate {
        counters.saturated_masks += all_cheap as u64;
    }
    counters.masks_nonempty += (mask != 0) as u64;
    mask
}
