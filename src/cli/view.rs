//! `izb view`: the interactive viewer ([`crate::view`]).

use super::{load_scene, SceneArgs};
use crate::gpu::GpuOptions;
use crate::output::write_json;
use crate::view::{run_view, script, ViewOptions};
use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct ViewArgs {
    #[command(flatten)]
    scene: SceneArgs,
    /// Timed actions to run in the window (see `src/view/script.rs`),
    /// e.g. for tests and screenshots.
    #[arg(long)]
    script: Option<PathBuf>,
    /// Write the session's UI frame times, shadow frame times, screenshots
    /// and validation messages here (JSON) when the window closes.
    #[arg(long)]
    stats: Option<PathBuf>,
    /// Window size WxH.
    #[arg(long, value_parser = super::parse_resolution, default_value = "1280x720")]
    window: [u32; 2],
    /// Vulkan device index for the shadow passes (see `izb devices`).
    #[arg(long)]
    device: Option<usize>,
    /// Where the screenshot key writes.
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

pub fn run_view_command(args: ViewArgs) -> Result<()> {
    let scene = load_scene(&args.scene)?;
    let script = match &args.script {
        Some(p) => script::load(p).map_err(anyhow::Error::msg)?,
        None => Vec::new(),
    };
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let stats = run_view(ViewOptions {
        scene,
        script,
        gpu: GpuOptions {
            device_index: args.device,
            ..GpuOptions::from_env()
        },
        window_size: args.window,
        out: args.out,
        truth_threads: cores.saturating_sub(1).max(1),
    })?;
    crate::note!(
        "view: {} UI frames, slowest {:.1} ms ({:.1} ms while a shadow frame computed), {} shadow frames, {} validation messages",
        stats.ui_frames,
        stats.ui_millis_max,
        stats.ui_millis_max_while_computing,
        stats.frame_seconds.len(),
        stats.validation_messages.len()
    );
    for m in &stats.validation_messages {
        crate::note!("validation: {m}");
    }
    if let Some(path) = &args.stats {
        write_json(path, &stats)?;
    }
    Ok(())
}
