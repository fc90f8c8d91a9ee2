//! The `izb` command line's commands, as library code: each command's
//! arguments (clap) and the function that runs it. `src/bin/izb.rs` only
//! parses and dispatches. Every command takes a `SCENE`: a procedural
//! scene's name (default: `default`) or a path to a `*.scene.json` spec.

pub mod bench;
pub mod console;
pub mod reference;
pub mod render;
pub mod tools;
pub mod view;

use crate::bvh::SceneBvh;
use crate::cascades::CascadeCount;
use crate::reference::{reference, ReferenceImage, ReferenceSettings};
use crate::scene::{self, Scene};
use crate::settings::{IzbSettings, ReceiverCull, VertexCache};
use anyhow::Result;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::time::Instant;

#[derive(Args)]
pub struct SceneArgs {
    /// Procedural scene name (default, wires, hairball, city, grazing, far,
    /// analytic) or path to a *.scene.json spec.
    #[arg(default_value = "default")]
    scene: String,
    /// Image size WxH, overriding the scene's.
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<[u32; 2]>,
    /// The light's size, overriding the scene's: a directional light's
    /// angular radius in degrees (the sun: 0.27), a point light's sphere
    /// radius in scene units; 0 for hard shadows.
    #[arg(long)]
    light_size: Option<f64>,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Backend {
    /// Vulkan when a device opens, else the CPU (saying why).
    Auto,
    /// The Vulkan backend (ash); fails if no device opens.
    Vulkan,
    /// The CPU twin (rayon).
    Cpu,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchBackend {
    Cpu,
    Vulkan,
    Both,
}

/// Grid, overflow and cascade choices of a render.
#[derive(Args, Clone)]
pub struct GridArgs {
    /// Cell budget of the light-space grids as the side of a square (200:
    /// 40 000 cells, square in light space whatever the footprint's shape),
    /// shared between the cascades in proportion to their pixels (default:
    /// from the pixel and triangle counts). At most 4096: no grid is
    /// longer than that either way, so a larger budget adds no cell.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=crate::cascades::MAX_GRID_SIDE as i64))]
    cells: Option<u32>,
    /// A triangle is binned at the finest grid-pyramid level where its
    /// cell rectangle holds at most this many cells (default 16384).
    #[arg(long)]
    level_cells: Option<u32>,
    /// Sample-distribution cascades: auto (as few as the view-depth range
    /// needs) or 1..4.
    #[arg(long, default_value = "auto", value_parser = CascadeCount::parse)]
    cascades: CascadeCount,
    /// Cascade split blend: 1 logarithmic, 0 uniform.
    #[arg(long, default_value_t = 1.0)]
    split_lambda: f32,
    /// When the CPU twin takes the behind-receivers skip: always, or
    /// where-dense (under an area light, or where the placed triangles'
    /// rectangles cover at least 20 cells per cell).
    #[arg(long, value_enum, default_value_t = ReceiverCull::WhereDense)]
    receiver_cull: ReceiverCull,
    /// When the CPU twin's bin writes its vertex cache in cell order for
    /// evaluate to read sixteen entries at a time: where-long (where cell
    /// lists are long enough for it to pay), always or never (each
    /// candidate read by id). The masks are the same.
    #[arg(long, value_enum, default_value_t = VertexCache::WhereLong)]
    vertex_cache: VertexCache,
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
            receiver_cull: self.receiver_cull,
            vertex_cache: self.vertex_cache,
            ..settings
        })
    }
}

pub fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}': expected WxH, e.g. 960x540"))?;
    let parse = |v: &str| v.trim().parse::<u32>().map_err(|e| format!("'{s}': {e}"));
    Ok([parse(w)?, parse(h)?])
}

/// The scene of `args`, its warnings printed.
pub fn load_scene(args: &SceneArgs) -> Result<Scene> {
    let scene = load_scene_quietly(args)?;
    for w in &scene.warnings {
        crate::note!("warning: {w}");
    }
    Ok(scene)
}

/// The scene of `args`, its warnings kept in [`Scene::warnings`].
pub fn load_scene_quietly(args: &SceneArgs) -> Result<Scene> {
    let mut scene = scene::load(&args.scene)?;
    if let Some(r) = args.resolution {
        scene = scene.with_resolution(r)?;
    }
    if let Some(size) = args.light_size {
        scene = scene.with_light_size(size)?;
    }
    Ok(scene)
}

/// The worker pool of `--threads` (default: one per core), at most
/// [`THREADS_PER_CORE`] per core: more only adds stacks and switching (and
/// `--threads 100000` spent over a minute starting threads).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        anyhow::ensure!(n > 0, "--threads must be at least 1");
        let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
        let most = THREADS_PER_CORE * cores;
        anyhow::ensure!(
            n <= most,
            "--threads {n}: at most {most} on this machine ({THREADS_PER_CORE} per core, {cores} cores)"
        );
        b = b.num_threads(n);
    }
    Ok(b.build()?)
}

/// The most worker threads per core `--threads` takes.
pub const THREADS_PER_CORE: usize = 4;

pub fn progress_bar(len: u64, what: &str) -> ProgressBar {
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
pub fn trace_reference(
    scene: &Scene,
    settings: ReferenceSettings,
) -> (ReferenceImage, SceneBvh, f64) {
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
