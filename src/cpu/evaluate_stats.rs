//! The counters of pass 3, `evaluate` ([`super::evaluate`]): what it
//! did per pixel, summed over pixels (and over mask halves), and the same
//! per tested pixel for `report.json` and `bench.json` (issue 13's work
//! counters: stable where times are noisy).

/// Counters of the evaluate pass.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct EvaluateStats {
    pub pixels_tested: usize,
    /// Edge pixels' extra surfaces tested (receivers beside the pixels,
    /// [`crate::gbuffer::edge_surfaces`]); their tests are in the counters
    /// below, so the per-pixel figures include them.
    pub extra_surfaces_tested: usize,
    /// Frustum-triangle tests started (candidate triangles visited).
    pub tests_spawned: u64,
    /// Of those, triangles with a vertex above the receiver's tangent
    /// plane (the depth test's first condition; the rest end there).
    pub tangent_passed: u64,
    /// Of those, triangles that passed the depth test at P (P beyond the
    /// triangle's plane from the light).
    pub depth_passed: u64,
    /// Pixels that stopped early because their mask was full.
    pub early_outs: usize,
    /// Depth-passing triangles whose mask the cheap path decided (shadow
    /// prism containing or missing the whole µQuad: no LUT read, no sample
    /// loop, later edges not computed). On the CPU this includes the
    /// batched triangles certified to leave no sample inside
    /// ([`super::empty_certificate`]), which the GPU evaluates through
    /// the LUT, so the two backends' counts differ.
    pub saturated_masks: u64,
    /// Grid cells visited over all pixels.
    pub cells_visited: u64,
    /// Pyramid levels visited over all pixels.
    pub levels_visited: u64,
    /// Triangles offered by the cells whose per-pixel test ran; with the
    /// tests of the longest pixel in each 8×4 group of 32 pixels (a GPU
    /// subgroup): `tests_spawned / (32 · Σ longest)` is the SIMD
    /// efficiency of a one-pixel-per-lane evaluate.
    pub group_longest_tests: u64,
    /// The most tests one pixel ran: a one-pixel-per-thread GPU evaluate
    /// waits for it (the tail the GPU's heavy step splits).
    pub longest_pixel_tests: u64,
    /// Tests whose mask was not empty.
    pub masks_nonempty: u64,
    /// Pixels whose cover triangle (the conservative shadow map) alone
    /// filled the mask: their triangle loop was skipped.
    pub shadow_map_early_outs: usize,
    /// Survivor batches tested ([`super::survivor_batch`]).
    pub survivor_batches: u64,
    /// Their lanes holding a candidate.
    pub survivor_lanes: u64,
    /// The lanes their kernels ran over
    /// ([`super::survivor_batch::lanes_issued`]).
    pub survivor_lanes_issued: u64,
}

impl EvaluateStats {
    /// Adds the counters of another pass over the same pixels (the second
    /// mask half, the edge surfaces): its tests count, its pixels do not.
    pub fn add_pass(&mut self, s: &EvaluateStats) {
        let pixels_tested = self.pixels_tested;
        self.add(s);
        self.pixels_tested = pixels_tested;
    }

    /// Adds the counters of `s` (another band of pixels, or another mask
    /// half of the same pixels: the caller then keeps one half's
    /// `pixels_tested`).
    pub fn add(&mut self, s: &EvaluateStats) {
        self.pixels_tested += s.pixels_tested;
        self.extra_surfaces_tested += s.extra_surfaces_tested;
        self.tests_spawned += s.tests_spawned;
        self.tangent_passed += s.tangent_passed;
        self.depth_passed += s.depth_passed;
        self.saturated_masks += s.saturated_masks;
        self.masks_nonempty += s.masks_nonempty;
        self.early_outs += s.early_outs;
        self.cells_visited += s.cells_visited;
        self.levels_visited += s.levels_visited;
        self.group_longest_tests += s.group_longest_tests;
        self.longest_pixel_tests = self.longest_pixel_tests.max(s.longest_pixel_tests);
        self.shadow_map_early_outs += s.shadow_map_early_outs;
        self.survivor_batches += s.survivor_batches;
        self.survivor_lanes += s.survivor_lanes;
        self.survivor_lanes_issued += s.survivor_lanes_issued;
    }

    /// Tests over 32 × the longest pixel of each 8×4 group: the share of
    /// SIMD lanes doing useful tests in a one-pixel-per-lane evaluate.
    pub fn simd_efficiency(&self) -> f64 {
        self.tests_spawned as f64 / (32.0 * self.group_longest_tests as f64).max(1.0)
    }

    /// The counters per tested pixel, as `report.json` and `bench.json`
    /// show them.
    pub fn per_pixel(&self) -> WorkPerPixel {
        let px = self.pixels_tested.max(1) as f64;
        WorkPerPixel {
            tests: self.tests_spawned as f64 / px,
            depth_passed: self.depth_passed as f64 / px,
            masks_nonempty: self.masks_nonempty as f64 / px,
            outcomes: TestOutcomes {
                below_tangent_plane: self.tests_spawned.saturating_sub(self.tangent_passed) as f64
                    / px,
                not_beyond_triangle_plane: self.tangent_passed.saturating_sub(self.depth_passed)
                    as f64
                    / px,
                outside_edges: self.depth_passed.saturating_sub(self.masks_nonempty) as f64 / px,
                nonempty_mask: self.masks_nonempty as f64 / px,
            },
            cells: self.cells_visited as f64 / px,
            levels: self.levels_visited as f64 / px,
            simd_efficiency: self.simd_efficiency(),
            batch_lanes_used: self.survivor_lanes as f64
                / (self.survivor_lanes_issued as f64).max(1.0),
        }
    }
}

/// The evaluate pass's work per tested pixel (issue 13's counters): stable
/// where times are noisy.
#[derive(Clone, Debug, serde::Serialize)]
pub struct WorkPerPixel {
    /// Frustum-triangle tests started.
    pub tests: f64,
    /// Tests passing the depth test at P.
    pub depth_passed: f64,
    /// Tests whose mask was not empty.
    pub masks_nonempty: f64,
    /// Where the tests ended.
    pub outcomes: TestOutcomes,
    /// Grid cells visited, over all pyramid levels.
    pub cells: f64,
    /// Pyramid levels visited.
    pub levels: f64,
    /// [`EvaluateStats::simd_efficiency`].
    pub simd_efficiency: f64,
    /// The CPU twin's vector lanes used over lanes issued: survivor
    /// batches' lanes holding a candidate over the lanes their kernels ran
    /// over (partial batches at the end of a pixel's walk leave the rest
    /// idle).
    pub batch_lanes_used: f64,
}

/// Where a tested pixel's tests ended, per tested pixel (the four add up
/// to [`WorkPerPixel::tests`]): what the cheap first condition rejects and
/// what reaches the edges tell where a faster test pays (issue 30).
#[derive(Clone, Debug, serde::Serialize)]
pub struct TestOutcomes {
    /// Every vertex at or below the receiver's tangent plane.
    pub below_tangent_plane: f64,
    /// Above the tangent plane, but P not beyond the triangle's plane
    /// from the light.
    pub not_beyond_triangle_plane: f64,
    /// Through the depth test, no sample inside all three edges (or
    /// edge-on from the light).
    pub outside_edges: f64,
    /// A non-empty mask.
    pub nonempty_mask: f64,
}
