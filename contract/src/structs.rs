//! The structs Rust and GLSL share (GLSL's scalar block layout: every
//! member 4-byte aligned, `vec3` = `[f32; 3]`, no padding).

use crate::macros::shared_struct;
use crate::size::MAX_CASCADES;

const CASCADES: usize = MAX_CASCADES as usize;

shared_struct! {
    /// `FrameParams`: per-frame constants, written by the host once per
    /// frame.
    pub struct FrameParams as "FrameParams" {
        /// Unnormalised ray direction through image point (0, 0).
        pub cam_corner: [f32; 3] => "vec3 cam_corner",
        pub near: f32 => "float near",
        /// d(direction)/dx per pixel.
        pub cam_dx: [f32; 3] => "vec3 cam_dx",
        pub far: f32 => "float far",
        /// d(direction)/dy per pixel (y down).
        pub cam_dy: [f32; 3] => "vec3 cam_dy",
        /// The G-buffer's largest µQuad stretch.
        pub max_stretch: f32 => "float max_stretch",
        /// Directional: unit vector toward the light; point: eye-relative
        /// position.
        pub light_vec: [f32; 3] => "vec3 light_vec",
        pub light_is_point: u32 => "uint light_is_point",
        /// Directional light: light-view rows (f64 on the host, then f32).
        pub rot_x: [f32; 3] => "vec3 rot_x",
        pub width: u32 => "uint width",
        pub rot_y: [f32; 3] => "vec3 rot_y",
        pub height: u32 => "uint height",
        pub rot_z: [f32; 3] => "vec3 rot_z",
        pub triangle_count: u32 => "uint triangle_count",
        /// `MODE_*`.
        pub mode: u32 => "uint mode",
        /// Cell budget as a square's side; 0: from the receiver count.
        pub cells_hint: u32 => "uint cells_hint",
        /// Cells per triangle and pyramid level; 0: the default.
        pub level_cells: u32 => "uint level_cells",
        /// Entries the cell list can hold.
        pub cell_capacity: u32 => "uint cell_capacity",
        pub lut_angle_scale: f32 => "float lut_angle_scale",
        pub lut_distance_scale: f32 => "float lut_distance_scale",
        pub lut_angles: u32 => "uint lut_angles",
        pub lut_distances: u32 => "uint lut_distances",
        /// `cell_start` capacity (all cascades' pyramids).
        pub max_cells: u32 => "uint max_cells",
        /// Loop iterations `evaluate` may run per pixel: lavapipe (gallivm)
        /// silently ends a shader's loops after 65535 iterations in total,
        /// so there the shader stops early and raises
        /// `LOOP_BUDGET_EXCEEDED` instead of returning a wrong mask;
        /// `u32::MAX` elsewhere.
        pub loop_budget: u32 => "uint loop_budget",
        /// `SKIP_*` bits.
        pub skips: u32 => "uint skips",
        /// Largest sample distance from the µQuad centre.
        pub pattern_radius: f32 => "float pattern_radius",
        /// Unit view direction (view depth = position · it).
        pub cam_forward: [f32; 3] => "vec3 cam_forward",
        /// 1..=4 cascades, 0 for auto.
        pub cascades: u32 => "uint cascades",
        /// Cascade split blend: 1 logarithmic, 0 uniform.
        pub split_lambda: f32 => "float split_lambda",
        /// Shadow-map frames: texels per side of each cascade's map; 0 in
        /// an IZB frame.
        pub map_side: u32 => "uint map_side",
        /// 0 one tap, k for k×k PCF, `PCSS_FILTER` for PCSS.
        pub map_filter: u32 => "uint map_filter",
        /// Texels the map reaches beyond the fitted bounds.
        pub map_reach: u32 => "uint map_reach",
        /// The light's size (`LightSetup::light_radius`): tan of a
        /// directional light's angular radius, a point light's sphere
        /// radius; 0 for a point-like light.
        pub light_radius: f32 => "float light_radius",
        /// 1 when masks are over the light's samples (soft shadows): then
        /// `pattern`, `pattern_radius` and the LUT buffer are the light's.
        pub light_samples: u32 => "uint light_samples",
        /// 32-bit mask halves per pixel: 2 in a `MODE_PAIRED64` IZB frame
        /// under an area light (`B_MASKS_HIGH` holds bits 32–63), else 1.
        pub mask_halves: u32 => "uint mask_halves",
        /// A directional light's disk axes (`LightSetup::sun_disk`, host
        /// `f64` then `f32`).
        pub sun_axis_u: [f32; 3] => "vec3 sun_axis_u",
        pub sun_axis_v: [f32; 3] => "vec3 sun_axis_v",
        /// PCSS: the light's size in the lookup's units, tan r of a
        /// directional light's angular radius r or a point light's radius;
        /// 0 otherwise.
        pub map_light_size: f32 => "float map_light_size",
        /// PCSS, directional light: the highest scene vertex along the
        /// direction toward the light (eye-relative), the near end of the
        /// map's depth range; 0 otherwise.
        pub map_near: f32 => "float map_near",
        /// Shadow volumes: how far each caster vertex moves away from the
        /// light for the dark cap (twice the scene's diagonal, past every
        /// receiver); 0 otherwise.
        pub volume_extrusion: f32 => "float volume_extrusion",
        /// 1: the shadow-map lookup adds contact shadows (`…+contact`).
        pub map_contact: u32 => "uint map_contact",
        /// Evaluate: a pixel whose cells list more entries than this hands
        /// them to the heavy step (a workgroup per pixel); 0: never.
        pub heavy_entries: u32 => "uint heavy_entries",
        /// Entries of the heavy step's queue (`B_HEAVY_PIXELS`).
        pub heavy_capacity: u32 => "uint heavy_capacity",
        /// Rows of receivers: `height`, then the rows of the edge pixels'
        /// extra surfaces (`B_EDGE_COVERAGE`), `width` per row, the last
        /// padded with misses.
        pub receiver_rows: u32 => "uint receiver_rows",
        /// 1 when the frame has edge surfaces (`B_EDGE_PIXELS`).
        pub edge_surfaces: u32 => "uint edge_surfaces",
        /// 1: a receiver covering only some of its µQuad's samples is
        /// binned and evaluated over the part its samples span (edge
        /// surfaces under a point-like light).
        pub covered_boxes: u32 => "uint covered_boxes",
        /// Extra surfaces the G-buffer rows below the image hold (the
        /// `edge_surfaces` pass's slots).
        pub edge_capacity: u32 => "uint edge_capacity",
        /// 1: a cell-list overrun sends every placed triangle through the
        /// overflow list (exact, slow: a frame nobody reruns); 0: the
        /// frame is rerun with room, its overrun masks are not used.
        pub overrun_exact: u32 => "uint overrun_exact",
        /// The eye relative to the shadow pass's anchor as a double-single
        /// (`eye_hi + eye_lo`), which `translate_vertices` subtracts from
        /// `B_WORLD_VERTICES`; zero where nothing translates.
        pub eye_hi: [f32; 3] => "vec3 eye_hi",
        /// Vertices `translate_vertices` writes (`B_WORLD_VERTICES`' pairs).
        pub world_vertex_count: u32 => "uint world_vertex_count",
        pub eye_lo: [f32; 3] => "vec3 eye_lo",
        /// A ray-cast shadow pass with a moving eye: BVH nodes
        /// `translate_vertices` makes eye-relative, from the anchor-space
        /// ones held after them in `B_BVH_NODES`; 0 elsewhere.
        pub world_node_count: u32 => "uint world_node_count",
        /// `gbuffer_from_depth`: the host's depth value D maps to the view
        /// depth `depth_near / (depth_near_over_far + u · depth_span)`,
        /// u = D with reverse Z (`depth_reversed` 1), 1 − D with standard
        /// Z; `depth_near_over_far` is 0 for an infinite far plane and
        /// `depth_span` = 1 − `depth_near_over_far`
        /// (`gbuffer::DepthConvention`).
        pub depth_near: f32 => "float depth_near",
        pub depth_near_over_far: f32 => "float depth_near_over_far",
        pub depth_span: f32 => "float depth_span",
        pub depth_reversed: u32 => "uint depth_reversed",
        /// The depth format's spacing where it is fixed (1/(2²⁴ − 1) for
        /// a 24-bit unorm); 0 for a float depth, whose spacing at D the
        /// shader takes from D's exponent.
        pub depth_step: f32 => "float depth_step",
        /// `gather_draws`: the frame's draws (`B_DRAWS`), and the bounds
        /// the pass was made for relative to this frame's eye (rounded
        /// outward), outside which a gathered vertex is counted
        /// (`COUNTER_OUTSIDE_BOUNDS`).
        pub draw_count: u32 => "uint draw_count",
        pub bounds_lo: [f32; 3] => "vec3 bounds_lo",
        pub bounds_hi: [f32; 3] => "vec3 bounds_hi",
        pub pattern: [[f32; 2]; 32] => "vec2 pattern[32]",
        /// The µQuad's samples, paired with `pattern`'s light samples in a
        /// paired frame (`MODE_PAIRED32`, `MODE_PAIRED64`) under an area
        /// light.
        pub pair_pattern: [[f32; 2]; 32] => "vec2 pair_pattern[32]",
        /// `MODE_PAIRED64`: the light and µQuad samples of the second 32
        /// pairs (`izb_lut::pairs`).
        pub second_pattern: [[f32; 2]; 32] => "vec2 second_pattern[32]",
        pub second_pair_pattern: [[f32; 2]; 32] => "vec2 second_pair_pattern[32]",
    }
}

shared_struct! {
    /// `CascadeGrid`: one cascade's grid.
    pub struct CascadeGrid as "CascadeGrid" {
        pub ndc_min: [f32; 2] => "vec2 ndc_min",
        pub ndc_max: [f32; 2] => "vec2 ndc_max",
        /// 0 for a cascade without receivers.
        pub cells_x: u32 => "uint cells_x",
        pub cells_y: u32 => "uint cells_y",
        /// First cell in the cell arrays (pyramids lie back to back).
        pub cell_offset: u32 => "uint cell_offset",
        /// A triangle is binned at the finest level where its rectangle
        /// holds at most this many cells.
        pub level_cells: u32 => "uint level_cells",
        pub receivers: u32 => "uint receivers",
        /// Reduction scratch (ordered bits): light-NDC bounds of its µQuads.
        pub ndc_lo: [u32; 2] => "uint ndc_lo[2]",
        pub ndc_hi: [u32; 2] => "uint ndc_hi[2]",
        /// Pyramid levels, finest (cells_x × cells_y) to 1×1.
        pub levels: u32 => "uint levels",
    }
}

shared_struct! {
    /// `LightState`: light view, cascades and grids, computed on the GPU
    /// by `light_setup`.
    pub struct LightState as "LightState" {
        pub rot_x: [f32; 3] => "vec3 rot_x",
        /// 0 orthographic (directional), 1 perspective (point).
        pub projection: u32 => "uint projection",
        pub rot_y: [f32; 3] => "vec3 rot_y",
        pub grid_disabled: u32 => "uint grid_disabled",
        pub rot_z: [f32; 3] => "vec3 rot_z",
        pub receivers: u32 => "uint receivers",
        pub origin: [f32; 3] => "vec3 origin",
        pub cascade_count: u32 => "uint cascade_count",
        pub receiver_z: [f32; 2] => "vec2 receiver_z",
        pub behind_light: u32 => "uint behind_light",
        /// Cells of all cascades.
        pub total_cells: u32 => "uint total_cells",
        /// Upper view depth per cascade.
        pub split: [f32; CASCADES] => "float split[MAX_CASCADES]",
        /// Near, far of the shadow-tested pixels.
        pub view_depth: [f32; 2] => "vec2 view_depth",
        /// Reduction scratch, floats in order-preserving uint encoding.
        pub pos_lo: [u32; 3] => "uint pos_lo[3]",
        pub pos_hi: [u32; 3] => "uint pos_hi[3]",
        pub depth_lo: u32 => "uint depth_lo",
        pub depth_hi: u32 => "uint depth_hi",
        pub z_lo: u32 => "uint z_lo",
        pub z_hi: u32 => "uint z_hi",
        pub cascade: [CascadeGrid; CASCADES] => "CascadeGrid cascade[MAX_CASCADES]",
    }
}

shared_struct! {
    /// `Triangle`: three eye-relative vertices, as the shaders assemble a
    /// triangle from its corners (`scene_triangle`) and the host uses it.
    pub struct GpuTriangle as "Triangle" {
        pub a: [f32; 3] => "vec3 a",
        pub b: [f32; 3] => "vec3 b",
        pub c: [f32; 3] => "vec3 c",
    }
}

shared_struct! {
    /// `TriangleCorners`: a triangle's vertices as indices into
    /// `B_VERTICES` (`B_TRIANGLES` holds one per triangle).
    pub struct GpuTriangleCorners as "TriangleCorners" {
        pub a: u32 => "uint a",
        pub b: u32 => "uint b",
        pub c: u32 => "uint c",
    }
}

shared_struct! {
    /// `BvhNode`: a node of the G-buffer pass's BVH2.
    pub struct BvhNode as "BvhNode" {
        pub lo: [f32; 3] => "vec3 lo",
        /// 0 for an inner node.
        pub prim_count: u32 => "uint prim_count",
        pub hi: [f32; 3] => "vec3 hi",
        /// Inner: left child (right = first + 1); leaf: first primitive
        /// slot.
        pub first: u32 => "uint first",
    }
}

impl LightState {
    /// The state before the reductions: every minimum at the largest
    /// ordered value, every maximum at the smallest.
    pub fn reset() -> Self {
        let grid = CascadeGrid {
            ndc_lo: [u32::MAX; 2],
            ndc_hi: [0; 2],
            ..bytemuck::Zeroable::zeroed()
        };
        LightState {
            pos_lo: [u32::MAX; 3],
            pos_hi: [0; 3],
            depth_lo: u32::MAX,
            depth_hi: 0,
            z_lo: u32::MAX,
            z_hi: 0,
            cascade: [grid; CASCADES],
            ..bytemuck::Zeroable::zeroed()
        }
    }
}

shared_struct! {
    /// `VisibilityView`: the push constants of the visibility raster
    /// (`visibility_raster.vert` / `.frag`), a pinhole camera with reverse
    /// Z (depth 1 at the near plane, 0 at the far). Positions and the eye
    /// are relative to one origin the host chooses (its vertex buffer's).
    pub struct VisibilityView as "VisibilityView" {
        /// The eye, relative to the vertex buffer's origin.
        pub eye: [f32; 3] => "vec3 eye",
        /// Clip z = depth_offset + depth_scale · view depth (reverse Z,
        /// near → 1, far → 0 after the divide by w = view depth).
        pub depth_offset: f32 => "float depth_offset",
        /// Unit right over (tan(fov_y / 2) · aspect): clip x.
        pub right: [f32; 3] => "vec3 right",
        /// Added to `gl_PrimitiveID`: the draw's first triangle id.
        pub first_triangle: u32 => "uint first_triangle",
        /// Unit image up over −tan(fov_y / 2) (Vulkan's y points down):
        /// clip y.
        pub down: [f32; 3] => "vec3 down",
        pub depth_scale: f32 => "float depth_scale",
        /// Unit view direction: clip w = view depth.
        pub forward: [f32; 3] => "vec3 forward",
    }
}

shared_struct! {
    /// `Draw`: one of the host's draws as `gather_draws` reads it — where
    /// its positions and indices lie in the host's buffers (`HOST_GEOMETRY`
    /// slots, in 4-byte words and in indices), and its object-to-eye
    /// transform folded on the host in `f64` and rounded once: a gathered
    /// vertex is `((row.x·v.x + row.y·v.y) + row.z·v.z) + row.w` per row,
    /// and a triangle's normal the cofactor rows times its object-space
    /// edge cross product (`izb::cpu::gather_draws`).
    pub struct GpuDraw as "Draw" {
        pub row_x: [f32; 4] => "vec4 row_x",
        pub row_y: [f32; 4] => "vec4 row_y",
        pub row_z: [f32; 4] => "vec4 row_z",
        pub cofactor_x: [f32; 3] => "vec3 cofactor_x",
        /// The draw's first triangle id (the sum of the counts before it).
        pub first_triangle: u32 => "uint first_triangle",
        pub cofactor_y: [f32; 3] => "vec3 cofactor_y",
        pub triangle_count: u32 => "uint triangle_count",
        pub cofactor_z: [f32; 3] => "vec3 cofactor_z",
        /// The `HOST_GEOMETRY` slot of its positions, their first word and
        /// stride in words, and how many vertices lie there.
        pub vertex_slot: u32 => "uint vertex_slot",
        pub vertex_offset: u32 => "uint vertex_offset",
        pub vertex_stride: u32 => "uint vertex_stride",
        pub vertex_count: u32 => "uint vertex_count",
        /// The slot of its indices (`NO_INDICES`: none, triangle t's
        /// corners are vertices 3t, 3t + 1, 3t + 2), their first index in
        /// units of its size, and the size in bytes (2 or 4).
        pub index_slot: u32 => "uint index_slot",
        pub index_offset: u32 => "uint index_offset",
        pub index_bytes: u32 => "uint index_bytes",
    }
}
