//! Ground truth for a scene through the library API: load, build the BVH,
//! trace 16×16 stratified rays per pixel, write the lit fraction as EXR.
//!
//! `cargo run --release --example reference_ground_truth -- [SCENE] [OUT.exr]`

use izb::bvh::SceneBvh;
use izb::output::write_exr;
use izb::reference::{reference, ReferenceSettings};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let scene_arg = args.next().unwrap_or_else(|| "default".into());
    let out = args
        .next()
        .unwrap_or_else(|| "out/example_reference.exr".into());

    let scene = izb::scene::load(&scene_arg)?.with_resolution([480, 270])?;
    let bvh = SceneBvh::build(&scene);
    let image = reference(&scene, &bvh, ReferenceSettings::default(), &|_| {});

    let [w, h] = scene.resolution;
    write_exr(
        out.as_ref(),
        w,
        h,
        &[("visibility", &image.visibility), ("smooth", &image.smooth)],
    )?;
    let tested: Vec<f32> = image
        .visibility
        .iter()
        .copied()
        .filter(|v| !v.is_nan())
        .collect();
    let mean = tested.iter().sum::<f32>() / tested.len().max(1) as f32;
    println!(
        "{}: {} shadow-tested pixels, mean lit fraction {mean:.3}, {:.1} Mrays/s -> {out}",
        scene.name,
        tested.len(),
        image.stats.rays_per_second / 1e6
    );
    Ok(())
}
