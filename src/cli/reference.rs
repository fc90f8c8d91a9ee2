//! `izb reference` (the supersampled ground truth, or the 32 same samples
//! in `f64`) and `izb compare` (every IZB mode against it).

use super::{load_scene, progress_bar, thread_pool, trace_reference, SceneArgs};
use crate::bvh::SceneBvh;
use crate::cpu::{render_cpu, IzbSettings, SampleMode};
use crate::gbuffer::gbuffer;
use crate::metrics::{error_heat_map, metrics, sample_mismatches};
use crate::output::{
    write_exr, write_exr_with_masks, write_json, write_png, write_shaded_png, write_visibility_png,
};
use crate::reference::same_samples::same_sample_masks;
use crate::reference::ReferenceSettings;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct ReferenceArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Sub-pixel samples per pixel, a perfect square k×k (stratified, jittered).
    #[arg(long, default_value_t = 256)]
    spp: u32,
    #[command(flatten)]
    run: TraceRunArgs,
    /// Trace exactly the 32 µQuad samples of each pixel (f64, the IZB's
    /// rule) and write their masks instead of the supersampled estimate.
    #[arg(long)]
    same_samples: bool,
}

#[derive(Args)]
pub struct CompareArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Methods to compare, comma separated: izb32, izb32-exact, izb1.
    #[arg(long, value_delimiter = ',', default_value = "izb32,izb32-exact,izb1")]
    methods: Vec<String>,
    /// Sub-pixel samples per pixel of the ground truth (a perfect square).
    #[arg(long, default_value_t = 256)]
    reference_spp: u32,
    #[command(flatten)]
    run: TraceRunArgs,
}

/// The jitter seed, output folder and threads of a traced reference.
#[derive(Args)]
pub struct TraceRunArgs {
    /// Seed of the jitter: the same seed gives the same image.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

pub fn run_same_sample_reference(args: ReferenceArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let pool = thread_pool(args.run.threads)?;
    let start = Instant::now();
    let (masks, g) = pool.install(|| {
        let bvh = SceneBvh::build(&scene);
        (
            same_sample_masks(&scene, &bvh, crate::lut::sample_pattern()),
            gbuffer(&scene, &bvh),
        )
    });
    let seconds = start.elapsed().as_secs_f64();
    let visibility = crate::cpu::resolve(&masks, &g);
    let [w, h] = scene.resolution;
    write_exr_with_masks(
        &args.run.out.join("visibility.exr"),
        w,
        h,
        &[("visibility", &visibility)],
        &[("mask", &masks)],
    )?;
    write_visibility_png(&args.run.out.join("visibility.png"), w, h, &visibility)?;
    let report = serde_json::json!({
        "command": "reference --same-samples",
        "scene": scene.summary(),
        "samples_per_pixel": 32,
        "threads": pool.current_num_threads(),
        "seconds": seconds,
        "gbuffer": g.stats,
    });
    write_json(&args.run.out.join("report.json"), &report)?;
    crate::say!(
        "same-sample reference {}: {w}x{h}, 32 µQuad samples per pixel, {seconds:.2} s -> {}",
        scene.name,
        args.run.out.display()
    )?;
    Ok(())
}

pub fn run_reference(args: ReferenceArgs) -> Result<()> {
    if args.same_samples {
        return run_same_sample_reference(args);
    }
    let scene = load_scene(&args.scene)?;
    let settings =
        ReferenceSettings::from_spp(args.spp, args.run.seed).map_err(anyhow::Error::msg)?;
    let pool = thread_pool(args.run.threads)?;
    let (image, bvh, bvh_seconds) = pool.install(|| trace_reference(&scene, settings));
    let [w, h] = scene.resolution;
    write_exr(
        &args.run.out.join("visibility.exr"),
        w,
        h,
        &[("visibility", &image.visibility), ("smooth", &image.smooth)],
    )?;
    write_visibility_png(
        &args.run.out.join("visibility.png"),
        w,
        h,
        &image.visibility,
    )?;
    let gbuffer = pool.install(|| gbuffer(&scene, &bvh));
    let light = scene.light.relative_to(scene.camera.eye);
    write_shaded_png(
        &args.run.out.join("shaded.png"),
        &gbuffer,
        &light,
        &image.visibility,
    )?;
    let report = serde_json::json!({
        "command": "reference",
        "scene": scene.summary(),
        "spp": settings.spp(),
        "seed": settings.seed,
        "threads": pool.current_num_threads(),
        "bvh_build_seconds": bvh_seconds,
        "seconds": image.stats.seconds,
        "rays_per_second": image.stats.rays_per_second,
        "stats": image.stats,
        "gbuffer": gbuffer.stats,
    });
    write_json(&args.run.out.join("report.json"), &report)?;
    crate::say!(
        "reference {}: {}x{} at {} spp, {} triangles, {:.2} s ({:.2} Mrays/s on {} threads) -> {}",
        scene.name,
        w,
        h,
        settings.spp(),
        scene.triangles.len(),
        image.stats.seconds,
        image.stats.rays_per_second / 1e6,
        pool.current_num_threads(),
        args.run.out.display()
    )?;
    Ok(())
}

pub fn parse_method(name: &str) -> Result<SampleMode> {
    Ok(match name {
        "izb32" => SampleMode::Lut32,
        "izb32-exact" => SampleMode::Exact32,
        "izb1" => SampleMode::One,
        other => anyhow::bail!("unknown method '{other}': expected izb32, izb32-exact or izb1"),
    })
}

pub fn run_compare(args: CompareArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let methods: Vec<(String, SampleMode)> = args
        .methods
        .iter()
        .map(|m| parse_method(m).map(|mode| (m.clone(), mode)))
        .collect::<Result<_>>()?;
    let settings = ReferenceSettings::from_spp(args.reference_spp, args.run.seed)
        .map_err(anyhow::Error::msg)?;
    let pool = thread_pool(args.run.threads)?;
    let [w, h] = scene.resolution;
    let (truth, bvh, _) = pool.install(|| trace_reference(&scene, settings));
    let bar = progress_bar(1, "same-sample reference");
    let same = pool.install(|| same_sample_masks(&scene, &bvh, crate::lut::sample_pattern()));
    bar.finish_and_clear();
    let mut rows = Vec::new();
    crate::say!(
        "{:<12} {:>8} {:>8} {:>8} {:>8} {:>10} {:>9} {:>12} {:>9}",
        "method",
        "MAE",
        "RMSE",
        "max",
        ">1/32 %",
        "smooth-pen",
        "edge",
        "mismatch",
        "seconds"
    )?;
    for (name, mode) in &methods {
        let settings = IzbSettings {
            mode: *mode,
            ..Default::default()
        };
        let render = pool.install(|| render_cpu(&scene, &bvh, settings));
        let mut m = metrics(&render.visibility, &truth.visibility, &truth.smooth);
        if *mode != SampleMode::One {
            let (diff, total) = sample_mismatches(&render.masks, &same, |i| {
                render.gbuffer.flags[i] & crate::gbuffer::flags::SHADOW_TESTED != 0
            });
            m.sample_mismatch_rate = Some(diff as f64 / total.max(1) as f64);
        }
        crate::say!(
            "{:<12} {:>8.5} {:>8.5} {:>8.4} {:>8.3} {:>10.5} {:>9.5} {:>12} {:>9.3}",
            name,
            m.mae,
            m.rmse,
            m.max_error,
            m.percent_over_one_sample,
            m.smooth_penumbra_mae,
            m.edge_mae,
            m.sample_mismatch_rate
                .map_or("-".into(), |r| format!("{r:.2e}")),
            render.report.seconds.total
        )?;
        write_png(
            &args.run.out.join(format!("error_{name}.png")),
            &error_heat_map(&render.visibility, &truth.visibility, w, h, 0.25),
        )?;
        rows.push(serde_json::json!({
            "method": name,
            "mode": mode,
            "metrics": m,
            "render": render.report,
        }));
    }
    write_exr(
        &args.run.out.join("reference.exr"),
        w,
        h,
        &[("visibility", &truth.visibility), ("smooth", &truth.smooth)],
    )?;
    let report = serde_json::json!({
        "command": "compare",
        "scene": scene.summary(),
        "reference_spp": settings.spp(),
        "reference_seconds": truth.stats.seconds,
        "threads": pool.current_num_threads(),
        "methods": rows,
    });
    write_json(&args.run.out.join("compare.json"), &report)?;
    crate::say!("wrote {}", args.run.out.join("compare.json").display())?;
    Ok(())
}
