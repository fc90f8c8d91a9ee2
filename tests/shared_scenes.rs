//! The five real scenes of `../shared/scenes` load through their specs with
//! the triangle counts listed in that folder's README. Skipped (with a
//! message) where the folder is not present, e.g. outside this workspace.

mod common;

use glam::DVec3;
use izb::scene::{Scene, Triangle};
use std::time::Instant;

/// Loads `<name>.scene.json` and checks its source triangle count and the
/// kept + dropped balance; `None` when the scenes are absent.
fn load_counted(name: &str, source_triangles: usize) -> Option<Scene> {
    let dir = common::shared_scenes_dir()?;
    let spec = dir.join(format!("{name}.scene.json"));
    let start = Instant::now();
    let scene = izb::scene::load(spec.to_str().unwrap()).unwrap_or_else(|e| panic!("{e}"));
    let seconds = start.elapsed().as_secs_f64();
    println!(
        "{name}: {} source triangles, {} kept, {} degenerate dropped, {} point/line primitives \
         skipped, loaded in {seconds:.3} s",
        scene.stats.source_triangles,
        scene.triangles.len(),
        scene.stats.dropped_degenerate,
        scene.stats.skipped_non_triangle_primitives,
    );
    assert_eq!(scene.name, name);
    assert_eq!(
        scene.stats.source_triangles, source_triangles,
        "README count for {name}"
    );
    assert_eq!(
        scene.triangles.len() + scene.stats.dropped_degenerate,
        scene.stats.source_triangles
    );
    assert_eq!(scene.source_ids.len(), scene.triangles.len());
    // Ids index the source array and increase with it.
    assert!(scene.source_ids.windows(2).all(|w| w[0] < w[1]));
    assert!(scene
        .source_ids
        .last()
        .is_some_and(|&id| (id as usize) < source_triangles));
    Some(scene)
}

#[test]
fn deckchair() {
    load_counted("deckchair", 1_154);
}

#[test]
fn tablefan() {
    load_counted("tablefan", 35_958);
}

#[test]
fn ficus() {
    load_counted("ficus", 118_878);
}

#[test]
fn engine() {
    let Some(scene) = load_counted("engine", 121_496) else {
        return;
    };
    // The README counts 11,160 triangles of exactly zero area in the
    // source; the scene also drops slivers thinner than 4 ε32 of their
    // longest edge, so it may drop more.
    let dropped = scene.stats.dropped_degenerate;
    let source =
        izb::scene::load_gltf(&common::shared_scenes_dir().unwrap().join("engine_121k.glb"))
            .unwrap();
    let zero_area = |t: &&Triangle| (t[1] - t[0]).cross(t[2] - t[0]) == DVec3::ZERO;
    let zero_area_in_source = source.triangles.iter().filter(zero_area).count();
    let zero_area_kept = scene.triangles.iter().filter(zero_area).count();
    println!(
        "engine: {dropped} degenerate dropped, {zero_area_in_source} of zero area in the source \
         (README: 11,160), {} slivers",
        dropped.saturating_sub(zero_area_in_source)
    );
    assert_eq!(
        zero_area_in_source, 11_160,
        "README count of zero-area triangles"
    );
    assert_eq!(zero_area_kept, 0, "zero-area triangles must all be dropped");
    assert!(
        dropped >= 11_160,
        "engine: only {dropped} degenerate triangles dropped"
    );
}

#[test]
fn courtyard() {
    load_counted("courtyard", 878_047);
}
