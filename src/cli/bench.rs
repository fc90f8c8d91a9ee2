//! `izb bench`: run time against error for every method, one process,
//! repetitions interleaved; `bench.json`.

use super::{
    load_scene, load_scene_quietly, parse_resolution, progress_bar, thread_pool, BenchBackend,
    SceneArgs,
};
use crate::bench;
use crate::bench::document::{
    BenchDocument, FlickerSettings, ResultRow, Scaling, SceneEntry, SceneFlicker, TruthEntry,
};
use crate::cascades::CascadeCount;
use crate::gpu::{GpuOptions, GpuRenderer};
use crate::output::write_json;
use crate::reference::ReferenceSettings;
use crate::settings::{IzbSettings, VertexCache};
use crate::skips::Skips;
use anyhow::{Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct BenchArgs {
    /// Scenes to measure (default: the largest shared scene,
    /// `../shared/scenes/courtyard.scene.json` from the working directory,
    /// if present, else the `default` procedural scene).
    scenes: Vec<String>,
    /// Sub-pixel samples per pixel of the ground truth (a square).
    #[arg(long, default_value_t = 16)]
    spp: u32,
    /// Image sizes WxH, comma separated (default: each scene's own). With
    /// several, every scene runs at each and is named `scene@WxH`, and the
    /// bench prints how izb32's time scales between them.
    #[arg(long, value_parser = parse_resolution, value_delimiter = ',')]
    resolution: Vec<[u32; 2]>,
    /// Methods, comma separated: izb1, izb32, izb32-exact, izb32-paired
    /// (area lights: light samples paired with µQuad samples),
    /// izb64-paired (64 such pairs, two mask words), rt32 (the
    /// 32 µQuad samples ray traced; under an area light the 32 light
    /// samples, also named rt-soft), shadow maps `sm-R`, `pcf3-R`, `pcf5-R`,
    /// `csmN-pcfK-R`, `pcss-R` (soft, Fernando 2005), `vsm-R` (variance),
    /// `msm-R` (4 moments), `esm-R` (exponential; R texels a side), any of them `+contact`
    /// (screen-space contact shadows), `volumes` (per-triangle shadow
    /// volumes, stencil), or `shadow-maps` for sm, pcf3, pcf5, csm4-pcf3,
    /// vsm, msm and pcf3+contact at every `--map-sides`. The ground truth
    /// is always traced.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "izb1,izb32,izb32-exact,rt32,shadow-maps"
    )]
    methods: Vec<String>,
    /// Map sides `shadow-maps` expands over.
    #[arg(long, value_delimiter = ',', default_value = "512,1024,2048,4096,8192")]
    map_sides: Vec<u32>,
    /// Light sizes, comma separated, each as `render --light-size` takes
    /// it (a sun's angular radius in degrees, a sphere light's radius);
    /// every scene runs at each, named `scene~SIZE` (default: the
    /// scene's own light).
    #[arg(long, value_delimiter = ',')]
    light_size: Vec<f64>,
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
    /// When the CPU twin writes its vertex cache: where-long, always or
    /// never (the same masks; `izb render --help`).
    #[arg(long, value_enum, default_value_t = VertexCache::WhereLong)]
    vertex_cache: VertexCache,
}

pub fn run_bench(args: BenchArgs) -> Result<()> {
    // Looked up where the command runs, not where it was built.
    let shared_largest = Path::new("../shared/scenes/courtyard.scene.json");
    let scenes = if args.scenes.is_empty() {
        if shared_largest.exists() {
            vec![shared_largest.display().to_string()]
        } else {
            crate::note!("bench: ../shared/scenes not found, measuring the `default` scene");
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
                edge_surfaces: true,
                vertex_cache: args.vertex_cache,
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
            bench::MethodKind::RayTraced32 { .. } | bench::MethodKind::Embree32
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
            .map(bench::timed_renderer)
            .context("bench --backend vulkan")?,
        )
    };
    let images_dir = args.out.with_extension("images");
    let image_prefix = bench::relative_to(&images_dir, &args.out);
    let flicker_options = bench::flicker::FlickerOptions {
        frames: args.flicker_frames,
        step_degrees: args.flicker_step,
        reference: reference_settings,
    };
    flicker_options.check().map_err(anyhow::Error::msg)?;
    let (mut rows, mut scene_rows, mut flicker_rows) = (Vec::new(), Vec::new(), Vec::new());
    let resolutions: Vec<Option<[u32; 2]>> = if args.resolution.is_empty() {
        vec![None]
    } else {
        args.resolution.iter().copied().map(Some).collect()
    };
    let light_sizes: Vec<Option<f64>> = if args.light_size.is_empty() {
        vec![None]
    } else {
        args.light_size.iter().copied().map(Some).collect()
    };
    let mut runs = Vec::new();
    for name in &scenes {
        for &r in &resolutions {
            for &l in &light_sizes {
                runs.push((name, r, l));
            }
        }
    }
    // Every scene loads before the first ground truth, so a bad one stops
    // the run before anything is written; the images go to a staged
    // folder that only a finished run renames into place.
    for &(name, resolution, light_size) in &runs {
        load_scene_quietly(&SceneArgs {
            scene: name.clone(),
            resolution,
            light_size,
        })?;
    }
    let images = crate::output::StagedDir::new(&images_dir)?;
    let options = bench::BenchOptions {
        repeat: args.repeat,
        reference: reference_settings,
        images: Some(images.path().to_path_buf()),
    };
    for (name, resolution, light_size) in runs {
        let mut scene = load_scene(&SceneArgs {
            scene: name.clone(),
            resolution,
            light_size,
        })?;
        if resolutions.len() > 1 {
            let [w, h] = scene.resolution;
            scene.name = format!("{}@{w}x{h}", scene.name);
        }
        if let Some(size) = light_size {
            scene.name = format!("{}~{size}", scene.name);
        }
        let bar = progress_bar(scene.pixel_count() as u64, &format!("truth {}", scene.name));
        let shared =
            pool.install(|| bench::SceneTruth::new(&scene, reference_settings, &|n| bar.inc(n)));
        bar.finish_and_clear();
        let stats = &shared.truth.stats;
        crate::say!(
            "{}: {} triangles, {}x{}; ground truth {} spp: {:.2} s ({:.2} Mrays/s, {} threads)",
            scene.name,
            scene.triangles.len(),
            scene.resolution[0],
            scene.resolution[1],
            reference_settings.spp(),
            stats.seconds,
            stats.rays_per_second / 1e6,
            pool.current_num_threads()
        )?;
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
            crate::note!("bench: {why}");
        }
        print_bench_table(&scene.name, &scene_results)?;
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
                crate::say!(
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
                )?;
            }
            flicker_rows.push(SceneFlicker {
                scene: scene.name.clone(),
                rows: f,
            });
        }
        scene_rows.push(SceneEntry {
            name: scene.name.clone(),
            summary: scene.summary(),
            truth: TruthEntry {
                spp: reference_settings.spp(),
                seconds: stats.seconds,
                rays_per_second: stats.rays_per_second,
                bvh_build_seconds: shared.bvh_seconds,
                stats: serde_json::to_value(stats)?,
                image: format!("{image_prefix}/{}/truth.exr", bench::file_stem(&scene.name)),
            },
            gbuffer_seconds: shared.gbuffer_seconds,
            refused,
        });
        rows.extend(scene_results.into_iter().map(|row| ResultRow {
            scene: scene.name.clone(),
            row,
        }));
    }
    let scaling = izb32_scaling(&rows);
    for s in &scaling {
        crate::say!(
            "{} ({}): izb32 shadow time {:.2}x from {} to {} ({:.1}x the pixels)",
            s.scene,
            s.backend,
            s.time_ratio,
            s.from,
            s.to,
            s.pixel_ratio
        )?;
    }
    let report = BenchDocument {
        command: "bench".into(),
        izb32_scaling: scaling,
        device: gpu.as_ref().map(|g| g.context.info().clone()),
        cpu: cpu_model(),
        threads: pool.current_num_threads(),
        logical_cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        repeat: args.repeat,
        reference_spp: reference_settings.spp(),
        flicker_settings: args.flicker.then_some(FlickerSettings {
            frames: flicker_options.frames,
            step_degrees: flicker_options.step_degrees,
        }),
        scenes: scene_rows,
        results: rows,
        flicker: flicker_rows,
    };
    images.commit()?;
    if let Err(e) = write_json(&args.out, &report) {
        // No document for the images: remove them too.
        let _ = std::fs::remove_dir_all(&images_dir);
        return Err(e.context(format!("writing {}", args.out.display())));
    }
    crate::say!(
        "wrote {} (images in {})",
        args.out.display(),
        images_dir.display()
    )?;
    Ok(())
}

/// For every scene benchmarked at several resolutions: izb32's shadow
/// time at the largest over the smallest, per backend.
pub fn izb32_scaling(rows: &[ResultRow]) -> Vec<Scaling> {
    // (scene, backend) -> (pixels, "WxH", shadow seconds) per resolution.
    type Runs = Vec<(u64, String, f64)>;
    let mut by_scene: std::collections::BTreeMap<(String, String), Runs> = Default::default();
    for r in rows.iter().filter(|r| r.row.method == "izb32") {
        let Some((scene, size)) = r.scene.rsplit_once('@') else {
            continue;
        };
        let pixels = size
            .split_once('x')
            .and_then(|(w, h)| Some(w.parse::<u64>().ok()? * h.parse::<u64>().ok()?))
            .unwrap_or(0);
        by_scene
            .entry((scene.to_string(), r.row.backend.clone()))
            .or_default()
            .push((pixels, size.to_string(), r.row.shadow_seconds));
    }
    by_scene
        .into_iter()
        .filter(|(_, v)| v.len() > 1)
        .map(|((scene, backend), mut v)| {
            v.sort_by_key(|e| e.0);
            let (lo, hi) = (&v[0], &v[v.len() - 1]);
            Scaling {
                scene,
                backend,
                from: lo.1.clone(),
                to: hi.1.clone(),
                pixel_ratio: hi.0 as f64 / lo.0.max(1) as f64,
                time_ratio: hi.2 / lo.2,
            }
        })
        .collect()
}

/// The CPU's model name (Linux), for the bench JSON.
pub fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    info.lines().find_map(|l| {
        l.strip_prefix("model name")?
            .split_once(':')
            .map(|(_, v)| v.trim().to_string())
    })
}

/// One line per method: time, ratio to `izb32`, and the error metrics.
pub fn print_bench_table(
    scene: &str,
    rows: &[bench::MethodRow],
) -> Result<(), crate::cli::console::StreamClosed> {
    // The method column fits the longest name (`csm4-pcf3-2048+contact`).
    let w = rows.iter().map(|r| r.method.len()).fold(16, usize::max);
    crate::say!(
        "{scene}: {:<w$} {:>7} {:>10} {:>8} {:>9} {:>9} {:>9} {:>8}",
        "method",
        "backend",
        "shadow s",
        "/izb32",
        "MAE",
        "penumbra",
        "edge",
        "% wrong"
    )?;
    for r in rows {
        crate::say!(
            "{scene}: {:<w$} {:>7} {:>10.4} {:>8} {:>9.5} {:>9.4} {:>9.4} {:>8.3}",
            r.method,
            r.backend,
            r.shadow_seconds,
            r.shadow_seconds_over_izb32
                .map_or("-".to_string(), |x| format!("{x:.2}")),
            r.metrics.mae,
            r.metrics.smooth_penumbra_mae,
            r.metrics.edge_mae,
            r.metrics.percent_over_one_sample
        )?;
    }
    Ok(())
}
