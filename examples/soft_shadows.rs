//! Soft shadows from an area light on the CPU twin
//! (paper-notes/soft-shadows.md): the `analytic` scene under a sun of a
//! given angular radius, the IZB's 32 light samples per pixel against
//! `rt-soft` (the same samples ray traced in `f64`) and against the
//! area-light ground truth, and the paired modes (each light sample from
//! its own point of the pixel; 32 pairs, or 64 in two mask words) against
//! the same truth.
//!
//! `cargo run --release --example soft_shadows -- [SUN_DEGREES]` (default 1)

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::gbuffer::flags;
use izb::reference::soft_samples::soft_same_sample_masks;
use izb::reference::{reference, ReferenceSettings};

fn main() -> anyhow::Result<()> {
    let degrees: f64 = match std::env::args().nth(1) {
        Some(a) => a.parse()?,
        None => 1.0,
    };
    let scene = izb::scene::load("analytic")?
        .with_resolution([320, 180])?
        .with_light_size(degrees)?;
    let bvh = SceneBvh::build(&scene);
    let izb = render_cpu(
        &scene,
        &bvh,
        IzbSettings {
            mode: SampleMode::Lut32,
            ..Default::default()
        },
    );
    let rt_soft = soft_same_sample_masks(&scene, &bvh, izb::lut::light_pattern(), None);
    let tested = |i: usize| izb.gbuffer.flags[i] & flags::SHADOW_TESTED != 0;
    let (differ, samples) = izb::metrics::sample_mismatches(&izb.masks, &rt_soft, tested);
    let truth = reference(
        &scene,
        &bvh,
        ReferenceSettings::from_spp(64, 1).unwrap(),
        &|_| {},
    );
    let m = izb::metrics::metrics(&izb.visibility, &truth.visibility, &truth.smooth);
    println!(
        "analytic under a {degrees}° sun, 320x180: IZB {:.1} ms ({:.1} tests per pixel); \
         {differ} of {samples} light samples differ from rt-soft (the LUT's bound); \
         MAE against the area-light truth {:.4} (smooth penumbra {:.4}, {} pixels)",
        izb.report.seconds.shadow() * 1e3,
        izb.report.work_per_pixel.tests,
        m.mae,
        m.smooth_penumbra_mae,
        m.smooth_penumbra_pixels
    );
    // Paired: each light sample from its own point of the pixel; 32
    // pairs, or 64 in two mask words.
    for mode in [SampleMode::Paired32, SampleMode::Paired64] {
        let paired = render_cpu(
            &scene,
            &bvh,
            IzbSettings {
                mode,
                ..Default::default()
            },
        );
        let m = izb::metrics::metrics(&paired.visibility, &truth.visibility, &truth.smooth);
        println!(
            "{mode:?}: {:.1} ms; MAE {:.4} (smooth penumbra {:.4})",
            paired.report.seconds.shadow() * 1e3,
            m.mae,
            m.smooth_penumbra_mae
        );
    }
    Ok(())
}
