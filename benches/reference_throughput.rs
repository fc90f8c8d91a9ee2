//! `cargo bench --bench reference_throughput`: rays per second of the
//! ground-truth tracer on the largest shared scene (or the `default` scene
//! when `../shared` is absent), written as JSON to `target/bench/`.
//! The same measurement is `izb bench`; this keeps it under `cargo bench`.

use izb::bvh::SceneBvh;
use izb::reference::{reference, ReferenceSettings};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let courtyard = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/scenes/courtyard.scene.json"
    );
    let arg = if std::path::Path::new(courtyard).exists() {
        courtyard
    } else {
        println!("../shared/scenes not found: measuring the `default` scene");
        "default"
    };
    let scene = izb::scene::load(arg)?;
    let t = Instant::now();
    let bvh = SceneBvh::build(&scene);
    let bvh_seconds = t.elapsed().as_secs_f64();
    let mut runs = Vec::new();
    for _ in 0..3 {
        let settings = ReferenceSettings {
            samples_per_side: 4,
            seed: 1,
        };
        runs.push(reference(&scene, &bvh, settings, &|_| {}).stats);
    }
    runs.sort_by(|a, b| a.rays_per_second.total_cmp(&b.rays_per_second));
    let median = &runs[1];
    let report = serde_json::json!({
        "scene": scene.name,
        "triangles": scene.triangles.len(),
        "resolution": scene.resolution,
        "spp": 16,
        "bvh_build_seconds": bvh_seconds,
        "median_seconds": median.seconds,
        "median_rays_per_second": median.rays_per_second,
        "threads": rayon::current_num_threads(),
    });
    println!("{}", serde_json::to_string_pretty(&report)?);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench");
    izb::output::write_json(&dir.join("reference_throughput.json"), &report)?;
    Ok(())
}
