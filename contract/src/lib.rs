//! The CPU–GPU contract of izb: every struct, constant, binding and
//! tolerance the Rust passes and the GLSL shaders share, declared once,
//! here (kajiya's shared crate does the same). `build.rs` renders
//! [`glsl_header`] to `contract.glsl`, which `shaders/common.glsl`
//! includes; the structs are `#[repr(C)]` + bytemuck, laid out as GLSL's
//! scalar block layout lays them out (every member 4-byte aligned, `vec3` =
//! `[f32; 3]`), and `tests/spirv_layout.rs` reads every member's offset
//! and size back from the compiled SPIR-V.

mod baselines;
pub mod macros;
pub mod pcss_taps;
mod structs;

pub use baselines::{contact, filtered, filtered_params, VOLUME_CORNERS};
use macros::{shared_constants, GlslConstant, SharedStruct};
pub use pcss_taps::pcss;
pub use structs::{
    BvhNode, CascadeGrid, FrameParams, GpuDraw, GpuTriangle, GpuTriangleCorners, LightState,
    VisibilityView,
};

shared_constants! {
    /// Descriptor bindings of the one set every pass shares (`B_*`).
    pub mod binding: u32 as Int, prefix "B_" {
        FRAME = 0;
        /// Per triangle its three corners' indices into `B_VERTICES`
        /// (`uvec3`, `scene_triangles.glsl`).
        TRIANGLES = 1;
        /// The G-buffer's BVH2 (`BvhNode`); with `world_node_count`, the
        /// anchor-space nodes follow the eye-relative ones.
        BVH_NODES = 2;
        BVH_PRIMS = 3;
        G_POSITION = 4;
        G_AXIS_X = 5;
        G_AXIS_Y = 6;
        /// Triangle id and flags in one word (`ID_BITS`).
        G_ID_FLAGS = 7;
        LIGHT = 8;
        COUNTERS = 9;
        /// Per cell: the conservative shadow map's cover floor (ordered
        /// bits) and !id of its cover triangle.
        CELL_COVER = 10;
        /// Per cell: the count, then (the scan's inclusive end, the
        /// scatter's decrementing cursor) the first entry.
        CELL_START = 11;
        CELL_TRIANGLES = 12;
        OVERFLOW = 13;
        EDGE_LUT = 14;
        MASKS = 15;
        /// Shaded RGB8 with the lit sample count in alpha
        /// (`ALPHA_NOT_TESTED`).
        SHADED = 16;
        /// Unit normal per triangle, computed on the host in `f64` exactly
        /// as the CPU twin computes it, then rounded. A receiver's normal
        /// is its triangle's, negated when its G-buffer word has
        /// `FLAG_NORMAL_FLIPPED`.
        TRIANGLE_NORMALS = 17;
        /// Per cell: lowest receiver z (ordered bits) and !reach.
        CELL_RECEIVERS = 18;
        /// The baselines' buffer: a shadow map's D32 depths cascade after
        /// cascade (copied from its depth attachment), then a filtered
        /// map's blur rows and moments; the volumes' receiver depths and
        /// stencil bytes; 4 bytes in an IZB frame.
        SHADOW_MAP = 19;
        /// Evaluate's heavy step: per queued pixel, its index and cascade
        /// (`uvec2`), `FrameParams::heavy_capacity` of them.
        HEAVY_PIXELS = 20;
        /// Bits 32–63 of a `MODE_PAIRED64` frame's masks under an area
        /// light (evaluate's second half writes them); 4 bytes otherwise.
        MASKS_HIGH = 21;
        /// Edge surfaces: per 8×8 tile of pixels (the pixel passes'
        /// workgroup, tiles in row order) `EDGE_TILE_WORDS` words: which of
        /// its pixels keep a record (bit 8y + x over two words), then the
        /// index of its first one's record; then the edge pixels' records,
        /// a tile's in pixel order (`uvec4` per mask half: the samples on
        /// the centre's surface, the samples that count, the samples on a
        /// surface facing away, and its extra surfaces, first entry and
        /// count above `EDGE_COUNT_SHIFT`). A pixel without a record has
        /// all its samples on its centre's surface. 4 bytes in a frame
        /// without edge surfaces.
        EDGE_PIXELS = 22;
        /// Edge surfaces, per extra surface: the samples of its pixel it
        /// covers. Its receiver is G-buffer entry `width × height + k` (the
        /// rows below the image); 4 bytes in a frame without them.
        EDGE_COVERAGE = 23;
        /// The scene's distinct eye-relative vertices (`vec3`), each once.
        VERTICES = 24;
        /// The shadow pass with a moving eye: the scene's distinct
        /// vertices relative to its anchor, each as a double-single (hi,
        /// lo: two `vec3`), from which `translate_vertices` writes
        /// `B_VERTICES` for each frame's eye; 4 bytes elsewhere.
        WORLD_VERTICES = 25;
        /// Per G-buffer entry whose triangle is not known (id
        /// `DEPTH_SURFACE`: the shadow pass fed the host's depth and
        /// normal images), its camera-facing unit normal and how far its
        /// depth's rounding may put P off its surface along that normal
        /// (`vec4`; `DEPTH_INPUT_SPACINGS`); 4 bytes where every entry
        /// names its triangle.
        G_NORMAL = 26;
        /// The shadow pass fed the host's vertex and index buffers: this
        /// frame's draws (`Draw`, `FrameParams::draw_count` of them, in
        /// triangle order), from which `gather_draws` writes
        /// `B_TRIANGLES`, `B_VERTICES` and `B_TRIANGLE_NORMALS`; 4 bytes
        /// elsewhere.
        DRAWS = 27;
    }
}

/// Number of bindings (one past the last of [`binding`]).
pub const BINDING_COUNT: u32 = binding::DRAWS + 1;

shared_constants! {
    /// The second descriptor set (`HOST_*`): the host's images a frame of
    /// the shadow pass reads, one set per frame slot, written when the
    /// slot records (`izb::gpu::host_images`).
    pub mod host_image: u32 as Int, prefix "HOST_" {
        /// The set's index in the pipeline layout.
        SET = 1;
        /// The visibility buffer: per pixel the id of the triangle it
        /// sees, `NO_HIT` for none (`R32_UINT`, a sampled image).
        VISIBILITY = 0;
        /// The masks out (a storage image): `R32_UINT`, or `R32G32_UINT`
        /// with a second mask half (`MODE_PAIRED64` under an area light).
        MASKS = 1;
        /// The lit fraction out (a storage image, `R16_UNORM` or
        /// `R8_UNORM`).
        LIT = 2;
        /// The host's depth (a sampled image, its depth aspect:
        /// `D32_SFLOAT`, `D24_UNORM_S8_UINT`, `X8_D24_UNORM_PACK32` or
        /// `D32_SFLOAT_S8_UINT`), with the depth + normal input.
        DEPTH = 3;
        /// The host's geometric normal per pixel, world axes, xyz of a
        /// float or snorm colour image (a sampled image), with the depth +
        /// normal input.
        NORMAL = 4;
        /// The host's vertex and index buffers (storage buffers, an array
        /// of `HOST_GEOMETRY_SLOTS`), which a frame's draws name by slot,
        /// with the host's vertex and index buffers as the geometry.
        GEOMETRY = 5;
        /// Elements of the `GEOMETRY` array: distinct buffers a frame's
        /// draws may read (a slot the frame leaves free repeats slot 0).
        /// With the pass's own set (`BINDING_COUNT` storage buffers) they
        /// fill 32 per-stage storage buffers, lavapipe's budget (gallium's
        /// `PIPE_MAX_SHADER_BUFFERS`).
        GEOMETRY_SLOTS = 4;
        /// Bindings of the set.
        BINDING_COUNT = 6;
    }
}

shared_constants! {
    /// Word indices into the counters buffer (`C_*`); 64-bit counters take
    /// two words, low first.
    pub mod counter: usize as Int, prefix "C_" {
        HITS = 0;
        SHADOW_TESTED = 1;
        CLAMPED = 2;
        BINNED = 3;
        OVERFLOW = 4;
        CULLED = 5;
        CELL_ENTRIES = 6;
        CAPACITY_EXCEEDED = 7;
        PIXELS_TESTED = 8;
        EARLY_OUTS = 9;
        /// 64-bit.
        TESTS_SPAWNED = 10;
        /// 64-bit.
        DEPTH_PASSED = 12;
        /// 64-bit.
        CELLS_VISITED = 14;
        LOOP_BUDGET_EXCEEDED = 16;
        /// 64-bit.
        SATURATED_MASKS = 17;
        /// Cell entries the behind-receivers skip dropped.
        ENTRIES_BEHIND = 19;
        /// Binned placements dropped from every cell.
        TRIANGLES_BEHIND = 20;
        /// Pixels the cover triangle alone filled.
        SHADOW_MAP_EARLY_OUTS = 21;
        /// Per cascade k, word `LEVELS + k`: bit l set when pyramid level l
        /// holds a placement (atomicOr in the bin count).
        LEVELS = 22;
        /// 64-bit.
        LEVELS_VISITED = 26;
        /// Rectangle cells a binned triangle's projection misses.
        CELLS_UNTOUCHED = 28;
        /// 64-bit.
        MASKS_NONEMPTY = 29;
        /// Pixels whose grid candidates went to evaluate's heavy step
        /// (those past `FrameParams::heavy_capacity` stayed in the tile
        /// step).
        HEAVY_PIXELS = 31;
        /// The most tests one pixel ran in evaluate's tile step (atomicMax):
        /// with the heavy step, about its threshold at most.
        LONGEST_TILE_TESTS = 32;
        /// `HEAVY_PIXELS` of evaluate's second mask half (`MODE_PAIRED64`),
        /// which runs first and has its own queue count.
        HEAVY_PIXELS_HIGH = 33;
        /// Edge pixels' extra surfaces evaluate tested (receivers past the
        /// image's rows; `PIXELS_TESTED` counts the image's).
        EXTRA_SURFACES_TESTED = 34;
        /// The `edge_surfaces` pass: extra surfaces it found (slots it
        /// reserved; past `FrameParams::edge_capacity` the host reruns the
        /// frame with room), edge candidates (32 sample rays each), edge
        /// pixels, and the samples on surfaces facing away, past the kept
        /// surfaces, and missing everything.
        EDGE_SURFACES = 35;
        EDGE_CANDIDATES = 36;
        EDGE_PIXELS = 37;
        EDGE_FACING_AWAY_SAMPLES = 38;
        EDGE_DROPPED_SAMPLES = 39;
        EDGE_MISSED_SAMPLES = 40;
        /// `gbuffer_from_visibility`: pixels whose host id named no
        /// triangle of the pass (past its count, and not `NO_HIT`) or a
        /// triangle whose plane the centre ray does not cross in front of
        /// the eye; `gbuffer_from_depth`: pixels whose depth gives no view
        /// depth in front of the eye or whose normal is zero or not
        /// finite. Each is stored as a miss.
        VISIBILITY_REJECTED = 41;
        /// `gather_draws`: triangles of the host's draws with an index at
        /// or past their draw's vertex count (each collapsed onto its
        /// draw's vertex 0: it casts no shadow and is never read out of
        /// bounds), and vertices outside the bounds the pass was made for
        /// (the precision envelope's); either makes the frame unusable
        /// (`PassStatus::geometry_error`).
        INDEX_OUT_OF_RANGE = 42;
        OUTSIDE_BOUNDS = 43;
        /// `gbuffer_from_visibility` on a multisampled buffer: pixels some
        /// of whose samples saw a triangle but whose centre ray meets none
        /// that the samples of the pixel and its neighbours saw (the
        /// background between a silhouette's samples, or a triangle no
        /// sample saw), stored as misses.
        CENTRE_UNCOVERED = 44;
        /// Words in the counters buffer.
        WORDS = 45;
    }
}

shared_constants! {
    /// Local sizes of the pixel passes (8×8 tiles) and the linear passes.
    pub mod workgroup: u32 as Int, prefix "WORKGROUP_" {
        PIXELS_X = 8;
        PIXELS_Y = 8;
        PIXELS = 64;
        LINEAR = 256;
    }
}

shared_constants! {
    /// `FrameParams::mode` (`MODE_*`).
    pub mod mode: u32 as Uint, prefix "MODE_" {
        ONE = 0;
        LUT32 = 1;
        EXACT32 = 2;
        /// Under an area light: 32 (µQuad sample, light sample) pairs,
        /// evaluated exactly; under a point-like light as `EXACT32`.
        PAIRED32 = 3;
        /// `PAIRED32` twice: a second 32 pairs from `second_pattern` and
        /// `second_pair_pattern`, in `B_MASKS_HIGH`.
        PAIRED64 = 4;
    }
}

shared_constants! {
    /// G-buffer flags (`FLAG_*`), the top bits of the G-buffer word.
    pub mod flags: u32 as Uint, prefix "FLAG_" {
        /// The centre ray hit a triangle within [near, far].
        HIT = 1;
        /// Hit and N·L > 0: the pixel's shadow is computed.
        SHADOW_TESTED = 2;
        /// The µQuad axes were clamped to the largest stretch.
        AXES_CLAMPED = 4;
        /// GPU only: the receiver's camera-facing normal is minus its
        /// triangle's stored normal. Stored instead of a per-pixel normal
        /// (12 bytes per pixel).
        NORMAL_FLIPPED = 8;
    }
}

shared_constants! {
    /// The skips' bits (`SKIP_*`, `Skips::bits`): each exact shortcut by
    /// name, not by its place in a field list.
    pub mod skip: u32 as Uint, prefix "SKIP_" {
        FACING_AWAY = 1;
        OUTSIDE_BOUNDS = 2;
        FULL_MASK = 4;
        SATURATED_EDGES = 8;
        BEHIND_RECEIVERS = 16;
        SHADOW_MAP = 32;
    }
}

shared_constants! {
    /// Words and sentinels.
    pub mod word: u32 as Uint, prefix "" {
        /// A triangle id of no triangle (a miss).
        NO_HIT = u32::MAX;
        /// `Draw::index_slot` of a draw without indices.
        NO_INDICES = u32::MAX;
        /// Id field of a miss in the G-buffer word.
        ID_MASK = (1 << crate::size::ID_BITS) - 1;
        /// Id field of a G-buffer entry made from the host's depth and
        /// normal: its triangle is not known (no candidate is skipped as
        /// the receiver's own), its normal is `B_G_NORMAL`'s. One more than
        /// the largest triangle id.
        DEPTH_SURFACE = (1 << crate::size::ID_BITS) - 2;
        /// Alpha of a shaded pixel that is not shadow-tested; otherwise
        /// alpha is the count of lit samples, 0..=32.
        ALPHA_NOT_TESTED = 255;
        /// A full 32-sample mask.
        FULL_MASK = u32::MAX;
        /// Placement of a triangle wholly outside the cascade.
        PLACEMENT_CULLED = 0xFFFF_FFFE;
        /// Placement of a triangle in the overflow list.
        PLACEMENT_OVERFLOW = u32::MAX;
        /// Cell entry bit: the triangle lacks the cell to the left.
        ENTRY_FIRST_COLUMN = 1 << crate::size::ID_BITS;
        /// Cell entry bit: the triangle lacks the cell below.
        ENTRY_FIRST_ROW = 2 << crate::size::ID_BITS;
        /// A cell no triangle covers (the conservative shadow map).
        NO_COVER = u32::MAX;
        /// The default cells per triangle and pyramid level (1 024 until
        /// session 22: with it, courtyard's pixels visited 5.8 levels
        /// each for 1 382 coarse triangles; `paper-notes/performance.md`).
        DEFAULT_LEVEL_CELLS = 16384;
        /// Smallest and largest default grid side (cells).
        GRID_SIDE_MIN = 8;
        GRID_SIDE_MAX = 1024;
    }
}

shared_constants! {
    /// Integer sizes.
    pub mod size: u32 as Int, prefix "" {
        /// Bits of the G-buffer word that hold the triangle id; the four
        /// flag bits sit above them.
        ID_BITS = 28;
        /// Most cascades of a frame.
        MAX_CASCADES = 4;
        /// Cells along either side of one cascade's finest grid, at most.
        MAX_GRID_SIDE = 4096;
        /// Cells per block of the bin's prefix sum (a workgroup each; the
        /// block sums follow `cell_start`'s cells and total).
        SCAN_BLOCK_CELLS = 4096;
        /// An edge pixel record's fourth word: the first extra surface below
        /// this bit, their count (0..=6: up to 3 per mask half) above it.
        EDGE_COUNT_SHIFT = 29;
        /// Surfaces an edge pixel keeps, the centre's included
        /// (`edge_surfaces::MAX_SURFACES`).
        EDGE_MAX_SURFACES = 4;
        /// Words per tile of `B_EDGE_PIXELS`' table: a 64-bit mask of its
        /// pixels with records, and its first record's index.
        EDGE_TILE_WORDS = 3;
        /// Samples a pixel of a multisampled visibility buffer may have
        /// (its candidates, and the edge surfaces' 3×3 of them, are held
        /// per thread).
        MAX_VISIBILITY_SAMPLES = 8;
    }
}

shared_constants! {
    /// Tolerances and grid rules, `f32` on both sides (exactness-critical:
    /// every one is derived where its Rust user documents it).
    pub mod tolerance: f32 as Float, prefix "" {
        /// Depth test: the part scaled by the µQuad (2⁻⁸ of its longer
        /// axis; `crate::frustum`).
        DEPTH_TOLERANCE_MICROQUAD = 1.0 / 256.0;
        /// Depth test: the part scaled by the triangle's distance from P
        /// (16 ε₃₂).
        DEPTH_TOLERANCE_ROUNDING = 16.0 * f32::EPSILON;
        /// A host depth value's error, in spacings of its format at that
        /// value: half of one from the format's rounding and up to one
        /// and a half from a rasteriser's interpolation in `f32`
        /// (`gbuffer::depth_uncertainty`).
        DEPTH_INPUT_SPACINGS = 2.0;
        /// Relative margin of the saturated-edge shortcut (2⁻¹⁰).
        SATURATION_MARGIN = 1.0 / 1024.0;
        /// Relative margin of the behind-receivers cull (2⁻¹⁰).
        BEHIND_MARGIN = 1.0 / 1024.0;
        /// Padding of every cell box, in cells (1/64).
        CELL_PADDING = 1.0 / 64.0;
        /// Margin around an edge surface's covered sub-rectangle of its
        /// µQuad, in µQuad units (1/64): its corners are not samples, so
        /// rounding at a corner cannot drop one.
        COVERED_MARGIN = 1.0 / 64.0;
        /// A sample hit lies on a surface's plane within this fraction of
        /// the surface's µQuad (`edge_surfaces::PLANE_TOLERANCE`, 10⁻³).
        EDGE_PLANE_TOLERANCE = 1.0e-3;
        /// Rounding bound of the triangle–cell overlap test (2⁻¹⁸).
        TOUCH_ROUNDING = 1.0 / 262_144.0;
        /// A BVH node made eye-relative by `translate_vertices` widens by
        /// this share of its reach, plus the floor: its vertices' rounding
        /// (≤ 3 ulps together, `izb::cpu::translate_vertices`) twice over.
        NODE_WIDENING = 1.0 / 1_048_576.0;
        NODE_WIDENING_FLOOR = 1.0e-30;
        /// A projection thinner than this share of its edge products keeps
        /// its whole rectangle (2⁻¹⁶).
        SLIVER_RATIO = 1.0 / 65_536.0;
        /// One grid suffices while the view-depth range stays within this
        /// ratio per cascade.
        AUTO_MAX_DEPTH_RATIO = 16.0;
        /// Closest a receiver may come to the point light's image plane,
        /// relative to its distance range, before the grid is given up.
        MIN_PERSPECTIVE_DEPTH_RATIO = 1e-3;
        /// Share of the receivers' depth range (plus the first cascade's
        /// width) a directional light's shadow map grows its depth range
        /// by on each side (`crate::baseline::raster::MapDepth`).
        MAP_DEPTH_MARGIN = 1.0 / 16.0;
        /// A shadow map's constant bias at lookup, in texel widths at the
        /// receiver, on top of the map's own (the rasteriser's
        /// slope-scaled bias for one tap, the receiver plane for the
        /// filters): the curvature of a receiver across one texel and the
        /// interpolated depth's rounding (`crate::baseline::shadow_map`).
        CONSTANT_BIAS_TEXELS = 0.1;
        /// A point light's map near plane relative to the nearest
        /// receiver's light distance: the rasteriser's clip, so nothing
        /// nearer is in the map (`crate::baseline::raster::MapDepth`, PCSS).
        MAP_NEAR_RATIO = 1e-3;
        /// Shadow volumes: how far a receiver moves toward the camera
        /// before its depth test, in widths of its pixel's footprint
        /// (`crate::baseline::volumes`).
        VOLUME_NUDGE_PIXELS = 1.0 / 1024.0;
        /// Contact shadows: the march's length in texel widths of the
        /// shadow map at the receiver (`crate::baseline::contact`).
        CONTACT_LENGTH_TEXELS = 16.0;
        /// Contact shadows: the depth a sample must lie behind the visible
        /// surface to count as occluded, in pixel footprints at that
        /// surface (the depth buffer's own quantisation).
        CONTACT_TOLERANCE_PIXELS = 0.25;
        /// Contact shadows: the thickness assumed of every surface in the
        /// depth buffer, in march steps (a step further behind it passes).
        CONTACT_THICKNESS_STEPS = 2.0;
        /// Receivers per level-0 cell the default grid aims at.
        RECEIVERS_PER_CELL = 6.0;
        /// Triangles per level-0 cell the default grid aims at when the
        /// scene has more triangles than receivers per cell allow.
        TRIANGLES_PER_CELL = 16.0;
        /// Fewest cells a cascade's share of the budget may get.
        MIN_CASCADE_CELLS = 64.0;
        /// Relative padding of the fitted light-NDC bounds.
        BOUNDS_PADDING = 1e-4;
        /// Relative margin of a triangle's penumbra pad in the bin (2⁻¹⁰;
        /// `crate::cpu::bin::penumbra_pad`).
        PENUMBRA_MARGIN = 1.0 / 1024.0;
        /// Largest tan φ · tan θ a point light's penumbra pad accepts
        /// before the triangle overflows.
        MAX_PENUMBRA_TAN_PRODUCT = 0.5;
    }
}

/// `contract.glsl`: every constant as a `#define` and every shared struct,
/// in the order the shaders need them.
pub fn glsl_header() -> String {
    let mut out = String::from(
        "// contract.glsl: generated by build.rs from the izb-contract crate\n\
         // (contract/src). Do not edit: change the Rust declaration.\n\n",
    );
    let groups: [(&str, Vec<GlslConstant>); 14] = [
        ("bindings", binding::glsl()),
        ("the host's images", host_image::glsl()),
        ("counters", counter::glsl()),
        ("workgroup sizes", workgroup::glsl()),
        ("sample modes", mode::glsl()),
        ("G-buffer flags", flags::glsl()),
        ("skips", skip::glsl()),
        ("words and sentinels", word::glsl()),
        ("sizes", size::glsl()),
        ("tolerances and grid rules", tolerance::glsl()),
        ("percentage-closer soft shadows", pcss::glsl()),
        ("filtered shadow maps", filtered::glsl()),
        ("filtered shadow maps' parameters", filtered_params::glsl()),
        ("contact shadows", contact::glsl()),
    ];
    for (what, constants) in groups {
        out += &format!("// ---- {what} ----\n");
        for c in constants {
            out += &format!("#define {} {}\n", c.name, c.literal);
        }
        out += "\n";
    }
    out += &format!("#define COUNTER_WORDS {}\n", counter::WORDS);
    out += &format!("#define BINDING_COUNT {BINDING_COUNT}\n\n");
    out += &pcss_taps::glsl_disks();
    let corners: Vec<String> = VOLUME_CORNERS.iter().map(|c| format!("{c}u")).collect();
    out += &format!(
        "const uint VOLUME_CORNERS[{n}] = uint[{n}]({});\n",
        corners.join(", "),
        n = VOLUME_CORNERS.len()
    );
    out += "\n";
    out += &glsl_struct::<FrameParams>();
    out += &glsl_struct::<CascadeGrid>();
    out += &glsl_struct::<LightState>();
    out += &glsl_struct::<GpuTriangle>();
    out += &glsl_struct::<GpuTriangleCorners>();
    out += &glsl_struct::<BvhNode>();
    out += &glsl_struct::<VisibilityView>();
    out += &glsl_struct::<GpuDraw>();
    out
}

/// The GLSL declaration of struct `S`.
fn glsl_struct<S: SharedStruct>() -> String {
    let mut out = format!("struct {} {{\n", S::GLSL_NAME);
    for m in S::members() {
        out += &format!("    {};\n", m.glsl);
    }
    out + "};\n\n"
}

/// The member lists of the shared structs that buffers hold, by GLSL name
/// (for the SPIR-V layout test; `Triangle` is only ever a shader's value,
/// assembled from its corners).
pub fn shared_structs() -> Vec<(&'static str, usize, Vec<macros::Member>)> {
    fn entry<S: SharedStruct>() -> (&'static str, usize, Vec<macros::Member>) {
        (S::GLSL_NAME, S::SIZE, S::members())
    }
    vec![
        entry::<FrameParams>(),
        entry::<CascadeGrid>(),
        entry::<LightState>(),
        entry::<GpuTriangleCorners>(),
        entry::<BvhNode>(),
        entry::<GpuDraw>(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_glsl_member_is_named_as_in_rust() {
        let mut checked = 0;
        for (name, size, members) in shared_structs() {
            let mut end = 0;
            for m in &members {
                let declared = m
                    .glsl
                    .split_whitespace()
                    .nth(1)
                    .and_then(|s| s.split('[').next())
                    .unwrap_or("");
                assert_eq!(declared, m.name, "{name}: `{}`", m.glsl);
                assert_eq!(
                    m.offset, end,
                    "{name}.{}: a gap (scalar layout has none)",
                    m.name
                );
                end = m.offset + m.size;
                checked += 1;
            }
            assert_eq!(end, size, "{name}: trailing padding");
        }
        assert_eq!(checked, 116, "members of the six shared structs");
    }

    #[test]
    fn float_literals_are_exact() {
        for v in [1.0f32 / 256.0, 16.0 * f32::EPSILON, 1e-3, 1e-4, 0.1] {
            let l = macros::literal(macros::GlslKind::Float, v as f64);
            let back = if let Some(hex) = l.strip_prefix("uintBitsToFloat(0x") {
                f32::from_bits(u32::from_str_radix(&hex[..8], 16).unwrap())
            } else {
                l.parse::<f64>().unwrap() as f32
            };
            assert_eq!(back.to_bits(), v.to_bits(), "{l}");
        }
    }
}
