//! What a GPU frame reports: per-pass milliseconds, counters, the light
//! setup as the GPU fitted it, memory per pass; and the step that turns a
//! frame's read-backs into that report.

use super::frame::{GBufferSource, GpuRenderer};
use super::frame_inputs::SceneUpload;
use super::shared::LightState;
use super::shared::{self, counter};
use crate::baseline::ShadowMapSettings;
use crate::cascades::CascadeChoice;
use crate::gbuffer::{flags, GBuffer, GBufferStats};
use crate::scene::Scene;
use crate::settings::IzbSettings;
use glam::Vec3;

/// Per-pass GPU milliseconds from timestamp queries.
pub type GpuPassMillis = crate::settings::PassTimes;

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
    /// Entries the cell list needed (its size when nothing overran).
    pub cell_entries: u32,
    /// The cell list was too small for `cell_entries`: the frame ran the
    /// slow exact way, every placed triangle through the overflow list
    /// (and `overflow` counts those entries too).
    pub cell_list_overrun: bool,
    pub pixels_tested: u32,
    /// Edge pixels' extra surfaces tested (receivers beside the pixels).
    pub extra_surfaces_tested: u32,
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
    /// Pixels evaluated by the heavy step (a workgroup each; a `Paired64`
    /// pixel once per mask half).
    pub heavy_pixels: u32,
    /// The most tests one pixel ran in the tile step (one thread's walk).
    pub longest_tile_tests: u32,
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
    /// Each dispatch of the timed repetition: kernel name and milliseconds
    /// (empty without timestamps).
    pub gpu_step_milliseconds: Vec<(String, f64)>,
    /// Host wall time of the frame (submit to fence), seconds.
    pub wall_seconds: f64,
    /// Host seconds spent building the G-buffer BVH.
    pub bvh_build_seconds: f64,
    pub counters: GpuCounters,
    pub light: GpuLightSummary,
    /// Frames run: 2 when the cell list or the edge surfaces' slots had
    /// to grow.
    pub frames_run: u32,
    pub memory: Vec<PassMemory>,
    pub memory_total_bytes: u64,
    pub memory_bytes_per_pixel_plus_triangle: f64,
}

/// What a GPU frame returns.
pub struct GpuRender {
    /// Occlusion mask per pixel (bit i = sample i in shadow).
    pub masks: Vec<u32>,
    /// Bits 32–63 of 64-sample masks (`Paired64` under an area light),
    /// empty otherwise: [`crate::cpu::ShadowRender::masks_high`]'s twin.
    pub masks_high: Vec<u32>,
    /// Lit fraction, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    /// Shaded image, RGB8 per pixel.
    pub shaded: Vec<[u8; 3]>,
    /// The G-buffer as the GPU saw it (read back).
    pub gbuffer: GBuffer,
    pub report: GpuRenderReport,
}

/// GPU milliseconds of a shadow-map frame: the IZB's G-buffer and light
/// setup, then the map's own two passes.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ShadowMapMillis {
    pub gbuffer: f64,
    pub light_setup: f64,
    /// `shadow_map`: the triangles rasterised into the maps.
    pub raster: f64,
    /// `shadow_lookup`: one filtered lookup per pixel.
    pub lookup: f64,
    pub total: f64,
}

impl ShadowMapMillis {
    /// From the frame's timestamps, whose third and fourth slots held the
    /// raster and the lookup.
    pub(super) fn from_frame(t: &GpuPassMillis) -> Self {
        ShadowMapMillis {
            gbuffer: t.gbuffer,
            light_setup: t.light_setup,
            raster: t.bin,
            lookup: t.evaluate,
            total: t.total,
        }
    }

    /// In the five-pass table every method's row shares (`izb bench`):
    /// the raster in the `bin` column, the lookup in `evaluate`.
    pub fn as_pass_times(&self) -> GpuPassMillis {
        GpuPassMillis {
            gbuffer: self.gbuffer,
            light_setup: self.light_setup,
            bin: self.raster,
            evaluate: self.lookup,
            resolve: 0.0,
            total: self.total,
        }
    }
}

/// What a GPU shadow-map frame returns.
pub struct GpuShadowMapRender {
    /// Lit fraction, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    /// The G-buffer as the GPU saw it (read back), for shading.
    pub gbuffer: GBuffer,
    pub gpu_milliseconds: Option<ShadowMapMillis>,
    pub wall_seconds: f64,
    pub map_bytes: u64,
    pub memory_total_bytes: u64,
    /// The whole map buffer: first the depth maps, cascade after cascade,
    /// `side`² each, row-major, as the depth attachments held them; for
    /// `vsm`/`msm` the blur's rows and the moments follow. Empty unless
    /// [`GpuRenderer::read_back_shadow_maps`] asked for it.
    pub maps: Vec<f32>,
}

impl GpuShadowMapRender {
    /// The result of a baseline's frame (maps or volumes): the lit
    /// fraction the lookup wrote as float bits in `masks`, the G-buffer
    /// read back, times and memory; `buffer_bytes` of method storage.
    pub(super) fn from_frame(
        scene: &Scene,
        source: GBufferSource,
        upload: &SceneUpload,
        mut out: FrameOutput,
        buffer_bytes: u64,
    ) -> Self {
        let visibility = out.per_tested_pixel(&out.masks, f32::from_bits);
        let gbuffer = read_back_gbuffer(scene, source, upload, &mut out);
        GpuShadowMapRender {
            visibility,
            gbuffer,
            gpu_milliseconds: out.millis.as_ref().map(ShadowMapMillis::from_frame),
            wall_seconds: out.wall_seconds,
            map_bytes: buffer_bytes,
            memory_total_bytes: out.memory.iter().map(|m| m.bytes).sum(),
            maps: std::mem::take(&mut out.shadow_maps),
        }
    }
}

/// What the batch `render` reads back from its pass after the frame
/// (`izb_frame`).
pub(super) struct IzbReadBack {
    pub(super) frame: super::shadow_pass::PassFrame,
    /// The G-buffer as the pass saw it (read back, or the uploaded one).
    pub(super) gbuffer: GBuffer,
    pub(super) counters: Vec<u32>,
    pub(super) light: LightState,
    pub(super) millis: Option<GpuPassMillis>,
    pub(super) step_millis: Vec<(String, f64)>,
    pub(super) wall_seconds: f64,
    pub(super) memory: Vec<PassMemory>,
}

impl GpuRenderer {
    /// The batch `render`'s result from its pass's read-backs.
    pub(super) fn finish(
        &self,
        scene: &Scene,
        settings: IzbSettings,
        source: GBufferSource,
        out: IzbReadBack,
        frames_run: u32,
        bvh_build_seconds: f64,
    ) -> GpuRender {
        let triangles = scene.triangles.len() as u32;
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
            cell_list_overrun: c[counter::CAPACITY_EXCEEDED] != 0,
            pixels_tested: c[counter::PIXELS_TESTED],
            extra_surfaces_tested: c[counter::EXTRA_SURFACES_TESTED],
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
            heavy_pixels: c[counter::HEAVY_PIXELS] + c[counter::HEAVY_PIXELS_HIGH],
            longest_tile_tests: c[counter::LONGEST_TILE_TESTS],
            levels: (0..out.light.cascade_count as usize)
                .map(|k| c[counter::LEVELS + k])
                .collect(),
        };
        let gbuffer = out.gbuffer;
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
            gpu_step_milliseconds: out.step_millis,
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
        GpuRender {
            masks: out.frame.masks,
            masks_high: out.frame.masks_high,
            visibility: out.frame.visibility,
            shaded: out.frame.shaded,
            gbuffer,
            report,
        }
    }
}

/// `resolve`'s packed pixels (RGB, and the lit samples in alpha) as the
/// lit fraction (NaN where not shadow-tested) and RGB8: over every sample
/// of `halves` mask halves, or over `counted(i)` at pixel `i` where a
/// frame has edge surfaces (the samples its surfaces keep).
pub(super) fn resolved_images(
    shaded: &[u32],
    halves: usize,
    counted: Option<impl Fn(usize) -> u32>,
) -> (Vec<f32>, Vec<[u8; 3]>) {
    let alpha = |i: usize| (shaded[i] >> 24) as u8;
    let visibility = (0..shaded.len())
        .map(|i| match &counted {
            Some(samples) => super::edge_surfaces::lit_fraction_over_counted(alpha(i), samples(i)),
            None => shared::lit_fraction_of_alpha(alpha(i), 32 * halves as u32),
        })
        .collect();
    let rgb = shaded
        .iter()
        .map(|&p| [p as u8, (p >> 8) as u8, (p >> 16) as u8])
        .collect();
    (visibility, rgb)
}

/// The G-buffer of a frame as the GPU saw it: read back (normals from the
/// uploaded triangles, depth along the view axis), or the uploaded one.
pub(super) fn read_back_gbuffer(
    scene: &Scene,
    source: GBufferSource,
    upload: &SceneUpload,
    out: &mut FrameOutput,
) -> GBuffer {
    let forward = scene.camera.frame(scene.resolution).forward.as_vec3();
    match source {
        GBufferSource::Upload(g) => g.clone(),
        GBufferSource::Gpu => {
            let vectors = [&mut out.position, &mut out.axis_x, &mut out.axis_y].map(std::mem::take);
            let mut g = gbuffer_from_gpu(
                scene.resolution,
                forward,
                &out.id_flags,
                vectors,
                &out.counters,
                |_, id, gpu_flags| upload.receiver_normal(id, gpu_flags),
            );
            g.truncate(scene.pixel_count());
            g
        }
    }
}

/// Which baseline's passes follow the G-buffer and light setup in a batch
/// frame.
#[derive(Clone, Copy, Debug)]
pub(super) enum BaselinePasses {
    /// The shadow-map baseline: raster (and for `vsm`/`msm` the blur),
    /// lookup (and the contact march).
    Map(ShadowMapSettings),
    /// The `rt32-rays` peer: shadow rays in the evaluate slot, resolve.
    Rays,
    /// The `volumes` baseline: receiver depths, stencil pass, lookup.
    Volumes,
}

impl BaselinePasses {
    /// Words of the `SHADOW_MAP` buffer: the depths (one per texel of
    /// every cascade), then for a filtered map the blur's rows and its
    /// result (the moment count per texel each). The volumes keep a
    /// depth per pixel and the stencil bytes behind them.
    pub(super) fn shadow_map_words(&self, pixels: u64) -> u64 {
        match self {
            BaselinePasses::Rays => 0,
            BaselinePasses::Volumes => pixels + pixels.div_ceil(4),
            BaselinePasses::Map(s) => {
                let texels = u64::from(s.cascades) * u64::from(s.side).pow(2);
                let moments = s.filter.moments().map_or(0, |k| k.count() as u64);
                texels * (1 + 2 * moments)
            }
        }
    }
}

/// What one frame read back.
pub(super) struct FrameOutput {
    pub(super) counters: Vec<u32>,
    pub(super) light: LightState,
    pub(super) masks: Vec<u32>,
    pub(super) shaded: Vec<u32>,
    pub(super) position: Vec<Vec3>,
    pub(super) axis_x: Vec<Vec3>,
    pub(super) axis_y: Vec<Vec3>,
    pub(super) id_flags: Vec<u32>,
    /// The shadow maps' depths when asked for, else empty.
    pub(super) shadow_maps: Vec<f32>,
    pub(super) millis: Option<GpuPassMillis>,
    pub(super) wall_seconds: f64,
    pub(super) memory: Vec<PassMemory>,
}

impl FrameOutput {
    /// `value(words[i])` for every shadow-tested pixel i, NaN elsewhere.
    pub(super) fn per_tested_pixel(&self, words: &[u32], value: impl Fn(u32) -> f32) -> Vec<f32> {
        words
            .iter()
            .zip(&self.id_flags)
            .map(|(&w, &id_flags)| {
                let (_, f) = shared::unpack_id_flags(id_flags);
                if f & crate::gbuffer::flags::SHADOW_TESTED != 0 {
                    value(w)
                } else {
                    f32::NAN
                }
            })
            .collect()
    }
}

/// The CPU twin's [`GBuffer`] from a GPU frame's G-buffer words,
/// positions and axes (one per entry, the image's pixels first): each
/// entry's id and flags unpacked (the GPU-only `FLAG_NORMAL_FLIPPED`
/// dropped), its normal `normal_of(entry, id, gpu_flags)`, its depth along
/// `forward` where it hit, and the counters' G-buffer statistics — the one
/// read-back both the batch frame and the shadow pass use.
pub(super) fn gbuffer_from_gpu(
    resolution: [u32; 2],
    forward: Vec3,
    words: &[u32],
    [position, axis_x, axis_y]: [Vec<Vec3>; 3],
    counters: &[u32],
    normal_of: impl Fn(usize, u32, u32) -> Vec3,
) -> GBuffer {
    let entries = words.len();
    let mut g = GBuffer {
        width: resolution[0],
        height: resolution[1],
        triangle_id: Vec::with_capacity(entries),
        depth: Vec::with_capacity(entries),
        position,
        normal: Vec::with_capacity(entries),
        axis_x,
        axis_y,
        flags: Vec::with_capacity(entries),
        stats: GBufferStats {
            pixels: resolution[0] as usize * resolution[1] as usize,
            hits: counters[counter::HITS] as usize,
            shadow_tested: counters[counter::SHADOW_TESTED] as usize,
            clamped_microquads: counters[counter::CLAMPED] as usize,
        },
        edges: None,
        edges_high: None,
        depth_uncertainty: None,
    };
    for (i, &word) in words.iter().enumerate() {
        let (id, gpu_flags) = shared::unpack_id_flags(word);
        let f = gpu_flags & !shared::FLAG_NORMAL_FLIPPED;
        g.triangle_id.push(id);
        g.normal.push(normal_of(i, id, gpu_flags));
        g.depth.push(if f & flags::HIT != 0 {
            g.position[i].dot(forward)
        } else {
            f32::INFINITY
        });
        g.flags.push(f);
    }
    g
}
