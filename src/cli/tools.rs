//! The small commands: `izb lut`, `izb report`, `izb info`, `izb devices`.

use super::{load_scene, SceneArgs};
use crate::settings::IzbSettings;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct InfoArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Also print the device memory a GPU frame allocates, per pass (no
    /// device needed).
    #[arg(long)]
    gpu_memory: bool,
    /// With --gpu-memory: plan for the edge pixels' extra surfaces too
    /// (casts the CPU G-buffer's sample rays to count them).
    #[arg(long, requires = "gpu_memory")]
    edge_surfaces: bool,
}

#[derive(Args)]
pub struct LutArgs {
    /// Angle cells of both tables (pixel and light).
    #[arg(long, default_value_t = crate::lut::DEFAULT_ANGLES)]
    angles: u32,
    /// Signed-distance cells of both tables.
    #[arg(long, default_value_t = crate::lut::DEFAULT_DISTANCES)]
    distances: u32,
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(Args)]
pub struct ReportArgs {
    /// A JSON file written by `izb bench`.
    #[arg(default_value = "out/bench.json")]
    bench: PathBuf,
    /// Folder for the charts, crops and index.html.
    #[arg(long, default_value = "out/report")]
    out: PathBuf,
}

pub fn run_report(args: ReportArgs) -> Result<()> {
    let files = crate::report::report(&args.bench, &args.out)?;
    for v in &files.verdicts {
        crate::say!(
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
        )?;
    }
    crate::say!(
        "report: {} charts, {} crops -> {}",
        files.charts.len(),
        files.crops.len(),
        files.index.display()
    )?;
    Ok(())
}

pub fn run_lut(args: LutArgs) -> Result<()> {
    let stats = crate::lut::regenerate_tables(args.angles, args.distances, &args.out)?;
    crate::say!(
        "pixel table ({}), edges crossing the pixel, distances in pixels:",
        crate::lut::SAMPLE_PATTERN_NAME
    )?;
    crate::say!("{:#?}", stats.edge)?;
    crate::say!(
        "light table ({}), edges crossing the light disk, coverage against the disk's area, \
         distances in light-disk diameters:",
        crate::lut::LIGHT_PATTERN_NAME
    )?;
    crate::say!("{:#?}", stats.light)?;
    for name in [
        "edge_lut.bin",
        "edge_lut.png",
        "light_lut.bin",
        "light_lut.png",
    ] {
        crate::say!("wrote {}", args.out.join(name).display())?;
    }
    Ok(())
}

use crate::gpu::frame::EdgeSlots;

pub fn run_info(args: InfoArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let (lo, hi) = scene.bounds();
    let mut summary = scene.summary();
    summary["bounds"] = serde_json::json!({"min": lo, "max": hi});
    if args.gpu_memory {
        let extra = args.edge_surfaces.then(|| {
            let bvh = crate::bvh::SceneBvh::build(&scene);
            let g = crate::gbuffer::gbuffer_with(&scene, &bvh, 1);
            g.edges.map_or(
                EdgeSlots {
                    surfaces: 0,
                    pixels: 0,
                },
                |e| EdgeSlots {
                    surfaces: e.pixel.len() as u64,
                    pixels: e.stats.edge_pixels as u64,
                },
            )
        });
        let plan_of = |one_view| {
            crate::gpu::shadow_pass::planned_memory(&scene, IzbSettings::default(), extra, one_view)
        };
        // `izb render`'s pass (one view), and a resident one whose eye
        // moves (the viewer's, a host's).
        let plan = plan_of(true)?;
        let resident: u64 = plan_of(false)?.iter().map(|m| m.bytes).sum();
        let total: u64 = plan.iter().map(|m| m.bytes).sum();
        let (p, t) = (scene.pixel_count() as u64, scene.triangles.len() as u64);
        summary["gpu_memory"] = serde_json::json!({
            "per_pass": plan,
            "total_bytes": total,
            "total_mib": total as f64 / (1024.0 * 1024.0),
            "budget_bytes_64_per_pixel_plus_64_per_triangle": 64 * (p + t),
            "bytes_per_pixel_plus_triangle": total as f64 / (p + t).max(1) as f64,
            "resident_pass_total_bytes": resident,
            "resident_pass_bytes_per_pixel_plus_triangle": resident as f64 / (p + t).max(1) as f64,
            "edge_surfaces": extra.map(|e| e.surfaces),
            "edge_pixels": extra.map(|e| e.pixels),
        });
    }
    crate::say!("{}", serde_json::to_string_pretty(&summary)?)?;
    Ok(())
}

pub fn run_devices() -> Result<()> {
    let devices = crate::gpu::list_devices()?;
    if devices.is_empty() {
        crate::say!("no Vulkan 1.2 device with compute and the scalar block layout")?;
    }
    for d in devices {
        crate::say!(
            "{}: {} ({}, Vulkan {}, max storage buffer {} MiB)",
            d.index,
            d.name,
            d.kind,
            d.api_version,
            d.max_storage_buffer_range / (1 << 20)
        )?;
    }
    Ok(())
}
