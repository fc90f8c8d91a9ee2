//! Scene load and BVH build times: per scene spec, the median of 5 runs of
//! `scene::load` (glTF read, degenerate and coincident triangles dropped),
//! of the CPU `SceneBvh::build` and of the GPU G-buffer's `build_bvh`,
//! with the largest group of triangles sharing one `f32` box (what
//! `src/bvh/clusters.rs` groups from 16 up).
//!
//! `cargo run --release --example bvh_build_times -- [SPEC...]`
//! (default: every `../shared/scenes/*.scene.json`)

use izb::bvh::SceneBvh;
use izb::gpu::gbuffer::build_bvh;
use izb::gpu::shared::GpuTriangle;
use std::collections::HashMap;
use std::time::Instant;

const RUNS: usize = 5;

fn median_ms(mut f: impl FnMut()) -> f64 {
    let mut times: Vec<f64> = (0..RUNS)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[RUNS / 2]
}

/// Largest number of eye-relative triangles whose `f32` boxes, padded by
/// `pad` in `f64` as `SceneBvh` pads them, are bit-identical.
fn largest_box_group(triangles: &[[glam::DVec3; 3]], pad: f64) -> usize {
    let mut groups: HashMap<[u32; 6], usize> = HashMap::new();
    for t in triangles {
        let lo = (t[0].min(t[1]).min(t[2]) - pad).as_vec3().to_array();
        let hi = (t[0].max(t[1]).max(t[2]) + pad).as_vec3().to_array();
        let key = [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits);
        *groups.entry(key).or_default() += 1;
    }
    groups.values().copied().max().unwrap_or(0)
}

fn main() {
    let mut specs: Vec<String> = std::env::args().skip(1).collect();
    if specs.is_empty() {
        let mut found: Vec<String> = std::fs::read_dir("../shared/scenes")
            .expect("../shared/scenes")
            .filter_map(|e| e.ok().map(|e| e.path().to_string_lossy().into_owned()))
            .filter(|p| p.ends_with(".scene.json"))
            .collect();
        found.sort();
        specs = found;
    }
    println!(
        "scene        triangles  load_ms  cpu_bvh_ms  gpu_bvh_ms  largest_box_group (cpu, gpu)"
    );
    for spec in &specs {
        let scene = izb::scene::load(spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
        let load = median_ms(|| {
            std::hint::black_box(izb::scene::load(spec).expect("loads again"));
        });
        // `Scene::new` alone: degenerate and coincident triangles dropped,
        // the scene validated (the part of `load` past reading the glTF).
        let assemble = median_ms(|| {
            let t = scene.triangles.to_vec();
            std::hint::black_box(
                izb::scene::Scene::new("again", t, scene.camera, scene.light, scene.resolution)
                    .expect("valid"),
            );
        });
        let cpu = median_ms(|| {
            std::hint::black_box(SceneBvh::build(&scene));
        });
        let eye_relative = scene.eye_relative_triangles();
        let radius = eye_relative
            .iter()
            .flatten()
            .map(|v| v.abs().max_element())
            .fold(0.0, f64::max);
        let groups = (
            largest_box_group(&eye_relative, 16.0 * f32::EPSILON as f64 * radius),
            largest_box_group(&eye_relative, 0.0),
        );
        let gpu_tris: Vec<GpuTriangle> = eye_relative
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v.as_vec3().to_array());
                GpuTriangle { a, b, c }
            })
            .collect();
        let gpu = median_ms(|| {
            std::hint::black_box(build_bvh(&gpu_tris).expect("builds"));
        });
        println!(
            "{:<12} {:>9} {:>8.1} {:>7.1} {:>11.1} {:>11.1} {:>18?}",
            scene.name,
            scene.triangles.len(),
            load,
            assemble,
            cpu,
            gpu,
            groups
        );
    }
}
