//! The shadow pass inside a host's frame (issue 29): a host that makes
//! its own Vulkan instance, device and queue, draws the scene into a
//! visibility buffer (or, with `--depth`, a depth and normal G-buffer) on
//! the rasteriser, and records izb's shadow pass into the same command
//! buffer each frame — the pass reading the raster's own vertex and index
//! buffers (`ShadowPass::with_host_geometry`) — then its own lighting pass
//! sampling the lit fraction the pass left, with the camera and light
//! moving and two frames in flight. Prints the run's counters as JSON: izb's
//! allocations after the first frame (0), `record`'s host time, the
//! validation layer's messages (with `IZB_VALIDATION=1`, synchronization
//! validation on), and how many shadow-tested pixels of the last frame
//! equal `izb render`'s masks of the same view (with `--depth`, also how
//! many equal the CPU twin's on the pass's G-buffer read back).
//!
//! ```text
//! cargo run --release --example embed_host -- [SCENE ...] [--frames N] [--resolution WxH]
//!     [--depth d32|d24s8|x8d24|d32s8] [--standard-z] [--infinite-far]
//!     [--msaa 1|2|4|8] [--exact] [--out DIR] [--stats FILE]
//! ```
//!
//! SCENE: a procedural name (`default`) or a `*.scene.json` spec;
//! default `default`. Frame 0 has the spec's camera and light. The mode is
//! the 32-sample LUT (`--exact`: the exact test). `--msaa N` draws the
//! visibility buffer and its depth with N samples a pixel, not resolved:
//! the pass reads every sample (`GBufferInput::MultisampledVisibility`,
//! edge pixels' surfaces from them), the host's lighting shades sample 0,
//! and the twin check feeds the CPU twin every sample, read back
//! (`multisampled`: frame 0's centre triangles that differ from the
//! twin's, and the rejected and uncovered centres of both). `--out DIR` writes frame
//! 0 as `izb render` writes a frame (`DIR/SCENE` with several scenes),
//! and the host's own lighting of it as `host_shaded.png`;
//! `--stats FILE` writes the run's counters as one JSON object (an array
//! of them with several scenes): `frames`, `allocations_after_first`,
//! `descriptor_allocations_after_first`, `maps_after_first`,
//! `waits_in_frame`, `readbacks_in_frame`, `record_us_median` (wall
//! time; `record_cpu_us_median`: the thread's CPU time), `gpu_ms`,
//! `validation_messages`, `sync_validation`, `masks_compared` and
//! `mask_mismatches` (frame 0's G-buffer, made from the host's raster,
//! read back and fed to the CPU twin in the frame's mode), and
//! `lighting_pixels_differing` / `lighting_max_difference` (the host's
//! lighting of frame 0 against izb's own shaded image, 8-bit codes).

mod after_loop;
mod first_frame;
mod frames;
mod gpu_timing;
mod host_device;
mod host_run;
mod lighting;
mod mesh;
mod multisampled_ids;
mod raster;
mod targets;

use ash::vk;
use frames::{run, HostOptions};
use izb::cpu::SampleMode;
use izb::gbuffer::DepthConvention;
use targets::HostDepth;

fn main() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut scenes = Vec::new();
    let mut frames = 30;
    let mut resolution = [160, 90];
    let (mut depth_format, mut standard_z, mut infinite_far) = (None, false, false);
    let (mut mode, mut out, mut stats_path) = (SampleMode::Lut32, None, None);
    let mut msaa = 1;
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
            "--depth" => {
                depth_format = Some(match args.next().as_deref() {
                    Some("d32") => vk::Format::D32_SFLOAT,
                    Some("d24s8") => vk::Format::D24_UNORM_S8_UINT,
                    Some("x8d24") => vk::Format::X8_D24_UNORM_PACK32,
                    Some("d32s8") => vk::Format::D32_SFLOAT_S8_UINT,
                    _ => return Err("--depth d32|d24s8|x8d24|d32s8".into()),
                })
            }
            "--standard-z" => standard_z = true,
            "--msaa" => {
                msaa = match args.next().as_deref() {
                    Some("1") => 1,
                    Some("2") => 2,
                    Some("4") => 4,
                    Some("8") => 8,
                    _ => return Err("--msaa 1|2|4|8".into()),
                }
            }
            "--exact" => mode = SampleMode::Exact32,
            "--out" => out = Some(std::path::PathBuf::from(args.next().ok_or("--out DIR")?)),
            "--stats" => {
                stats_path = Some(std::path::PathBuf::from(args.next().ok_or("--stats FILE")?))
            }
            "--infinite-far" => infinite_far = true,
            _ => scenes.push(a),
        }
    }
    if scenes.is_empty() {
        scenes.push("default".into());
    }
    let validation = std::env::var("IZB_VALIDATION").is_ok_and(|v| v == "1");
    let gpu = host_device::HostGpu::new(validation)?;
    let mut report = Vec::new();
    let mut stats = Vec::new();
    for name in &scenes {
        let scene = izb::scene::load(name)
            .and_then(|s| s.with_resolution(resolution))
            .map_err(|e| format!("{name}: {e}"))?;
        let options = HostOptions {
            frames,
            frames_in_flight: 2,
            mode,
            cell_capacity: None,
            resize: None,
            depth: depth_format.map(|format| HostDepth {
                format,
                convention: DepthConvention {
                    near: scene.camera.near,
                    far: (!infinite_far).then_some(scene.camera.far),
                    reversed: !standard_z,
                },
            }),
            msaa,
            heavy_entries: std::env::var("IZB_GPU_HEAVY_ENTRIES")
                .ok()
                .and_then(|v| v.parse().ok()),
            check_first_frame: out.is_some() || stats_path.is_some(),
        };
        let result = run(&gpu, &scene, options)?;
        if let (Some(dir), Some((frame, view))) = (&out, &result.first_frame_images) {
            let dir = match scenes.len() {
                1 => dir.clone(),
                _ => dir.join(&scene.name),
            };
            let seen = first_frame::seen_as(&scene, view, result.resolution);
            let extra = serde_json::json!({ "mode": mode, "first_frame": result.first_frame });
            first_frame::write_frame(frame, &seen, &dir, extra)?;
            let host_shaded = &result.first_frame_host_shaded;
            first_frame::write_host_shaded(host_shaded, result.resolution, &dir)?;
        }
        stats.push(stats_of(&result, validation));
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
    if let Some(path) = &stats_path {
        let value = match stats.len() {
            1 => stats.remove(0),
            _ => serde_json::Value::Array(stats),
        };
        izb::output::write_json(path, &value).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}

/// The counters `--stats` writes for one scene's run.
fn stats_of(run: &frames::HostRun, validation: bool) -> serde_json::Value {
    let after = &run.in_frames_after_first;
    let twin = run.first_frame.unwrap_or_default();
    serde_json::json!({
        "scene": run.scene,
        "device": run.device,
        "resolution": run.resolution,
        "frames": run.frames,
        "frames_in_flight": run.frames_in_flight,
        "msaa": run.msaa,
        "multisampled": run.first_frame_multisampled,
        "allocations_after_first": after.buffers,
        "descriptor_allocations_after_first": after.descriptor_sets,
        "maps_after_first": after.mappings,
        // izb waits only in its submissions (uploads and read-backs).
        "waits_in_frame": after.waits,
        "readbacks_in_frame": after.waits,
        "record_us_median": gpu_timing::median(&run.record_us),
        "record_cpu_us_median": gpu_timing::median(&run.record_cpu_us),
        "record_alone_us_median": gpu_timing::median(&run.record_alone_us),
        "record_cold_us_median": gpu_timing::median(&run.record_cold_us),
        "gpu_ms": run.gpu_ms,
        "validation_messages": run.validation_messages.len(),
        "sync_validation": validation,
        "masks_compared": twin.masks_compared,
        "mask_mismatches": twin.mask_mismatches,
        "sample_mismatches": twin.sample_mismatches,
        "lighting_pixels_differing": run.first_frame_lighting.map(|l| l.differing),
        "lighting_max_difference": run.first_frame_lighting.map(|l| l.max_difference),
        "overruns": run.overruns,
        "grown": run.grown,
        "loop_capped_frames": run.loop_capped_frames.len(),
    })
}
