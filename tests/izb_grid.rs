//! The light-space grid pyramid against brute force: the scatter holds
//! exactly the triangles whose footprint touches each cell of each level
//! (within their rectangle), and no triangle able to
//! shadow any of a pixel's 32 samples is missing from the candidates the
//! pixel visits (zero light leaks by construction, paper-notes/reference-estimator.md), with one
//! grid and with several cascades.

mod common;

use izb::bvh::SceneBvh;
use izb::cpu::bin::{
    bin, cell_range_at, cell_receivers, place, CellEntry, CullAgainst, Placement, CELL_PADDING,
};
use izb::cpu::evaluate::{for_each_candidate, triangle_mask_for_pixel};
use izb::cpu::light_setup::level_scale;
use izb::cpu::receivers::{cull_box, receiver_reach};
use izb::cpu::{
    eye_relative_f32, is_receiver, light_setup, CascadeCount, GridRequest, IzbSettings, MaskRule,
    ReceiverCull, SampleMode, Skips,
};
use izb::gbuffer::{flags, gbuffer, gbuffer_with};
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
        simd: izb::cpu::simd::SimdPath::detected(),
    };
    let setup = light_setup(scene, &g, request);
    assert_eq!(setup.cascades.len(), cascades as usize);
    let triangles = eye_relative_f32(scene);
    let boxes = std::cell::OnceCell::new();
    let cull_against = CullAgainst {
        g: &g,
        boxes: &boxes,
        covered_only: false,
        when: ReceiverCull::Always,
    };
    let bins = bin(&setup, &triangles, Skips::ALL, cull.then_some(cull_against));

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

/// The behind-receivers cull's premise, with edge surfaces: the µQuad
/// centre P of every receiver (where its depth test is taken) lies in each
/// cell it registers in, grown by that cell's reach and the padding. An
/// edge surface's box spans only the samples it covers and can leave P
/// cells away (`receivers::reach_box`); the grown cell must still hold it.
/// Counts the registrations where the box's own reach would not have.
/// Also holds each registered cell's precomputed cull box to its
/// definition.
#[test]
fn every_receiver_centre_lies_in_its_cells_reach() {
    let mut scenes: Vec<Scene> = ["default", "grazing", "wires", "city"]
        .iter()
        .map(|name| {
            scene::load(name)
                .unwrap()
                .with_resolution([320, 180])
                .unwrap()
        })
        .collect();
    scenes.extend(common::shared_scene("ficus").map(|s| s.with_resolution([960, 540]).unwrap()));
    let (mut checked, mut outside_box, mut beyond_box_reach) = (0u64, 0u64, 0u64);
    for scene in &scenes {
        let bvh = SceneBvh::build(scene);
        let settings = IzbSettings {
            edge_surfaces: true,
            ..IzbSettings::default()
        };
        let g = gbuffer_with(scene, &bvh, settings.edge_halves(scene));
        assert!(g.edges.is_some(), "{}: no edge surfaces", scene.name);
        let setup = light_setup(scene, &g, GridRequest::from(&settings));
        let boxes = setup.receiver_boxes(&g, Skips::ALL, true);
        let levels: Vec<u32> = setup.cascades.iter().map(|c| (1 << c.levels) - 1).collect();
        let tables = setup.level_tables();
        let receivers = cell_receivers(&setup, &g, &boxes, Skips::ALL, &levels, &tables).unwrap();
        let before = checked;
        for (layer, layer_boxes) in g.layers().zip(boxes.layers()) {
            for i in (0..layer.flags.len()).filter(|&i| is_receiver(layer.flags[i], Skips::ALL)) {
                let k = setup.cascade_of(layer.position[i]);
                let grid = &setup.cascades[k];
                let (lo, hi) = layer_boxes.grid_box(grid, i);
                let p = setup.to_light_view(layer.position[i]);
                let centre = grid.grid_coords(setup.ndc(p).unwrap());
                outside_box += !(centre.cmpge(lo).all() && centre.cmple(hi).all()) as u64;
                for level in 0..grid.levels {
                    let Some([x0, y0, x1, y1]) = cell_range_at(grid, level, lo, hi) else {
                        continue;
                    };
                    let s = level_scale(level);
                    let own = receiver_reach(lo * s, hi * s) as f32 + CELL_PADDING;
                    let c = centre * s;
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            let cell = tables[k][level as usize].index(x, y);
                            // The cull's box, computed once per cell, is
                            // the one of this cell and its reach.
                            assert_eq!(
                                receivers.cull_box[cell],
                                cull_box(grid, level, (x, y), receivers.reach[cell]),
                                "{}: cull box of cell ({x}, {y}) of level {level}",
                                scene.name
                            );
                            let r = receivers.reach[cell] as f32 + CELL_PADDING;
                            let within = |r: f32| {
                                (x as f32 - r..=x as f32 + 1.0 + r).contains(&c.x)
                                    && (y as f32 - r..=y as f32 + 1.0 + r).contains(&c.y)
                            };
                            assert!(
                                within(r),
                                "{}: receiver {i}'s centre {c} outside cell ({x}, {y}) of level \
                                 {level} grown by its reach {r}",
                                scene.name
                            );
                            beyond_box_reach += !within(own) as u64;
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert!(
            checked - before > 10_000,
            "{}: too few registrations",
            scene.name
        );
    }
    println!(
        "{} scenes: {checked} registrations, {outside_box} receivers' centres outside their \
         box, {beyond_box_reach} registrations beyond the box's own reach",
        scenes.len()
    );
    assert!(outside_box > 100, "no edge surface's centre left its box");
    assert!(
        beyond_box_reach > 0,
        "the case reach_box covers did not occur"
    );
}
