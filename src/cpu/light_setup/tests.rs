//! The grid pyramid's sizes and the cascades' share of the cell arrays.

use super::*;

#[test]
fn cascade_grids_fit_the_cell_arrays() {
    let extents = [
        glam::Vec2::new(1.0, 1.0),
        glam::Vec2::new(100.0, 0.3),
        glam::Vec2::new(1e-3, 7.0),
    ];
    for side in [8, 100, 720, 1024] {
        for shares in [[1, 0, 0, 0], [1, 1, 1, 1], [100, 10, 1, 0], [5, 3, 2, 1]] {
            for extent in extents {
                let all: usize = shares.iter().sum::<usize>() * 1000;
                let cells: u64 = shares
                    .iter()
                    .map(|&s| {
                        let cells = cascades::cascade_cells(side, s * 1000, all, 4, extent);
                        let grid = CascadeGrid {
                            cells,
                            levels: pyramid_levels(cells),
                            ..Default::default()
                        };
                        u64::from(grid.cell_count())
                    })
                    .sum();
                assert!(
                    cells <= cascades::max_total_cells(side),
                    "side {side}: {cells} cells"
                );
            }
        }
        // One cascade fills its budget to within the rounding of its sides.
        let [x, y] = cascades::cascade_cells(side, 1, 1, 1, glam::Vec2::new(3.0, 1.0));
        assert!(
            u64::from(x * y) * 2 >= u64::from(side * side),
            "side {side}: {x}x{y}"
        );
    }
}

#[test]
fn pyramid_levels_halve_down_to_one_cell() {
    assert_eq!(pyramid_levels([1, 1]), 1);
    assert_eq!(pyramid_levels([2, 1]), 2);
    assert_eq!(pyramid_levels([1024, 3]), 11);
    assert_eq!(pyramid_levels([1025, 700]), 12);
    assert_eq!(pyramid_levels([0, 0]), 0);
    assert_eq!(level_side(1025, 11), 1);
    assert_eq!(level_side(1025, 10), 2);
    let grid = CascadeGrid {
        cells: [5, 3],
        levels: pyramid_levels([5, 3]),
        cell_offset: 7,
        ..Default::default()
    };
    // 5×3, 3×2, 2×1, 1×1.
    assert_eq!(grid.levels, 4);
    assert_eq!(grid.cell_count(), 15 + 6 + 2 + 1);
    assert_eq!(grid.cell_index_at(1, 2, 1), 7 + 15 + 5);
    assert_eq!(grid.cell_index_at(3, 0, 0), 7 + 23);
}
