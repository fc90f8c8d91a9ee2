//! The `izb` command line. Every command takes a `SCENE`: a procedural
//! scene's name (default: `default`) or a path to a `*.scene.json` spec.

use anyhow::{Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use izb::gbuffer::gbuffer;
use izb::output::{write_exr, write_json, write_shaded_png, write_visibility_png};
use izb::reference::bvh::SceneBvh;
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
    /// Supersampled ray-traced ground truth: lit fraction per pixel.
    Reference(ReferenceArgs),
    /// Benchmark the ground-truth tracer (rays per second) and write JSON.
    Bench(BenchArgs),
    /// Print a scene's triangle counts, bounds, camera and light.
    Info(SceneArgs),
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
}

#[derive(Args)]
struct BenchArgs {
    /// Scenes to measure (default: the largest shared scene if present,
    /// else the `default` procedural scene).
    scenes: Vec<String>,
    /// Sub-pixel samples per pixel of the reference.
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Image size WxH (default: each scene's own).
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<[u32; 2]>,
    /// Output JSON file.
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

fn run_reference(args: ReferenceArgs) -> Result<()> {
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
    let settings = ReferenceSettings::from_spp(args.spp, 1).map_err(anyhow::Error::msg)?;
    let pool = thread_pool(args.threads)?;
    let mut rows = Vec::new();
    for name in &scenes {
        let scene = load_scene(&SceneArgs {
            scene: name.clone(),
            resolution: args.resolution,
        })?;
        let (image, _, bvh_seconds) = pool.install(|| trace_reference(&scene, settings));
        println!(
            "{}: {} triangles, {}x{} at {} spp: BVH {:.2} s, trace {:.2} s, {:.2} Mrays/s ({} threads)",
            scene.name,
            scene.triangles.len(),
            scene.resolution[0],
            scene.resolution[1],
            settings.spp(),
            bvh_seconds,
            image.stats.seconds,
            image.stats.rays_per_second / 1e6,
            pool.current_num_threads()
        );
        rows.push(serde_json::json!({
            "method": "reference",
            "scene": scene_summary(&scene),
            "spp": settings.spp(),
            "bvh_build_seconds": bvh_seconds,
            "seconds": image.stats.seconds,
            "rays_per_second": image.stats.rays_per_second,
            "stats": image.stats,
        }));
    }
    let report = serde_json::json!({
        "threads": pool.current_num_threads(),
        "logical_cores": std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
        "results": rows,
    });
    write_json(&args.out, &report).with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}

fn run_info(args: SceneArgs) -> Result<()> {
    let scene = load_scene(&args)?;
    let (lo, hi) = scene.bounds();
    let mut summary = scene_summary(&scene);
    summary["bounds"] = serde_json::json!({"min": lo, "max": hi});
    println!("{}", serde_json::to_string_pretty(&summary)?);
    Ok(())
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Reference(a) => run_reference(a),
        Command::Bench(a) => run_bench(a),
        Command::Info(a) => run_info(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
