//! `izb render`: one shadow mask, on Vulkan or the CPU twin.

use super::{load_scene, thread_pool, Backend, GridArgs, SceneArgs};
use crate::bvh::SceneBvh;
use crate::cpu::{render_cpu, IzbSettings, SampleMode, Skips};
use crate::gpu::{GBufferSource, GpuOptions, GpuRenderer};
use crate::output::{write_json, write_mask_outputs, write_png, write_shaded_png};
use crate::scene::Scene;
use anyhow::{Context, Result};
use clap::builder::TypedValueParser;
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Visibility samples per pixel: 32 (µQuad frustum test) or 1 (point test).
    #[arg(long, default_value_t = 32, value_parser = clap::builder::PossibleValuesParser::new(["32", "1"]).map(|s| s.parse::<u32>().expect("listed values")))]
    spp: u32,
    /// Evaluate every edge function at every sample instead of the LUT.
    #[arg(long)]
    exact: bool,
    /// Under an area light: pair the 32 light samples with the µQuad's 32
    /// samples, each ray from its own point of the pixel, evaluated
    /// exactly (the soft mask antialiased over the pixel); implies
    /// --exact. Half the default's (--paired64's) time, with 3–49 % more
    /// smooth-penumbra error.
    #[arg(long)]
    paired: bool,
    /// Under an area light: the light's 32 samples seen from the µQuad
    /// centre P alone, with the light LUT (before issue 27 the default;
    /// no edge surfaces).
    #[arg(long, conflicts_with_all = ["paired", "paired64", "exact"])]
    unpaired: bool,
    /// --paired with 64 pairs: a second 32, both patterns turned, in a
    /// second mask word (`mask_high` in visibility.exr), each half's
    /// samples on their own surfaces at edge pixels. The default under an
    /// area light at 32 spp, unless --paired, --exact or --unpaired asks
    /// otherwise.
    #[arg(long)]
    paired64: bool,
    /// Every sample on the pixel centre's µQuad: no per-sample surfaces at
    /// edge pixels (by default an edge pixel's samples each stand on the
    /// surface their own ray sees).
    #[arg(long)]
    no_edge_surfaces: bool,
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    backend: Backend,
    /// Vulkan device index (see `izb devices`; default: the best one).
    #[arg(long)]
    device: Option<usize>,
    #[command(flatten)]
    grid: GridArgs,
    /// Exact shortcuts to take: all, none, or a comma-separated list of
    /// facing-away, outside-bounds, full-mask, saturated-edges,
    /// behind-receivers, shadow-map.
    #[arg(long, default_value = "all")]
    skip: Skips,
    /// Output folder.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

pub fn mode_for(spp: u32, exact: bool, paired: bool, paired64: bool) -> SampleMode {
    match (spp, exact, paired, paired64) {
        (1, _, _, _) => SampleMode::One,
        (_, _, _, true) => SampleMode::Paired64,
        (_, _, true, _) => SampleMode::Paired32,
        (_, true, _, _) => SampleMode::Exact32,
        _ => SampleMode::Lut32,
    }
}

pub fn run_render(args: RenderArgs) -> Result<()> {
    // Before the frame: an --out that cannot become a folder is named now,
    // not after seconds of rendering.
    crate::output::check_folder(&args.out)?;
    let scene = load_scene(&args.scene)?;
    anyhow::ensure!(
        !((args.exact || args.paired || args.paired64) && args.spp == 1),
        "--exact, --paired and --paired64 apply to 32 spp; 1 spp is always an exact point test"
    );
    // Under an area light the paired rays average over the pixel's area
    // as the ground truth does, and take edge surfaces; 64 pairs are
    // measured the closest to the truth, the 32 pairs' smooth penumbrae
    // 3–49 % further off (paper-notes/edge-surfaces.md).
    let paired64 =
        args.paired64 || (scene.has_area_light() && !args.exact && !args.unpaired && !args.paired);
    let settings = args.grid.apply(IzbSettings {
        mode: mode_for(args.spp, args.exact, args.paired, paired64),
        skips: args.skip,
        edge_surfaces: !args.no_edge_surfaces,
        ..Default::default()
    })?;
    let edges_on_cpu_only = settings.uses_edge_surfaces(&scene);
    let renderer = match args.backend {
        Backend::Cpu => None,
        Backend::Auto if edges_on_cpu_only => {
            crate::note!(
                "backend: cpu (edge surfaces' G-buffer is the CPU's; --backend vulkan uploads \
                 it, --no-edge-surfaces renders wholly on Vulkan)"
            );
            None
        }
        Backend::Vulkan | Backend::Auto => {
            let options = GpuOptions {
                device_index: args.device,
                ..GpuOptions::from_env()
            };
            match GpuRenderer::new(&options) {
                Ok(r) => Some(r),
                Err(e) if args.backend == Backend::Auto => {
                    crate::note!("backend: cpu ({e})");
                    None
                }
                Err(e) => return Err(e).context("--backend vulkan"),
            }
        }
    };
    match renderer {
        Some(r) => match render_on_gpu(&r, &scene, settings, &args) {
            // lavapipe refuses frames its loop cap would cut short: with
            // --backend auto the CPU renders the same masks instead.
            Err(e) if args.backend == Backend::Auto && is_loop_cap(&e) => {
                crate::note!("backend: cpu ({e:#})");
                render_on_cpu(&scene, settings, &args)
            }
            other => other,
        },
        None => render_on_cpu(&scene, settings, &args),
    }
}

pub fn is_loop_cap(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        matches!(
            c.downcast_ref::<crate::gpu::GpuError>(),
            Some(crate::gpu::GpuError::LoopCap { .. })
        )
    })
}

/// The one-line summary of a render: cascades and grids, binning, tests,
/// timing.
#[allow(clippy::too_many_arguments)]
pub fn print_render_summary(
    scene: &Scene,
    mode: SampleMode,
    backend: &str,
    [binned, overflow, culled]: [u64; 3],
    grids: impl Iterator<Item = ([u32; 2], u32)>,
    cascade_reason: &str,
    tests: u64,
    timing: &str,
    out: &Path,
) -> Result<(), crate::cli::console::StreamClosed> {
    let [w, h] = scene.resolution;
    let grids: Vec<String> = grids
        .map(|([x, y], cap)| format!("{x}x{y} pyramid (≤ {cap} cells per triangle)"))
        .collect();
    crate::say!(
        "render {} ({mode:?}, {backend}): {w}x{h}, {} triangles ({binned} placements binned, \
         {overflow} overflow, {culled} culled), {} cascade(s) ({cascade_reason}): {}, {tests} tests, \
         {timing} -> {}",
        scene.name,
        scene.triangles.len(),
        grids.len(),
        grids.join(" + "),
        out.display()
    )
}

pub fn render_on_gpu(
    renderer: &GpuRenderer,
    scene: &Scene,
    settings: IzbSettings,
    args: &RenderArgs,
) -> Result<()> {
    crate::note!(
        "backend: vulkan ({}, {})",
        renderer.context.info().name,
        renderer.context.info().kind
    );
    // Edge surfaces: the CPU twin's G-buffer with its f64 sample rays goes
    // up, the one the same-sample reference checks (the GPU's
    // edge_surfaces pass casts them in f32, and on lavapipe passes its loop
    // cap on dense scenes, paper-notes/edge-surfaces.md); the passes after
    // it run on the device.
    let cpu_gbuffer = settings.uses_edge_surfaces(scene).then(|| {
        crate::note!("gbuffer: cpu (edge surfaces' sample rays), uploaded");
        crate::gbuffer::gbuffer_with(scene, &SceneBvh::build(scene), settings.edge_halves(scene))
    });
    let source = cpu_gbuffer
        .as_ref()
        .map_or(GBufferSource::Gpu, GBufferSource::Upload);
    let render = renderer.render(scene, settings, source)?;
    let messages = renderer.take_validation_messages();
    for m in &messages {
        crate::note!("validation: {m}");
    }
    let [w, h] = scene.resolution;
    write_mask_outputs(
        &args.out,
        scene,
        &render.visibility,
        &render.masks,
        &render.masks_high,
        render
            .gbuffer
            .edges
            .as_ref()
            .map_or(&[][..], |e| &e.counted),
    )?;
    let shaded =
        image::RgbImage::from_raw(w, h, render.shaded.concat()).context("shaded image size")?;
    write_png(&args.out.join("shaded.png"), &shaded)?;
    let report = serde_json::json!({
        "command": "render",
        "backend": "vulkan",
        "gbuffer": if cpu_gbuffer.is_some() { "cpu (uploaded)" } else { "vulkan" },
        "scene": scene.summary(),
        "render": render.report,
        "validation_messages": messages,
    });
    write_json(&args.out.join("report.json"), &report)?;
    let r = &render.report;
    let ms = r
        .gpu_milliseconds
        .as_ref()
        .map_or("no timestamps".to_string(), |m| {
            format!("GPU {:.3} ms (evaluate {:.3} ms)", m.total, m.evaluate)
        });
    let c = &r.counters;
    print_render_summary(
        scene,
        settings.mode,
        "vulkan",
        [c.triangles_binned, c.overflow, c.culled].map(u64::from),
        r.light.cascades.iter().map(|g| (g.cells, g.level_cells)),
        &r.light.cascade_choice.reason,
        c.tests_spawned,
        &format!(
            "{ms}, {:.1} MiB",
            r.memory_total_bytes as f64 / (1024.0 * 1024.0)
        ),
        &args.out,
    )?;
    Ok(())
}

pub fn render_on_cpu(scene: &Scene, settings: IzbSettings, args: &RenderArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    let (render, bvh_seconds) = pool.install(|| {
        let t = Instant::now();
        let bvh = SceneBvh::build(scene);
        let bvh_seconds = t.elapsed().as_secs_f64();
        (render_cpu(scene, &bvh, settings), bvh_seconds)
    });
    write_mask_outputs(
        &args.out,
        scene,
        &render.visibility,
        &render.masks,
        &render.masks_high,
        render
            .gbuffer
            .edges
            .as_ref()
            .map_or(&[][..], |e| &e.counted),
    )?;
    let light = scene.light.relative_to(scene.camera.eye);
    write_shaded_png(
        &args.out.join("shaded.png"),
        &render.gbuffer,
        &light,
        &render.visibility,
    )?;
    let report = serde_json::json!({
        "command": "render",
        "backend": "cpu",
        "scene": scene.summary(),
        "threads": pool.current_num_threads(),
        "bvh_build_seconds": bvh_seconds,
        "render": render.report,
    });
    write_json(&args.out.join("report.json"), &report)?;
    let r = &render.report;
    print_render_summary(
        scene,
        settings.mode,
        "cpu",
        [r.bin.binned, r.bin.overflow, r.bin.culled].map(|n| n as u64),
        r.light.cascades.iter().map(|g| (g.cells, g.level_cells)),
        &r.light.cascade_choice.reason,
        r.evaluate.tests_spawned,
        &format!(
            "{:.3} s (evaluate {:.3} s)",
            r.seconds.total, r.seconds.evaluate
        ),
        &args.out,
    )?;
    Ok(())
}
