//! The `izb` command line. Every command takes a `SCENE`: a procedural
//! scene's name (default: `default`) or a path to a `*.scene.json` spec.

use anyhow::{Context, Result};
use clap::builder::TypedValueParser;
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use izb::bench;
use izb::gbuffer::gbuffer;
use izb::gpu::{GBufferSource, GpuOptions, GpuRenderer};
use izb::izb::{render_cpu, CascadeCount, IzbSettings, SampleMode, Skips};
use izb::metrics::{error_heat_map, metrics, sample_mismatches};
use izb::output::{
    write_exr, write_exr_with_masks, write_json, write_png, write_shaded_png, write_visibility_png,
};
use izb::reference::bvh::SceneBvh;
use izb::reference::same_samples::same_sample_masks;
use izb::reference::{reference, ReferenceImage, ReferenceSettings};
use izb::scene::{self, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "izb",
    version,
    about = "Analytic antialiased hard shadows with a compute irregular z-buffer"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render the shadow mask: 32-sample analytic IZB (or 1 spp).
    Render(RenderArgs),
    /// Ground truth and every method side by side: error table, JSON, heat maps.
    Compare(CompareArgs),
    /// Regenerate the 32-sample edge LUT (the code build.rs runs), with a picture.
    Lut(LutArgs),
    /// Supersampled ray-traced ground truth: lit fraction per pixel.
    Reference(ReferenceArgs),
    /// Run time against error: IZB, ray-traced samples and shadow maps against one ground truth; JSON.
    Bench(BenchArgs),
    /// Pareto charts (PNG, SVG), crops at a shadow edge and an index.html from a bench JSON.
    Report(ReportArgs),
    /// Print a scene's triangle counts, bounds, camera and light.
    Info(InfoArgs),
    /// List the Vulkan devices `--device` can pick, best first.
    Devices,
}

#[derive(Args)]
struct SceneArgs {
    /// Procedural scene name (default, wires, hairball, city, grazing, far,
    /// analytic) or path to a *.scene.json spec.
    #[arg(default_value = "default")]
    scene: String,
    /// Image size WxH, overriding the scene's.
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<[u32; 2]>,
}

#[derive(Args)]
struct InfoArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Also print the device memory a GPU frame allocates, per pass (no
    /// device needed).
    #[arg(long)]
    gpu_memory: bool,
}

#[derive(Args)]
struct ReferenceArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Sub-pixel samples per pixel, a perfect square k×k (stratified, jittered).
    #[arg(long, default_value_t = 256)]
    spp: u32,
    /// Seed of the jitter: the same seed gives the same image.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output folder.
    #[arg(long, default_value = "out")]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Trace exactly the 32 µQuad samples of each pixel (f64, the IZB's
    /// rule) and write their masks instead of the supersampled estimate.
    #[arg(long)]
    same_samples: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Backend {
    /// Vulkan when a device opens, else the CPU (saying why).
    Auto,
    /// The Vulkan backend (ash); fails if no device opens.
    Vulkan,
    /// The CPU twin (rayon).
    Cpu,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum BenchBackend {
    Cpu,
    Vulkan,
    Both,
}

/// Grid, overflow and cascade choices of a render.
#[derive(Args, Clone)]
struct GridArgs {
    /// Cell budget of the light-space grids as the side of a square (200:
    /// 40 000 cells, square in light space whatever the footprint's shape),
    /// shared between the cascades in proportion to their pixels (default:
    /// from the pixel and triangle counts).
    #[arg(long)]
    cells: Option<u32>,
    /// A triangle is binned at the finest grid-pyramid level where its
    /// cell rectangle holds at most this many cells (default 1024).
    #[arg(long)]
    level_cells: Option<u32>,
    /// Sample-distribution cascades: auto (as few as the view-depth range
    /// needs) or 1..4.
    #[arg(long, default_value = "auto", value_parser = CascadeCount::parse)]
    cascades: CascadeCount,
    /// Cascade split blend: 1 logarithmic, 0 uniform.
    #[arg(long, default_value_t = 1.0)]
    split_lambda: f32,
}

impl GridArgs {
    fn apply(&self, settings: IzbSettings) -> Result<IzbSettings> {
        anyhow::ensure!(
            (0.0..=1.0).contains(&self.split_lambda),
            "--split-lambda must be in 0..=1, not {}",
            self.split_lambda
        );
        anyhow::ensure!(
            self.level_cells != Some(0) && self.cells != Some(0),
            "--level-cells and --cells must be at least 1"
        );
        Ok(IzbSettings {
            cells: self.cells,
            level_cells: self.level_cells,
            cascades: self.cascades,
            split_lambda: self.split_lambda,
            ..settings
        })
    }
}

#[derive(Args)]
struct RenderArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Visibility samples per pixel: 32 (µQuad frustum test) or 1 (point test).
    #[arg(long, default_value_t = 32, value_parser = clap::builder::PossibleValuesParser::new(["32", "1"]).map(|s| s.parse::<u32>().expect("listed values")))]
    spp: u32,
    /// Evaluate every edge function at every sample instead of the LUT.
    #[arg(long)]
    exact: bool,
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

#[derive(Args)]
struct CompareArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Methods to compare, comma separated: izb32, izb32-exact, izb1.
    #[arg(long, value_delimiter = ',', default_value = "izb32,izb32-exact,izb1")]
    methods: Vec<String>,
    /// Sub-pixel samples per pixel of the ground truth (a perfect square).
    #[arg(long, default_value_t = 256)]
    reference_spp: u32,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long, default_value = "out")]
    out: PathBuf,
    #[arg(long)]
    threads: Option<usize>,
}

#[derive(Args)]
struct LutArgs {
    /// Angle cells of the table.
    #[arg(long, default_value_t = izb::lut::DEFAULT_ANGLES)]
    angles: u32,
    /// Signed-distance cells of the table.
    #[arg(long, default_value_t = izb::lut::DEFAULT_DISTANCES)]
    distances: u32,
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(Args)]
struct ReportArgs {
    /// A JSON file written by `izb bench`.
    #[arg(default_value = "out/bench.json")]
    bench: PathBuf,
    /// Folder for the charts, crops and index.html.
    #[arg(long, default_value = "out/report")]
    out: PathBuf,
}

#[derive(Args)]
struct BenchArgs {
    /// Scenes to measure (default: the largest shared scene if present,
    /// else the `default` procedural scene).
    scenes: Vec<String>,
    /// Sub-pixel samples per pixel of the ground truth (a square).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Image sizes WxH, comma separated (default: each scene's own). With
    /// several, every scene runs at each and is named `scene@WxH`, and the
    /// bench prints how izb32's time scales between them.
    #[arg(long, value_parser = parse_resolution, value_delimiter = ',')]
    resolution: Vec<[u32; 2]>,
    /// Methods, comma separated: izb1, izb32, izb32-exact, rt32 (the 32
    /// µQuad samples ray traced), shadow maps `sm-R`, `pcf3-R`, `pcf5-R`,
    /// `csmN-pcfK-R` (R texels a side), or `shadow-maps` for all four
    /// kinds at every `--map-sides`. The ground truth is always traced.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "izb1,izb32,izb32-exact,rt32,shadow-maps"
    )]
    methods: Vec<String>,
    /// Map sides `shadow-maps` expands over.
    #[arg(long, value_delimiter = ',', default_value = "512,1024,2048,4096,8192")]
    map_sides: Vec<u32>,
    /// Repetitions of every method, interleaved; medians are reported.
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    /// Where to run the IZB and shadow-map methods: cpu, vulkan, or both
    /// (in one run, so ratios GPU / CPU twin come from one process; rt32
    /// always runs on the CPU).
    #[arg(long, value_enum, default_value_t = BenchBackend::Cpu)]
    backend: BenchBackend,
    /// Vulkan device index (see `izb devices`).
    #[arg(long)]
    device: Option<usize>,
    /// Skip settings to time, each as `render --skip` takes it; repeat the
    /// flag to time several (e.g. `--skip all --skip none`).
    #[arg(long, default_value = "all")]
    skip: Vec<Skips>,
    /// Cascade counts to time, each as `render --cascades` takes it; repeat
    /// the flag to time several (e.g. `--cascades auto --cascades 1`).
    #[arg(long, default_value = "auto", value_parser = CascadeCount::parse)]
    cascades: Vec<CascadeCount>,
    /// Also measure temporal stability: the light turns by
    /// `--flicker-step` degrees per frame over `--flicker-frames` frames.
    #[arg(long)]
    flicker: bool,
    #[arg(long, default_value_t = 100)]
    flicker_frames: usize,
    #[arg(long, default_value_t = 0.01)]
    flicker_step: f64,
    /// Output JSON file; the images go to a folder beside it with the
    /// extension `.images`.
    #[arg(long, default_value = "out/bench.json")]
    out: PathBuf,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
}

fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': expected WxH, e.g. 960x540"))?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("'{s}': {e}"));
    Ok([parse(w)?, parse(h)?])
}

fn load_scene(args: &SceneArgs) -> Result<Scene> {
    let mut scene = scene::load(&args.scene)?;
    if let Some(r) = args.resolution {
        scene = scene.with_resolution(r)?;
    }
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    Ok(scene)
}

fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        anyhow::ensure!(n > 0, "--threads must be at least 1");
        b = b.num_threads(n);
    }
    Ok(b.build()?)
}

fn progress_bar(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent}% {elapsed_precise} (eta {eta})")
            .expect("static template")
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// Builds the BVH and traces the reference, with a progress bar.
fn trace_reference(scene: &Scene, settings: ReferenceSettings) -> (ReferenceImage, SceneBvh, f64) {
    let t = Instant::now();
    let bvh = SceneBvh::build(scene);
    let bvh_seconds = t.elapsed().as_secs_f64();
    let bar = progress_bar(
        scene.pixel_count() as u64,
        &format!("reference {}", scene.name),
    );
    let image = reference(scene, &bvh, settings, &|n| bar.inc(n));
    bar.finish_and_clear();
    (image, bvh, bvh_seconds)
}

fn scene_summary(scene: &Scene) -> serde_json::Value {
    serde_json::json!({
        "name": scene.name,
        "resolution": scene.resolution,
        "triangles": scene.triangles.len(),
        "source_triangles": scene.stats.source_triangles,
        "dropped_degenerate_triangles": scene.stats.dropped_degenerate,
        "skipped_non_triangle_primitives": scene.stats.skipped_non_triangle_primitives,
        "camera": scene.camera,
        "light": scene.light,
    })
}

fn run_same_sample_reference(args: ReferenceArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let pool = thread_pool(args.threads)?;
    let start = Instant::now();
    let (masks, g) = pool.install(|| {
        let bvh = SceneBvh::build(&scene);
        (
            same_sample_masks(&scene, &bvh, izb::lut::sample_pattern()),
            gbuffer(&scene, &bvh),
        )
    });
    let seconds = start.elapsed().as_secs_f64();
    let visibility = izb::izb::resolve(&masks, &g);
    let [w, h] = scene.resolution;
    write_exr_with_masks(
        &args.out.join("visibility.exr"),
        w,
        h,
        &[("visibility", &visibility)],
        &[("mask", &masks)],
    )?;
    write_visibility_png(&args.out.join("visibility.png"), w, h, &visibility)?;
    let report = serde_json::json!({
        "command": "reference --same-samples",
        "scene": scene_summary(&scene),
        "samples_per_pixel": 32,
        "threads": pool.current_num_threads(),
        "seconds": seconds,
        "gbuffer": g.stats,
    });
    write_json(&args.out.join("report.json"), &report)?;
    println!(
        "same-sample reference {}: {w}x{h}, 32 µQuad samples per pixel, {seconds:.2} s -> {}",
        scene.name,
        args.out.display()
    );
    Ok(())
}

fn run_reference(args: ReferenceArgs) -> Result<()> {
    if args.same_samples {
        return run_same_sample_reference(args);
    }
    let scene = load_scene(&args.scene)?;
    let settings = ReferenceSettings::from_spp(args.spp, args.seed).map_err(anyhow::Error::msg)?;
    let pool = thread_pool(args.threads)?;
    let (image, bvh, bvh_seconds) = pool.install(|| trace_reference(&scene, settings));
    let [w, h] = scene.resolution;
    write_exr(
        &args.out.join("visibility.exr"),
        w,
        h,
        &[("visibility", &image.visibility), ("smooth", &image.smooth)],
    )?;
    write_visibility_png(&args.out.join("visibility.png"), w, h, &image.visibility)?;
    let gbuffer = pool.install(|| gbuffer(&scene, &bvh));
    let light = scene.light.relative_to(scene.camera.eye);
    write_shaded_png(
        &args.out.join("shaded.png"),
        &gbuffer,
        &light,
        &image.visibility,
    )?;
    let report = serde_json::json!({
        "command": "reference",
        "scene": scene_summary(&scene),
        "spp": settings.spp(),
        "seed": settings.seed,
        "threads": pool.current_num_threads(),
        "bvh_build_seconds": bvh_seconds,
        "seconds": image.stats.seconds,
        "rays_per_second": image.stats.rays_per_second,
        "stats": image.stats,
        "gbuffer": gbuffer.stats,
    });
    write_json(&args.out.join("report.json"), &report)?;
    println!(
        "reference {}: {}x{} at {} spp, {} triangles, {:.2} s ({:.2} Mrays/s on {} threads) -> {}",
        scene.name,
        w,
        h,
        settings.spp(),
        scene.triangles.len(),
        image.stats.seconds,
        image.stats.rays_per_second / 1e6,
        pool.current_num_threads(),
        args.out.display()
    );
    Ok(())
}

fn run_bench(args: BenchArgs) -> Result<()> {
    let shared_largest =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/courtyard.scene.json");
    let scenes = if args.scenes.is_empty() {
        if shared_largest.exists() {
            vec![shared_largest.display().to_string()]
        } else {
            eprintln!("bench: ../shared/scenes not found, measuring the `default` scene");
            vec!["default".to_string()]
        }
    } else {
        args.scenes.clone()
    };
    anyhow::ensure!(args.repeat > 0, "--repeat must be at least 1");
    let reference_settings =
        ReferenceSettings::from_spp(args.spp, 1).map_err(anyhow::Error::msg)?;
    // IZB methods once per skip × cascade setting; the others once.
    let mut methods: Vec<bench::Method> = Vec::new();
    for &cascades in &args.cascades {
        for &skips in &args.skip {
            let izb = IzbSettings {
                skips,
                cascades,
                ..Default::default()
            };
            for mut m in bench::parse_methods(&args.methods, &args.map_sides, izb)
                .map_err(anyhow::Error::msg)?
            {
                let is_izb = matches!(m.kind, bench::MethodKind::Izb(_));
                let first = skips == args.skip[0] && cascades == args.cascades[0];
                if !is_izb && !first {
                    continue;
                }
                if is_izb && args.skip.len() > 1 {
                    m.name += &format!(" skip={skips}");
                }
                if is_izb && args.cascades.len() > 1 {
                    m.name += &format!(" cascades={cascades}");
                }
                methods.push(m);
            }
        }
    }
    let pool = thread_pool(args.threads)?;
    let cpu_only = |m: &bench::Method| {
        matches!(
            m.kind,
            bench::MethodKind::RayTraced32 | bench::MethodKind::Embree32
        )
    };
    let has_gpu_method = methods.iter().any(|m| !cpu_only(m));
    let gpu = if args.backend == BenchBackend::Cpu || !has_gpu_method {
        None
    } else {
        Some(
            GpuRenderer::new(&GpuOptions {
                device_index: args.device,
                ..GpuOptions::from_env()
            })
            .context("bench --backend vulkan")?,
        )
    };
    let images_dir = args.out.with_extension("images");
    let image_prefix = bench::relative_to(&images_dir, &args.out);
    let options = bench::BenchOptions {
        repeat: args.repeat,
        reference: reference_settings,
        images: Some(images_dir.clone()),
    };
    let flicker_options = bench::flicker::FlickerOptions {
        frames: args.flicker_frames,
        step_degrees: args.flicker_step,
        reference: reference_settings,
    };
    let (mut rows, mut scene_rows, mut flicker_rows) = (Vec::new(), Vec::new(), Vec::new());
    let resolutions: Vec<Option<[u32; 2]>> = if args.resolution.is_empty() {
        vec![None]
    } else {
        args.resolution.iter().copied().map(Some).collect()
    };
    let runs = scenes
        .iter()
        .flat_map(|name| resolutions.iter().map(move |&r| (name, r)));
    for (name, resolution) in runs {
        let mut scene = load_scene(&SceneArgs {
            scene: name.clone(),
            resolution,
        })?;
        if resolutions.len() > 1 {
            let [w, h] = scene.resolution;
            scene.name = format!("{}@{w}x{h}", scene.name);
        }
        let bar = progress_bar(scene.pixel_count() as u64, &format!("truth {}", scene.name));
        let shared =
            pool.install(|| bench::SceneTruth::new(&scene, reference_settings, &|n| bar.inc(n)));
        bar.finish_and_clear();
        let stats = &shared.truth.stats;
        println!(
            "{}: {} triangles, {}x{}; ground truth {} spp: {:.2} s ({:.2} Mrays/s, {} threads)",
            scene.name,
            scene.triangles.len(),
            scene.resolution[0],
            scene.resolution[1],
            reference_settings.spp(),
            stats.seconds,
            stats.rays_per_second / 1e6,
            pool.current_num_threads()
        );
        let mut scene_results = Vec::new();
        let mut refused = Vec::new();
        // rt32 and rt32-embree have no Vulkan twin: they run on the CPU
        // whatever the backend.
        let cpu_methods: Vec<bench::Method> = methods
            .iter()
            .filter(|m| args.backend != BenchBackend::Vulkan || cpu_only(m))
            .cloned()
            .collect();
        if !cpu_methods.is_empty() {
            let (r, why) = pool.install(|| {
                bench::bench_scene_cpu(&scene, &shared, &cpu_methods, &options, Some(&image_prefix))
            })?;
            scene_results.extend(r);
            refused.extend(why);
        }
        if let Some(gpu) = &gpu {
            let (r, why) = bench::bench_scene_vulkan(gpu, &scene, &shared, &methods, args.repeat)?;
            scene_results.extend(r);
            refused.extend(why);
        }
        for why in &refused {
            eprintln!("bench: {why}");
        }
        print_bench_table(&scene.name, &scene_results);
        if args.flicker {
            let bar = progress_bar(
                args.flicker_frames as u64,
                &format!("flicker {}", scene.name),
            );
            let f = pool.install(|| {
                bench::flicker::flicker(&scene, &shared, &methods, &flicker_options, &|| bar.inc(1))
            });
            bar.finish_and_clear();
            for r in &f {
                println!(
                    "{}: flicker {:<14} mean |Δ| {:.5} per frame, {:.2}x the ground truth's \
                     (95% {:.2}-{:.2}x; smooth pixels {:.2}x, edge pixels {:.2}x)",
                    scene.name,
                    r.method,
                    r.mean_abs_delta,
                    r.ratio_to_truth,
                    r.ratio_ci95[0],
                    r.ratio_ci95[1],
                    r.smooth_ratio_to_truth,
                    r.edge_ratio_to_truth
                );
            }
            flicker_rows.push(serde_json::json!({ "scene": scene.name, "rows": f }));
        }
        scene_rows.push(serde_json::json!({
            "summary": scene_summary(&scene),
            "truth": {
                "spp": reference_settings.spp(),
                "seconds": stats.seconds,
                "rays_per_second": stats.rays_per_second,
                "bvh_build_seconds": shared.bvh_seconds,
                "stats": stats,
                "image": format!("{image_prefix}/{}/truth.exr", bench::file_stem(&scene.name)),
            },
            "gbuffer_seconds": shared.gbuffer_seconds,
            "refused": refused,
        }));
        for r in scene_results {
            let mut v = serde_json::to_value(&r)?;
            v["scene"] = serde_json::json!(scene.name);
            rows.push(v);
        }
    }
    let scaling = izb32_scaling(&rows);
    for s in &scaling {
        let text = |k: &str| s[k].as_str().unwrap_or("?").to_string();
        let number = |k: &str| s[k].as_f64().unwrap_or(f64::NAN);
        println!(
            "{} ({}): izb32 shadow time {:.2}x from {} to {} ({:.1}x the pixels)",
            text("scene"),
            text("backend"),
            number("time_ratio"),
            text("from"),
            text("to"),
            number("pixel_ratio")
        );
    }
    let report = serde_json::json!({
        "command": "bench",
        "izb32_scaling": scaling,
        "device": gpu.as_ref().map(|g| g.context.info().clone()),
        "cpu": cpu_model(),
        "threads": pool.current_num_threads(),
        "logical_cores": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        "repeat": args.repeat,
        "reference_spp": reference_settings.spp(),
        "flicker_settings": args.flicker.then_some(flicker_options),
        "scenes": scene_rows,
        "results": rows,
        "flicker": flicker_rows,
    });
    write_json(&args.out, &report).with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "wrote {} (images in {})",
        args.out.display(),
        images_dir.display()
    );
    Ok(())
}

/// For every scene benchmarked at several resolutions: izb32's shadow
/// time at the largest over the smallest, per backend.
fn izb32_scaling(rows: &[serde_json::Value]) -> Vec<serde_json::Value> {
    // (scene, backend) -> (pixels, "WxH", shadow seconds) per resolution.
    type Runs = Vec<(u64, String, f64)>;
    let mut by_scene: std::collections::BTreeMap<(String, String), Runs> = Default::default();
    for r in rows.iter().filter(|r| r["method"] == "izb32") {
        let (Some(full), Some(backend), Some(t)) = (
            r["scene"].as_str(),
            r["backend"].as_str(),
            r["shadow_seconds"].as_f64(),
        ) else {
            continue;
        };
        let Some((scene, size)) = full.rsplit_once('@') else {
            continue;
        };
        let pixels = size
            .split_once('x')
            .and_then(|(w, h)| Some(w.parse::<u64>().ok()? * h.parse::<u64>().ok()?))
            .unwrap_or(0);
        by_scene
            .entry((scene.to_string(), backend.to_string()))
            .or_default()
            .push((pixels, size.to_string(), t));
    }
    by_scene
        .into_iter()
        .filter(|(_, v)| v.len() > 1)
        .map(|((scene, backend), mut v)| {
            v.sort_by_key(|e| e.0);
            let (lo, hi) = (&v[0], &v[v.len() - 1]);
            serde_json::json!({
                "scene": scene,
                "backend": backend,
                "from": lo.1,
                "to": hi.1,
                "pixel_ratio": hi.0 as f64 / lo.0.max(1) as f64,
                "time_ratio": hi.2 / lo.2,
            })
        })
        .collect()
}

fn run_report(args: ReportArgs) -> Result<()> {
    let files = izb::report::report(&args.bench, &args.out)?;
    for v in &files.verdicts {
        println!(
            "{} ({}): izb32 vs {:<16} penumbra MAE {:+.4}, MAE {:+.5}, time {:.2}x izb32{}",
            v.scene,
            v.backend,
            v.shadow_map,
            v.penumbra_mae_margin,
            v.mae_margin,
            v.time_ratio,
            if v.izb_more_accurate() {
                ""
            } else {
                "  <- not more accurate"
            }
        );
    }
    println!(
        "report: {} charts, {} crops -> {}",
        files.charts.len(),
        files.crops.len(),
        files.index.display()
    );
    Ok(())
}

/// The CPU's model name (Linux), for the bench JSON.
fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    info.lines().find_map(|l| {
        l.strip_prefix("model name")?
            .split_once(':')
            .map(|(_, v)| v.trim().to_string())
    })
}

/// One line per method: time, ratio to `izb32`, and the error metrics.
fn print_bench_table(scene: &str, rows: &[bench::MethodRow]) {
    println!(
        "{scene}: {:<16} {:>7} {:>10} {:>8} {:>9} {:>9} {:>9} {:>8}",
        "method", "backend", "shadow s", "/izb32", "MAE", "penumbra", "edge", "% wrong"
    );
    for r in rows {
        println!(
            "{scene}: {:<16} {:>7} {:>10.4} {:>8} {:>9.5} {:>9.4} {:>9.4} {:>8.3}",
            r.method,
            r.backend,
            r.shadow_seconds,
            r.shadow_seconds_over_izb32
                .map_or("-".to_string(), |x| format!("{x:.2}")),
            r.metrics.mae,
            r.metrics.smooth_penumbra_mae,
            r.metrics.edge_mae,
            r.metrics.percent_over_one_sample
        );
    }
}

fn mode_for(spp: u32, exact: bool) -> SampleMode {
    match (spp, exact) {
        (1, _) => SampleMode::One,
        (_, true) => SampleMode::Exact32,
        _ => SampleMode::Lut32,
    }
}

fn run_render(args: RenderArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    anyhow::ensure!(
        !(args.exact && args.spp == 1),
        "--exact applies to 32 spp; 1 spp is always an exact point test"
    );
    let settings = args.grid.apply(IzbSettings {
        mode: mode_for(args.spp, args.exact),
        skips: args.skip,
        ..Default::default()
    })?;
    let renderer = match args.backend {
        Backend::Cpu => None,
        Backend::Vulkan | Backend::Auto => {
            let options = GpuOptions {
                device_index: args.device,
                ..GpuOptions::from_env()
            };
            match GpuRenderer::new(&options) {
                Ok(r) => Some(r),
                Err(e) if args.backend == Backend::Auto => {
                    eprintln!("backend: cpu ({e})");
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
                eprintln!("backend: cpu ({e:#})");
                render_on_cpu(&scene, settings, &args)
            }
            other => other,
        },
        None => render_on_cpu(&scene, settings, &args),
    }
}

fn is_loop_cap(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        matches!(
            c.downcast_ref::<izb::gpu::GpuError>(),
            Some(izb::gpu::GpuError::LoopCap { .. })
        )
    })
}

/// Writes `visibility.exr` (lit fraction + masks) and `visibility.png`.
fn write_mask_outputs(out: &Path, scene: &Scene, visibility: &[f32], masks: &[u32]) -> Result<()> {
    let [w, h] = scene.resolution;
    write_exr_with_masks(
        &out.join("visibility.exr"),
        w,
        h,
        &[("visibility", visibility)],
        &[("mask", masks)],
    )?;
    write_visibility_png(&out.join("visibility.png"), w, h, visibility)
}

/// The one-line summary of a render: cascades and grids, binning, tests,
/// timing.
#[allow(clippy::too_many_arguments)]
fn print_render_summary(
    scene: &Scene,
    mode: SampleMode,
    backend: &str,
    [binned, overflow, culled]: [u64; 3],
    grids: &[([u32; 2], u32)],
    cascade_reason: &str,
    tests: u64,
    timing: &str,
    out: &Path,
) {
    let [w, h] = scene.resolution;
    let grids: Vec<String> = grids
        .iter()
        .map(|([x, y], cap)| format!("{x}x{y} pyramid (≤ {cap} cells per triangle)"))
        .collect();
    println!(
        "render {} ({mode:?}, {backend}): {w}x{h}, {} triangles ({binned} placements binned, \
         {overflow} overflow, {culled} culled), {} cascade(s) ({cascade_reason}): {}, {tests} tests, \
         {timing} -> {}",
        scene.name,
        scene.triangles.len(),
        grids.len(),
        grids.join(" + "),
        out.display()
    );
}

fn render_on_gpu(
    renderer: &GpuRenderer,
    scene: &Scene,
    settings: IzbSettings,
    args: &RenderArgs,
) -> Result<()> {
    eprintln!(
        "backend: vulkan ({}, {})",
        renderer.context.info().name,
        renderer.context.info().kind
    );
    let render = renderer.render(scene, settings, GBufferSource::Gpu)?;
    let messages = renderer.take_validation_messages();
    for m in &messages {
        eprintln!("validation: {m}");
    }
    let [w, h] = scene.resolution;
    write_mask_outputs(&args.out, scene, &render.visibility, &render.masks)?;
    let shaded =
        image::RgbImage::from_raw(w, h, render.shaded.concat()).context("shaded image size")?;
    write_png(&args.out.join("shaded.png"), &shaded)?;
    let report = serde_json::json!({
        "command": "render",
        "backend": "vulkan",
        "scene": scene_summary(scene),
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
        &r.light
            .cascades
            .iter()
            .map(|g| (g.cells, g.level_cells))
            .collect::<Vec<_>>(),
        &r.light.cascade_choice.reason,
        c.tests_spawned,
        &format!(
            "{ms}, {:.1} MiB",
            r.memory_total_bytes as f64 / (1024.0 * 1024.0)
        ),
        &args.out,
    );
    Ok(())
}

fn render_on_cpu(scene: &Scene, settings: IzbSettings, args: &RenderArgs) -> Result<()> {
    let pool = thread_pool(args.threads)?;
    let (render, bvh_seconds) = pool.install(|| {
        let t = Instant::now();
        let bvh = SceneBvh::build(scene);
        let bvh_seconds = t.elapsed().as_secs_f64();
        (render_cpu(scene, &bvh, settings), bvh_seconds)
    });
    write_mask_outputs(&args.out, scene, &render.visibility, &render.masks)?;
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
        "scene": scene_summary(scene),
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
        &r.light
            .cascades
            .iter()
            .map(|g| (g.cells, g.level_cells))
            .collect::<Vec<_>>(),
        &r.light.cascade_choice.reason,
        r.evaluate.tests_spawned,
        &format!(
            "{:.3} s (evaluate {:.3} s)",
            r.seconds.total, r.seconds.evaluate
        ),
        &args.out,
    );
    Ok(())
}

fn parse_method(name: &str) -> Result<SampleMode> {
    Ok(match name {
        "izb32" => SampleMode::Lut32,
        "izb32-exact" => SampleMode::Exact32,
        "izb1" => SampleMode::One,
        other => anyhow::bail!("unknown method '{other}': expected izb32, izb32-exact or izb1"),
    })
}

fn run_compare(args: CompareArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let methods: Vec<(String, SampleMode)> = args
        .methods
        .iter()
        .map(|m| parse_method(m).map(|mode| (m.clone(), mode)))
        .collect::<Result<_>>()?;
    let settings =
        ReferenceSettings::from_spp(args.reference_spp, args.seed).map_err(anyhow::Error::msg)?;
    let pool = thread_pool(args.threads)?;
    let [w, h] = scene.resolution;
    let (truth, bvh, _) = pool.install(|| trace_reference(&scene, settings));
    let bar = progress_bar(1, "same-sample reference");
    let same = pool.install(|| same_sample_masks(&scene, &bvh, izb::lut::sample_pattern()));
    bar.finish_and_clear();
    let mut rows = Vec::new();
    println!(
        "{:<12} {:>8} {:>8} {:>8} {:>8} {:>10} {:>9} {:>12} {:>9}",
        "method", "MAE", "RMSE", "max", ">1/32 %", "smooth-pen", "edge", "mismatch", "seconds"
    );
    for (name, mode) in &methods {
        let settings = IzbSettings {
            mode: *mode,
            ..Default::default()
        };
        let render = pool.install(|| render_cpu(&scene, &bvh, settings));
        let mut m = metrics(&render.visibility, &truth.visibility, &truth.smooth);
        if *mode != SampleMode::One {
            let (diff, total) = sample_mismatches(&render.masks, &same, |i| {
                render.gbuffer.flags[i] & izb::gbuffer::flags::SHADOW_TESTED != 0
            });
            m.sample_mismatch_rate = Some(diff as f64 / total.max(1) as f64);
        }
        println!(
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
        );
        write_png(
            &args.out.join(format!("error_{name}.png")),
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
        &args.out.join("reference.exr"),
        w,
        h,
        &[("visibility", &truth.visibility), ("smooth", &truth.smooth)],
    )?;
    let report = serde_json::json!({
        "command": "compare",
        "scene": scene_summary(&scene),
        "reference_spp": settings.spp(),
        "reference_seconds": truth.stats.seconds,
        "threads": pool.current_num_threads(),
        "methods": rows,
    });
    write_json(&args.out.join("compare.json"), &report)?;
    println!("wrote {}", args.out.join("compare.json").display());
    Ok(())
}

fn run_lut(args: LutArgs) -> Result<()> {
    let stats = izb::lut::regenerate(args.angles, args.distances, &args.out)?;
    println!("{stats:#?}");
    println!(
        "wrote {} and {}",
        args.out.join("edge_lut.bin").display(),
        args.out.join("edge_lut.png").display()
    );
    Ok(())
}

fn run_info(args: InfoArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let (lo, hi) = scene.bounds();
    let mut summary = scene_summary(&scene);
    summary["bounds"] = serde_json::json!({"min": lo, "max": hi});
    if args.gpu_memory {
        let plan = izb::gpu::frame::planned_memory(&scene, IzbSettings::default())?;
        let total: u64 = plan.iter().map(|m| m.bytes).sum();
        let (p, t) = (scene.pixel_count() as u64, scene.triangles.len() as u64);
        summary["gpu_memory"] = serde_json::json!({
            "per_pass": plan,
            "total_bytes": total,
            "total_mib": total as f64 / (1024.0 * 1024.0),
            "budget_bytes_64_per_pixel_plus_64_per_triangle": 64 * (p + t),
            "bytes_per_pixel_plus_triangle": total as f64 / (p + t).max(1) as f64,
        });
    }
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}

fn run_devices() -> Result<()> {
    let devices = izb::gpu::list_devices()?;
    if devices.is_empty() {
        println!("no Vulkan 1.2 device with compute and the scalar block layout");
    }
    for d in devices {
        println!(
            "{}: {} ({}, Vulkan {}, max storage buffer {} MiB)",
            d.index,
            d.name,
            d.kind,
            d.api_version,
            d.max_storage_buffer_range / (1 << 20)
        );
    }
    Ok(())
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(a) => run_render(a),
        Command::Compare(a) => run_compare(a),
        Command::Lut(a) => run_lut(a),
        Command::Reference(a) => run_reference(a),
        Command::Bench(a) => run_bench(a),
        Command::Report(a) => run_report(a),
        Command::Info(a) => run_info(a),
        Command::Devices => run_devices(),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
