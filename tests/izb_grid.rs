//! The light-space grid pyramid against brute force: the scatter holds
//! exactly the triangles whose footprint touches each cell of each level
//! (within their rectangle), and no triangle able to
//! shadow any of a pixel's 32 samples is missing from the candidates the
//! pixel visits (zero light leaks by construction, paper-notes/reference-estimator.md), with one
//! grid and with several cascades.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::bin::{bin, place, CellEntry, Placement};
use izb::cpu::evaluate::{for_each_candidate, triangle_mask_for_pixel};
use izb::cpu::{
    eye_relative_f32, light_setup, CascadeCount, GridRequest, MaskRule, SampleMode, Skips,
};
use izb::gbuffer::{flags, gbuffer};
use izb::scene::{self, Scene};
use std::collections::HashSet;

/// `cull`: bin with the `behind_receivers` skip, so the brute force below
/// also proves that skip never drops an occluder.
fn check_grid(
    scene: &Scene,
    cells: Option<u32>,
    level_cells: u32,
    cascades: u32,
    pixel_stride: usize,
    cull: bool,
) -> (usize, usize, usize) {
    let bvh = SceneBvh::build(scene);
    let g = gbuffer(scene, &bvh);
    let request = GridRequest {
        cells,
        level_cells: Some(level_cells),
        cascades: CascadeCount::Fixed(cascades),
        split_lambda: 1.0,
    };
    let setup = light_setup(scene, &g, request);
    assert_eq!(setup.cascades.len(), cascades as usize);
    let triangles = eye_relative_f32(scene);
    let boxes = setup.microquad_boxes(&g, Skips::ALL);
    let bins = bin(&setup, &triangles, Skips::ALL, cull.then_some((&g, &boxes)));

    // Scatter against the placements, cell by cell, level by level and
    // cascade by cascade (with the cull, a subset of them), neighbour bits
    // included; every listed cell inside the triangle's rectangle.
    let light_view: Vec<[glam::Vec3; 3]> = triangles
        .iter()
        .map(|t| t.map(|v| setup.to_light_view(v)))
        .collect();
    let mut entries = 0usize;
    for (k, grid) in setup.cascades.iter().enumerate() {
        let footprints: Vec<_> = light_view.iter().map(|t| place(&setup, grid, t)).collect();
        for level in 0..grid.levels {
            let [w, h] = grid.level_dims(level);
            for y in 0..h {
                for x in 0..w {
                    let got: Vec<CellEntry> = bins.cell(grid, level, x, y).to_vec();
                    entries += got.len();
                    let expected: Vec<CellEntry> = (0..scene.triangles.len() as u32)
                        .filter_map(|id| match footprints[id as usize] {
                            (
                                Placement::Cells {
                                    level: l,
                                    x0,
                                    y0,
                                    x1,
                                    y1,
                                },
                                Some(f),
                            ) if l == level && f.touches(x.into(), y.into()) => {
                                assert!((x0..=x1).contains(&x) && (y0..=y1).contains(&y));
                                assert_eq!(
                                    bins.placement[k][id as usize],
                                    footprints[id as usize].0
                                );
                                Some(CellEntry::new(id, &f, x, y))
                            }
                            _ => None,
                        })
                        .collect();
                    if cull {
                        assert!(
                            got.iter().all(|e| expected.contains(e)),
                            "cascade {k} level {level} cell ({x}, {y}) lists a triangle not placed there"
                        );
                    } else {
                        assert_eq!(got, expected, "cascade {k} level {level} cell ({x}, {y})");
                    }
                }
            }
        }
    }
    assert_eq!(entries, bins.stats.cell_entries);

    // Every occluder of a sample is a candidate, checked by brute force over
    // every triangle of the scene.
    // Without the cheap path, so every edge of every triangle is evaluated.
    let rule = MaskRule::new(SampleMode::Exact32, Skips::NONE);
    let (mut pixels, mut occluder_pairs, mut twice) = (0, 0, 0);
    for i in (0..g.flags.len()).step_by(pixel_stride) {
        if g.flags[i] & flags::SHADOW_TESTED == 0 {
            continue;
        }
        pixels += 1;
        // A thin diagonal may be offered twice (see `CellEntry`): counted.
        let mut candidates = HashSet::new();
        for_each_candidate(&setup, &bins, &g, i, |id| {
            twice += !candidates.insert(id) as usize;
            false
        });
        for id in 0..scene.triangles.len() as u32 {
            let mask = triangle_mask_for_pixel(&setup, &triangles, &g, i, id, &rule);
            if mask != 0 {
                occluder_pairs += 1;
                assert!(
                    candidates.contains(&id),
                    "pixel {i}: triangle {id} shadows samples {mask:#010x} but is not a candidate ({:?})",
                    bins.placement.iter().map(|p| p[id as usize]).collect::<Vec<_>>()
                );
            }
        }
    }
    (pixels, occluder_pairs, twice)
}

#[test]
fn grid_offers_every_occluder_on_thin_and_grazing_scenes() {
    let mut checked = 0;
    for (name, cells) in [
        ("hairball", Some(24)),
        ("hairball", None),
        ("wires", Some(40)),
        ("grazing", Some(16)),
        ("default", None),
    ] {
        let mut scene = scene::load(name)
            .unwrap()
            .with_resolution([96, 54])
            .unwrap();
        if name == "hairball" {
            // Fewer hairs keep the brute force quick; still thousands of
            // sub-cell occluders.
            let p = scene::procedural::hairball(3000);
            scene = Scene::new("hairball", p.triangles, p.camera, p.light, [96, 54]).unwrap();
        }
        for (cull, cascades) in [(false, 1), (true, 1), (true, 3)] {
            // Triangles over 48 cells move up a level (about a 7-cell side).
            let (pixels, pairs, twice) = check_grid(&scene, cells, 48, cascades, 3, cull);
            println!(
                "{name} (cells {cells:?}, {cascades} cascade(s), behind-receivers cull {cull}): \
                 {pixels} pixels, {pairs} occluder/pixel pairs, all offered ({twice} twice)"
            );
            assert!(pixels > 300 && pairs > 100, "{name}: too little exercised");
            checked += 1;
        }
    }
    assert_eq!(checked, 15);
}

#[test]
fn point_light_grid_offers_every_occluder() {
    let Some(dir) = common::shared_scenes_dir() else {
        return;
    };
    let dir = dir.display();
    // The engine: a point light, 82 transformed nodes, self-shadowing. A
    // coarse 32-cell grid and a 9-cell level threshold exercise every level;
    // the cull runs with the point light's pyramid test.
    let scene = scene::load(&format!("{dir}/engine.scene.json"))
        .unwrap()
        .with_resolution([64, 36])
        .unwrap();
    let mut checked = 0;
    for (cascades, cull) in [(1, false), (1, true), (2, true)] {
        let (pixels, pairs, twice) = check_grid(&scene, Some(32), 9, cascades, 5, cull);
        println!(
            "engine ({cascades} cascade(s), behind-receivers cull {cull}): {pixels} pixels, \
             {pairs} occluder/pixel pairs, all offered ({twice} twice)"
        );
        assert!(pixels > 50 && pairs > 50);
        checked += 1;
    }
    assert_eq!(checked, 3);
}
