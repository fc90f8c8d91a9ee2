//! The 32-sample IZB against supersampled ray-traced ground truth through
//! the library API: MAE overall, on smooth penumbra pixels and on edge
//! pixels, next to the 1-sample IZB (paper-notes/reference-estimator.md).
//!
//! `cargo run --release --example compare_to_reference -- [SCENE]`

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::metrics::metrics;
use izb::reference::{reference, ReferenceSettings};

fn main() -> anyhow::Result<()> {
    let scene_arg = std::env::args().nth(1).unwrap_or_else(|| "default".into());
    let scene = izb::scene::load(&scene_arg)?.with_resolution([320, 180])?;
    let bvh = SceneBvh::build(&scene);
    let settings = ReferenceSettings::from_spp(256, 1).map_err(anyhow::Error::msg)?;
    let truth = reference(&scene, &bvh, settings, &|_| {});
    println!("{}: 256-spp ground truth", scene.name);
    for mode in [SampleMode::Lut32, SampleMode::One] {
        let render = render_cpu(
            &scene,
            &bvh,
            IzbSettings {
                mode,
                ..Default::default()
            },
        );
        let m = metrics(&render.visibility, &truth.visibility, &truth.smooth);
        println!(
            "{mode:?}: MAE {:.5}, smooth-penumbra MAE {:.5} ({} px), edge MAE {:.5} ({} px)",
            m.mae, m.smooth_penumbra_mae, m.smooth_penumbra_pixels, m.edge_mae, m.edge_pixels
        );
    }
    Ok(())
}
