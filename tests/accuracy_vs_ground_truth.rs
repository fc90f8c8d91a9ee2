//! 32 spp against 1 spp, both against the 256-spp ray-traced ground truth
//! (paper-notes/reference-estimator.md): on smooth penumbra pixels the 32-sample mask must be at
//! least 5× more accurate, and on edge pixels and overall no worse. The
//! full-resolution numbers are in the closing notes (`izb compare`); this
//! guards them at reduced resolution: 240×135 for the procedural scenes,
//! 480×270 for the shared ones (at 240×135 the engine's edge pixels each
//! span so much geometry that 32 spp and 1 spp tie on them, 0.058 vs 0.057;
//! at its own 960×540 the 32-sample edge MAE is 7% lower).

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::metrics::metrics;
use izb::reference::{reference, ReferenceSettings};
use izb::scene::{self, Scene};

const PROCEDURAL_RESOLUTION: [u32; 2] = [240, 135];
const SHARED_RESOLUTION: [u32; 2] = [480, 270];
/// Required smooth-penumbra MAE ratio 1 spp / 32 spp (calibration in
/// paper-notes/reference-estimator.md: 6–9× for an exact implementation).
const MIN_PENUMBRA_GAIN: f64 = 5.0;

fn check(name: &str, scene: Scene, resolution: [u32; 2]) {
    let scene = scene.with_resolution(resolution).unwrap();
    let bvh = SceneBvh::build(&scene);
    let truth = reference(
        &scene,
        &bvh,
        ReferenceSettings::from_spp(256, 1).unwrap(),
        &|_| {},
    );
    let run = |mode| {
        let r = render_cpu(
            &scene,
            &bvh,
            IzbSettings {
                mode,
                ..Default::default()
            },
        );
        metrics(&r.visibility, &truth.visibility, &truth.smooth)
    };
    let (m32, m1) = (run(SampleMode::Lut32), run(SampleMode::One));
    let gain = m1.smooth_penumbra_mae / m32.smooth_penumbra_mae;
    println!(
        "{name}: smooth penumbra ({} px) 32 spp {:.4} vs 1 spp {:.4} ({gain:.1}x); edge ({} px) {:.4} vs {:.4}; \
         overall {:.5} vs {:.5}",
        m32.smooth_penumbra_pixels,
        m32.smooth_penumbra_mae,
        m1.smooth_penumbra_mae,
        m32.edge_pixels,
        m32.edge_mae,
        m1.edge_mae,
        m32.mae,
        m1.mae
    );
    assert!(
        m32.smooth_penumbra_pixels > 50,
        "{name}: too few penumbra pixels to judge"
    );
    assert!(
        gain >= MIN_PENUMBRA_GAIN,
        "{name}: smooth-penumbra gain {gain:.2}x < {MIN_PENUMBRA_GAIN}x"
    );
    assert!(
        m32.edge_mae < m1.edge_mae,
        "{name}: edge MAE {} >= 1 spp's {}",
        m32.edge_mae,
        m1.edge_mae
    );
    assert!(
        m32.mae < m1.mae,
        "{name}: MAE {} >= 1 spp's {}",
        m32.mae,
        m1.mae
    );
}

#[test]
fn thirty_two_samples_beat_one_on_procedural_scenes() {
    for name in ["default", "city", "grazing", "hairball"] {
        check(name, scene::load(name).unwrap(), PROCEDURAL_RESOLUTION);
    }
}

#[test]
fn thirty_two_samples_beat_one_on_shared_scenes() {
    if common::shared_scenes_dir().is_none() {
        return;
    }
    for name in common::SHARED_SCENES {
        check(name, common::shared_scene(name).unwrap(), SHARED_RESOLUTION);
    }
}
