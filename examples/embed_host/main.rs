//! The shadow pass inside a host's frame (issue 29): a host that makes
//! its own Vulkan instance, device and queue, draws the scene into a
//! visibility buffer on the rasteriser, and records izb's shadow pass into
//! the same command buffer each frame, with the camera and light moving
//! and two frames in flight. Prints the run's counters as JSON: izb's
//! allocations after the first frame (0), `record`'s host time, the
//! validation layer's messages (with `IZB_VALIDATION=1`, synchronization
//! validation on), and how many shadow-tested pixels of the last frame
//! equal `izb render`'s masks of the same view.
//!
//! ```text
//! cargo run --release --example embed_host -- [SCENE ...] [--frames N] [--resolution WxH]
//! ```
//!
//! SCENE: a procedural name (`default`) or a `*.scene.json` spec;
//! default `default`.

mod after_loop;
mod frames;
mod host_device;
mod raster;
mod targets;

use frames::{run, HostOptions};
use izb::cpu::SampleMode;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut scenes = Vec::new();
    let mut frames = 30;
    let mut resolution = [160, 90];
    while let Some(a) = args.next() {
        match a.as_str() {
            "--frames" => {
                frames = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .ok_or("--frames N")?
            }
            "--resolution" => {
                let v = args.next().ok_or("--resolution WxH")?;
                let (w, h) = v.split_once('x').ok_or("--resolution WxH")?;
                resolution = [
                    w.parse().map_err(|_| "--resolution WxH")?,
                    h.parse().map_err(|_| "--resolution WxH")?,
                ];
            }
            _ => scenes.push(a),
        }
    }
    if scenes.is_empty() {
        scenes.push("default".into());
    }
    let validation = std::env::var("IZB_VALIDATION").is_ok_and(|v| v == "1");
    let gpu = host_device::HostGpu::new(validation)?;
    let mut report = Vec::new();
    for name in &scenes {
        let scene = izb::scene::load(name)
            .and_then(|s| s.with_resolution(resolution))
            .map_err(|e| format!("{name}: {e}"))?;
        let options = HostOptions {
            frames,
            frames_in_flight: 2,
            mode: SampleMode::Exact32,
            cell_capacity: None,
            resize: None,
            heavy_entries: std::env::var("IZB_GPU_HEAVY_ENTRIES")
                .ok()
                .and_then(|v| v.parse().ok()),
        };
        let result = run(&gpu, &scene, options)?;
        let agreement = after_loop::agreement_with_render(&scene, &result, options.mode);
        let mut json = serde_json::to_value(&result).map_err(|e| e.to_string())?;
        json["last_frame_against_render"] =
            serde_json::to_value(agreement).map_err(|e| e.to_string())?;
        report.push(json);
    }
    println!(
        "{}",
        serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?
    );
    Ok(())
}
