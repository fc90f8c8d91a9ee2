//! Every skip is exact (issue 5): with all skips on and all off, the masks
//! are bit-identical on every procedural and shared scene, in every sample
//! mode, on the CPU twin and on the Vulkan backend, while the counters show
//! that the skips removed work. The conservative shadow-map early-out is
//! also checked on its own (all skips with and without it, and it must fire
//! somewhere), and so is the cascade split: 1 and 4 cascades give the same
//! exact masks (one light-view frame for all cascades, so only the grids
//! differ) and LUT masks within [`MAX_LUT_CASCADE_MISMATCH`].
//!
//! GPU part: skips with a message without a Vulkan device, fails instead
//! with `IZB_REQUIRE_GPU=1`; any validation message fails it.

mod common;

use common::gpu::{lock, renderer};
use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, CascadeCount, IzbSettings, ReceiverCull, SampleMode, Skips};
use izb::gpu::{GBufferSource, GpuError};
use izb::scene::{self, Scene};

const MODES: [SampleMode; 3] = [SampleMode::One, SampleMode::Lut32, SampleMode::Exact32];

/// CPU test resolution.
const RESOLUTION: [u32; 2] = [240, 135];
/// GPU test resolution and modes: lavapipe needs ~10 min for all three modes
/// at 240×135 (`grazing` without skips tests 80 M pairs), so CI checks the
/// 32-sample modes at 160×90; `IZB_GPU_TEST_RESOLUTION=scene` runs every
/// mode at each scene's own resolution (for a real GPU).
fn gpu_resolution_and_modes() -> (Option<[u32; 2]>, &'static [SampleMode]) {
    match std::env::var("IZB_GPU_TEST_RESOLUTION").as_deref() {
        Ok("scene") => (None, &MODES),
        _ => (Some([160, 90]), &MODES[1..]),
    }
}

/// Every procedural scene, and the shared ones when `../shared` is there,
/// at `resolution` (None: the scene's own).
fn scenes(resolution: Option<[u32; 2]>) -> Vec<(String, Scene)> {
    let mut out: Vec<(String, Scene)> = scene::procedural::NAMES
        .iter()
        .map(|n| (n.to_string(), scene::load(n).unwrap()))
        .collect();
    if common::shared_scenes_dir().is_some() {
        for n in common::SHARED_SCENES {
            out.push((n.to_string(), common::shared_scene(n).unwrap()));
        }
    }
    out.into_iter()
        .map(|(n, s)| {
            let r = resolution.unwrap_or(s.resolution);
            (n, s.with_resolution(r).unwrap())
        })
        .collect()
}

/// `mode` with `skips`; the `behind_receivers` skip taken whatever the
/// grid's density, so that it is tested on every scene.
fn settings(mode: SampleMode, skips: Skips) -> IzbSettings {
    IzbSettings {
        mode,
        skips,
        receiver_cull: ReceiverCull::Always,
        ..Default::default()
    }
}

/// Every skip but the shadow-map early-out.
const ALL_BUT_SHADOW_MAP: Skips = Skips {
    shadow_map: false,
    ..Skips::ALL
};

fn with_cascades(mode: SampleMode, cascades: u32) -> IzbSettings {
    IzbSettings {
        mode,
        cascades: CascadeCount::Fixed(cascades),
        ..Default::default()
    }
}

/// Index and values of the first differing mask, if any.
fn first_difference(a: &[u32], b: &[u32]) -> Option<(usize, u32, u32)> {
    a.iter()
        .zip(b)
        .enumerate()
        .find(|(_, (x, y))| x != y)
        .map(|(i, (x, y))| (i, *x, *y))
}

#[test]
fn cpu_masks_are_identical_with_and_without_skips() {
    let (mut tests_on, mut tests_off) = (0u64, 0u64);
    let mut shadow_map_early_outs = 0;
    for (name, scene) in scenes(Some(RESOLUTION)) {
        let bvh = SceneBvh::build(&scene);
        for mode in MODES {
            let on = render_cpu(&scene, &bvh, settings(mode, Skips::ALL));
            let off = render_cpu(&scene, &bvh, settings(mode, Skips::NONE));
            let no_map = render_cpu(&scene, &bvh, settings(mode, ALL_BUT_SHADOW_MAP));
            if let Some((i, a, b)) = first_difference(&on.masks, &off.masks) {
                panic!("{name} {mode:?}: pixel {i}: skips on {a:#010x}, off {b:#010x}");
            }
            if let Some((i, a, b)) = first_difference(&on.masks, &no_map.masks) {
                panic!("{name} {mode:?}: pixel {i}: shadow map on {a:#010x}, off {b:#010x}");
            }
            shadow_map_early_outs += on.report.evaluate.shadow_map_early_outs;
            println!(
                "{name} {mode:?}: shadow-map early-outs {} of {} pixels ({} covered cells), \
                 tests {} with / {} without it",
                on.report.evaluate.shadow_map_early_outs,
                on.report.evaluate.pixels_tested,
                on.report.bin.covered_cells,
                on.report.evaluate.tests_spawned,
                no_map.report.evaluate.tests_spawned
            );
            let (e_on, e_off) = (&on.report.evaluate, &off.report.evaluate);
            println!(
                "{name} {mode:?}: tests {} on / {} off, pixels {} / {}, early outs {}, \
                 saturated {}, culled {} / {}, behind receivers {} entries {} triangles",
                e_on.tests_spawned,
                e_off.tests_spawned,
                e_on.pixels_tested,
                e_off.pixels_tested,
                e_on.early_outs,
                e_on.saturated_masks,
                on.report.bin.culled,
                off.report.bin.culled,
                on.report.bin.entries_behind_receivers,
                on.report.bin.triangles_behind_receivers
            );
            // Skips off never stop early, never take the cheap path, never
            // cull, and test at least every pixel the skips test.
            assert_eq!(e_off.early_outs, 0, "{name}");
            assert_eq!(e_off.shadow_map_early_outs, 0, "{name}");
            assert_eq!(no_map.report.evaluate.shadow_map_early_outs, 0, "{name}");
            assert_eq!(e_off.saturated_masks, 0, "{name}");
            assert_eq!(off.report.bin.culled, 0, "{name}");
            assert_eq!(off.report.bin.entries_behind_receivers, 0, "{name}");
            assert!(e_off.pixels_tested >= e_on.pixels_tested, "{name}");
            tests_on += e_on.tests_spawned;
            tests_off += e_off.tests_spawned;
        }
    }
    assert!(
        tests_on < tests_off,
        "the skips removed no test ({tests_on} vs {tests_off})"
    );
    assert!(
        shadow_map_early_outs > 0,
        "the shadow-map early-out never fired: the exactness check above proved nothing"
    );
}

/// The `behind_receivers` skip is taken where the grid is dense
/// (`ReceiverCull::WhereDense`: under an area light, or where the placed
/// rectangles cover at least `DENSE_RECTANGLE_CELLS` cells per cell), and
/// taken or not, the masks are those it gives when always taken: every
/// scene in the LUT and exact modes, the procedural ones also on a grid of
/// 16 cells a side, dense for each of them.
#[test]
fn the_receiver_cull_is_taken_where_the_grid_is_dense() {
    let all = scenes(Some(RESOLUTION));
    let procedural = |name: &str| scene::procedural::NAMES.contains(&name);
    // Two modes, on two grids for the procedural scenes.
    let expected_cases: usize = all
        .iter()
        .map(|(name, _)| if procedural(name) { 4 } else { 2 })
        .sum();
    let (mut taken, mut left, mut cases) = (0, 0, 0);
    for (name, scene) in all {
        let bvh = SceneBvh::build(&scene);
        let procedural = procedural(&name);
        let grids: &[Option<u32>] = if procedural {
            &[None, Some(16)]
        } else {
            &[None]
        };
        for &cells in grids {
            for mode in [SampleMode::Lut32, SampleMode::Exact32] {
                let with = |receiver_cull| IzbSettings {
                    mode,
                    cells,
                    receiver_cull,
                    ..Default::default()
                };
                let dense = render_cpu(&scene, &bvh, with(ReceiverCull::WhereDense));
                let always = render_cpu(&scene, &bvh, with(ReceiverCull::Always));
                let (d, a) = (&dense.report.bin, &always.report.bin);
                let density = d.rectangle_cells_per_cell;
                println!(
                    "{name} {mode:?} cells {cells:?}: {density:.2} rectangle cells per cell, \
                     culled {}; entries {} where dense, {} always",
                    d.receivers_culled_against, d.cell_entries, a.cell_entries
                );
                let expected =
                    scene.has_area_light() || density >= ReceiverCull::DENSE_RECTANGLE_CELLS;
                assert_eq!(
                    d.receivers_culled_against, expected,
                    "{name} {mode:?} {cells:?}"
                );
                assert!(a.receivers_culled_against, "{name}");
                assert_eq!(a.rectangle_cells_per_cell, density, "{name}");
                if !expected {
                    assert_eq!(d.entries_behind_receivers, 0, "{name}");
                    assert!(d.cell_entries >= a.cell_entries, "{name}");
                }
                if let Some((i, x, y)) = first_difference(&dense.masks, &always.masks) {
                    panic!("{name} {mode:?} {cells:?}: pixel {i}: where dense {x:#010x}, always {y:#010x}");
                }
                taken += expected as usize;
                left += !expected as usize;
                cases += 1;
            }
        }
    }
    assert_eq!(cases, expected_cases);
    assert!(
        taken > 0 && left > 0,
        "the cull was taken in {taken} cases and left in {left}: one way is untested"
    );
}

/// Largest share of samples on which the LUT mode may differ between
/// cascade counts. The exact modes may not differ at all: the cascades
/// change which triangles a pixel is offered, never how one is tested, and
/// every triangle able to shadow a sample is offered either way. The LUT
/// can mark a sample shadowed by a triangle whose shadow misses it (its
/// quantisation, near a µQuad corner); whether such a near miss is offered
/// depends on the grid, so only there may the LUT masks differ.
const MAX_LUT_CASCADE_MISMATCH: f64 = 1e-4;

/// Samples in which `a` and `b` differ.
fn differing_samples(a: &[u32], b: &[u32]) -> u64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| u64::from((x ^ y).count_ones()))
        .sum()
}

#[test]
fn cpu_masks_agree_for_any_cascade_count() {
    for (name, scene) in scenes(Some(RESOLUTION)) {
        let bvh = SceneBvh::build(&scene);
        for mode in MODES {
            let one = render_cpu(&scene, &bvh, with_cascades(mode, 1));
            let four = render_cpu(&scene, &bvh, with_cascades(mode, 4));
            assert_eq!(four.report.light.cascades.len(), 4, "{name}");
            let differing = differing_samples(&one.masks, &four.masks);
            let rate = differing as f64 / (32 * one.masks.len()) as f64;
            let pixels = one.report.evaluate.pixels_tested.max(1) as f64;
            println!(
                "{name} {mode:?}: 1 vs 4 cascades: {differing} samples differ ({rate:.1e}); \
                 candidates per pixel {:.1} vs {:.1}; grids {:?}",
                one.report.evaluate.tests_spawned as f64 / pixels,
                four.report.evaluate.tests_spawned as f64 / pixels,
                four.report
                    .light
                    .cascades
                    .iter()
                    .map(|g| g.cells)
                    .collect::<Vec<_>>()
            );
            if mode == SampleMode::Lut32 {
                assert!(
                    rate <= MAX_LUT_CASCADE_MISMATCH,
                    "{name}: {differing} LUT samples differ ({rate:.1e})"
                );
            } else if let Some((i, a, b)) = first_difference(&one.masks, &four.masks) {
                panic!("{name} {mode:?}: pixel {i}: 1 cascade {a:#010x}, 4 cascades {b:#010x}");
            }
        }
    }
}

#[test]
fn gpu_masks_are_identical_with_and_without_skips() {
    let Some(r) = renderer() else { return };
    let r = lock(r);
    let (resolution, modes) = gpu_resolution_and_modes();
    let (mut tests_on, mut tests_off) = (0u64, 0u64);
    let scenes = scenes(resolution);
    let (cases, mut compared) = (scenes.len() * modes.len(), 0);
    for (name, scene) in scenes {
        for &mode in modes {
            let render = |skips| {
                let out = r.render(&scene, settings(mode, skips), GBufferSource::Gpu);
                let messages = r.take_validation_messages();
                assert!(messages.is_empty(), "{name}: {}", messages.join("\n"));
                out
            };
            let (on, off) = match (render(Skips::ALL), render(Skips::NONE)) {
                (Ok(on), Ok(off)) => (on, off),
                // lavapipe's loop cap: the frame is refused, never cut short.
                (Err(e @ GpuError::LoopCap { .. }), _) | (_, Err(e @ GpuError::LoopCap { .. })) => {
                    println!("{name} {mode:?}: skipped on this device: {e}");
                    continue;
                }
                (Err(e), _) | (_, Err(e)) => panic!("{name} {mode:?}: {e}"),
            };
            if let Some((i, a, b)) = first_difference(&on.masks, &off.masks) {
                panic!("{name} {mode:?}: pixel {i}: skips on {a:#010x}, off {b:#010x}");
            }
            let (c_on, c_off) = (&on.report.counters, &off.report.counters);
            println!(
                "{name} {mode:?} (GPU): tests {} on / {} off, pixels {} / {}, early outs {} \
                 (shadow map {}), saturated {}, culled {} / {}, behind receivers {} entries {} \
                 triangles",
                c_on.tests_spawned,
                c_off.tests_spawned,
                c_on.pixels_tested,
                c_off.pixels_tested,
                c_on.early_outs,
                c_on.shadow_map_early_outs,
                c_on.saturated_masks,
                c_on.culled,
                c_off.culled,
                c_on.entries_behind_receivers,
                c_on.triangles_behind_receivers
            );
            assert_eq!(c_off.early_outs, 0, "{name}");
            assert_eq!(c_off.shadow_map_early_outs, 0, "{name}");
            assert_eq!(c_off.saturated_masks, 0, "{name}");
            assert_eq!(c_off.culled, 0, "{name}");
            assert_eq!(c_off.entries_behind_receivers, 0, "{name}");
            tests_on += c_on.tests_spawned;
            tests_off += c_off.tests_spawned;
            compared += 1;
        }
    }
    assert_compared_most(compared, cases);
    assert!(
        tests_on < tests_off,
        "the skips removed no test ({tests_on} vs {tests_off})"
    );
}

/// The GPU loops may skip a case lavapipe's loop cap refuses (the frame
/// is refused, never cut short), but not most of them: a test that skips
/// everything would pass without checking anything.
fn assert_compared_most(compared: usize, cases: usize) {
    println!("compared {compared} of {cases} cases");
    assert!(
        2 * compared > cases,
        "only {compared} of {cases} cases compared: the rest hit the device's loop cap"
    );
}

#[test]
fn gpu_masks_are_identical_for_any_cascade_count() {
    // Exact mode: bit-identical (the LUT's allowance is for the CPU test).
    let Some(r) = renderer() else { return };
    let r = lock(r);
    let (resolution, _) = gpu_resolution_and_modes();
    let scenes = scenes(resolution);
    let (cases, mut compared) = (scenes.len(), 0);
    for (name, scene) in scenes {
        let render = |cascades| {
            let out = r.render(
                &scene,
                with_cascades(SampleMode::Exact32, cascades),
                GBufferSource::Gpu,
            );
            let messages = r.take_validation_messages();
            assert!(messages.is_empty(), "{name}: {}", messages.join("\n"));
            out
        };
        let (one, four) = match (render(1), render(4)) {
            (Ok(a), Ok(b)) => (a, b),
            (Err(e @ GpuError::LoopCap { .. }), _) | (_, Err(e @ GpuError::LoopCap { .. })) => {
                println!("{name}: skipped on this device: {e}");
                continue;
            }
            (Err(e), _) | (_, Err(e)) => panic!("{name}: {e}"),
        };
        assert_eq!(four.report.light.cascades.len(), 4, "{name}");
        if let Some((i, a, b)) = first_difference(&one.masks, &four.masks) {
            panic!("{name}: pixel {i}: 1 cascade {a:#010x}, 4 cascades {b:#010x}");
        }
        println!(
            "{name} (GPU): 1 vs 4 cascades identical; tests {} vs {}; grids {:?}",
            one.report.counters.tests_spawned,
            four.report.counters.tests_spawned,
            four.report
                .light
                .cascades
                .iter()
                .map(|g| g.cells)
                .collect::<Vec<_>>()
        );
        compared += 1;
    }
    assert_compared_most(compared, cases);
}
