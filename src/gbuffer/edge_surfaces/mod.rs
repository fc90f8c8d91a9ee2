//! Edge pixels' per-sample surfaces: each of the 32 samples of a pixel
//! whose footprint covers more than one surface is tested on the surface
//! its own primary ray sees, not on the tangent plane through the pixel
//! centre (paper-notes/edge-surfaces.md).
//!
//! Wyman et al. 2015 (§5), like every shadow method that resolves one
//! shadow value per pixel, place all of a pixel's samples on the surface
//! seen through its centre. At a silhouette, a crease or between two
//! facets that are not coplanar, part of those samples then stands on a
//! plane the pixel does not show there (railing floating in front of the
//! wall it hides), and the ground truth — each sub-pixel ray shaded on
//! what it hits — disagrees. Keeping a few surfaces per pixel, each with a
//! coverage mask of the samples that see it, is the antialiased deferred
//! shading of Kerzner & Salvi 2014 (streaming G-buffer compression) and
//! Crassin et al. 2015 (aggregate G-buffers), applied to shadow masks.
//!
//! Per shadow-tested pixel:
//! 1. **Edge candidates.** The eight neighbours' centre hits are probes
//!    (already traced, so free): a pixel none of whose neighbours misses
//!    or leaves its centre's plane is smooth and costs nothing more.
//! 2. **Sample rays.** A candidate casts its 32 sample positions as primary
//!    rays, first against the triangles its probes and its centre hit —
//!    each a camera-space edge test, three dot products per sample (the
//!    homogeneous rasterisation of Olano & Greer 1997) — then through the
//!    BVH bounded by the nearest of those hits, so a nearer triangle no
//!    probe saw is still found: the hits are the BVH's closest hits. A
//!    sample hit on the centre's plane (within 10⁻³ of the µQuad, the
//!    reference's rule for a smooth pixel) belongs to the centre's
//!    surface; the rest are grouped by plane.
//! 3. **Surfaces.** At most [`MAX_SURFACES`] surfaces per pixel: the
//!    centre's, then the groups by sample count. Each extra surface gets
//!    its own µQuad: its plane's tangent frame at the centroid of its
//!    samples (always a point its own rays hit), re-expressed about the
//!    pixel centre so the µQuad coordinates, the LUT and the depth
//!    tolerance are those of every other µQuad. A surface facing away from
//!    the light shadows its samples, as the ground truth counts them.
//!    Samples that miss, and those of surfaces past the limit, do not
//!    count: the lit fraction is lit samples over counted samples.
//!
//! The same function serves the G-buffer ([`super::gbuffer_with`]) and
//! the same-sample reference, which therefore test the same samples on
//! the same surfaces.

use super::{GBuffer, PixelSurface, SurfaceHit};
use glam::DVec3;

mod grouping;
mod image;
// The sample rays trace the CPU BVH (obvhs): not part of the pass alone
// (`--no-default-features`).
#[cfg(feature = "cli")]
mod sample_rays;
pub use grouping::{group_sample_hits, sample_points};
pub use image::{add_edge_surfaces, edge_surfaces_of};
#[cfg(feature = "cli")]
pub use sample_rays::sample_surfaces;

/// Surfaces a pixel keeps, the centre's included (K of issue 27; K = 2
/// and 4 were measured, paper-notes/edge-surfaces.md).
pub const MAX_SURFACES: usize = izb_contract::size::EDGE_MAX_SURFACES as usize;

/// A sample hit lies on a surface's plane when its distance to the plane
/// is at most this fraction of the surface's µQuad: the reference's rule
/// for a smooth pixel (coplanar neighbours ~10⁻¹², any other surface in
/// the footprint ~1).
/// The GPU pass's is `EDGE_PLANE_TOLERANCE`, the same value in `f32`.
pub const PLANE_TOLERANCE: f64 = 1e-3;

/// A full 32-sample mask.
const FULL: u32 = u32::MAX;

/// One extra surface of an edge pixel.
#[derive(Clone, Copy, Debug)]
pub struct SampleSurface {
    /// Its µQuad, centred on the pixel centre's image point.
    pub surface: PixelSurface,
    /// The samples whose rays hit it.
    pub coverage: u32,
}

/// What a pixel's 32 sample rays see.
#[derive(Clone, Debug)]
pub struct PixelSamples {
    /// Samples on the centre's surface.
    pub centre_coverage: u32,
    /// Samples that count: those on a kept surface.
    pub counted: u32,
    /// Samples on a kept surface facing away from the light: shadowed.
    pub facing_away: u32,
    /// The extra surfaces that face the light, most samples first.
    pub extra: Vec<SampleSurface>,
    /// Samples on surfaces past [`MAX_SURFACES`] (not counted).
    pub dropped: u32,
    /// Samples whose ray missed everything (not counted).
    pub missed: u32,
    /// Sample rays no probed triangle answered: BVH queries without a bound.
    pub unbounded_rays: u32,
}

impl PixelSamples {
    /// A pixel whose samples all see the centre's surface.
    pub const SMOOTH: PixelSamples = PixelSamples {
        centre_coverage: FULL,
        counted: FULL,
        facing_away: 0,
        extra: Vec::new(),
        dropped: 0,
        missed: 0,
        unbounded_rays: 0,
    };

    /// Whether the pixel has samples off the centre's surface.
    pub fn is_edge(&self) -> bool {
        self.centre_coverage != FULL
    }
}

/// A plane and how far from it a hit may lie and still be on it:
/// [`PLANE_TOLERANCE`] of the µQuad of a surface on the plane.
struct Plane {
    point: DVec3,
    normal: DVec3,
    tolerance: f64,
}

impl Plane {
    /// The plane of the surface hit at `hit` whose µQuad axes are `ex`, `ey`.
    fn of(hit: &SurfaceHit, ex: DVec3, ey: DVec3) -> Plane {
        Plane {
            point: hit.position,
            normal: hit.normal,
            tolerance: PLANE_TOLERANCE * ex.length().max(ey.length()),
        }
    }

    #[inline]
    fn holds(&self, position: DVec3) -> bool {
        self.normal.dot(position - self.point).abs() <= self.tolerance
    }
}

/// Whether a shadow-tested pixel with centre surface `centre` is an edge
/// candidate: one of `probes` (its neighbours' centre hits,
/// [`neighbour_probes`]; `None` for a miss) misses or lies off the
/// centre's plane.
pub fn is_edge_candidate(centre: &PixelSurface, probes: &[Option<SurfaceHit>]) -> bool {
    let plane = Plane::of(&centre.hit, centre.axis_x, centre.axis_y);
    probes
        .iter()
        .any(|p| p.as_ref().is_none_or(|h| !plane.holds(h.position)))
}

/// The probes of pixel (`x`, `y`) of a `w × h` image: the centre hits of
/// its neighbours inside the image (each `None` for a miss, from
/// `hit_at`), and how many there are.
pub fn neighbour_probes(
    x: u32,
    y: u32,
    [w, h]: [u32; 2],
    hit_at: impl Fn(u32, u32) -> Option<SurfaceHit>,
) -> ([Option<SurfaceHit>; 8], usize) {
    let mut probes = [None; 8];
    let mut n = 0;
    for (dx, dy) in NEIGHBOURS {
        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
        if nx >= 0 && ny >= 0 && nx < w as i64 && ny < h as i64 {
            probes[n] = hit_at(nx as u32, ny as u32);
            n += 1;
        }
    }
    (probes, n)
}

/// Whether every neighbour of pixel (`x`, `y`) inside the `w × h` image
/// hits `triangle` (`triangle_at`: a pixel's centre triangle, `None` for
/// a miss): then every probe lies on the centre's plane (to rounding,
/// ~10⁻¹⁶ of the distance against the 10⁻³-of-a-µQuad tolerance) and the
/// pixel is no candidate, decided on ids alone — most pixels of an image
/// are, and copying their eight probes cost more than their sample rays.
pub fn neighbours_on_triangle(
    x: u32,
    y: u32,
    [w, h]: [u32; 2],
    triangle: u32,
    triangle_at: impl Fn(u32, u32) -> Option<u32>,
) -> bool {
    NEIGHBOURS.iter().all(|&(dx, dy)| {
        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
        let inside = nx >= 0 && ny >= 0 && nx < w as i64 && ny < h as i64;
        !inside || triangle_at(nx as u32, ny as u32) == Some(triangle)
    })
}

/// The eight neighbours' offsets.
const NEIGHBOURS: [(i64, i64); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Counts of the edge-surface step.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct EdgeStats {
    /// Shadow-tested pixels whose probes left the centre's plane.
    pub candidates: usize,
    /// Pixels with samples off the centre's surface.
    pub edge_pixels: usize,
    /// Extra surfaces facing the light (each an extra receiver).
    pub extra_surfaces: usize,
    /// Sample rays cast (32 per candidate), each a BVH query bounded by
    /// the nearest probed hit; and of those the ones no probed triangle
    /// answered (unbounded queries).
    pub sample_rays: u64,
    pub sample_rays_unbounded: u64,
    /// Samples on surfaces facing away from the light (shadowed).
    pub facing_away_samples: u64,
    /// Samples on surfaces past [`MAX_SURFACES`] (not counted).
    pub dropped_samples: u64,
    /// Samples whose rays missed (not counted).
    pub missed_samples: u64,
}

/// The edge pixels' extra surfaces of a G-buffer and each pixel's sample
/// coverage.
#[derive(Clone, Debug)]
pub struct EdgeSurfaces {
    /// The extra surfaces, one entry each, as a one-row G-buffer (whose
    /// own `edges` is `None`): every pass that reads receivers reads them
    /// as it reads pixels.
    pub surfaces: GBuffer,
    /// The pixel of each extra surface.
    pub pixel: Vec<u32>,
    /// The samples of its pixel each extra surface covers.
    pub coverage: Vec<u32>,
    /// Per pixel: samples on the centre's surface (all for a smooth pixel
    /// or one not shadow-tested).
    pub centre_coverage: Vec<u32>,
    /// Per pixel: the samples that count (on a kept surface).
    pub counted: Vec<u32>,
    /// Per pixel: samples on a surface facing away from the light.
    pub facing_away: Vec<u32>,
    pub stats: EdgeStats,
}

impl EdgeSurfaces {
    /// The per-pixel masks combined over a pixel's surfaces: the centre's
    /// mask on its own samples, each extra surface's on its samples, and
    /// every sample on a surface facing away. `masks` holds the centre
    /// surfaces' masks (per pixel), `extra` the extra surfaces' (per entry).
    pub fn combine(&self, masks: &mut [u32], extra: &[u32]) {
        for (i, m) in masks.iter_mut().enumerate() {
            *m = (*m & self.centre_coverage[i]) | self.facing_away[i];
        }
        for (k, &m) in extra.iter().enumerate() {
            masks[self.pixel[k] as usize] |= m & self.coverage[k];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_gpu_plane_tolerance_is_the_cpu_one() {
        assert_eq!(
            PLANE_TOLERANCE as f32,
            izb_contract::tolerance::EDGE_PLANE_TOLERANCE
        );
    }

    /// One pixel's masks: the centre's on its samples, each extra
    /// surface's on its own, the facing-away samples dark; bits outside
    /// the coverage ignored.
    #[test]
    fn combine_takes_each_surface_on_its_samples() {
        let edges = EdgeSurfaces {
            surfaces: GBuffer::with_capacity(2, 1),
            pixel: vec![1, 1],
            coverage: vec![0x0000_ff00, 0x00ff_0000],
            centre_coverage: vec![FULL, 0x0000_00ff],
            counted: vec![FULL, 0xffff_ffff],
            facing_away: vec![0, 0xff00_0000],
            stats: EdgeStats::default(),
        };
        let mut masks = vec![0x1234_5678, 0xffff_ff0f];
        edges.combine(&mut masks, &[0xffff_0f00, 0x00f0_0000]);
        assert_eq!(masks[0], 0x1234_5678, "a smooth pixel keeps its mask");
        assert_eq!(
            masks[1],
            0x0000_000f | 0x0000_0f00 | 0x00f0_0000 | 0xff00_0000
        );
    }
}
