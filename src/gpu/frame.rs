//! The renderer ([`GpuRenderer`]: the device, the layout, every pipeline)
//! and the baselines' batch frame (`GpuRenderer::run_frame`): one
//! command buffer (uploads → the IZB's G-buffer and light setup, then the
//! baseline's own passes, with timestamps → read-backs). The IZB's own
//! frames run on the shadow pass (`shadow_pass`, the batch `render`
//! around it in `izb_frame`). Its parts live beside it: the uploads and
//! parameters (`frame_inputs`), the buffers by intent (`frame_memory`),
//! the timestamps (`timestamps`) and the report (`frame_report`); the
//! shadow-map, volume and shadow-ray frames are in `shadow_map`,
//! `shadow_volumes` and `shadow_rays`.

use super::context::{DeviceShared, GpuContext, GpuOptions};
pub use super::frame_inputs::LLVMPIPE_LOOP_CAP;
use super::frame_inputs::{
    check_workgroups, frame_params, heavy_entries, loop_budget, SceneUpload,
};
use super::frame_memory::{
    frame_allocation, memory_by_pass, reset_pass_state, restaged_each_repetition,
};
pub use super::frame_memory::{frame_buffer_descs, EdgeSlots, FrameSizes};
use super::frame_report::{BaselinePasses, FrameOutput};
pub use super::frame_report::{
    GpuCascadeSummary, GpuCounters, GpuLightSummary, GpuPassMillis, GpuRender, GpuRenderReport,
    GpuShadowMapRender, PassMemory,
};
use super::pipeline::{BindingLayout, DescriptorSet};
use super::resources::{BufferDesc, BufferDomain, GpuBuffer};
use super::shared::{binding, counter, LightState};
use super::timestamps::TimestampPool;
use super::{GpuError, Kernels, Recorder};
use crate::gbuffer::GBuffer;
use crate::scene::Scene;
use crate::settings::IzbSettings;
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

/// The device, the shared layout and every pass's pipeline.
pub struct GpuRenderer {
    // Field order is drop order: pipelines before the device.
    pub kernels: Kernels,
    /// The shadow maps' depth-only pass, or why this device has none.
    pub(super) raster: Result<super::shadow_raster::ShadowRaster, String>,
    /// The volumes' stencil pass, or why this device has none.
    pub(super) volume_raster: Result<super::shadow_volumes::VolumeRaster, String>,
    pub layout: BindingLayout,
    pub context: GpuContext,
    /// Repetitions of the passes per frame ([`GpuRenderer::timed`]).
    timed_repeats: u32,
    /// `FrameParams::heavy_entries` of every frame.
    heavy_entries: u32,
    /// Whether shadow-map frames read their maps back
    /// ([`GpuShadowMapRender::maps`]).
    read_back_maps: bool,
}

/// The frame's device buffers ([`frame_allocation`]) and each binding's.
struct FrameBuffers {
    buffers: Vec<Arc<GpuBuffer>>,
    at: [usize; super::shared::BINDING_COUNT as usize],
}

impl FrameBuffers {
    fn get(&self, b: u32) -> &GpuBuffer {
        &self.buffers[self.at[b as usize]]
    }
}

fn as_bytes<T: Pod>(v: &[T]) -> &[u8] {
    bytemuck::cast_slice(v)
}

impl GpuRenderer {
    /// Opens a device and builds every pipeline.
    pub fn new(options: &GpuOptions) -> Result<Self, GpuError> {
        let context = GpuContext::new(options)?;
        let layout = BindingLayout::new(&context.shared)?;
        let kernels = Kernels::new(&context.shared, &layout)?;
        let raster = super::shadow_raster::ShadowRaster::new(&context.shared, &layout)
            .map_err(|e| e.to_string());
        let volume_raster = super::shadow_volumes::VolumeRaster::new(&context.shared, &layout)
            .map_err(|e| e.to_string());
        let heavy_entries = heavy_entries(context.info(), options.heavy_entries);
        Ok(GpuRenderer {
            kernels,
            raster,
            volume_raster,
            layout,
            context,
            timed_repeats: 1,
            heavy_entries,
            read_back_maps: false,
        })
    }

    /// The pipelines on the host's device ([`GpuContext::on_host_device`]):
    /// what a [`super::shadow_pass::ShadowPass`] inside the host's frame
    /// needs. The baselines' raster passes are not built there.
    ///
    /// # Safety
    /// As [`GpuContext::on_host_device`].
    pub unsafe fn on_host_device(
        host: super::host_device::HostDevice,
        heavy_threshold: Option<u32>,
    ) -> Result<Self, GpuError> {
        // SAFETY: the caller's promise.
        let context = unsafe { GpuContext::on_host_device(host) }?;
        let layout = BindingLayout::new(&context.shared)?;
        let kernels = Kernels::new(&context.shared, &layout)?;
        let why = context.shared.raster_missing.clone().unwrap_or_default();
        Ok(GpuRenderer {
            kernels,
            raster: Err(format!("shadow maps: {why}")),
            volume_raster: Err(format!("shadow volumes: {why}")),
            layout,
            heavy_entries: heavy_entries(context.info(), heavy_threshold),
            context,
            timed_repeats: 1,
            read_back_maps: false,
        })
    }

    /// For timing: every frame runs its passes `repeats` times in one
    /// submission and reports the median of the repetitions after the
    /// first. An idle GPU lowers its clocks between frames (an H200 idles
    /// at 345 MHz against 1 980 MHz under load), so one short frame after
    /// host work is timed at whatever clock it finds; back-to-back
    /// repetitions are timed under load. Results are the last
    /// repetition's, the same as a single run's. The IZB's repetitions
    /// are frame slots of its pass: at most 63.
    pub fn timed(mut self, repeats: u32) -> Self {
        let most = super::shadow_pass::MAX_FRAMES_IN_FLIGHT as u32;
        self.timed_repeats = repeats.clamp(1, most);
        self
    }

    /// Repetitions of the passes per frame ([`Self::timed`]).
    pub(super) fn timed_repeats(&self) -> u32 {
        self.timed_repeats.max(1)
    }

    /// For the twin tests: shadow-map frames read their depth maps back.
    pub fn read_back_shadow_maps(&mut self, on: bool) {
        self.read_back_maps = on;
    }

    /// `FrameParams::heavy_entries` of every frame on this device.
    pub(super) fn heavy_entries(&self) -> u32 {
        self.heavy_entries
    }

    pub(super) fn shared(&self) -> &Arc<DeviceShared> {
        &self.context.shared
    }

    /// Validation messages collected since the last call.
    pub fn take_validation_messages(&self) -> Vec<String> {
        self.shared().take_messages()
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
        passes: BaselinePasses,
    ) -> Result<FrameOutput, GpuError> {
        let triangles = &upload.triangles[..];
        let shared = self.shared();
        let [w, h] = scene.resolution;
        let pixels = scene.pixel_count() as u64;
        let t = triangles.len() as u64;
        check_workgroups(&self.shared().limits, [w, h])?;
        let (lut, _) = crate::lut::tables_for(settings.light_samples(scene));
        let descs = frame_buffer_descs(&FrameSizes {
            pixels,
            tiles: super::edge_surfaces::edge_tiles(scene.resolution),
            receivers: pixels,
            edge_surfaces: None,
            triangles: t,
            vertices: upload.vertices.len() as u64,
            world_vertices: 0,
            normal_entries: 0,
            draws: 0,
            bvh_nodes: bvh.nodes.len() as u64,
            bvh_prims: bvh.prims.len() as u64,
            max_cells,
            cell_capacity,
            lut_entries: lut.masks.len() as u64,
            shadow_map_words: passes.shadow_map_words(pixels),
            mask_halves: 1,
        });
        let (buffer_descs, at) = frame_allocation(descs);
        let frame_buffers = FrameBuffers {
            buffers: buffer_descs
                .into_iter()
                .map(|d| GpuBuffer::new(shared, d).map(Arc::new))
                .collect::<Result<_, _>>()?,
            at,
        };
        let fb = &frame_buffers;
        let bound = std::array::from_fn(|b| fb.buffers[fb.at[b]].clone());
        let set = DescriptorSet::new(shared, &self.layout, bound)?;
        let depth_target = match passes {
            BaselinePasses::Map(map) => Some(self.depth_target(map)?),
            _ => None,
        };
        let volume_target = match passes {
            BaselinePasses::Volumes => Some(self.volume_target(scene)?),
            _ => None,
        };

        // Uploads through staging buffers, kept alive until the fence.
        let mut params = frame_params(
            scene,
            settings,
            triangles.len(),
            max_cells,
            cell_capacity,
            loop_budget(&shared.info.name),
            self.heavy_entries,
        );
        params.mask_halves = 1;
        match passes {
            BaselinePasses::Map(map) => {
                super::shadow_map::map_params(&mut params, scene, triangles, map)
            }
            BaselinePasses::Volumes => {
                params.volume_extrusion =
                    crate::baseline::screen_frame::ScreenFrame::new(scene).extrusion
            }
            _ => {}
        }
        let mut uploads: Vec<(GpuBuffer, u32)> = Vec::new();
        let mut stage = |b: u32, bytes: &[u8]| -> Result<(), GpuError> {
            if bytes.is_empty() {
                return Ok(());
            }
            uploads.push((GpuBuffer::staging(shared, bytes)?, b));
            Ok(())
        };
        stage(binding::FRAME, bytemuck::bytes_of(&params))?;
        stage(binding::TRIANGLES, as_bytes(&upload.corners))?;
        stage(binding::VERTICES, as_bytes(&upload.vertices))?;
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

        let maps_back = self.read_back_maps && matches!(passes, BaselinePasses::Map(_));
        let readback_of = [
            maps_back.then_some(binding::SHADOW_MAP),
            Some(binding::COUNTERS),
            Some(binding::LIGHT),
            Some(binding::MASKS),
            Some(binding::SHADED),
            Some(binding::G_POSITION),
            Some(binding::G_AXIS_X),
            Some(binding::G_AXIS_Y),
            Some(binding::G_ID_FLAGS),
        ];
        let readbacks: Vec<(GpuBuffer, u32)> = readback_of
            .iter()
            .flatten()
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

        // Several repetitions of the passes in one submission keep the GPU
        // busy (its clocks up) for the timed ones; each starts from the
        // same state, so the last one's results are a single frame's.
        let repeats = self.timed_repeats.max(1);
        let timestamps = TimestampPool::new(shared, TIMESTAMPS_PER_FRAME * repeats)?;
        let restaged: Vec<&(GpuBuffer, u32)> = uploads
            .iter()
            .filter(|(_, b)| restaged_each_repetition(*b))
            .collect();
        let device = &shared.device;
        let start = Instant::now();
        let record = |cmd| {
            // SAFETY: `cmd` is recording on this thread (`submit_and_wait`);
            // the kernels, the layout and the set live in `self` and this
            // function, past the wait below.
            let rec = unsafe { Recorder::new(shared, cmd, &self.layout, &set) };
            // SAFETY: `cmd` is recording; every buffer belongs to this frame and
            // lives until after its fence wait; copies stay within each buffer.
            unsafe {
                for (staging, b) in &uploads {
                    let region = [vk::BufferCopy::default().size(staging.size())];
                    device.cmd_copy_buffer(cmd, staging.buffer, fb.get(*b).buffer, &region);
                }
            }
            timestamps.reset(cmd);
            for rep in 0..repeats {
                if rep > 0 {
                    // The previous repetition's passes are done with the
                    // state reset below.
                    rec.barrier();
                    for (staging, b) in &restaged {
                        let region = [vk::BufferCopy::default().size(staging.size())];
                        // SAFETY: as above.
                        unsafe {
                            device.cmd_copy_buffer(cmd, staging.buffer, fb.get(*b).buffer, &region)
                        };
                    }
                }
                reset_pass_state(device, cmd, |b| fb.get(b).buffer, false);
                rec.barrier();
                let mark = |j: u32| timestamps.write(cmd, rep * TIMESTAMPS_PER_FRAME + j);
                mark(0);
                if let GBufferSource::Gpu = source {
                    super::gbuffer::gbuffer(&rec, &self.kernels, [w, h], false);
                }
                mark(1);
                super::light_setup::light_setup(&rec, &self.kernels, [w, h]);
                mark(2);
                match passes {
                    BaselinePasses::Map(map) => {
                        let (raster, target) = depth_target.as_ref().expect("made above");
                        let map_buffer = fb.get(binding::SHADOW_MAP).buffer;
                        let drawn = (triangles.len() as u32, params.light_is_point != 0);
                        super::shadow_map::shadow_map(&rec, raster, target, map_buffer, drawn, map);
                        super::shadow_map::shadow_blur(&rec, &self.kernels, map);
                        mark(3);
                        super::shadow_map::shadow_lookup(&rec, &self.kernels, [w, h]);
                        mark(4);
                    }
                    BaselinePasses::Volumes => {
                        let (raster, target) = volume_target.as_ref().expect("made above");
                        let buffer = fb.get(binding::SHADOW_MAP).buffer;
                        let n = triangles.len() as u32;
                        super::shadow_volumes::shadow_volumes(
                            &rec,
                            &self.kernels,
                            raster,
                            target,
                            buffer,
                            n,
                        );
                        mark(3);
                        super::shadow_volumes::volume_lookup(&rec, &self.kernels, [w, h]);
                        mark(4);
                    }
                    BaselinePasses::Rays => {
                        mark(3);
                        super::shadow_rays::shadow_rays(&rec, &self.kernels, [w, h]);
                        mark(4);
                        super::resolve::resolve(&rec, &self.kernels, [w, h]);
                    }
                }
                mark(5);
            }
            for (rb, b) in &readbacks {
                let region = [vk::BufferCopy::default().size(rb.size())];
                // SAFETY: as above; each read-back buffer is its source's size.
                unsafe { device.cmd_copy_buffer(cmd, fb.get(*b).buffer, rb.buffer, &region) };
            }
            // SAFETY: `cmd` is recording.
            unsafe { super::transfers_visible_to_host(device, cmd) };
            Ok(())
        };
        // SAFETY: everything the commands use — the frame's buffers, the
        // staging and read-back buffers, the set, the timestamp pools and
        // the render targets — is owned by this function or `self` and
        // outlives the call, which waits for the commands to finish.
        unsafe { self.context.submit_and_wait(record) }?;
        let wall_seconds = start.elapsed().as_secs_f64();
        let millis = timestamps.millis(repeats)?;

        let read = |b: u32| -> Result<&[u8], GpuError> {
            let (rb, _) = readbacks
                .iter()
                .find(|(_, x)| *x == b)
                .expect("every read binding has a read-back buffer");
            rb.mapped()
        };
        let counters: Vec<u32> =
            bytemuck::pod_collect_to_vec(&read(binding::COUNTERS)?[..counter::WORDS * 4]);
        let entries = pixels as usize;
        let words_of = |b: u32, n: usize| -> Result<Vec<u32>, GpuError> {
            Ok(bytemuck::pod_collect_to_vec(&read(b)?[..n * 4]))
        };
        let words = |b: u32| words_of(b, pixels as usize);
        let vec3s = |b: u32| -> Result<Vec<Vec3>, GpuError> {
            let f: Vec<f32> = bytemuck::pod_collect_to_vec(&read(b)?[..entries * 12]);
            Ok(f.chunks_exact(3).map(Vec3::from_slice).collect())
        };
        let light: LightState =
            bytemuck::pod_read_unaligned(&read(binding::LIGHT)?[..size_of::<LightState>()]);
        let mut memory = memory_by_pass(&frame_buffers.buffers);
        for (pass, target) in [
            ("shadow_map", depth_target.as_ref().map(|t| &t.1)),
            ("shadow_volumes", volume_target.as_ref().map(|t| &t.1)),
        ] {
            if let Some(target) = target {
                memory.push(super::frame_report::PassMemory {
                    pass,
                    bytes: target.bytes,
                    buffers: vec![("depth attachment (image)", target.bytes)],
                });
            }
        }
        Ok(FrameOutput {
            counters,
            light,
            masks: words(binding::MASKS)?,
            shaded: words(binding::SHADED)?,
            position: vec3s(binding::G_POSITION)?,
            axis_x: vec3s(binding::G_AXIS_X)?,
            axis_y: vec3s(binding::G_AXIS_Y)?,
            id_flags: words_of(binding::G_ID_FLAGS, entries)?,
            shadow_maps: match maps_back {
                true => bytemuck::pod_collect_to_vec(read(binding::SHADOW_MAP)?),
                false => Vec::new(),
            },
            millis,
            wall_seconds,
            memory,
        })
    }
}

/// Timestamps of one repetition of a frame's passes: before the G-buffer,
/// then after each pass.
const TIMESTAMPS_PER_FRAME: u32 = 6;
