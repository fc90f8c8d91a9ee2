//! Ray-traced ground truth (paper-notes/reference-estimator.md).
//!
//! Per pixel, `k × k` stratified jittered sub-pixel primary rays hit the real
//! geometry; each hit sends one shadow ray toward the light. The pixel's
//! value is lit hits / all hits: sub-rays that miss are ignored, hits on
//! surfaces facing away from the light count as shadowed, and pixels whose
//! *centre* is not shadow-tested are NaN (excluded from every metric).
//!
//! With an area light (`Scene::light_radius > 0`) each sub-pixel hit sends
//! [`LIGHT_SAMPLES_PER_RAY`] shadow rays instead, stratified over the
//! light's disk ([`crate::scene::LightDisk`]); the pixel's value is lit
//! samples / all samples. With `light_radius == 0` the hard path above runs
//! unchanged, bit for bit.
//!
//! Everything is `f64` and eye-relative; see [`crate::bvh`] for the ray caster and
//! [`crate::bvh::self_hit_offset`] for how shadow rays leave their surface.

pub mod analytic;
pub mod analytic_soft;
pub mod disk_area;
pub mod same_samples;
pub mod soft_samples;

use crate::bvh::{self_hit_offset, SceneBvh};
use crate::gbuffer::{faces_light, pixel_surface, trace_primary};
use crate::scene::{CameraFrame, Light, Scene};
use glam::{DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;
use std::time::Instant;

/// Side of the square tiles the image is split into for the thread pool.
const TILE: u32 = 16;

/// Light samples per sub-pixel hit under an area light: the unit square
/// cut into 2 × 2 strata, one jittered point each, mapped onto the disk by
/// the concentric map, so each sample is uniform over one quarter of the
/// disk (paper-notes/reference-estimator.md, "Area lights").
pub const LIGHT_SAMPLES_PER_RAY: u32 = 4;

/// Strata per side of the light samples' square (L = side²).
const LIGHT_STRATA_PER_SIDE: u32 = 2;

/// The area-preserving concentric map of Shirley and Chiu 1997 from the
/// unit square [0, 1)² onto the unit disk. Each quadrant of the square goes
/// to the matching quarter of the disk, and uniform density stays uniform,
/// so stratifying the square stratifies the disk.
pub fn concentric_disk(u: f64, v: f64) -> DVec2 {
    let (a, b) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    if a == 0.0 && b == 0.0 {
        return DVec2::ZERO;
    }
    let quarter = std::f64::consts::FRAC_PI_4;
    let (r, phi) = if a.abs() > b.abs() {
        (a, quarter * (b / a))
    } else {
        (b, 2.0 * quarter - quarter * (a / b))
    };
    DVec2::new(r * phi.cos(), r * phi.sin())
}

/// The most rays per pixel a reference takes: 256 × 256. A count far
/// beyond (a million per pixel at 1080p is 2·10¹² rays) would not fail,
/// it would run for days.
pub const MAX_SPP: u32 = 65_536;

/// What the ground truth is traced with.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct ReferenceSettings {
    /// k: the pixel is split into k × k strata, one jittered ray each.
    pub samples_per_side: u32,
    /// Seed of the jitter; the output is a pure function of it.
    pub seed: u64,
}

impl Default for ReferenceSettings {
    fn default() -> Self {
        ReferenceSettings {
            samples_per_side: 16,
            seed: 1,
        }
    }
}

impl ReferenceSettings {
    /// Settings for `spp` samples per pixel, which must be a perfect square
    /// no larger than [`MAX_SPP`].
    pub fn from_spp(spp: u32, seed: u64) -> Result<Self, String> {
        let k = (spp as f64).sqrt().round() as u32;
        if spp == 0 || k * k != spp {
            return Err(format!(
                "--spp {spp}: the reference stratifies the pixel into k×k cells, so spp must be a \
                 perfect square (e.g. 64, 256, 1024)"
            ));
        }
        if spp > MAX_SPP {
            return Err(format!(
                "--spp {spp}: at most {MAX_SPP} ({side}×{side}) rays per pixel are supported \
                 (the bench's ground truth uses 64 to 256)",
                side = (MAX_SPP as f64).sqrt()
            ));
        }
        Ok(ReferenceSettings {
            samples_per_side: k,
            seed,
        })
    }

    pub fn spp(&self) -> u32 {
        self.samples_per_side * self.samples_per_side
    }
}

/// Counters of one reference run.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ReferenceStats {
    pub pixels: usize,
    pub shadow_tested_pixels: usize,
    pub smooth_pixels: usize,
    pub primary_rays: u64,
    pub shadow_rays: u64,
    pub seconds: f64,
    /// (primary + shadow rays) / seconds.
    pub rays_per_second: f64,
}

/// The ground-truth image.
#[derive(Clone, Debug)]
pub struct ReferenceImage {
    pub width: u32,
    pub height: u32,
    /// Lit fraction per pixel, NaN where the centre is not shadow-tested.
    pub visibility: Vec<f32>,
    /// 1 where every sub-pixel hit lies on the centre hit's plane (a
    /// *smooth* pixel, paper-notes/reference-estimator.md), 0 otherwise, NaN where not shadow-tested.
    pub smooth: Vec<f32>,
    pub settings: ReferenceSettings,
    pub stats: ReferenceStats,
}

/// Per-pixel result of the estimator.
#[derive(Clone, Copy, Debug)]
struct PixelResult {
    visibility: f32,
    smooth: f32,
    primary_rays: u32,
    shadow_rays: u32,
}

const UNTESTED: PixelResult = PixelResult {
    visibility: f32::NAN,
    smooth: f32::NAN,
    primary_rays: 1,
    shadow_rays: 0,
};

/// Shared state of one run.
struct Tracer<'a> {
    scene: &'a Scene,
    bvh: &'a SceneBvh,
    frame: CameraFrame,
    light: Light,
    /// The light's size ([`Scene::light_radius`]); `None` for a hard light.
    light_radius: Option<f64>,
    settings: ReferenceSettings,
}

impl Tracer<'_> {
    /// Whether the surface point `p` (eye-relative, on triangle `triangle`,
    /// camera-facing normal `normal`) receives light.
    fn lit(&self, p: DVec3, normal: DVec3, triangle: u32) -> bool {
        if !faces_light(&self.light, p, normal) {
            return false;
        }
        let (toward, distance) = self.light.toward(p);
        !self
            .bvh
            .occluded(p, toward, self_hit_offset(p), distance, triangle)
    }

    /// Area light: how many of [`LIGHT_SAMPLES_PER_RAY`] stratified light
    /// samples reach the surface point `p`, and how many shadow rays that
    /// took. A sample below the tangent plane (normal · sample ≤ 0) is
    /// occluded by the receiver itself and costs no ray, so a surface that
    /// faces away from the light's centre still receives the part of the
    /// disk its tangent plane sees.
    fn lit_area(
        &self,
        p: DVec3,
        normal: DVec3,
        triangle: u32,
        light_radius: f64,
        rng: &mut Pcg32,
    ) -> (u32, u32) {
        let disk = self.light.disk_from(light_radius, p);
        let (mut lit, mut rays) = (0, 0);
        let side = LIGHT_STRATA_PER_SIDE;
        for stratum in 0..LIGHT_SAMPLES_PER_RAY {
            let u = ((stratum % side) as f64 + rng.random::<f64>()) / side as f64;
            let v = ((stratum / side) as f64 + rng.random::<f64>()) / side as f64;
            // The axes are orthonormal scaled to the diameter: half of each
            // takes the unit disk to the light's.
            let q = concentric_disk(u, v);
            let sample = disk.centre + 0.5 * q.x * disk.axis_u + 0.5 * q.y * disk.axis_v;
            if normal.dot(sample) <= 0.0 {
                continue;
            }
            rays += 1;
            let (toward, distance) = match self.light {
                Light::Directional { .. } => (sample.normalize(), f64::INFINITY),
                Light::Point { .. } => {
                    let len = sample.length();
                    (sample / len, len)
                }
            };
            lit += !self
                .bvh
                .occluded(p, toward, self_hit_offset(p), distance, triangle)
                as u32;
        }
        (lit, rays)
    }

    /// What one surface hit contributes: (lit samples, samples, shadow
    /// rays) — one shadow ray toward a point-like light, or
    /// [`LIGHT_SAMPLES_PER_RAY`] samples of an area light
    /// ([`Tracer::lit_area`], drawing from `rng`).
    fn hit_samples(
        &self,
        p: DVec3,
        normal: DVec3,
        triangle: u32,
        rng: &mut Pcg32,
    ) -> (u32, u32, u32) {
        match self.light_radius {
            None => (self.lit(p, normal, triangle) as u32, 1, 1),
            Some(light_radius) => {
                let (lit, rays) = self.lit_area(p, normal, triangle, light_radius, rng);
                (lit, LIGHT_SAMPLES_PER_RAY, rays)
            }
        }
    }

    fn pixel(&self, x: u32, y: u32) -> PixelResult {
        let Some(centre) = pixel_surface(self.bvh, self.scene, &self.frame, x, y) else {
            return UNTESTED;
        };
        if !centre.shadow_tested {
            return UNTESTED;
        }
        // A sub-pixel hit is on the centre's plane when its distance to the
        // plane is below 1e-3 of the µQuad: coplanar neighbours (~1e-12) pass,
        // any other surface in the footprint (~the footprint) fails.
        let plane_tolerance = 1e-3 * centre.axis_x.length().max(centre.axis_y.length());
        let k = self.settings.samples_per_side;
        let pixel_index = y as u64 * self.frame.width as u64 + x as u64;
        let mut rng = Pcg32::seed_from_u64(
            self.settings.seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ pixel_index,
        );
        let (mut samples, mut lit, mut shadow_rays) = (0u32, 0u32, 0u32);
        let mut smooth = true;
        let (near, far) = (self.scene.camera.near, self.scene.camera.far);
        for j in 0..k {
            for i in 0..k {
                let u = (i as f64 + rng.random::<f64>()) / k as f64;
                let v = (j as f64 + rng.random::<f64>()) / k as f64;
                let sub =
                    trace_primary(self.bvh, &self.frame, near, far, x as f64 + u, y as f64 + v);
                let Some(sub) = sub else {
                    smooth = false;
                    continue;
                };
                smooth &= centre
                    .hit
                    .normal
                    .dot(sub.position - centre.hit.position)
                    .abs()
                    <= plane_tolerance;
                let (l, n, rays) =
                    self.hit_samples(sub.position, sub.normal, sub.triangle, &mut rng);
                lit += l;
                samples += n;
                shadow_rays += rays;
            }
        }
        if samples == 0 {
            // Every sub-ray slipped past a sub-pixel sliver the centre ray
            // hit: fall back to the centre's own samples.
            let hit = centre.hit;
            let (l, n, rays) = self.hit_samples(hit.position, hit.normal, hit.triangle, &mut rng);
            (lit, samples) = (l, n);
            shadow_rays += rays;
        }
        PixelResult {
            visibility: lit as f32 / samples as f32,
            smooth: smooth as u32 as f32,
            primary_rays: 1 + k * k,
            shadow_rays,
        }
    }
}

/// Traces the ground truth of `scene`. `on_tile(pixels)` is called after
/// each finished tile (for a progress bar).
pub fn reference(
    scene: &Scene,
    bvh: &SceneBvh,
    settings: ReferenceSettings,
    on_tile: &(dyn Fn(u64) + Sync),
) -> ReferenceImage {
    let start = Instant::now();
    let [w, h] = scene.resolution;
    let tracer = Tracer {
        scene,
        bvh,
        frame: scene.camera.frame(scene.resolution),
        light: scene.light.relative_to(scene.camera.eye),
        light_radius: scene.has_area_light().then_some(scene.light_radius),
        settings,
    };
    let tiles: Vec<(u32, u32)> = (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..w.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect();
    let results: Vec<Vec<(u32, u32, PixelResult)>> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            let mut out = Vec::with_capacity((TILE * TILE) as usize);
            for y in y0..(y0 + TILE).min(h) {
                for x in x0..(x0 + TILE).min(w) {
                    out.push((x, y, tracer.pixel(x, y)));
                }
            }
            on_tile(out.len() as u64);
            out
        })
        .collect();
    let n = scene.pixel_count();
    let mut visibility = vec![f32::NAN; n];
    let mut smooth = vec![f32::NAN; n];
    let mut stats = ReferenceStats {
        pixels: n,
        ..Default::default()
    };
    for (x, y, r) in results.into_iter().flatten() {
        let i = (y * w + x) as usize;
        visibility[i] = r.visibility;
        smooth[i] = r.smooth;
        stats.primary_rays += r.primary_rays as u64;
        stats.shadow_rays += r.shadow_rays as u64;
        if !r.visibility.is_nan() {
            stats.shadow_tested_pixels += 1;
            stats.smooth_pixels += (r.smooth == 1.0) as usize;
        }
    }
    stats.seconds = start.elapsed().as_secs_f64();
    stats.rays_per_second =
        (stats.primary_rays + stats.shadow_rays) as f64 / stats.seconds.max(1e-9);
    ReferenceImage {
        width: w,
        height: h,
        visibility,
        smooth,
        settings,
        stats,
    }
}
