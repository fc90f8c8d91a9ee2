//! The compute irregular z-buffer on the CPU (rayon): the CPU twin of the
//! GPU passes, one function per pass with the pass's name.
//!
//! 1. [`light_setup`](mod@light_setup): light-view frame, cascades ([`crate::cascades`]), one grid
//!    per cascade fitted to its pixels' µQuads;
//! 2. [`bin`](bin::bin): count, prefix sum, scatter into every cascade's
//!    grid; overflow; the conservative shadow map;
//! 3. [`evaluate`](evaluate::evaluate): frustum-triangle tests per pixel,
//!    OR of per-triangle masks, early exit when full;
//! 4. [`resolve`]: lit fraction from the mask.
//!
//! The G-buffer (pass 0) comes from [`crate::gbuffer`].

pub mod bin;
pub mod cell_vertices;
mod counting_sort;
pub mod empty_certificate;
pub mod evaluate;
pub mod evaluate_stats;
mod export_images;
pub mod footprint;
pub mod gather_draws;
pub mod light_samples;
pub mod light_setup;
pub mod lut_batch;
mod mask_rule;
pub mod penumbra;
mod placement;
pub mod receiver_cull;
pub mod receivers;
pub mod registration_lanes;
mod shadow_map_cover;
pub mod simd;
mod spare;
pub mod survivor_batch;
#[cfg(test)]
mod test_random;
pub mod translate_vertices;
pub mod triangle_lanes;

// The settings the CPU twins take, declared below both backends.
pub use crate::cascades::CascadeCount;
pub use crate::settings::{
    IzbSettings, PassSeconds, PassTimes, ReceiverCull, SampleMode, VertexCache,
};
pub use crate::skips::Skips;
pub use evaluate::{MaskRule, FULL};
pub use export_images::{export_images, ExportedImages};
pub use light_setup::{light_setup, GridRequest, LightSetup};

#[cfg(feature = "cli")]
use crate::bvh::SceneBvh;
use crate::gbuffer::edge_surfaces::{EdgeStats, EdgeSurfaces};
use crate::gbuffer::{flags, GBuffer, GBufferStats};
#[cfg(feature = "cli")]
use crate::gbuffer::{gbuffer, gbuffer_with};
use crate::scene::Scene;
use glam::Vec3;
use light_setup::ReceiverBoxes;
use rayon::prelude::*;
use std::time::Instant;

/// Whether `evaluate` tests a pixel with G-buffer `flags`: shadow-tested
/// pixels, and with the `facing_away` skip off also the hits that face away
/// from the light. The light view and grid are fitted to the shadow-tested
/// pixels either way: moving the light-view origin changes the f32
/// rounding of every test, and the skips must leave masks bit-identical.
pub fn is_receiver(pixel_flags: u32, skips: Skips) -> bool {
    pixel_flags & receiver_flags(skips) != 0
}

/// The G-buffer flags of which [`is_receiver`] asks for any: shadow-tested,
/// and with the `facing_away` skip off any hit.
pub fn receiver_flags(skips: Skips) -> u32 {
    flags::SHADOW_TESTED | if skips.facing_away { 0 } else { flags::HIT }
}

/// Settings, timings and counters of one render (`report.json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderReport {
    pub settings: IzbSettings,
    pub seconds: PassSeconds,
    pub gbuffer: GBufferStats,
    /// The edge pixels' surfaces, when the render placed samples on them.
    pub edge_surfaces: Option<EdgeStats>,
    /// `Paired64`'s second half's (its own µQuad pattern's sample rays).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub edge_surfaces_high: Option<EdgeStats>,
    pub light: LightSetup,
    pub bin: bin::BinStats,
    pub evaluate: evaluate::EvaluateStats,
    /// `evaluate` per tested pixel, and its seconds × threads per test.
    pub work_per_pixel: evaluate::WorkPerPixel,
    pub evaluate_ns_per_test_per_thread: f64,
    /// The other passes' time (light setup, bin, resolve) × threads per
    /// receiver (tested pixel or edge pixel's extra surface): the
    /// per-pixel floor outside evaluate, which its ns per test leaves out
    /// (issue 30).
    pub ns_per_receiver_outside_evaluate_per_thread: f64,
}

/// A rendered shadow mask.
pub struct ShadowRender {
    pub gbuffer: GBuffer,
    /// Occlusion mask per pixel: bit i set = sample i in shadow (0 where not
    /// shadow-tested).
    pub masks: Vec<u32>,
    /// Bits 32–63 of a 64-sample mask ([`SampleMode::Paired64`] under an
    /// area light), empty otherwise.
    pub masks_high: Vec<u32>,
    /// Lit fraction per pixel, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    pub report: RenderReport,
}

/// Pass 4: lit fraction = 1 − popcount / 32, NaN where not shadow-tested.
pub fn resolve(masks: &[u32], g: &GBuffer) -> Vec<f32> {
    resolve_halves(masks, &[], g)
}

/// [`resolve`] of 64-sample masks: bits 0–31 in `masks`, 32–63 in
/// `high` (1 − popcount / 64), or of 32-sample ones when `high` is empty.
/// With edge surfaces ([`GBuffer::edges`]) over the counted samples only:
/// 1 − popcount(mask) / popcount(counted).
pub fn resolve_halves(masks: &[u32], high: &[u32], g: &GBuffer) -> Vec<f32> {
    let halves = 1 + usize::from(!high.is_empty());
    // Each pixel's value is its own, so the threads change no bit
    // (single-threaded, 6–8 ms of `default`'s 1080p shadow pass).
    (0..masks.len())
        .into_par_iter()
        .with_min_len(4096)
        .map(|i| {
            if g.flags[i] & flags::SHADOW_TESTED == 0 {
                return f32::NAN;
            }
            let hidden = masks[i].count_ones() + high.get(i).map_or(0, |h| h.count_ones());
            let samples = g.counted_samples(i, halves);
            1.0 - hidden as f32 / samples as f32
        })
        .collect()
}

/// The lit fraction of masks over the samples `counted` marks per pixel:
/// 1 − popcount(mask) / popcount(counted), NaN where not shadow-tested
/// (the same-sample reference's masks with edge surfaces).
pub fn resolve_counted(masks: &[u32], counted: &[u32], g: &GBuffer) -> Vec<f32> {
    (0..masks.len())
        .map(|i| {
            if g.flags[i] & flags::SHADOW_TESTED == 0 {
                f32::NAN
            } else {
                1.0 - masks[i].count_ones() as f32 / counted[i].count_ones() as f32
            }
        })
        .collect()
}

/// Eye-relative `f32` triangles: the vertex buffer a GPU would receive.
pub fn eye_relative_f32(scene: &Scene) -> Vec<[glam::Vec3; 3]> {
    scene
        .eye_relative_triangles()
        .iter()
        .map(|t| t.map(|v| v.as_vec3()))
        .collect()
}

/// One mask half of every pixel under `rule`: the pixels' centre
/// surfaces, then the half's edge surfaces (`edges`, with their boxes) —
/// more receivers of the same bins — combined into the pixels' masks.
fn evaluate_half(
    (setup, bins, triangles): (&LightSetup, &bin::Bins, &[[Vec3; 3]]),
    g: &GBuffer,
    (edges, edge_boxes): (Option<&EdgeSurfaces>, Option<ReceiverBoxes<'_>>),
    boxes: ReceiverBoxes<'_>,
    rule: &MaskRule,
    stats: &mut evaluate::EvaluateStats,
) -> Vec<u32> {
    let centre_wanted = edges.map(|e| &e.centre_coverage[..]);
    let (mut masks, pass) =
        evaluate::evaluate_wanted(setup, bins, triangles, g, boxes, rule, centre_wanted);
    // The pixels count once, in the first half.
    match stats.pixels_tested {
        0 => stats.add(&pass),
        _ => stats.add_pass(&pass),
    }
    if let (Some(e), Some(b)) = (edges, edge_boxes) {
        let (extra, pass) = evaluate::evaluate_wanted(
            setup,
            bins,
            triangles,
            &e.surfaces,
            b,
            rule,
            Some(&e.coverage[..]),
        );
        stats.add_pass(&pass);
        stats.extra_surfaces_tested += pass.pixels_tested;
        e.combine(&mut masks, &extra);
    }
    masks
}

/// Renders the shadow mask of `scene` on the CPU.
#[cfg(feature = "cli")]
pub fn render_cpu(scene: &Scene, bvh: &SceneBvh, settings: IzbSettings) -> ShadowRender {
    let start = Instant::now();
    let g = gbuffer_with(scene, bvh, settings.edge_halves(scene));
    let gbuffer_seconds = start.elapsed().as_secs_f64();
    let mut render = render_cpu_on(scene, g, settings);
    render.report.seconds.gbuffer = gbuffer_seconds;
    render.report.seconds.total += gbuffer_seconds;
    render
}

/// Renders the shadow mask of `scene` on the CPU from a G-buffer made
/// elsewhere: a host's (`gbuffer_from_visibility`, `gbuffer_from_depth`)
/// or the GPU's, read back (`ShadowPass::read_back_gbuffer`), so the
/// twin's later passes run on exactly the entries the GPU's did.
pub fn render_cpu_on(scene: &Scene, g: GBuffer, settings: IzbSettings) -> ShadowRender {
    render_cpu_with(scene, g, &eye_relative_f32(scene), settings)
}

/// [`render_cpu_on`] with `triangles` (eye-relative `f32`) as the
/// occluders instead of the scene's: the host's draws as the shadow pass
/// gathered them ([`gather_draws`]), the scene giving the view and light.
pub fn render_cpu_with(
    scene: &Scene,
    g: GBuffer,
    triangles: &[[glam::Vec3; 3]],
    settings: IzbSettings,
) -> ShadowRender {
    let start = Instant::now();
    let soft = settings.light_samples(scene);
    let mut seconds = PassSeconds::default();
    let mut lap = {
        let mut t = Instant::now();
        move || {
            let s = t.elapsed().as_secs_f64();
            t = Instant::now();
            s
        }
    };
    let request = GridRequest::from(&settings);
    let setup = light_setup::light_setup_for(scene, &g, request, triangles.len());
    seconds.light_setup = lap();
    // With edge surfaces every bit is one of the pixel's own samples (a
    // µQuad sample's line toward the light, or a paired ray), so a
    // surface's mask is full once its own samples are set; under a
    // point-like light a surface needs only the part of its µQuad its
    // samples span.
    let covered_only = !soft;
    // The µQuad boxes: projected for the whole image by the bin where its
    // cull takes them, else band by band in evaluate.
    let stored_boxes = std::cell::OnceCell::new();
    let cull_behind = settings.skips.behind_receivers.then_some(bin::CullAgainst {
        g: &g,
        boxes: &stored_boxes,
        covered_only,
        when: settings.receiver_cull,
    });
    let mut bins = bin::bin(&setup, triangles, settings.skips, cull_behind);
    // The vertex cache serves the walk that batches its survivors: a
    // point-like light's.
    if !soft {
        bins.cache_vertices(triangles, settings.vertex_cache);
    }
    let boxes = match stored_boxes.get() {
        Some(stored) => ReceiverBoxes::Stored(stored),
        None => ReceiverBoxes::PerBand { covered_only },
    };
    seconds.bin = lap();
    let rule = MaskRule {
        simd: settings.simd.or_supported(),
        ..MaskRule::for_light(settings.mode, settings.skips, soft)
    };
    let mut eval_stats = evaluate::EvaluateStats::default();
    let masks = evaluate_half(
        (&setup, &bins, triangles),
        &g,
        (g.edges.as_deref(), boxes.layer(|b| b.edges.as_deref())),
        boxes,
        &rule,
        &mut eval_stats,
    );
    // Paired64: the second half, the same passes with the turned patterns
    // (and that half's own edge surfaces).
    let masks_high = if settings.mask_halves(scene) == 2 {
        evaluate_half(
            (&setup, &bins, triangles),
            &g,
            (
                g.edges_high.as_deref(),
                boxes.layer(|b| b.edges_high.as_deref()),
            ),
            boxes,
            &rule.half(1),
            &mut eval_stats,
        )
    } else {
        Vec::new()
    };
    seconds.evaluate = lap();
    let visibility = resolve_halves(&masks, &masks_high, &g);
    seconds.resolve = lap();
    seconds.total = start.elapsed().as_secs_f64();
    let evaluate_ns_per_test_per_thread =
        seconds.evaluate * rayon::current_num_threads() as f64 * 1e9
            / eval_stats.tests_spawned.max(1) as f64;
    let receivers = eval_stats.pixels_tested + eval_stats.extra_surfaces_tested;
    let ns_per_receiver_outside_evaluate_per_thread =
        (seconds.light_setup + seconds.bin + seconds.resolve)
            * rayon::current_num_threads() as f64
            * 1e9
            / receivers.max(1) as f64;
    ShadowRender {
        report: RenderReport {
            settings,
            seconds,
            gbuffer: g.stats.clone(),
            edge_surfaces: g.edges.as_ref().map(|e| e.stats.clone()),
            edge_surfaces_high: g.edges_high.as_ref().map(|e| e.stats.clone()),
            light: setup,
            bin: std::mem::take(&mut bins.stats),
            work_per_pixel: eval_stats.per_pixel(),
            evaluate_ns_per_test_per_thread,
            ns_per_receiver_outside_evaluate_per_thread,
            evaluate: eval_stats,
        },
        gbuffer: g,
        masks,
        masks_high,
        visibility,
    }
}

/// Candidates per pixel: how many triangles `evaluate` would visit for
/// each shadow-tested pixel (every cell list under its µQuad and the
/// overflow list, no early exit), 0 elsewhere. The heat map of the
/// viewer (`izb view`): where the grid concentrates its work.
#[cfg(feature = "cli")]
pub fn candidate_counts(scene: &Scene, bvh: &SceneBvh, settings: IzbSettings) -> Vec<u32> {
    let g = gbuffer(scene, bvh);
    let setup = light_setup(scene, &g, GridRequest::from(&settings));
    let triangles = eye_relative_f32(scene);
    let boxes = std::cell::OnceCell::new();
    let cull_behind = settings.skips.behind_receivers.then_some(bin::CullAgainst {
        g: &g,
        boxes: &boxes,
        covered_only: false,
        when: settings.receiver_cull,
    });
    let bins = bin::bin(&setup, &triangles, settings.skips, cull_behind);
    (0..g.flags.len())
        .into_par_iter()
        .map(|i| {
            if g.flags[i] & flags::SHADOW_TESTED == 0 {
                return 0;
            }
            let mut n = 0u32;
            evaluate::for_each_candidate(&setup, &bins, &g, i, |_| {
                n += 1;
                false
            });
            n
        })
        .collect()
}
