//! The CPU IZB against the same-sample reference, sample by sample, on
//! every procedural scene and every shared scene (reduced resolution).
//!
//! `--exact` evaluates the same rule the reference traces (design §4), so
//! they may differ only where a sample lies within float rounding of a
//! shadow boundary (the IZB runs in `f32`, the reference in `f64`).

use izb::gbuffer::flags;
use izb::izb::{render_cpu, IzbSettings, SampleMode};
use izb::reference::bvh::SceneBvh;
use izb::reference::same_samples::same_sample_masks;
use izb::scene::{self, Scene};

const RESOLUTION: [u32; 2] = [240, 135];

/// (mismatched samples, compared samples) of `mode` against the reference.
fn mismatches(scene: &Scene, mode: SampleMode) -> (u64, u64) {
    let bvh = SceneBvh::build(scene);
    let reference = same_sample_masks(scene, &bvh, izb::lut::sample_pattern());
    let render = render_cpu(
        scene,
        &bvh,
        IzbSettings {
            mode,
            ..Default::default()
        },
    );
    izb::metrics::sample_mismatches(&render.masks, &reference, |i| {
        render.gbuffer.flags[i] & flags::SHADOW_TESTED != 0
    })
}

fn check_exact(name: &str, scene: Scene) {
    let scene = scene.with_resolution(RESOLUTION).unwrap();
    let (diff, total) = mismatches(&scene, SampleMode::Exact32);
    let rate = diff as f64 / total.max(1) as f64;
    println!("{name}: exact 32 spp vs same-sample reference: {diff} of {total} samples differ ({rate:.2e})");
    assert!(total > 0, "{name}: nothing shadow-tested");
    assert!(
        rate < 1e-5,
        "{name}: {diff} of {total} samples differ ({rate:.2e})"
    );
}

#[test]
fn exact_matches_same_samples_on_procedural_scenes() {
    for name in scene::procedural::NAMES {
        check_exact(name, scene::load(name).unwrap());
    }
}

#[test]
fn exact_matches_same_samples_on_shared_scenes() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/scenes");
    if !std::path::Path::new(dir).exists() {
        eprintln!("skipped: ../shared/scenes not found");
        return;
    }
    for name in ["deckchair", "tablefan", "ficus", "engine", "courtyard"] {
        check_exact(
            name,
            scene::load(&format!("{dir}/{name}.scene.json")).unwrap(),
        );
    }
}
