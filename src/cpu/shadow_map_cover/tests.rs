//! The cover gate against the cover test it stands before.

use super::*;
use crate::bvh::SceneBvh;
use crate::cpu::bin::place;
use crate::cpu::light_setup::Projection;
use crate::cpu::{eye_relative_f32, light_setup, CascadeCount, GridRequest};

/// The gate never turns away a cell the cover test takes: every cell of
/// every binned triangle's rectangle on the directional procedural scenes,
/// at a small size, with the grid `light_setup` sizes and a finer one
/// (12 grids, 4.2 M cells, 0.3 M covered; a few slivers take the gate's
/// open path); and it turns away most of the cells the cover test rejects
/// (99.5 % here).
#[test]
fn the_gate_keeps_every_covered_cell() {
    let (mut scenes, mut cells, mut covered, mut gated) = (0, 0u64, 0u64, 0u64);
    let mut open = 0;
    for name in ["default", "city", "grazing", "analytic", "hairball", "far"] {
        let scene = crate::scene::load(name)
            .and_then(|s| s.with_resolution([240, 135]))
            .expect("a procedural scene");
        let bvh = SceneBvh::build(&scene);
        let g = crate::gbuffer::gbuffer(&scene, &bvh);
        for cells_per_side in [None, Some(512)] {
            let request = GridRequest {
                cells: cells_per_side,
                level_cells: None,
                cascades: CascadeCount::Fixed(1),
                split_lambda: 1.0,
                simd: crate::cpu::simd::SimdPath::detected(),
            };
            let setup = light_setup(&scene, &g, request);
            if setup.projection != Projection::Orthographic {
                continue;
            }
            scenes += 1;
            let grid = &setup.cascades[0];
            for tri in eye_relative_f32(&scene) {
                let tri = tri.map(|v| setup.to_light_view(v));
                let (_, Some(f)) = place(&setup, grid, &tri) else {
                    continue;
                };
                let gate = CoverGate::new(&f);
                open += (gate.verdict == GateVerdict::EveryCell) as usize;
                let [x0, y0, x1, y1] = f.rect;
                for y in y0..=y1 {
                    let row = gate.row(y);
                    for x in x0..=x1 {
                        let takes = cover_floor(grid, &tri, f.level, x, y).is_some();
                        let passes = row.may_cover(x);
                        assert!(
                            passes || !takes,
                            "{name}: cell ({x}, {y}) of level {} covered by {tri:?}, gated",
                            f.level
                        );
                        cells += 1;
                        covered += takes as u64;
                        gated += !passes as u64;
                    }
                }
            }
        }
    }
    assert!(scenes >= 8, "{scenes} directional scene grids");
    assert!(covered > 1_000, "{covered} covered cells of {cells}");
    assert!(open > 0, "no gate took the open path");
    assert!(
        gated * 10 > (cells - covered) * 8,
        "the gate turned away {gated} of {} uncovered cells",
        cells - covered
    );
}
