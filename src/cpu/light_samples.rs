//! The soft-shadow part of `evaluate` (paper-notes/soft-shadows.md): the
//! light samples one triangle hides from a receiver point P, as the AND of
//! its edges' masks over the light's disk ([`crate::frustum::soft`]).
//! `evaluate` calls it in place of the µQuad test when the light has a
//! size; the grid, the candidate walk and the skips are the same.

use super::evaluate::{MaskRule, TestCounters, FULL};
use crate::frustum::soft::{
    below_horizon_function, beyond_plane_function, cone_orientation, light_edge_function,
    off_triangle_plane,
};
use crate::scene::LightDisk;
use glam::Vec3;

/// What the soft test needs of one receiver.
#[derive(Clone, Copy)]
pub struct LightView {
    pub disk: LightDisk<Vec3>,
    /// A sphere light: its samples are points at a finite distance, so a
    /// fourth line (the triangle's own plane, [`beyond_plane_function`])
    /// keeps only those beyond the triangle.
    pub finite: bool,
}

/// The light samples the receiver itself hides (below its tangent plane,
/// normal `normal`): where a pixel's soft mask starts.
#[inline]
pub(super) fn below_horizon(normal: Vec3, view: &LightView, rule: &MaskRule) -> u32 {
    rule.edge_mask(below_horizon_function(normal, &view.disk)).0
}

/// The light samples triangle `t` (vertices minus P), already found above
/// the tangent plane by `height`, hides from P; 0 when it fails the rest
/// of the soft depth rule. With the `saturated_edges` skip an edge that
/// keeps no sample ends the test.
#[inline(never)]
pub(super) fn occluded_light_samples(
    t: &[Vec3; 3],
    height: f32,
    microquad_part: f32,
    view: &LightView,
    rule: &MaskRule,
    counters: &mut TestCounters,
) -> u32 {
    if !off_triangle_plane(t, height, microquad_part) {
        return 0;
    }
    counters.depth_passed += 1;
    let o = cone_orientation(t);
    if !(o != 0.0) {
        return 0; // P in the triangle's plane (or NaN): no cone
    }
    let flip = o < 0.0;
    let lines = if view.finite { 4 } else { 3 };
    let line = |k: usize| {
        if k < 3 {
            light_edge_function(t, k, &view.disk, flip)
        } else {
            beyond_plane_function(t, &view.disk)
        }
    };
    let mut mask = FULL;
    let mut all_cheap = true;
    for k in 0..lines {
        let (m, cheap) = rule.edge_mask(line(k));
        mask &= m;
        all_cheap &= cheap;
        if mask == 0 && rule.skips.saturated_edges {
            break;
        }
    }
    if rule.skips.saturated_edges {
        counters.saturated_masks += all_cheap as u64;
    }
    counters.masks_nonempty += (mask != 0) as u64;
    mask
}
