//! One frame on the GPU: buffers described by intent, one command buffer
//! (uploads → five passes with timestamps → read-backs), the capacity
//! rerun of the bin pass, and the report (per-pass milliseconds, counters,
//! memory per pass).

use super::context::{DeviceShared, GpuContext, GpuOptions};
use super::pipeline::{BindingLayout, DescriptorSet};
use super::resources::{BufferDesc, BufferDomain, GpuBuffer};
use super::shared::{self, binding, counter, FrameParams, GpuTriangle, LightState};
use super::{GpuError, Kernels, Recorder};
use crate::baseline::ShadowMapSettings;
use crate::gbuffer::{flags, GBuffer, GBufferStats, MAX_MICROQUAD_STRETCH};
use crate::izb::cascades::CascadeChoice;
use crate::izb::light_setup::directional_rotation;
use crate::izb::{IzbSettings, SampleMode};
use crate::scene::{Light, Scene};
use ash::vk;
use bytemuck::Pod;
use glam::Vec3;
use std::sync::Arc;
use std::time::Instant;

/// Where the frame's G-buffer comes from.
#[derive(Clone, Copy)]
pub enum GBufferSource<'a> {
    /// The GPU `gbuffer` pass casts the primary rays.
    Gpu,
    /// A CPU G-buffer is uploaded and the `gbuffer` pass is skipped: the
    /// later passes then see exactly the CPU twin's inputs (tests).
    Upload(&'a GBuffer),
}

/// Per-pass GPU milliseconds from timestamp queries.
pub type GpuPassMillis = crate::izb::PassTimes;

/// Device memory of one pass's buffers.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PassMemory {
    pub pass: &'static str,
    pub bytes: u64,
    pub buffers: Vec<(&'static str, u64)>,
}

/// One cascade's grid as the GPU fitted it.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GpuCascadeSummary {
    pub receivers: u32,
    pub cells: [u32; 2],
    pub cell_offset: u32,
    pub levels: u32,
    pub level_cells: u32,
    pub ndc_min: [f32; 2],
    pub ndc_max: [f32; 2],
}

/// The light view, cascades and grids as the GPU fitted them.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GpuLightSummary {
    pub perspective: bool,
    pub grid_disabled: bool,
    pub receivers: u32,
    /// How many cascades and why (the host's words for the GPU's choice,
    /// from the view-depth range it reduced).
    pub cascade_choice: CascadeChoice,
    /// View depth range of the shadow-tested pixels.
    pub view_depth: [f32; 2],
    /// Upper view depth of each cascade.
    pub split_depths: Vec<f32>,
    pub cascades: Vec<GpuCascadeSummary>,
    pub total_cells: u32,
    pub receiver_z: [f32; 2],
}

/// Counters read back once after the frame.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GpuCounters {
    pub hits: u32,
    pub shadow_tested: u32,
    pub clamped_microquads: u32,
    pub triangles_binned: u32,
    pub overflow: u32,
    pub culled: u32,
    pub cell_entries: u32,
    pub pixels_tested: u32,
    /// Pixels never shadow-tested (sky, facing away from the light).
    pub pixels_skipped: u32,
    pub early_outs: u32,
    pub shadow_map_early_outs: u32,
    pub saturated_masks: u64,
    pub entries_behind_receivers: u32,
    pub triangles_behind_receivers: u32,
    pub tests_spawned: u64,
    pub depth_passed: u64,
    pub cells_visited: u64,
    pub levels_visited: u64,
    /// Rectangle cells a binned triangle's projection misses (not listed).
    pub cells_untouched: u32,
    /// Tests whose mask was not empty.
    pub masks_nonempty: u64,
    /// Per cascade, bit l set when pyramid level l holds a placement.
    pub levels: Vec<u32>,
}

/// Settings, timings, counters and memory of one GPU frame.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GpuRenderReport {
    pub device: String,
    pub device_kind: String,
    pub settings: IzbSettings,
    pub gbuffer_source: &'static str,
    /// `None` when the queue has no timestamps.
    pub gpu_milliseconds: Option<GpuPassMillis>,
    /// Host wall time of the frame (submit to fence), seconds.
    pub wall_seconds: f64,
    /// Host seconds spent building the G-buffer BVH.
    pub bvh_build_seconds: f64,
    pub counters: GpuCounters,
    pub light: GpuLightSummary,
    /// Frames run: 2 when the cell list had to grow.
    pub frames_run: u32,
    pub memory: Vec<PassMemory>,
    pub memory_total_bytes: u64,
    pub memory_bytes_per_pixel_plus_triangle: f64,
}

/// What a GPU frame returns.
pub struct GpuRender {
    /// Occlusion mask per pixel (bit i = sample i in shadow).
    pub masks: Vec<u32>,
    /// Lit fraction, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    /// Shaded image, RGB8 per pixel.
    pub shaded: Vec<[u8; 3]>,
    /// The G-buffer as the GPU saw it (read back).
    pub gbuffer: GBuffer,
    pub report: GpuRenderReport,
}

/// The device, the shared layout and every pass's pipeline.
pub struct GpuRenderer {
    // Field order is drop order: pipelines before the device.
    pub kernels: Kernels,
    pub layout: BindingLayout,
    pub context: GpuContext,
}

/// The scene as the GPU receives it, built once per render (a capacity
/// rerun reuses it): eye-relative `f32` vertices and the unit normals the
/// CPU twin computes from the `f64` vertices, rounded.
pub(super) struct SceneUpload {
    pub(super) triangles: Vec<GpuTriangle>,
    normals: Vec<[f32; 3]>,
}

impl SceneUpload {
    pub(super) fn new(scene: &Scene) -> Self {
        let eye_relative = scene.eye_relative_triangles();
        SceneUpload {
            triangles: eye_relative
                .iter()
                .map(|t| GpuTriangle {
                    v: t.map(|v| v.as_vec3().to_array()),
                })
                .collect(),
            normals: eye_relative
                .iter()
                .map(|t| {
                    (t[1] - t[0])
                        .cross(t[2] - t[0])
                        .normalize()
                        .as_vec3()
                        .to_array()
                })
                .collect(),
        }
    }

    /// The camera-facing normal of a receiver on triangle `id` with GPU
    /// G-buffer flags `gpu_flags` (zero for a miss).
    fn receiver_normal(&self, id: u32, gpu_flags: u32) -> Vec3 {
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
    fn gbuffer_words(&self, g: &GBuffer) -> Result<Vec<u32>, GpuError> {
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

/// The frame's device buffers, one per binding, in binding order.
struct FrameBuffers {
    buffers: Vec<GpuBuffer>,
}

impl FrameBuffers {
    fn get(&self, b: u32) -> &GpuBuffer {
        &self.buffers[b as usize]
    }
}

fn as_bytes<T: Pod>(v: &[T]) -> &[u8] {
    bytemuck::cast_slice(v)
}

fn mode_code(mode: SampleMode) -> u32 {
    match mode {
        SampleMode::One => shared::mode::ONE,
        SampleMode::Lut32 => shared::mode::LUT32,
        SampleMode::Exact32 => shared::mode::EXACT32,
    }
}

/// lavapipe's gallivm stops every loop of a shader invocation once they
/// have run this many iterations in total (`LP_MAX_TGSI_LOOP_ITERATIONS`).
pub const LLVMPIPE_LOOP_CAP: u32 = 65535;

/// `FrameParams::loop_budget` for a device: below llvmpipe's cap with room
/// for the shader's other loops, unbounded on every other driver.
fn loop_budget(device_name: &str) -> u32 {
    if device_name.contains("llvmpipe") {
        LLVMPIPE_LOOP_CAP - 1024
    } else {
        u32::MAX
    }
}

/// The largest cell budget (as a square's side) the light setup may choose:
/// its upper bound, every receiver being a pixel.
fn grid_budget_side(pixels: usize, triangles: usize, hint: Option<u32>) -> u32 {
    hint.unwrap_or_else(|| crate::izb::light_setup::default_grid_side(pixels, triangles))
}

impl GpuRenderer {
    /// Opens a device and builds every pipeline.
    pub fn new(options: &GpuOptions) -> Result<Self, GpuError> {
        let context = GpuContext::new(options)?;
        let layout = BindingLayout::new(&context.shared)?;
        let kernels = Kernels::new(&context.shared, &layout)?;
        Ok(GpuRenderer {
            kernels,
            layout,
            context,
        })
    }

    pub(super) fn shared(&self) -> &Arc<DeviceShared> {
        &self.context.shared
    }

    /// Validation messages collected since the last call.
    pub fn take_validation_messages(&self) -> Vec<String> {
        self.shared().take_messages()
    }

    /// What every frame checks before it allocates — the image's
    /// workgroups within the device's limits, an uploaded G-buffer of the
    /// scene's size, triangle ids that fit the G-buffer word — and then the
    /// scene as the GPU receives it.
    pub(super) fn prepare_frame(
        &self,
        scene: &Scene,
        source: GBufferSource,
    ) -> Result<SceneUpload, GpuError> {
        let [w, h] = scene.resolution;
        let limits = &self.shared().limits;
        let groups = [w.div_ceil(8), h.div_ceil(8)];
        if groups[0] > limits.max_compute_work_group_count[0]
            || groups[1] > limits.max_compute_work_group_count[1]
        {
            return Err(GpuError::Unsupported(format!(
                "{w}x{h} needs {}x{} workgroups, above this device's limit of {}x{}",
                groups[0],
                groups[1],
                limits.max_compute_work_group_count[0],
                limits.max_compute_work_group_count[1]
            )));
        }
        if let GBufferSource::Upload(g) = source {
            if g.width != w || g.height != h {
                return Err(GpuError::Unsupported(format!(
                    "uploaded G-buffer is {}x{}, the scene renders at {w}x{h}",
                    g.width, g.height
                )));
            }
        }
        let upload = SceneUpload::new(scene);
        if upload.triangles.len() >= shared::ID_MASK as usize {
            return Err(GpuError::Unsupported(format!(
                "{} triangles: the GPU G-buffer holds ids below 2^{} - 1",
                upload.triangles.len(),
                shared::ID_BITS
            )));
        }
        Ok(upload)
    }

    /// Renders `scene`'s shadow mask.
    pub fn render(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
    ) -> Result<GpuRender, GpuError> {
        let pixels = scene.pixel_count();
        let upload = self.prepare_frame(scene, source)?;
        let triangles = &upload.triangles;
        let bvh_start = Instant::now();
        let bvh = match source {
            GBufferSource::Gpu => super::gbuffer::build_bvh(triangles)?,
            GBufferSource::Upload(_) => super::gbuffer::GpuBvh {
                nodes: Vec::new(),
                prims: Vec::new(),
                depth: 0,
            },
        };
        let bvh_build_seconds = bvh_start.elapsed().as_secs_f64();

        let side = grid_budget_side(pixels, triangles.len(), settings.cells);
        if side > 0xFFFF {
            return Err(GpuError::Unsupported(format!(
                "--cells {side}: the GPU's cell budget is at most 65535² cells"
            )));
        }
        let max_cells = crate::izb::cascades::max_total_cells(side);
        let mut capacity = initial_cell_capacity(triangles.len());
        let mut frames_run = 0;
        loop {
            frames_run += 1;
            let out = self.run_frame(
                scene,
                settings,
                source,
                &upload,
                &bvh,
                max_cells,
                capacity,
                FramePasses::Izb,
            )?;
            let needed = u64::from(out.counters[counter::CELL_ENTRIES]);
            if out.counters[counter::CAPACITY_EXCEEDED] != 0 && frames_run == 1 {
                capacity = needed;
                continue;
            }
            let trips = out.counters[counter::LOOP_BUDGET_EXCEEDED];
            if trips != 0 {
                return Err(GpuError::LoopCap {
                    device: self.context.info().name.clone(),
                    cap: LLVMPIPE_LOOP_CAP,
                    trips,
                });
            }
            if out.counters[counter::CAPACITY_EXCEEDED] != 0 {
                return Err(GpuError::Unsupported(format!(
                    "the cell list still overflowed after growing to {capacity} entries"
                )));
            }
            return Ok(self.finish(
                scene,
                settings,
                source,
                out,
                frames_run,
                bvh_build_seconds,
                &upload,
            ));
        }
    }

    /// Renders the shadow-map baseline `map` on the GPU: the IZB's
    /// G-buffer and light setup (with `map.cascades` cascades), then the
    /// raster and lookup passes; the twin of
    /// [`crate::baseline::render_shadow_map`].
    pub fn render_shadow_map(
        &self,
        scene: &Scene,
        map: ShadowMapSettings,
        source: GBufferSource,
    ) -> Result<GpuShadowMapRender, GpuError> {
        let limits = &self.shared().limits;
        let passes = FramePasses::ShadowMap(map);
        let map_bytes = passes.shadow_map_texels() * 4;
        let range = u64::from(limits.max_storage_buffer_range);
        if map_bytes > range {
            return Err(GpuError::Unsupported(format!(
                "{map}: {} MiB of maps, above this device's {} MiB storage-buffer range",
                map_bytes >> 20,
                range >> 20
            )));
        }
        let upload = self.prepare_frame(scene, source)?;
        let bvh = match source {
            GBufferSource::Gpu => super::gbuffer::build_bvh(&upload.triangles)?,
            GBufferSource::Upload(_) => super::gbuffer::GpuBvh {
                nodes: Vec::new(),
                prims: Vec::new(),
                depth: 0,
            },
        };
        // The light setup the CPU baseline asks for: `map.cascades` fixed
        // cascades; the 8×8 grid is unused.
        let settings = IzbSettings {
            cells: Some(8),
            cascades: crate::izb::CascadeCount::Fixed(map.cascades),
            ..Default::default()
        };
        let max_cells = crate::izb::cascades::max_total_cells(8);
        let out = self.run_frame(scene, settings, source, &upload, &bvh, max_cells, 1, passes)?;
        let trips = out.counters[counter::LOOP_BUDGET_EXCEEDED];
        if trips != 0 {
            return Err(GpuError::LoopCap {
                device: self.context.info().name.clone(),
                cap: LLVMPIPE_LOOP_CAP,
                trips,
            });
        }
        if out.light.grid_disabled != 0 {
            return Err(GpuError::Unsupported(format!(
                "{map} on {}: the receivers surround the point light, which one shadow-map frustum cannot hold (a cube map would)",
                scene.name
            )));
        }
        let visibility = out
            .masks
            .iter()
            .zip(&out.id_flags)
            .map(|(&m, &word)| {
                let (_, flags) = shared::unpack_id_flags(word);
                if flags & flags::SHADOW_TESTED != 0 {
                    f32::from_bits(m)
                } else {
                    f32::NAN
                }
            })
            .collect();
        Ok(GpuShadowMapRender {
            visibility,
            gpu_milliseconds: out.millis,
            wall_seconds: out.wall_seconds,
            map_bytes,
            memory_total_bytes: out.memory.iter().map(|m| m.bytes).sum(),
        })
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn run_frame(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
        upload: &SceneUpload,
        bvh: &super::gbuffer::GpuBvh,
        max_cells: u64,
        cell_capacity: u64,
        passes: FramePasses,
    ) -> Result<FrameOutput, GpuError> {
        let triangles = &upload.triangles[..];
        let shared = self.shared();
        let [w, h] = scene.resolution;
        let pixels = scene.pixel_count() as u64;
        let t = triangles.len() as u64;
        let lut = crate::lut::edge_lut();
        let descs = frame_buffer_descs(&FrameSizes {
            pixels,
            triangles: t,
            bvh_nodes: bvh.nodes.len() as u64,
            bvh_prims: bvh.prims.len() as u64,
            max_cells,
            cell_capacity,
            lut_entries: lut.masks.len() as u64,
            shadow_map_texels: passes.shadow_map_texels(),
        });
        debug_assert_eq!(descs.len(), binding::COUNT as usize);
        let frame_buffers = FrameBuffers {
            buffers: descs
                .into_iter()
                .map(|d| GpuBuffer::new(shared, d))
                .collect::<Result<_, _>>()?,
        };
        let fb = &frame_buffers;
        let refs: [&GpuBuffer; binding::COUNT as usize] = std::array::from_fn(|b| fb.get(b as u32));
        let set = DescriptorSet::new(shared, &self.layout, &refs)?;

        // Uploads through staging buffers, kept alive until the fence.
        let mut params = frame_params(
            scene,
            settings,
            triangles.len(),
            max_cells,
            cell_capacity,
            loop_budget(&shared.info.name),
        );
        if let FramePasses::ShadowMap(map) = passes {
            params.map_side = map.side;
            params.map_filter = match map.filter {
                crate::baseline::Filter::OneTap => 0,
                crate::baseline::Filter::Pcf(k) => k,
            };
            params.map_reach = map.filter.reach();
        }
        let mut uploads: Vec<(GpuBuffer, u32)> = Vec::new();
        let mut stage = |b: u32, bytes: &[u8]| -> Result<(), GpuError> {
            if bytes.is_empty() {
                return Ok(());
            }
            let mut staging = GpuBuffer::new(
                shared,
                BufferDesc {
                    name: "staging",
                    pass: "upload",
                    size: bytes.len() as u64,
                    domain: BufferDomain::Upload,
                },
            )?;
            staging.mapped_mut()?[..bytes.len()].copy_from_slice(bytes);
            uploads.push((staging, b));
            Ok(())
        };
        stage(binding::FRAME, bytemuck::bytes_of(&params))?;
        stage(binding::TRIANGLES, as_bytes(triangles))?;
        stage(binding::TRIANGLE_NORMALS, as_bytes(&upload.normals))?;
        stage(binding::BVH_NODES, as_bytes(&bvh.nodes))?;
        stage(binding::BVH_PRIMS, as_bytes(&bvh.prims))?;
        stage(binding::LIGHT, bytemuck::bytes_of(&LightState::reset()))?;
        stage(binding::EDGE_LUT, as_bytes(&lut.masks))?;
        if let GBufferSource::Upload(g) = source {
            let words = upload.gbuffer_words(g)?;
            stage(binding::G_POSITION, as_bytes(&g.position))?;
            stage(binding::G_AXIS_X, as_bytes(&g.axis_x))?;
            stage(binding::G_AXIS_Y, as_bytes(&g.axis_y))?;
            stage(binding::G_ID_FLAGS, as_bytes(&words))?;
        }

        let readback_of = [
            binding::COUNTERS,
            binding::LIGHT,
            binding::MASKS,
            binding::SHADED,
            binding::G_POSITION,
            binding::G_AXIS_X,
            binding::G_AXIS_Y,
            binding::G_ID_FLAGS,
        ];
        let readbacks: Vec<(GpuBuffer, u32)> = readback_of
            .iter()
            .map(|&b| {
                GpuBuffer::new(
                    shared,
                    BufferDesc {
                        name: "readback",
                        pass: "readback",
                        size: fb.get(b).size(),
                        domain: BufferDomain::Readback,
                    },
                )
                .map(|r| (r, b))
            })
            .collect::<Result<_, _>>()?;

        let timestamps = TimestampPool::new(shared, 6)?;
        let device = &shared.device;
        let start = Instant::now();
        self.context.submit_and_wait(|cmd| {
            let rec = Recorder {
                shared,
                cmd,
                layout: &self.layout,
                set: set.set,
            };
            unsafe {
                for (staging, b) in &uploads {
                    let region = [vk::BufferCopy::default().size(staging.size())];
                    device.cmd_copy_buffer(cmd, staging.buffer, fb.get(*b).buffer, &region);
                }
                device.cmd_fill_buffer(cmd, fb.get(binding::COUNTERS).buffer, 0, vk::WHOLE_SIZE, 0);
                device.cmd_fill_buffer(
                    cmd,
                    fb.get(binding::CELL_START).buffer,
                    0,
                    vk::WHOLE_SIZE,
                    0,
                );
                // No cover triangle anywhere yet (floor bits 0, !id 0).
                device.cmd_fill_buffer(
                    cmd,
                    fb.get(binding::CELL_COVER).buffer,
                    0,
                    vk::WHOLE_SIZE,
                    0,
                );
                // Empty cells: no receiver (z = ~0), reach 0 (stored as !0).
                device.cmd_fill_buffer(
                    cmd,
                    fb.get(binding::CELL_RECEIVERS).buffer,
                    0,
                    vk::WHOLE_SIZE,
                    u32::MAX,
                );
                // Every texel empty (the largest ordered distance).
                device.cmd_fill_buffer(
                    cmd,
                    fb.get(binding::SHADOW_MAP).buffer,
                    0,
                    vk::WHOLE_SIZE,
                    u32::MAX,
                );
            }
            rec.barrier();
            timestamps.reset(cmd);
            timestamps.write(cmd, 0);
            if let GBufferSource::Gpu = source {
                super::gbuffer::gbuffer(&rec, &self.kernels, [w, h]);
            }
            timestamps.write(cmd, 1);
            super::light_setup::light_setup(&rec, &self.kernels, [w, h]);
            timestamps.write(cmd, 2);
            match passes {
                FramePasses::Izb => {
                    let receivers = settings.skips.behind_receivers.then_some(w * h);
                    super::bin::bin(&rec, &self.kernels, triangles.len() as u32, receivers);
                    timestamps.write(cmd, 3);
                    super::evaluate::evaluate(&rec, &self.kernels, [w, h]);
                    timestamps.write(cmd, 4);
                    super::resolve::resolve(&rec, &self.kernels, [w, h]);
                }
                FramePasses::ShadowMap(_) => {
                    super::shadow_map::shadow_map(&rec, &self.kernels, triangles.len() as u32);
                    timestamps.write(cmd, 3);
                    super::shadow_map::shadow_lookup(&rec, &self.kernels, [w, h]);
                    timestamps.write(cmd, 4);
                }
                FramePasses::ShadowRays => {
                    timestamps.write(cmd, 3);
                    super::shadow_rays::shadow_rays(&rec, &self.kernels, [w, h]);
                    timestamps.write(cmd, 4);
                    super::resolve::resolve(&rec, &self.kernels, [w, h]);
                }
            }
            timestamps.write(cmd, 5);
            for (rb, b) in &readbacks {
                let region = [vk::BufferCopy::default().size(rb.size())];
                unsafe { device.cmd_copy_buffer(cmd, fb.get(*b).buffer, rb.buffer, &region) };
            }
            let to_host = [vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
                .dst_access_mask(vk::AccessFlags::HOST_READ)];
            unsafe {
                device.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::TRANSFER,
                    vk::PipelineStageFlags::HOST,
                    vk::DependencyFlags::empty(),
                    &to_host,
                    &[],
                    &[],
                );
            }
            Ok(())
        })?;
        let wall_seconds = start.elapsed().as_secs_f64();
        let millis = timestamps.millis()?;

        let read = |b: u32| -> Result<&[u8], GpuError> {
            let (rb, _) = readbacks
                .iter()
                .find(|(_, x)| *x == b)
                .expect("every read binding has a read-back buffer");
            rb.mapped()
        };
        let words = |b: u32| -> Result<Vec<u32>, GpuError> {
            Ok(bytemuck::pod_collect_to_vec(
                &read(b)?[..pixels as usize * 4],
            ))
        };
        let vec3s = |b: u32| -> Result<Vec<Vec3>, GpuError> {
            let f: Vec<f32> = bytemuck::pod_collect_to_vec(&read(b)?[..pixels as usize * 12]);
            Ok(f.chunks_exact(3).map(Vec3::from_slice).collect())
        };
        let counters: Vec<u32> =
            bytemuck::pod_collect_to_vec(&read(binding::COUNTERS)?[..counter::WORDS * 4]);
        let light: LightState =
            bytemuck::pod_read_unaligned(&read(binding::LIGHT)?[..size_of::<LightState>()]);
        let memory = memory_by_pass(&frame_buffers.buffers);
        Ok(FrameOutput {
            counters,
            light,
            masks: words(binding::MASKS)?,
            shaded: words(binding::SHADED)?,
            position: vec3s(binding::G_POSITION)?,
            axis_x: vec3s(binding::G_AXIS_X)?,
            axis_y: vec3s(binding::G_AXIS_Y)?,
            id_flags: words(binding::G_ID_FLAGS)?,
            millis,
            wall_seconds,
            memory,
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn finish(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
        out: FrameOutput,
        frames_run: u32,
        bvh_build_seconds: f64,
        upload: &SceneUpload,
    ) -> GpuRender {
        let triangles = upload.triangles.len() as u32;
        let c = &out.counters;
        let wide = |i: usize| u64::from(c[i]) | (u64::from(c[i + 1]) << 32);
        let counters = GpuCounters {
            hits: c[counter::HITS],
            shadow_tested: c[counter::SHADOW_TESTED],
            clamped_microquads: c[counter::CLAMPED],
            triangles_binned: c[counter::BINNED],
            overflow: c[counter::OVERFLOW],
            culled: c[counter::CULLED],
            cell_entries: c[counter::CELL_ENTRIES],
            pixels_tested: c[counter::PIXELS_TESTED],
            pixels_skipped: (scene.pixel_count() as u32).saturating_sub(c[counter::PIXELS_TESTED]),
            early_outs: c[counter::EARLY_OUTS],
            shadow_map_early_outs: c[counter::SHADOW_MAP_EARLY_OUTS],
            saturated_masks: wide(counter::SATURATED_MASKS),
            entries_behind_receivers: c[counter::ENTRIES_BEHIND],
            triangles_behind_receivers: c[counter::TRIANGLES_BEHIND],
            tests_spawned: wide(counter::TESTS_SPAWNED),
            depth_passed: wide(counter::DEPTH_PASSED),
            cells_visited: wide(counter::CELLS_VISITED),
            levels_visited: wide(counter::LEVELS_VISITED),
            cells_untouched: c[counter::CELLS_UNTOUCHED],
            masks_nonempty: wide(counter::MASKS_NONEMPTY),
            levels: (0..out.light.cascade_count as usize)
                .map(|k| c[counter::LEVELS + k])
                .collect(),
        };
        let [w, h] = scene.resolution;
        let frame = scene.camera.frame(scene.resolution);
        let forward = frame.forward.as_vec3();
        let gbuffer = match source {
            GBufferSource::Upload(g) => g.clone(),
            GBufferSource::Gpu => {
                let (triangle_id, gpu_flags): (Vec<u32>, Vec<u32>) = out
                    .id_flags
                    .iter()
                    .map(|&w| shared::unpack_id_flags(w))
                    .unzip();
                let normal = triangle_id
                    .iter()
                    .zip(&gpu_flags)
                    .map(|(&id, &f)| upload.receiver_normal(id, f))
                    .collect();
                let flags: Vec<u32> = gpu_flags
                    .iter()
                    .map(|f| f & !shared::FLAG_NORMAL_FLIPPED)
                    .collect();
                let depth = out
                    .position
                    .iter()
                    .zip(&flags)
                    .map(|(p, &f)| {
                        if f & flags::HIT != 0 {
                            p.dot(forward)
                        } else {
                            f32::INFINITY
                        }
                    })
                    .collect();
                GBuffer {
                    width: w,
                    height: h,
                    triangle_id,
                    depth,
                    position: out.position,
                    normal,
                    axis_x: out.axis_x,
                    axis_y: out.axis_y,
                    flags,
                    stats: GBufferStats {
                        pixels: scene.pixel_count(),
                        hits: counters.hits as usize,
                        shadow_tested: counters.shadow_tested as usize,
                        clamped_microquads: counters.clamped_microquads as usize,
                    },
                }
            }
        };
        let memory_total_bytes: u64 = out.memory.iter().map(|m| m.bytes).sum();
        let l = &out.light;
        let report = GpuRenderReport {
            device: self.context.info().name.clone(),
            device_kind: self.context.info().kind.clone(),
            settings,
            gbuffer_source: match source {
                GBufferSource::Gpu => "gpu",
                GBufferSource::Upload(_) => "uploaded",
            },
            gpu_milliseconds: out.millis,
            wall_seconds: out.wall_seconds,
            bvh_build_seconds,
            counters,
            light: GpuLightSummary {
                perspective: l.projection == 1,
                grid_disabled: l.grid_disabled != 0,
                receivers: l.receivers,
                cascade_choice: if l.receivers == 0 || l.grid_disabled != 0 {
                    CascadeChoice {
                        count: l.cascade_count,
                        reason: "no grid: no receivers, or every triangle overflows".into(),
                        ..Default::default()
                    }
                } else {
                    CascadeChoice::new(
                        settings.cascades,
                        l.view_depth[0],
                        l.view_depth[1],
                        settings.split_lambda,
                    )
                },
                view_depth: l.view_depth,
                split_depths: l.split[..l.cascade_count as usize].to_vec(),
                cascades: l.cascade[..l.cascade_count as usize]
                    .iter()
                    .map(|c| GpuCascadeSummary {
                        receivers: c.receivers,
                        cells: [c.cells_x, c.cells_y],
                        cell_offset: c.cell_offset,
                        levels: c.levels,
                        level_cells: c.level_cells,
                        ndc_min: c.ndc_min,
                        ndc_max: c.ndc_max,
                    })
                    .collect(),
                total_cells: l.total_cells,
                receiver_z: l.receiver_z,
            },
            frames_run,
            memory: out.memory,
            memory_total_bytes,
            memory_bytes_per_pixel_plus_triangle: memory_total_bytes as f64
                / (scene.pixel_count() as f64 + f64::from(triangles)).max(1.0),
        };
        let shaded = out
            .shaded
            .iter()
            .map(|&p| [p as u8, (p >> 8) as u8, (p >> 16) as u8])
            .collect();
        let visibility = out
            .shaded
            .iter()
            .map(|&p| shared::lit_fraction_of_alpha((p >> 24) as u8))
            .collect();
        GpuRender {
            masks: out.masks,
            visibility,
            shaded,
            gbuffer,
            report,
        }
    }
}

/// Which passes follow the G-buffer and light setup in a frame.
#[derive(Clone, Copy, Debug)]
pub(super) enum FramePasses {
    /// bin, evaluate, resolve.
    Izb,
    /// The shadow-map baseline: raster, lookup.
    ShadowMap(ShadowMapSettings),
    /// The `rt32-rays` peer: shadow rays in the evaluate slot, resolve.
    ShadowRays,
}

impl FramePasses {
    fn shadow_map_texels(&self) -> u64 {
        match self {
            FramePasses::Izb | FramePasses::ShadowRays => 0,
            FramePasses::ShadowMap(s) => u64::from(s.cascades) * u64::from(s.side).pow(2),
        }
    }
}

/// What a GPU shadow-map frame returns.
pub struct GpuShadowMapRender {
    /// Lit fraction, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    /// GPU milliseconds: `bin` holds the raster pass, `evaluate` the
    /// lookup, `resolve` is 0.
    pub gpu_milliseconds: Option<GpuPassMillis>,
    pub wall_seconds: f64,
    pub map_bytes: u64,
    pub memory_total_bytes: u64,
}

/// What one frame read back.
pub(super) struct FrameOutput {
    pub(super) counters: Vec<u32>,
    pub(super) light: LightState,
    pub(super) masks: Vec<u32>,
    pub(super) shaded: Vec<u32>,
    position: Vec<Vec3>,
    axis_x: Vec<Vec3>,
    axis_y: Vec<Vec3>,
    pub(super) id_flags: Vec<u32>,
    pub(super) millis: Option<GpuPassMillis>,
    pub(super) wall_seconds: f64,
    pub(super) memory: Vec<PassMemory>,
}

/// The sizes that decide a frame's buffers.
pub struct FrameSizes {
    pub pixels: u64,
    pub triangles: u64,
    pub bvh_nodes: u64,
    pub bvh_prims: u64,
    pub max_cells: u64,
    pub cell_capacity: u64,
    pub lut_entries: u64,
    /// Texels of every cascade's shadow map (0 in an IZB frame).
    pub shadow_map_texels: u64,
}

/// Every device buffer of a frame, in binding order (`shared::binding`),
/// each with the pass it counts toward and its size.
pub fn frame_buffer_descs(z: &FrameSizes) -> [BufferDesc; binding::COUNT as usize] {
    let (p, t, vec3) = (z.pixels, z.triangles, 12u64);
    [
        BufferDesc::device("frame", "frame_params", size_of::<FrameParams>() as u64),
        BufferDesc::device("scene", "triangles", t * 36),
        BufferDesc::device("gbuffer", "bvh_nodes", z.bvh_nodes * 32),
        BufferDesc::device("gbuffer", "bvh_prims", z.bvh_prims * 4),
        BufferDesc::device("gbuffer", "g_position", p * vec3),
        BufferDesc::device("gbuffer", "g_axis_x", p * vec3),
        BufferDesc::device("gbuffer", "g_axis_y", p * vec3),
        BufferDesc::device("gbuffer", "g_id_flags", p * 4),
        BufferDesc::device("light_setup", "light_state", size_of::<LightState>() as u64),
        BufferDesc::device("frame", "counters", counter::WORDS as u64 * 4),
        BufferDesc::device("bin", "cell_cover", z.max_cells * 8),
        BufferDesc::device("bin", "cell_start", (z.max_cells + 1) * 4),
        BufferDesc::device("bin", "cell_triangles", z.cell_capacity * 4),
        BufferDesc::device("bin", "overflow", t * 4),
        BufferDesc::device("evaluate", "edge_lut", z.lut_entries * 4),
        BufferDesc::device("evaluate", "masks", p * 4),
        BufferDesc::device("resolve", "shaded_and_lit_samples", p * 4),
        BufferDesc::device("scene", "triangle_normals", t * vec3),
        BufferDesc::device("bin", "cell_receivers", z.max_cells * 8),
        BufferDesc::device("shadow_map", "shadow_maps", z.shadow_map_texels.max(1) * 4),
    ]
}

/// The device memory a GPU frame of `scene` allocates before it runs (the
/// cell list at its first guess), per pass, without a device: for budgets
/// on machines that cannot run the frame.
pub fn planned_memory(scene: &Scene, settings: IzbSettings) -> Result<Vec<PassMemory>, GpuError> {
    let triangles = SceneUpload::new(scene).triangles;
    let bvh = super::gbuffer::build_bvh(&triangles)?;
    let side = grid_budget_side(scene.pixel_count(), triangles.len(), settings.cells);
    let descs = frame_buffer_descs(&FrameSizes {
        pixels: scene.pixel_count() as u64,
        triangles: triangles.len() as u64,
        bvh_nodes: bvh.nodes.len() as u64,
        bvh_prims: bvh.prims.len() as u64,
        max_cells: crate::izb::cascades::max_total_cells(side),
        cell_capacity: initial_cell_capacity(triangles.len()),
        lut_entries: crate::lut::edge_lut().masks.len() as u64,
        shadow_map_texels: 0,
    });
    Ok(group_by_pass(descs.iter().map(|d| {
        (d.pass, d.name, d.size.max(4).next_multiple_of(4))
    })))
}

/// Sums buffer sizes per owning pass, keeping each buffer's own size.
fn group_by_pass(
    buffers: impl Iterator<Item = (&'static str, &'static str, u64)>,
) -> Vec<PassMemory> {
    let mut out: Vec<PassMemory> = Vec::new();
    for (pass, name, size) in buffers {
        match out.iter_mut().find(|m| m.pass == pass) {
            Some(m) => {
                m.bytes += size;
                m.buffers.push((name, size));
            }
            None => out.push(PassMemory {
                pass,
                bytes: size,
                buffers: vec![(name, size)],
            }),
        }
    }
    out
}

/// First guess of the cell list's entries: 4 per triangle, at least 2^16.
fn initial_cell_capacity(triangles: usize) -> u64 {
    (4 * triangles as u64).max(1 << 16)
}

fn memory_by_pass(buffers: &[GpuBuffer]) -> Vec<PassMemory> {
    group_by_pass(buffers.iter().map(|b| (b.desc.pass, b.desc.name, b.size())))
}

/// `FrameParams` for `scene`: camera rays as affine functions of the pixel
/// coordinates, the light, the directional light-view rotation (the CPU
/// twin's matrix, f64 then f32), the mode, the LUT and the pattern.
fn frame_params(
    scene: &Scene,
    settings: IzbSettings,
    triangles: usize,
    max_cells: u64,
    cell_capacity: u64,
    loop_budget: u32,
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
    let lut = crate::lut::edge_lut();
    let rows = rotation.transpose();
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
        pattern_radius: crate::izb::frustum::pattern_radius(crate::lut::sample_pattern()),
        cam_forward: frame.forward.as_vec3().to_array(),
        cascades: settings.cascades.code(),
        split_lambda: settings.split_lambda,
        map_side: 0,
        map_filter: 0,
        map_reach: 0,
        pattern: *crate::lut::sample_pattern(),
    }
}

/// A timestamp query pool (absent when the queue has no timestamps).
struct TimestampPool {
    shared: Arc<DeviceShared>,
    pool: Option<vk::QueryPool>,
    count: u32,
}

impl TimestampPool {
    fn new(shared: &Arc<DeviceShared>, count: u32) -> Result<Self, GpuError> {
        let pool = match shared.timestamp_period_ns {
            None => None,
            Some(_) => {
                let info = vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(count);
                Some(
                    unsafe { shared.device.create_query_pool(&info, None) }
                        .map_err(GpuError::vk)?,
                )
            }
        };
        Ok(TimestampPool {
            shared: shared.clone(),
            pool,
            count,
        })
    }

    fn reset(&self, cmd: vk::CommandBuffer) {
        if let Some(pool) = self.pool {
            unsafe {
                self.shared
                    .device
                    .cmd_reset_query_pool(cmd, pool, 0, self.count)
            };
        }
    }

    fn write(&self, cmd: vk::CommandBuffer, index: u32) {
        if let Some(pool) = self.pool {
            unsafe {
                self.shared.device.cmd_write_timestamp(
                    cmd,
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    pool,
                    index,
                )
            };
        }
    }

    /// Milliseconds between consecutive timestamps, per pass.
    fn millis(&self) -> Result<Option<GpuPassMillis>, GpuError> {
        let (Some(pool), Some(period)) = (self.pool, self.shared.timestamp_period_ns) else {
            return Ok(None);
        };
        let mut ticks = vec![0u64; self.count as usize];
        unsafe {
            self.shared.device.get_query_pool_results(
                pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .map_err(GpuError::vk)?;
        let ms = |a: usize, b: usize| ticks[b].wrapping_sub(ticks[a]) as f64 * period * 1e-6;
        Ok(Some(GpuPassMillis {
            gbuffer: ms(0, 1),
            light_setup: ms(1, 2),
            bin: ms(2, 3),
            evaluate: ms(3, 4),
            resolve: ms(4, 5),
            total: ms(0, 5),
        }))
    }
}

impl Drop for TimestampPool {
    fn drop(&mut self) {
        if self.shared.is_poisoned() {
            return;
        }
        if let Some(pool) = self.pool {
            unsafe { self.shared.device.destroy_query_pool(pool, None) };
        }
    }
}
