//! What a frame uploads besides the G-buffer: the scene as the GPU
//! receives it and the frame's parameters, with the per-device loop
//! budget.

use super::shared::{self, FrameParams, GpuTriangle, GpuTriangleCorners};
use super::GpuError;
use crate::cpu::light_setup::directional_rotation;
use crate::gbuffer::{flags, GBuffer, MAX_MICROQUAD_STRETCH};
use crate::scene::{Light, Scene};
use crate::settings::{IzbSettings, SampleMode};
use glam::Vec3;

/// The scene as the GPU receives it, built once per render (a capacity
/// rerun reuses it): eye-relative `f32` vertices and the unit normals the
/// CPU twin computes from the `f64` vertices, rounded.
#[derive(Default)]
pub(super) struct SceneUpload {
    /// Each triangle's three vertices, for the host's own uses (the BVH
    /// build, a shadow map's fit).
    pub(super) triangles: Vec<GpuTriangle>,
    /// What the device holds instead (`B_TRIANGLES`, `B_VERTICES`): per
    /// triangle its corners' indices into `vertices`, each distinct
    /// vertex (by its `f32` bits) once.
    pub(super) corners: Vec<GpuTriangleCorners>,
    pub(super) vertices: Vec<[f32; 3]>,
    pub(super) normals: Vec<[f32; 3]>,
}

/// Each triangle's unit normal as the CPU twin computes it, from its
/// `f64` eye-relative vertices, rounded to `f32`.
pub(super) fn triangle_normals(eye_relative: &[[glam::DVec3; 3]]) -> Vec<[f32; 3]> {
    eye_relative
        .iter()
        .map(|t| {
            (t[1] - t[0])
                .cross(t[2] - t[0])
                .normalize()
                .as_vec3()
                .to_array()
        })
        .collect()
}

impl SceneUpload {
    pub(super) fn new(scene: &Scene) -> Self {
        let eye_relative = scene.eye_relative_triangles();
        let triangles: Vec<GpuTriangle> = eye_relative
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| v.as_vec3().to_array());
                GpuTriangle { a, b, c }
            })
            .collect();
        let (corners, vertices) = distinct_vertices(&triangles);
        SceneUpload {
            triangles,
            corners,
            vertices,
            normals: triangle_normals(&eye_relative),
        }
    }

    /// The camera-facing normal of a receiver on triangle `id` with GPU
    /// G-buffer flags `gpu_flags` (zero for a miss).
    pub(super) fn receiver_normal(&self, id: u32, gpu_flags: u32) -> Vec3 {
        match self.normals.get(id as usize) {
            None => Vec3::ZERO,
            Some(&n) if gpu_flags & shared::FLAG_NORMAL_FLIPPED != 0 => -Vec3::from(n),
            Some(&n) => Vec3::from(n),
        }
    }

    /// The GPU G-buffer words of a CPU G-buffer: id, flags, and whether the
    /// CPU's normal is its triangle's negated. The CPU twin computes the
    /// same `f64` normal and rounds it the same way, so anything but an
    /// exact match up to sign is an inconsistent upload.
    pub(super) fn gbuffer_words(&self, g: &GBuffer) -> Result<Vec<u32>, GpuError> {
        (0..g.triangle_id.len())
            .map(|i| {
                let (id, f) = (g.triangle_id[i], g.flags[i]);
                let mut gpu_flags = f;
                if f & flags::HIT != 0 {
                    let stored = self.normals.get(id as usize).map(|&n| Vec3::from(n));
                    match stored {
                        Some(n) if n == g.normal[i] => {}
                        Some(n) if -n == g.normal[i] => gpu_flags |= shared::FLAG_NORMAL_FLIPPED,
                        _ => {
                            return Err(GpuError::Unsupported(format!(
                                "uploaded G-buffer: pixel {i}'s normal {} is not triangle {id}'s                                  normal up to sign",
                                g.normal[i]
                            )))
                        }
                    }
                }
                Ok(shared::pack_id_flags(id, gpu_flags))
            })
            .collect()
    }
}

/// Each triangle's corners as indices into a table of distinct vertices,
/// in order of first use. Vertices are the same by their bits, so a
/// triangle read back through its indices is the very triangle (`-0.0`
/// and `0.0` stay apart).
fn distinct_vertices(triangles: &[GpuTriangle]) -> (Vec<GpuTriangleCorners>, Vec<[f32; 3]>) {
    let mut index: std::collections::HashMap<[u32; 3], u32> =
        std::collections::HashMap::with_capacity(triangles.len());
    let mut vertices = Vec::with_capacity(triangles.len());
    let corners = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = [t.a, t.b, t.c].map(|v| {
                *index.entry(v.map(f32::to_bits)).or_insert_with(|| {
                    vertices.push(v);
                    (vertices.len() - 1) as u32
                })
            });
            GpuTriangleCorners { a, b, c }
        })
        .collect();
    (corners, vertices)
}

fn mode_code(mode: SampleMode) -> u32 {
    match mode {
        SampleMode::One => shared::mode::ONE,
        SampleMode::Lut32 => shared::mode::LUT32,
        SampleMode::Exact32 => shared::mode::EXACT32,
        SampleMode::Paired32 => shared::mode::PAIRED32,
        SampleMode::Paired64 => shared::mode::PAIRED64,
    }
}

/// lavapipe's gallivm stops every loop of a shader invocation once they
/// have run this many iterations in total (`LP_MAX_TGSI_LOOP_ITERATIONS`).
pub const LLVMPIPE_LOOP_CAP: u32 = 65535;

/// `FrameParams::loop_budget` for a device: below llvmpipe's cap with room
/// for the shader's other loops, unbounded on every other driver.
pub(super) fn loop_budget(device_name: &str) -> u32 {
    if device_name.contains("llvmpipe") {
        LLVMPIPE_LOOP_CAP - 1024
    } else {
        u32::MAX
    }
}

/// Default of `FrameParams::heavy_entries`: a pixel whose cells list more
/// candidates than this is evaluated by a whole workgroup in the heavy
/// step. On a GPU one thread's sequential candidates are the pass's tail:
/// courtyard at 960×540 has a pixel with 40 967 tests (CPU twin), which
/// one thread runs alone long after its tile's others are done.
pub const HEAVY_ENTRIES: u32 = 128;

/// `FrameParams::heavy_entries` on `device`: `requested`
/// (`GpuOptions::heavy_entries`), else [`HEAVY_ENTRIES`] on a GPU and 0
/// (no heavy step) on a CPU implementation: lavapipe runs a subgroup as a
/// SIMD loop on one core, where a long list holds no other lanes back,
/// and runs a heavy workgroup's 256 invocations in turn (at 160×90
/// `default` the step took 2.8 s of lavapipe's 3.8 s frame).
pub(super) fn heavy_entries(device: &super::context::DeviceInfo, requested: Option<u32>) -> u32 {
    requested.unwrap_or(if device.is_cpu() { 0 } else { HEAVY_ENTRIES })
}

/// The largest cell budget (as a square's side) the light setup may choose:
/// its upper bound, every receiver being a pixel.
pub(super) fn grid_budget_side(pixels: usize, triangles: usize, hint: Option<u32>) -> u32 {
    hint.unwrap_or_else(|| crate::cpu::light_setup::default_grid_side(pixels, triangles))
}

/// `FrameParams` for `scene`: camera rays as affine functions of the pixel
/// coordinates, the light, the directional light-view rotation (the CPU
/// twin's matrix, f64 then f32), the mode, the LUT and the pattern.
pub(super) fn frame_params(
    scene: &Scene,
    settings: IzbSettings,
    triangles: usize,
    max_cells: u64,
    cell_capacity: u64,
    loop_budget: u32,
    heavy_entries: u32,
) -> FrameParams {
    let frame = scene.camera.frame(scene.resolution);
    let corner = frame.direction(0.0, 0.0);
    let light = scene.light.relative_to(scene.camera.eye);
    let (light_vec, is_point, rotation) = match light {
        Light::Directional { direction } => {
            ((-direction).as_vec3(), 0, directional_rotation(direction))
        }
        Light::Point { position } => (position.as_vec3(), 1, glam::Mat3::IDENTITY),
    };
    let soft = settings.light_samples(scene);
    let (lut, pattern) = crate::lut::tables_for(soft);
    let rows = rotation.transpose();
    // LightSetup's light size and sun disk: the same f64 values, then f32.
    let light_radius = light.disk_radius(scene.light_radius) as f32;
    let (mut sun_axis_u, mut sun_axis_v) = (glam::Vec3::ZERO, glam::Vec3::ZERO);
    if let (Light::Directional { .. }, true) = (light, scene.has_area_light()) {
        let disk = light.disk_from(scene.light_radius, glam::DVec3::ZERO);
        (sun_axis_u, sun_axis_v) = (disk.axis_u.as_vec3(), disk.axis_v.as_vec3());
    }
    FrameParams {
        cam_corner: corner.as_vec3().to_array(),
        near: scene.camera.near as f32,
        cam_dx: frame.direction_dx().as_vec3().to_array(),
        far: scene.camera.far as f32,
        cam_dy: frame.direction_dy().as_vec3().to_array(),
        max_stretch: MAX_MICROQUAD_STRETCH as f32,
        light_vec: light_vec.to_array(),
        light_is_point: is_point,
        rot_x: rows.x_axis.to_array(),
        width: scene.resolution[0],
        rot_y: rows.y_axis.to_array(),
        height: scene.resolution[1],
        rot_z: rows.z_axis.to_array(),
        triangle_count: triangles as u32,
        mode: mode_code(settings.mode),
        cells_hint: settings.cells.unwrap_or(0),
        level_cells: settings.level_cells.unwrap_or(0),
        cell_capacity: cell_capacity.min(u64::from(u32::MAX)) as u32,
        lut_angle_scale: lut.angle_scale_f32(),
        lut_distance_scale: lut.distance_scale_f32(),
        lut_angles: lut.angles,
        lut_distances: lut.distances,
        max_cells: max_cells as u32,
        loop_budget,
        skips: settings.skips.bits(),
        pattern_radius: crate::frustum::pattern_radius(pattern),
        cam_forward: frame.forward.as_vec3().to_array(),
        cascades: settings.cascades.code(),
        split_lambda: settings.split_lambda,
        map_side: 0,
        map_filter: 0,
        map_reach: 0,
        light_radius,
        light_samples: soft as u32,
        mask_halves: settings.mask_halves(scene) as u32,
        sun_axis_u: sun_axis_u.to_array(),
        sun_axis_v: sun_axis_v.to_array(),
        map_light_size: 0.0,
        map_near: 0.0,
        volume_extrusion: 0.0,
        map_contact: 0,
        heavy_entries,
        heavy_capacity: super::frame_memory::heavy_capacity(scene.pixel_count() as u64)
            .min(u64::from(u32::MAX)) as u32,
        receiver_rows: scene.resolution[1],
        edge_surfaces: 0,
        covered_boxes: 0,
        edge_capacity: 0,
        overrun_exact: 0,
        eye_hi: [0.0; 3],
        world_vertex_count: 0,
        eye_lo: [0.0; 3],
        world_node_count: 0,
        depth_near: 0.0,
        depth_near_over_far: 0.0,
        depth_span: 0.0,
        depth_reversed: 0,
        depth_step: 0.0,
        draw_count: 0,
        bounds_lo: [0.0; 3],
        bounds_hi: [0.0; 3],
        pattern: *pattern,
        pair_pattern: *crate::lut::sample_pattern(),
        second_pattern: *crate::lut::paired_patterns(1).0,
        second_pair_pattern: *crate::lut::paired_patterns(1).1,
    }
}

/// A pixel pass over `[w, h]` entries (the image, or every receiver row)
/// fits the device's workgroup counts.
pub(super) fn check_workgroups(
    limits: &ash::vk::PhysicalDeviceLimits,
    [w, h]: [u32; 2],
) -> Result<(), GpuError> {
    let max = limits.max_compute_work_group_count;
    let [tile_x, tile_y] = shared::WORKGROUP_PIXELS;
    let groups = [w.div_ceil(tile_x), h.div_ceil(tile_y)];
    if groups[0] > max[0] || groups[1] > max[1] {
        return Err(GpuError::Unsupported(format!(
            "{w}x{h} entries need {}x{} workgroups, above this device's limit of {}x{}",
            groups[0], groups[1], max[0], max[1]
        )));
    }
    Ok(())
}
