//! A 32-sample shadow mask through the library API: Vulkan when a device
//! opens, the CPU twin otherwise; prints the mean lit fraction and writes
//! the masks and lit fraction as EXR.
//!
//! `cargo run --release --example render_mask -- [SCENE] [OUT.exr]`

use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings};
use izb::gpu::{GBufferSource, GpuOptions, GpuRenderer};
use izb::output::write_exr_with_masks;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let scene_arg = args.next().unwrap_or_else(|| "default".into());
    let out = args.next().unwrap_or_else(|| "out/example_mask.exr".into());
    let scene = izb::scene::load(&scene_arg)?.with_resolution([480, 270])?;
    let settings = IzbSettings::default(); // 32 spp, edge LUT

    let (masks, visibility, backend) = match GpuRenderer::new(&GpuOptions::from_env()) {
        Ok(gpu) => {
            let r = gpu.render(&scene, settings, GBufferSource::Gpu)?;
            (r.masks, r.visibility, gpu.context.info().name.clone())
        }
        Err(e) => {
            eprintln!("no GPU ({e}); rendering on the CPU");
            let r = render_cpu(&scene, &SceneBvh::build(&scene), settings);
            (r.masks, r.visibility, "cpu".to_string())
        }
    };
    let [w, h] = scene.resolution;
    write_exr_with_masks(
        out.as_ref(),
        w,
        h,
        &[("visibility", &visibility)],
        &[("mask", &masks)],
    )?;
    let lit: Vec<f32> = visibility.into_iter().filter(|v| !v.is_nan()).collect();
    println!(
        "{} on {backend}: {} shadow-tested pixels, mean lit fraction {:.4} -> {out}",
        scene.name,
        lit.len(),
        lit.iter().sum::<f32>() / lit.len().max(1) as f32
    );
    Ok(())
}
