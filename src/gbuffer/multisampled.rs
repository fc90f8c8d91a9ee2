//! The G-buffer from a host's multisampled visibility buffer — per pixel
//! the ids its raster saw at N sample positions, not resolved — the CPU
//! twin of the shadow pass's `gbuffer_from_visibility.comp` built with
//! `MULTISAMPLED` and of `edge_surfaces.comp` built with
//! `CANDIDATE_HITS`.
//!
//! A raster's samples cannot trace rays, but they can *nominate*: the
//! triangles a pixel's samples saw are the only ones its centre ray and
//! its sample rays can see first, up to a triangle thinner than the sample
//! spacing. So:
//! - **The centre.** A standard N× pattern has no sample at the pixel
//!   centre, where every pass after the G-buffer puts P. Samples that
//!   agree on one triangle nominate it alone; where they disagree or some
//!   missed (a sliver between them, the far side of a quad's diagonal),
//!   or the centre ray misses their one triangle, the distinct ids of the
//!   3×3 pixels' samples do. The centre ray meets each with the watertight
//!   test (Woop et al. 2013) and keeps the closest hit, ties to the lower
//!   id (the GPU traversal's rule; the CPU BVH keeps its first); the entry
//!   then follows from that triangle's plane exactly as the
//!   single-sampled visibility buffer's ([`super::gbuffer_from_visibility`]).
//!   A centre no candidate covers is a miss, counted as
//!   `centre_uncovered`. A pixel with a sample id past the triangles is a
//!   rejected miss and nominates nothing for its neighbours. No sample
//!   position is assumed: the samples only nominate.
//! - **Edge pixels** (the ray cast's rule: a neighbour's centre off the
//!   plane): their 32 µQuad sample rays take the closest hit among the
//!   distinct ids of the 3×3 pixels' samples (at most 9N) in place of the
//!   BVH, then are grouped by plane as the ray cast's are.
//!
//! Where the candidates hold the triangle the BVH would find, both are the
//! ray cast's hits; they differ only where no raster sample of the 3×3
//! neighbourhood saw the triangle a ray meets first.

use super::edge_surfaces;
use super::visibility::surface_of;
use super::{facing_normal, GBuffer, PixelSurface, SurfaceHit, VisibilityGBuffer, NO_HIT};
use crate::scene::{Scene, Triangle, WatertightRay};
use glam::DVec3;
use rayon::prelude::*;

/// Samples a pixel may have: a multisampled visibility buffer of 2, 4 or
/// 8 samples.
pub const MAX_VISIBILITY_SAMPLES: usize = izb_contract::size::MAX_VISIBILITY_SAMPLES as usize;

/// The most candidates an edge pixel's sample rays test: its 3×3 pixels'
/// samples.
const MAX_CANDIDATES: usize = 9 * MAX_VISIBILITY_SAMPLES;

/// The G-buffer of `scene`'s view from the ids of a visibility buffer of
/// `samples` samples a pixel: `ids[i * samples + s]` is sample `s` of
/// pixel `i` (row-major), [`NO_HIT`] for none. `edge_halves` as
/// [`super::gbuffer_with`]'s: 0 for no edge surfaces, 1, or 2 for the
/// paired mode's second pattern. An error names a buffer of the wrong
/// size or an unsupported sample count.
pub fn gbuffer_from_multisampled_visibility(
    scene: &Scene,
    ids: &[u32],
    samples: usize,
    edge_halves: usize,
) -> Result<VisibilityGBuffer, String> {
    let triangles = scene.eye_relative_triangles();
    gbuffer_from_multisampled_visibility_on(scene, &triangles, ids, samples, edge_halves)
}

/// [`gbuffer_from_multisampled_visibility`] on eye-relative `triangles`
/// other than the scene's (a host's own vertices, as the pass gathered
/// them), which the ids index.
pub fn gbuffer_from_multisampled_visibility_on(
    scene: &Scene,
    triangles: &[Triangle],
    ids: &[u32],
    samples: usize,
    edge_halves: usize,
) -> Result<VisibilityGBuffer, String> {
    let [w, h] = scene.resolution;
    if !(2..=MAX_VISIBILITY_SAMPLES).contains(&samples) || !samples.is_power_of_two() {
        return Err(format!(
            "a multisampled visibility buffer of {samples} samples a pixel: 2, 4 or 8 are read"
        ));
    }
    if ids.len() != scene.pixel_count() * samples {
        return Err(format!(
            "the visibility buffer holds {} ids; the view is {w}x{h} at {samples} samples",
            ids.len()
        ));
    }
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let near_far = (scene.camera.near, scene.camera.far);
    let pixel_ids = |x: u32, y: u32| {
        let i = y as usize * w as usize + x as usize;
        &ids[i * samples..(i + 1) * samples]
    };
    let valid = |own: &[u32]| {
        own.iter()
            .all(|&id| id == NO_HIT || (id as usize) < triangles.len())
    };
    // The distinct ids of the samples of pixel (x, y) and its neighbours
    // inside the image; a pixel with an id past the triangles is rejected
    // and nominates nothing.
    let neighbourhood = |x: u32, y: u32| {
        let mut candidates = Candidates::default();
        for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
            for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                let own = pixel_ids(nx, ny);
                if valid(own) {
                    candidates.add_all(own);
                }
            }
        }
        candidates
    };
    // Per pixel: its surface, and whether it was rejected or uncovered.
    let centres: Vec<(Option<PixelSurface>, Outcome)> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| (0..w).map(move |x| (x, y)))
        .map(|(x, y)| {
            let own = pixel_ids(x, y);
            if !valid(own) {
                return (None, Outcome::Rejected);
            }
            let mut candidates = Candidates::default();
            candidates.add_all(own);
            if candidates.count == 0 {
                return (None, Outcome::Miss);
            }
            let d = frame.direction(x as f64 + 0.5, y as f64 + 0.5);
            // Samples that agree on one triangle nominate it alone; where
            // they disagree the centre may lie on a triangle none of them
            // saw (a sliver between them, the far side of a quad's
            // diagonal), which a neighbour's samples nominate; so does an
            // agreeing pixel whose centre ray misses its one triangle.
            let unanimous = candidates.count == 1 && !own.contains(&NO_HIT);
            let own_hit = unanimous
                .then(|| candidates.closest_hit(triangles, d, near_far))
                .flatten();
            let hit = own_hit.or_else(|| neighbourhood(x, y).closest_hit(triangles, d, near_far));
            let Some(hit) = hit else {
                return (None, Outcome::Uncovered);
            };
            match surface_of(triangles, &frame, &light, (x, y), hit.triangle) {
                Some(s) => (Some(s), Outcome::Surface),
                None => (None, Outcome::Rejected),
            }
        })
        .collect();
    let mut g = GBuffer::with_capacity(w, h);
    for (s, _) in &centres {
        g.push(s.as_ref());
    }
    let count = |o: Outcome| centres.iter().filter(|(_, c)| *c == o).count();
    let (rejected, uncovered) = (count(Outcome::Rejected), count(Outcome::Uncovered));
    let rows: Vec<Vec<Option<PixelSurface>>> = centres
        .chunks(w as usize)
        .map(|row| row.iter().map(|(s, _)| *s).collect())
        .collect();
    let from_candidates = |pattern: &[[f32; 2]; 32],
                           x: u32,
                           y: u32,
                           centre: &PixelSurface,
                           _: &[Option<SurfaceHit>]| {
        let candidates = neighbourhood(x, y);
        let points = edge_surfaces::sample_points(x, y, pattern);
        let hits = points
            .map(|(px, py)| candidates.closest_hit(triangles, frame.direction(px, py), near_far));
        edge_surfaces::group_sample_hits(&frame, &light, (x, y), centre, &hits, pattern)
    };
    edge_surfaces::add_edge_surfaces(&mut g, scene, &rows, edge_halves, from_candidates);
    Ok(VisibilityGBuffer {
        gbuffer: g,
        rejected,
        centre_uncovered: uncovered,
    })
}

/// What a pixel's centre became.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Surface,
    /// No sample saw a triangle.
    Miss,
    /// An id past the triangles, or a plane the centre ray does not cross
    /// in front of the eye.
    Rejected,
    /// Samples saw triangles, the centre ray meets none of them.
    Uncovered,
}

/// The distinct triangle ids some pixels' samples saw, in the order first
/// seen.
struct Candidates {
    ids: [u32; MAX_CANDIDATES],
    count: usize,
}

impl Default for Candidates {
    fn default() -> Self {
        Candidates {
            ids: [NO_HIT; MAX_CANDIDATES],
            count: 0,
        }
    }
}

impl Candidates {
    fn add_all(&mut self, ids: &[u32]) {
        for &id in ids {
            if id != NO_HIT && !self.ids[..self.count].contains(&id) && self.count < MAX_CANDIDATES
            {
                self.ids[self.count] = id;
                self.count += 1;
            }
        }
    }

    /// The closest hit of the eye ray along `d` among the candidates with
    /// view depth in (near, far), ties to the lower id (the GPU traversal's
    /// rule, whatever the order the ids were seen in).
    fn closest_hit(
        &self,
        triangles: &[Triangle],
        d: DVec3,
        (near, far): (f64, f64),
    ) -> Option<SurfaceHit> {
        let ray = WatertightRay::new(DVec3::ZERO, d);
        let mut best: Option<(f64, u32)> = None;
        for &id in &self.ids[..self.count] {
            let Some(t) = ray.intersect(&triangles[id as usize]) else {
                continue;
            };
            let better = best.is_none_or(|(bt, bid)| t < bt || (t == bt && id < bid));
            if t > near && t < far && better {
                best = Some((t, id));
            }
        }
        best.map(|(t, triangle)| SurfaceHit {
            triangle,
            t,
            position: d * t,
            normal: facing_normal(&triangles[triangle as usize], d),
        })
    }
}

// Every test here traces the scene (the `cli` feature's BVH).
#[cfg(all(test, feature = "cli"))]
mod tests {
    use super::*;

    /// Vulkan's standard 4× sample positions, in pixel units.
    const STANDARD_4X: [(f64, f64); 4] = [
        (0.375, 0.125),
        (0.875, 0.375),
        (0.125, 0.625),
        (0.625, 0.875),
    ];

    /// A raster's 4× ids as the CPU's own rays see them: the BVH's
    /// closest hit through each standard sample position.
    fn traced_samples(scene: &Scene, bvh: &crate::bvh::SceneBvh) -> Vec<u32> {
        let [w, h] = scene.resolution;
        let frame = scene.camera.frame(scene.resolution);
        let (near, far) = (scene.camera.near, scene.camera.far);
        let mut ids = Vec::with_capacity(scene.pixel_count() * 4);
        for y in 0..h {
            for x in 0..w {
                for (sx, sy) in STANDARD_4X {
                    let hit = crate::gbuffer::trace_primary(
                        bvh,
                        &frame,
                        near,
                        far,
                        x as f64 + sx,
                        y as f64 + sy,
                    );
                    ids.push(hit.map_or(NO_HIT, |h| h.triangle));
                }
            }
        }
        ids
    }

    /// The ray cast's own 4× sample ids give the ray cast's G-buffer and
    /// masks: each centre whose triangle one of its samples saw gets the
    /// ray cast's triangle and flags, and the exact masks — edge pixels
    /// included — equal the ray cast's on nearly every shadow-tested
    /// pixel (a ray can meet first a triangle no sample of its 3×3 pixels
    /// saw).
    #[test]
    fn the_ray_cast_s_sample_ids_give_the_ray_cast_s_masks() {
        use crate::cpu::{render_cpu_on, SampleMode};
        use crate::settings::IzbSettings;
        let mut checked = 0;
        // The least share of shadow-tested pixels whose masks equal the
        // ray cast's, per scene at 192×108 (measured: 99.72 %, 99.93 %,
        // 91.7 %; hairball's strands are thinner than the sample spacing).
        for (name, least) in [("default", 0.995), ("city", 0.998), ("hairball", 0.9)] {
            let scene = crate::scene::load(name)
                .unwrap()
                .with_resolution([192, 108])
                .unwrap();
            let bvh = crate::bvh::SceneBvh::build(&scene);
            let cast = crate::gbuffer::gbuffer_with(&scene, &bvh, 1);
            let ids = traced_samples(&scene, &bvh);
            let v = gbuffer_from_multisampled_visibility(&scene, &ids, 4, 1).unwrap();
            assert_eq!(v.rejected, 0, "{name}");
            let g = &v.gbuffer;
            let mut nominated = 0;
            for i in 0..scene.pixel_count() {
                let t = cast.triangle_id[i];
                if t != NO_HIT && ids[4 * i..4 * i + 4].contains(&t) {
                    assert_eq!(g.triangle_id[i], t, "{name} pixel {i}");
                    assert_eq!(g.flags[i], cast.flags[i], "{name} pixel {i}");
                    nominated += 1;
                }
            }
            let settings = IzbSettings {
                mode: SampleMode::Exact32,
                ..IzbSettings::default()
            };
            let a = render_cpu_on(&scene, cast.clone(), settings);
            let b = render_cpu_on(&scene, g.clone(), settings);
            let tested = (0..a.masks.len())
                .filter(|&i| cast.flags[i] & super::super::flags::SHADOW_TESTED != 0);
            let (mut same, mut all) = (0, 0);
            for i in tested {
                all += 1;
                same += usize::from(a.masks[i] == b.masks[i]);
            }
            let edges = g.edges.as_ref().unwrap().stats.edge_pixels;
            eprintln!(
                "{name}: {nominated} nominated centres, {same} of {all} masks equal, {} uncovered, \
                 {edges} edge pixels (the ray cast's: {})",
                v.centre_uncovered,
                cast.edges.as_ref().unwrap().stats.edge_pixels
            );
            assert!(edges > 0, "{name}: no edge pixel");
            let hits = cast.stats.hits;
            assert!(nominated * 10 > hits * 8, "{name}: {nominated} of {hits}");
            assert!(same as f64 >= least * all as f64, "{name}: {same} of {all}");
            checked += 1;
        }
        assert_eq!(checked, 3);
    }
}
