//! An area light's penumbrae in the bin (paper-notes/soft-shadows.md): how
//! far beyond its light-space projection a triangle may hide part of the
//! light, frame-wide ([`penumbra_pad`]) and per cell from the cell's own
//! receivers ([`penumbra_reaches_cell`]). Both are conservative bounds: the
//! brute-force test in `tests/soft_shadows.rs` holds the grid complete.

use super::footprint::{Footprint, CELL_PADDING};
use super::light_setup::{level_scale, CascadeGrid, LightSetup, Projection};
use super::receivers::{cull_box, CellReceivers};
use glam::{Vec2, Vec3};

/// Relative margin on a penumbra pad (2⁻¹⁰): ~10⁴ times the `f32`
/// rounding of the few operations that form it.
const PENUMBRA_MARGIN: f32 = izb_contract::tolerance::PENUMBRA_MARGIN;

/// Largest tan φ · tan θ a point light's pad accepts (φ the widest
/// vertex angle from the light's axis, θ the penumbra's angle): beyond,
/// φ + θ nears 90° and the pad grows without bound; such a triangle
/// overflows instead.
const MAX_PENUMBRA_TAN_PRODUCT: f32 = izb_contract::tolerance::MAX_PENUMBRA_TAN_PRODUCT;

/// The penumbra triangle `tri` (light view, NDC `ndc`) may cast on any
/// receiver, in light NDC: how far beyond its own projection a receiver
/// it hides part of the light from can lie (0 for a point-like light);
/// `None` when it must go to the overflow list instead.
///
/// - Directional light of angular radius r (`light_radius` = tan r): a
///   ray toward a light sample climbs 1 in z per at most tan r sideways,
///   so an occluding point at height z_Q hides light from receivers
///   within tan r · (z_Q − z_P) of it; z_Q ≤ the triangle's top vertex,
///   z_P ≥ the lowest receiver ([`LightSetup::receiver_z`]).
/// - Point light of radius R: an occluding point Q on the segment from P
///   to a light sample lies at depth z ≥ z_min (the triangle's nearest
///   vertex), which bounds the angle at the light between Q and P by
///   tan θ ≤ R / (z_min − 2R) (paper-notes/soft-shadows.md derives it);
///   seen from the light a cone of half-angle θ around a direction at
///   tan φ = ρ from the axis spans at most tan(φ + θ) − tan φ =
///   tan θ (1 + ρ²) / (1 − ρ tan θ) in NDC, largest at the triangle's
///   widest vertex. Triangles within 2R of the light overflow.
pub fn penumbra_pad(setup: &LightSetup, tri: &[Vec3; 3], ndc: &[Vec2; 3]) -> Option<f32> {
    let r = setup.light_radius;
    if r == 0.0 {
        return Some(0.0);
    }
    let grow = 1.0 + PENUMBRA_MARGIN;
    match setup.projection {
        Projection::Orthographic => {
            let top = tri[0].z.max(tri[1].z).max(tri[2].z);
            Some(r * (top - setup.receiver_z[0]).max(0.0) * grow)
        }
        Projection::Perspective => {
            let z_min = tri[0].z.min(tri[1].z).min(tri[2].z);
            let clearance = z_min - 2.0 * r * grow;
            // NaN or within 2R of the light: overflow.
            if clearance.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
                return None;
            }
            cone_ndc_pad(r / clearance * grow, ndc)
        }
    }
}

/// How far, in light NDC, directions within angle θ (`tan_theta`) of the
/// directions to a triangle with NDC vertices `ndc` reach beyond its
/// projection: tan θ (1 + ρ²) / (1 − ρ tan θ) at the widest vertex
/// (tan φ = ρ), with [`PENUMBRA_MARGIN`]; `None` (overflow) when
/// ρ tan θ exceeds [`MAX_PENUMBRA_TAN_PRODUCT`] or is NaN.
fn cone_ndc_pad(tan_theta: f32, ndc: &[Vec2; 3]) -> Option<f32> {
    let grow = 1.0 + PENUMBRA_MARGIN;
    let rho = ndc[0].length().max(ndc[1].length()).max(ndc[2].length()) * grow;
    let product = rho * tan_theta;
    if product.is_nan() || product > MAX_PENUMBRA_TAN_PRODUCT {
        return None;
    }
    Some(tan_theta * (1.0 + rho * rho) / (1.0 - product) * grow)
}

/// A light-NDC distance `pad` in level-0 cells of `grid`, along x and y.
pub fn ndc_pad_in_cells(grid: &CascadeGrid, pad: f32) -> Vec2 {
    let cells = Vec2::new(grid.cells[0] as f32, grid.cells[1] as f32);
    pad * cells / (grid.ndc_max - grid.ndc_min)
}

/// The per-cell bound on a directional area light's penumbra (with the
/// `behind_receivers` skip, whose per-cell receiver depths it uses):
/// whether triangle `tri` (light view, footprint `f` padded for the
/// lowest receiver of the frame) may hide light from a receiver that
/// tests cell `c` = (`x`, `y`). Such a receiver's P lies within the cell
/// grown by the cell's reach, no lower than the cell's lowest receiver,
/// so the penumbra it can fall in is tan r · (top − that depth) wide:
/// the cell must list the triangle only when the footprint grown by that
/// pad and the reach touches it. Every cell of a pixel's range keeps a
/// triangle the pixel needs (it is registered in all of them), so the
/// entries' neighbour bits, computed from the frame-wide footprint,
/// still name one cell per pixel (`bin::CellEntry`).
///
/// Sphere light of radius R: with the receivers of the cell no farther
/// from the light than D (their largest depth along the axis, times
/// √(1 + ρ²) for the widest NDC radius ρ of the grown cell), the bound of
/// [`penumbra_pad`] before D → ∞, tan θ ≤ R(D − z)/(z(D + R) − 2DR) (z
/// the triangle's nearest depth; increasing in D), spans the same NDC
/// pad formula; a triangle no nearer than D hides nothing there.
#[allow(clippy::too_many_arguments)]
pub fn penumbra_reaches_cell(
    setup: &LightSetup,
    grid: &CascadeGrid,
    receivers: &CellReceivers,
    f: &Footprint,
    tri: &[Vec3; 3],
    c: usize,
    x: u32,
    y: u32,
) -> bool {
    if setup.light_radius == 0.0 {
        return true;
    }
    let reach = receivers.reach[c] as f32;
    let pad = match setup.projection {
        Projection::Orthographic => {
            let top = tri[0].z.max(tri[1].z).max(tri[2].z);
            setup.light_radius * (top - receivers.z_min[c]).max(0.0) * (1.0 + PENUMBRA_MARGIN)
        }
        Projection::Perspective => {
            let Some(pad) = sphere_pad_in_cell(setup, grid, receivers, tri, f.level, c, x, y)
            else {
                return true;
            };
            pad
        }
    };
    let pad = ndc_pad_in_cells(grid, pad) * level_scale(f.level);
    f.touches_grown(i64::from(x), i64::from(y), pad + reach + CELL_PADDING)
}

/// The sphere light's NDC pad for the receivers of cell `c` = (`x`, `y`)
/// of level `level` ([`penumbra_reaches_cell`]), or `None` to keep the
/// frame-wide pad.
#[allow(clippy::too_many_arguments)]
fn sphere_pad_in_cell(
    setup: &LightSetup,
    grid: &CascadeGrid,
    receivers: &CellReceivers,
    tri: &[Vec3; 3],
    level: u32,
    c: usize,
    x: u32,
    y: u32,
) -> Option<f32> {
    let grow = 1.0 + PENUMBRA_MARGIN;
    let r = setup.light_radius;
    // The cell grown by its reach, in light NDC (unset for a cell without
    // receivers, whose infinite depth answers `None` below).
    let [lo, hi] = receivers.cull_box[c];
    debug_assert!(
        receivers.z_min[c] == f32::INFINITY
            || [lo, hi] == cull_box(grid, level, (x, y), receivers.reach[c])
    );
    let rho_cell = lo.abs().max(hi.abs()).length();
    let depth = -receivers.z_min[c];
    let far = depth * (1.0 + rho_cell * rho_cell).sqrt() * grow;
    let near = tri[0].z.min(tri[1].z).min(tri[2].z);
    if !(far.is_finite() && near > 2.0 * r * grow) {
        return None;
    }
    if far <= near {
        return Some(0.0); // every receiver nearer than the triangle
    }
    let denominator = near * (far + r) - 2.0 * far * r * grow;
    if denominator.is_nan() || denominator <= 0.0 {
        return None;
    }
    let tan_theta = r * (far - near) / denominator * grow;
    cone_ndc_pad(tan_theta, &tri.map(|v| Vec2::new(v.x / v.z, v.y / v.z)))
}
