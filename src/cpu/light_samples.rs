//! The soft-shadow part of `evaluate` (paper-notes/soft-shadows.md): the
//! light samples one triangle hides from a receiver point P, as the AND of
//! its edges' masks over the light's disk ([`crate::frustum::soft`]).
//! `evaluate` calls it in place of the µQuad test when the light has a
//! size; the grid, the candidate walk and the skips are the same.

use super::mask_rule::{and_of_edges, MaskRule, TestCounters};
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
    and_of_edges(rule, lines, line, counters)
}

/// The 32 rays of [`crate::settings::SampleMode::Paired32`] for one
/// pixel, relative to P: pair i starts at µQuad sample i, S_i = P + δ_i,
/// and goes toward light sample i (the disk point c_i from P): direction
/// d_i = c_i for a sun (at infinity), the offset c_i − δ_i to the point
/// for a sphere. Pairing the two patterns sample by sample makes the mask
/// estimate the light's visible fraction averaged over the pixel, as the
/// ground truth does, with each pattern's stratification in its own
/// dimensions (Cook et al. 1984's distributed ray tracing pairs pixel and
/// light samples the same way).
pub(super) struct PairedRays {
    delta: [Vec3; 32],
    c: [Vec3; 32],
    d: [Vec3; 32],
    /// δ_i × c_i: the edge plane through S_i is the one through P plus
    /// (t_{k+1} − t_k) × δ_i, so f = n·d_i + (t_{k+1} − t_k)·w_i.
    w: [Vec3; 32],
}

impl PairedRays {
    /// The rays of the pixel with µQuad axes `ex`, `ey` under `view`,
    /// pairing `pixel_pattern[i]` with `light_pattern[i]` (the operations
    /// and their order are the GPU's).
    pub(super) fn new(
        view: &LightView,
        ex: Vec3,
        ey: Vec3,
        pixel_pattern: &[[f32; 2]; 32],
        light_pattern: &[[f32; 2]; 32],
    ) -> PairedRays {
        let disk = &view.disk;
        let delta: [Vec3; 32] = std::array::from_fn(|i| {
            let s = pixel_pattern[i];
            ex * (s[0] - 0.5) + ey * (s[1] - 0.5)
        });
        let c: [Vec3; 32] = std::array::from_fn(|i| {
            let l = light_pattern[i];
            disk.centre + disk.axis_u * (l[0] - 0.5) + disk.axis_v * (l[1] - 0.5)
        });
        PairedRays {
            d: std::array::from_fn(|i| if view.finite { c[i] - delta[i] } else { c[i] }),
            w: std::array::from_fn(|i| delta[i].cross(c[i])),
            delta,
            c,
        }
    }

    /// The pairs whose ray leaves the receiver's tangent plane (normal
    /// `normal`) downward or along it: hidden by the receiver itself.
    pub(super) fn below_horizon(&self, normal: Vec3) -> u32 {
        (0..32).fold(0, |m, i| m | ((normal.dot(self.d[i]) <= 0.0) as u32) << i)
    }
}

/// The pairs whose ray triangle `t` (vertices minus P, above the tangent
/// plane by `height`) blocks, every ray evaluated: the cone from S_i
/// through the triangle has the orientation det(t − δ_i) = o − δ_i·m (o
/// the triple product at P, m the triangle's normal), and for a sphere
/// light the sample must lie beyond the triangle's plane seen from S_i
/// (m·(c_i − t₀) of that orientation's sign). The depth rule is the
/// unpaired one, at P.
pub(super) fn paired_occluded_samples(
    t: &[Vec3; 3],
    height: f32,
    microquad_part: f32,
    finite: bool,
    rays: &PairedRays,
    counters: &mut TestCounters,
) -> u32 {
    if !off_triangle_plane(t, height, microquad_part) {
        return 0;
    }
    counters.depth_passed += 1;
    let m = (t[1] - t[0]).cross(t[2] - t[0]);
    let o = cone_orientation(t);
    let n = [t[0].cross(t[1]), t[1].cross(t[2]), t[2].cross(t[0])];
    let e = [t[1] - t[0], t[2] - t[1], t[0] - t[2]];
    let mut mask = 0u32;
    for i in 0..32 {
        let oi = o - rays.delta[i].dot(m);
        // S_i on P's side of the triangle's plane: o_i has o's sign. A
        // sample beyond the plane lies, as far as the µQuad can tell,
        // inside the occluder's solid (the wall at a crease): the
        // triangle does not shadow it. (Zero or NaN: no cone.)
        if (oi * o).partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            continue;
        }
        let flip = oi < 0.0;
        let side = |f: f32| (if flip { -f } else { f }) >= 0.0;
        let (d, w) = (rays.d[i], rays.w[i]);
        let mut hit = (0..3).all(|k| side(n[k].dot(d) + e[k].dot(w)));
        if finite {
            hit &= side(m.dot(rays.c[i] - t[0]));
        }
        mask |= (hit as u32) << i;
    }
    counters.masks_nonempty += (mask != 0) as u64;
    mask
}
