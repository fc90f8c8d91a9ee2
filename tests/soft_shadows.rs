//! Soft shadows from area lights on the CPU (paper-notes/soft-shadows.md):
//! the penumbra-padded grid against brute force, and the exact soft mode
//! against `rt-soft` (the same 32 light samples traced in `f64`, from P or,
//! paired, from the µQuad's samples), sample by sample, on procedural scenes under suns of three sizes and on the
//! point-lit engine under a sphere light.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::bin::{bin, CullAgainst};
use izb::cpu::evaluate::{for_each_candidate, triangle_mask_for_pixel};
use izb::cpu::{
    eye_relative_f32, light_setup, render_cpu, CascadeCount, GridRequest, IzbSettings, MaskRule,
    ReceiverCull, SampleMode, Skips,
};
use izb::gbuffer::{flags, gbuffer, pixel_surface};
use izb::reference::same_samples::FLOAT_DECISION_TOLERANCE;
use izb::reference::soft_samples::{soft_decision_margin, soft_same_sample_masks};
use izb::scene::{self, Scene};
use std::collections::HashSet;

/// Every triangle that hides a light sample from a pixel is among the
/// candidates the grid offers it: (pixels, occluder/pixel pairs).
fn check_soft_grid(
    scene: &Scene,
    cells: Option<u32>,
    level_cells: u32,
    stride: usize,
    cull: bool,
) -> (usize, usize) {
    let bvh = SceneBvh::build(scene);
    let g = gbuffer(scene, &bvh);
    let request = GridRequest {
        cells,
        level_cells: Some(level_cells),
        cascades: CascadeCount::Fixed(1),
        split_lambda: 1.0,
        simd: izb::cpu::simd::SimdPath::detected(),
    };
    let setup = light_setup(scene, &g, request);
    assert!(setup.light_radius > 0.0, "{}: no area light", scene.name);
    let triangles = eye_relative_f32(scene);
    let boxes = std::cell::OnceCell::new();
    let cull_against = CullAgainst {
        g: &g,
        boxes: &boxes,
        covered_only: false,
        when: ReceiverCull::Always,
    };
    let bins = bin(&setup, &triangles, Skips::ALL, cull.then_some(cull_against));
    let rule = MaskRule::for_light(SampleMode::Exact32, Skips::NONE, true);
    let (mut pixels, mut pairs) = (0, 0);
    for i in (0..g.flags.len()).step_by(stride) {
        if g.flags[i] & flags::SHADOW_TESTED == 0 {
            continue;
        }
        pixels += 1;
        let mut candidates = HashSet::new();
        for_each_candidate(&setup, &bins, &g, i, |id| {
            candidates.insert(id);
            false
        });
        for id in 0..scene.triangles.len() as u32 {
            let mask = triangle_mask_for_pixel(&setup, &triangles, &g, i, id, &rule);
            if mask != 0 {
                pairs += 1;
                assert!(
                    candidates.contains(&id),
                    "{}: pixel {i}: triangle {id} hides light samples {mask:#010x} but is not a \
                     candidate ({:?})",
                    scene.name,
                    bins.placement
                        .iter()
                        .map(|p| p[id as usize])
                        .collect::<Vec<_>>()
                );
            }
        }
    }
    (pixels, pairs)
}

#[test]
fn padded_grid_offers_every_occluder_of_a_light_sample() {
    let mut checked = 0;
    for (name, size) in [
        ("default", 3.0),
        ("wires", 1.0),
        ("grazing", 3.0),
        ("analytic", 3.0),
    ] {
        let scene = scene::load(name)
            .unwrap()
            .with_resolution([96, 54])
            .unwrap()
            .with_light_size(size)
            .unwrap();
        // A fine grid and a low level threshold: the pads span many cells
        // and several levels; with and without the per-cell bounds.
        for cull in [false, true] {
            let (pixels, pairs) = check_soft_grid(&scene, Some(40), 16, 3, cull);
            println!(
                "{name} (sun {size}°, per-cell bounds {cull}): {pixels} pixels, {pairs} \
                 occluder/pixel pairs, all offered"
            );
            assert!(pixels > 300 && pairs > 100, "{name}: too little exercised");
            checked += 1;
        }
    }
    let hairball = scene::procedural::hairball(3000);
    let scene = Scene::new(
        "hairball",
        hairball.triangles,
        hairball.camera,
        hairball.light,
        [96, 54],
    )
    .unwrap()
    .with_light_size(1.0)
    .unwrap();
    let (pixels, pairs) = check_soft_grid(&scene, Some(24), 16, 3, true);
    println!("hairball (sun 1°): {pixels} pixels, {pairs} occluder/pixel pairs, all offered");
    assert!(pixels > 300 && pairs > 100);
    checked += 1;
    if let Some(engine) = common::shared_scene("engine") {
        let scene = engine
            .with_resolution([96, 54])
            .unwrap()
            .with_light_size(20.0)
            .unwrap();
        let (pixels, pairs) = check_soft_grid(&scene, Some(32), 9, 1, true);
        println!("engine (sphere light r = 20): {pixels} pixels, {pairs} occluder/pixel pairs, all offered");
        assert!(pixels > 50 && pairs > 50);
        checked += 1;
    }
    assert!(checked >= 9, "only {checked} configurations checked");
}

const RESOLUTION: [u32; 2] = [160, 90];

/// (differing samples, compared samples) of exact soft mode against
/// `rt-soft` (both mask halves of `Paired64`, each against the same rays
/// traced), after checking every difference lies within float rounding
/// of a boundary.
fn check_exact_soft(scene: Scene, mode: SampleMode) -> (u64, u64) {
    let scene = scene.with_resolution(RESOLUTION).unwrap();
    let bvh = SceneBvh::build(&scene);
    let exact = render_cpu(
        &scene,
        &bvh,
        IzbSettings {
            mode,
            ..Default::default()
        },
    );
    assert_eq!(
        exact.masks_high.len(),
        if mode.halves() == 2 {
            exact.masks.len()
        } else {
            0
        },
        "{mode:?}: the second mask half"
    );
    let (mut diff, mut total) = (0, 0);
    for (half, masks) in [&exact.masks, &exact.masks_high].into_iter().enumerate() {
        if half < mode.halves() {
            let (d, t) = check_half(&scene, &bvh, &exact.gbuffer, masks, mode, half);
            diff += d;
            total += t;
        }
    }
    let partial = common::penumbra_pixels(&exact.masks, &exact.gbuffer);
    println!(
        "{} (light radius {:.4}, {mode:?}): {diff} of {total} light samples differ; \
         {partial} penumbra pixels",
        scene.name, scene.light_radius
    );
    assert!(total > 0, "{}: nothing shadow-tested", scene.name);
    (diff, total)
}

/// [`check_exact_soft`] for mask half `half` (`masks`): its rays traced.
fn check_half(
    scene: &Scene,
    bvh: &SceneBvh,
    g: &izb::gbuffer::GBuffer,
    masks: &[u32],
    mode: SampleMode,
    half: usize,
) -> (u64, u64) {
    let (pattern, pixel_pattern) = izb::lut::paired_patterns(half);
    let paired = mode.is_paired().then_some(pixel_pattern);
    let reference = soft_same_sample_masks(scene, bvh, pattern, paired);
    let tested = |i: usize| g.flags[i] & flags::SHADOW_TESTED != 0;
    let (diff, total) = izb::metrics::sample_mismatches(masks, &reference, tested);
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let triangles = scene.eye_relative_triangles();
    let mut worst = 0.0f64;
    for i in (0..reference.len()).filter(|&i| tested(i) && masks[i] != reference[i]) {
        let (x, y) = (i as u32 % RESOLUTION[0], i as u32 / RESOLUTION[0]);
        let px = pixel_surface(bvh, scene, &frame, x, y).unwrap();
        let differing = masks[i] ^ reference[i];
        for bit in (0..32).filter(|b| differing & (1 << b) != 0) {
            let margin = soft_decision_margin(
                &triangles,
                &px,
                &light,
                scene.light_radius,
                pattern[bit],
                paired.map(|p| p[bit]),
            );
            worst = worst.max(margin);
            assert!(
                margin < FLOAT_DECISION_TOLERANCE,
                "{}: pixel ({x}, {y}) half {half} light sample {bit}: IZB {} and rt-soft {} \
                 disagree with a decision margin {margin:.3e}",
                scene.name,
                masks[i] >> bit & 1,
                reference[i] >> bit & 1
            );
        }
    }
    println!("  half {half}: {diff} of {total} differ, worst margin {worst:.2e}");
    (diff, total)
}

#[test]
fn exact_soft_matches_rt_soft_on_procedural_scenes() {
    let (mut diff, mut total, mut cases) = (0, 0, 0);
    for name in scene::procedural::NAMES {
        for size in [0.25, 1.0, 3.0] {
            for mode in [
                SampleMode::Exact32,
                SampleMode::Paired32,
                SampleMode::Paired64,
            ] {
                let scene = scene::load(name).unwrap().with_light_size(size).unwrap();
                let (d, t) = check_exact_soft(scene, mode);
                diff += d;
                total += t;
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 9 * scene::procedural::NAMES.len());
    let rate = diff as f64 / total as f64;
    println!("all: {diff} of {total} light samples within rounding of a boundary ({rate:.2e})");
    assert!(rate < 1e-5, "{diff} of {total} samples differ ({rate:.2e})");
}

#[test]
fn exact_soft_matches_rt_soft_under_a_sphere_light() {
    let Some(engine) = common::shared_scene("engine") else {
        return;
    };
    for mode in [
        SampleMode::Exact32,
        SampleMode::Paired32,
        SampleMode::Paired64,
    ] {
        let scene = engine.clone().with_light_size(20.0).unwrap();
        let (diff, total) = check_exact_soft(scene, mode);
        assert!(
            diff as f64 / (total as f64) < 1e-5,
            "{diff} of {total} differ"
        );
    }
}
