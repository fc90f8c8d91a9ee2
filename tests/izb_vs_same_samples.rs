//! The CPU IZB against the same-sample reference, sample by sample, on
//! every procedural scene and every shared scene (reduced resolution).
//!
//! `--exact` evaluates the rule the reference traces (paper-notes/frustum-test.md), so they
//! may differ only where a sample lies within float rounding of a shadow
//! boundary (the IZB runs in `f32`, the reference in `f64`): every
//! mismatch must have a decision margin below
//! `FLOAT_DECISION_TOLERANCE`, and such samples must stay below 1e-5 of all
//! samples. LUT mode is checked against `--exact` in `tests/lut_bound.rs`;
//! here its mismatch rate against the reference is reported.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::gbuffer::{flags, pixel_surface};
use izb::reference::same_samples::{decision_margin, same_sample_masks, FLOAT_DECISION_TOLERANCE};
use izb::scene::{self, Scene};

const RESOLUTION: [u32; 2] = [240, 135];

/// (mismatched samples, compared samples) for exact mode, after checking
/// that every mismatch lies within float rounding of a boundary.
fn check_exact(name: &str, scene: Scene) -> (u64, u64) {
    let scene = scene.with_resolution(RESOLUTION).unwrap();
    let bvh = SceneBvh::build(&scene);
    let pattern = izb::lut::sample_pattern();
    let reference = same_sample_masks(&scene, &bvh, pattern);
    let exact = render_cpu(
        &scene,
        &bvh,
        IzbSettings {
            mode: SampleMode::Exact32,
            ..Default::default()
        },
    );
    let lut = render_cpu(
        &scene,
        &bvh,
        IzbSettings {
            mode: SampleMode::Lut32,
            ..Default::default()
        },
    );
    let tested = |i: usize| exact.gbuffer.flags[i] & flags::SHADOW_TESTED != 0;
    let (diff, total) = izb::metrics::sample_mismatches(&exact.masks, &reference, tested);
    let (lut_diff, _) = izb::metrics::sample_mismatches(&lut.masks, &reference, tested);

    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let triangles = scene.eye_relative_triangles();
    let mut worst_margin = 0.0f64;
    for i in (0..reference.len()).filter(|&i| tested(i) && exact.masks[i] != reference[i]) {
        let (x, y) = (
            i as u32 % scene.resolution[0],
            i as u32 / scene.resolution[0],
        );
        let px = pixel_surface(&bvh, &scene, &frame, x, y).unwrap();
        let differing = exact.masks[i] ^ reference[i];
        for bit in (0..32).filter(|b| differing & (1 << b) != 0) {
            let margin = decision_margin(&triangles, &px, &light, pattern[bit]);
            worst_margin = worst_margin.max(margin);
            assert!(
                margin < FLOAT_DECISION_TOLERANCE,
                "{name}: pixel ({x}, {y}) sample {bit}: IZB and reference disagree with a decision margin \
                 {margin:.3e} (tolerance {FLOAT_DECISION_TOLERANCE:.3e})"
            );
        }
    }
    println!(
        "{name}: exact vs same-sample: {diff} of {total} samples differ ({:.2e}), worst margin {worst_margin:.2e}; \
         LUT vs same-sample: {lut_diff} ({:.2e})",
        diff as f64 / total as f64,
        lut_diff as f64 / total as f64
    );
    assert!(total > 0, "{name}: nothing shadow-tested");
    (diff, total)
}

#[test]
fn exact_matches_same_samples_on_procedural_scenes() {
    let (mut diff, mut total) = (0, 0);
    for name in scene::procedural::NAMES {
        let (d, t) = check_exact(name, scene::load(name).unwrap());
        diff += d;
        total += t;
    }
    common::assert_boundary_rate(diff, total);
}

#[test]
fn exact_matches_same_samples_on_shared_scenes() {
    let Some(dir) = common::shared_scenes_dir() else {
        return;
    };
    let dir = dir.display();
    let (mut diff, mut total) = (0, 0);
    for name in ["deckchair", "tablefan", "ficus", "engine", "courtyard"] {
        let (d, t) = check_exact(
            name,
            scene::load(&format!("{dir}/{name}.scene.json")).unwrap(),
        );
        diff += d;
        total += t;
    }
    common::assert_boundary_rate(diff, total);
}
