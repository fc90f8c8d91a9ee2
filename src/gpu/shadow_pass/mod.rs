//! The IZB as a pass of a frame the caller records (issue 29): resources
//! made once, then per frame only commands and
//! parameters — no buffer, descriptor set, mapping, submission, wait or
//! read-back. The shape of shipped effect SDKs (AMD FidelityFX FSR2's
//! context and dispatch, NVIDIA's GFSDK_ShadowLib: a context made once,
//! per-frame parameters, a status for too many primitives).
//!
//! What it holds and does:
//! - The scene is resident: its vertices, normals, BVH (ray cast only)
//!   and LUT are uploaded once. The camera may move and turn and the
//!   light may move or change size per frame: the vertices are held
//!   relative to an anchor as double-singles, and `translate_vertices`
//!   makes them eye-relative on the GPU each frame (the twin:
//!   [`crate::cpu::translate_vertices`]), with a ray-cast G-buffer the
//!   BVH's nodes too, built in anchor space and widened as they are
//!   translated so that every translated vertex stays inside.
//! - Or the geometry is the host's own: a pass made with
//!   [`ShadowPass::with_host_geometry`] reads each frame's draws from the
//!   host's vertex and index buffers (`u16`/`u32`/none, any 4-byte offset
//!   and stride, a transform per draw) and gathers them on the GPU into
//!   its eye-relative triangles (`gather_draws.comp`, the twin
//!   [`crate::cpu::gather_draws`]; `host_geometry.rs`).
//! - Or the pass is for one view (the batch `render`'s, whose eye never
//!   moves: `one_view.rs`): the scene's eye-relative vertices and a BVH
//!   built around that eye, the bin's lists in the BVH's memory and the
//!   BVH copied in again at each frame's start.
//! - The G-buffer is the pass's first step, from one of four producers
//!   ([`GBufferInput`]): the ray-cast one (`gbuffer.comp`, over a BVH
//!   built once), the host's visibility buffer (`R32_UINT` triangle ids,
//!   `gbuffer_from_visibility.comp`), the host's depth and normal
//!   images (`gbuffer_from_depth.comp`), read under the state contract
//!   of [`super::host_images`], or the CPU twin's, written once
//!   (`uploaded_gbuffer.rs`).
//! - With the ray-cast G-buffer, edge pixels' per-sample surfaces are
//!   traced by the `edge_surfaces` step (`edge_slots.rs`: slots sized
//!   once, a frame past them keeps tangent-plane masks at the pixels that
//!   did not fit and says so, [`ShadowPass::grow`] makes room); with the
//!   host's multisampled visibility buffer the same step finds their
//!   hits among the ids its samples saw; a single-sampled visibility
//!   buffer and depth carry one surface a pixel, so there they are
//!   refused by name (`--no-edge-surfaces`).
//! - A frame whose cell list overruns stays exact the slow way
//!   (`bin.comp`) and says so in its status; [`ShadowPass::grow`] makes
//!   room between frames and [`ShadowPass::resize`] follows a new image
//!   size, each releasing the old buffers once every frame slot has
//!   recorded again (`capacity.rs`).
//!
//! Per frame `record` writes the parameters, the light state's start and
//! the draw table through the slot's upload ring (`slot_uploads.rs`) and
//! records (`record.rs`): the slot's *opening* (the barrier after the
//! previous frame's work on the pass's buffers, the ring's copies, for
//! one view the BVH copied in, the counters cleared), the host's images
//! and buffers acquired (one barrier each, from the state the host
//! declares: [`super::host_images`]) with `gather_draws` and `gbuffer`
//! (or `gbuffer_from_visibility`, `gbuffer_from_depth`), the slot's
//! *core* (`light_setup`, `bin`, `evaluate`, `resolve`, the counters
//! copied into the slot's status buffer), then `export_images` into the
//! host's mask and lit-fraction images, when given. The opening and the
//! core name only the pass's objects: they are secondary command buffers
//! recorded once per slot and executed again (`slot_commands.rs`).
//! Afterwards the masks and the shaded image are also in the pass's
//! storage buffers, written by compute shaders and made visible to later
//! compute-shader and transfer reads; the output images are in
//! `GENERAL`, written by compute shaders; no pipeline or descriptor set
//! of the pass's is left bound that the host may rely on.

mod batch;
mod capacity;
mod config;
mod edge_slots;
mod frame_view;
mod host_geometry;
mod layout;
mod one_view;
mod read_back;
mod record;
mod slot_commands;
mod slot_uploads;
mod status;
mod uploaded_gbuffer;

pub use config::{GBufferInput, ShadowPassConfig};
pub use frame_view::FrameView;
pub use host_geometry::HostGeometryConfig;
pub use layout::planned_memory;
pub use read_back::{PassFrame, PassImages};
pub use status::PassStatus;

use super::frame::GpuRenderer;
use super::frame_inputs::{loop_budget, SceneUpload};
use super::frame_memory::FrameSizes;
use super::host_images::HostImageSets;
use super::pass_copies::upload_into;
use super::pipeline::DescriptorSet;
use super::resources::{BufferDesc, BufferDomain, GpuBuffer};
use super::shared::{binding, counter, BINDING_COUNT};
use super::translate_vertices::WorldVertices;
use super::GpuError;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use std::sync::Arc;

const BINDINGS: usize = BINDING_COUNT as usize;

/// The IZB, resident on a device, recorded into the caller's command
/// buffers.
pub struct ShadowPass<'r> {
    renderer: &'r GpuRenderer,
    config: ShadowPassConfig,
    /// The scene; its camera and light are the last recorded frame's.
    scene: Scene,
    bounds: (DVec3, DVec3),
    /// Triangles the buffers hold: the scene's, or with the host's
    /// geometry the most a frame may draw.
    triangles: u32,
    /// Triangles of the last recorded frame.
    frame_triangles: u32,
    /// With the host's geometry: its limits and the draw table reused
    /// every frame.
    host_geometry: Option<host_geometry::HostGeometryState>,
    /// `FrameParams::loop_budget` on this device.
    loop_budget: u32,
    buffers: [Arc<GpuBuffer>; BINDINGS],
    set: DescriptorSet,
    /// Per frame slot, the set of the host's images.
    host_sets: HostImageSets,
    /// Per frame slot, the counters of its last frame (host-visible).
    status: Vec<GpuBuffer>,
    /// Per frame slot, its parameters' upload buffer, mapped once.
    uploads: slot_uploads::SlotUploads,
    /// Per frame slot, its frames' commands that name only the pass's
    /// objects, recorded once and executed again (`slot_commands.rs`).
    slot_commands: slot_commands::SlotCommands,
    /// The read-backs' buffer, kept between them (tests and tools).
    readback: super::pass_copies::ReadbackBuffer,
    /// Per frame slot, its last frame's timestamps at the passes'
    /// boundaries ([`Self::gpu_millis`]; none where the queue has none).
    timestamps: Vec<super::timestamps::TimestampPool>,
    /// Per frame slot, the edge surfaces' slots of its last frame (its
    /// status's overrun is against them, whatever grew since).
    slot_edge_slots: Vec<u64>,
    /// Sets replaced by `grow` or `resize` that frames in flight may
    /// still use.
    retired: Vec<capacity::Retired>,
    /// With a visibility buffer: the vertices a moving eye translates.
    world: Option<WorldVertices>,
    /// What the buffers were sized for, the cell list's capacity and the
    /// cell pyramid's size among them ([`Self::grow`] and
    /// [`Self::resize`] change it).
    sizes: FrameSizes,
    /// `FrameParams::overrun_exact`: a frame whose cell list overruns
    /// stays exact the slow way. Only the batch `render`, which records
    /// such a frame again after growing, turns it off.
    overrun_exact: bool,
    /// With the batch `render`'s step timing on: a timestamp after each
    /// dispatch of the last frame slot's frame.
    step_marks: Option<super::timestamps::StepMarks>,
    /// With an uploaded G-buffer that has edge surfaces: per pixel the
    /// samples that count (`GBuffer::counted_samples`), for the lit
    /// fraction [`Self::read_back_frame`] resolves.
    uploaded_counted: Option<Vec<u32>>,
    /// A pass for its scene's view only (`one_view.rs`): its camera and
    /// image size stay.
    one_view: bool,
    /// For one view, the BVH copied in at each frame's start (the bin's
    /// lists reuse its memory).
    restaged_bvh: Option<one_view::RestagedBvh>,
    /// Host seconds the ray cast's BVH took to build (0 without one).
    bvh_build_seconds: f64,
}

/// Most frame slots (a bit each in `Retired::slots_pending`).
pub(crate) const MAX_FRAMES_IN_FLIGHT: usize = 63;

/// Timestamps a frame writes: its start, then after the G-buffer, light
/// setup, bin, evaluate and resolve (with the output images).
const PASS_TIMESTAMPS: u32 = 6;

impl<'r> ShadowPass<'r> {
    /// Makes the pass for `scene` on `renderer`'s device: every buffer,
    /// the descriptor set, and the scene, BVH and LUT uploaded (this call
    /// waits for the upload).
    pub fn new(
        renderer: &'r GpuRenderer,
        scene: Scene,
        config: ShadowPassConfig,
    ) -> Result<Self, GpuError> {
        if config.gbuffer == GBufferInput::Uploaded {
            return Err(GpuError::Unsupported(
                "an uploaded G-buffer is given when the pass is made: \
                 ShadowPass::with_uploaded_gbuffer"
                    .into(),
            ));
        }
        Self::make(renderer, scene, config, None, None, None)
    }

    /// [`Self::new`], or with `host` the pass for the host's own vertex
    /// and index buffers ([`Self::with_host_geometry`]): the scene's
    /// triangles are then neither read nor uploaded. `uploaded_edges`: the
    /// slots of an uploaded G-buffer's edge surfaces
    /// ([`Self::with_uploaded_gbuffer`]); `one_view`: a pass for the
    /// scene's view only (`one_view.rs`), with the scene's eye-relative
    /// upload its callers made.
    fn make(
        renderer: &'r GpuRenderer,
        scene: Scene,
        config: ShadowPassConfig,
        host: Option<HostGeometryConfig>,
        uploaded_edges: Option<super::frame_memory::EdgeSlots>,
        one_view: Option<SceneUpload>,
    ) -> Result<Self, GpuError> {
        let settings = config.settings;
        let edge_slots = match config.gbuffer {
            GBufferInput::Uploaded => uploaded_edges,
            _ => edge_slots::edge_slots_for(&scene, &config)?,
        };
        if !(1..=MAX_FRAMES_IN_FLIGHT).contains(&config.frames_in_flight) {
            return Err(GpuError::Unsupported(format!(
                "frames_in_flight is {}: from 1 to {MAX_FRAMES_IN_FLIGHT}",
                config.frames_in_flight
            )));
        }
        if let GBufferInput::DepthNormal(convention) = config.gbuffer {
            convention.check().map_err(GpuError::Unsupported)?;
        }
        let shared = renderer.shared();
        config.gbuffer.check(&shared.limits)?;
        if let Some(h) = &host {
            h.check(&config)?;
        }
        // The scene's triangle normals, or none where `gather_draws` makes
        // them from the host's geometry each frame.
        let normals = match host {
            None => {
                let known = one_view.as_ref().map(|u| &u.normals[..]);
                renderer.prepare_resident(&scene, known)?
            }
            Some(_) => {
                super::frame_inputs::check_workgroups(&shared.limits, scene.resolution)?;
                Vec::new()
            }
        };
        let layout = layout::ResidentLayout::new(&scene, &config, host, edge_slots, one_view)?;
        let sizes = layout.sizes;
        edge_slots::checked_receivers(&shared.limits, scene.resolution, edge_slots)?;
        let (lut, _) = crate::lut::tables_for(settings.light_samples(&scene));
        // One buffer per binding, but for one view the bin's lists in the
        // BVH's buffers (`layout.rs`).
        let (descs, at) = layout.allocation();
        let made: Vec<Arc<GpuBuffer>> = descs
            .into_iter()
            .map(|d| GpuBuffer::new(shared, d).map(Arc::new))
            .collect::<Result<_, _>>()?;
        let buffers: [Arc<GpuBuffer>; BINDINGS] = std::array::from_fn(|b| made[at[b]].clone());
        let restaged_bvh = one_view::RestagedBvh::new(shared, &layout, &at)?;
        let (bounds, world, bvh) = (layout.bounds, layout.world, layout.bvh);
        let (triangles, node_copies) = (layout.triangles, layout.node_copies);
        let one_view = layout.one_view;
        let set = DescriptorSet::new(shared, &renderer.layout, buffers.clone())?;
        let host_sets = HostImageSets::new(shared, &renderer.layout, config.frames_in_flight)?;
        let status: Vec<GpuBuffer> = (0..config.frames_in_flight)
            .map(|_| {
                let desc = BufferDesc {
                    name: "pass_status",
                    pass: "frame",
                    size: counter::WORDS as u64 * 4,
                    domain: BufferDomain::Readback,
                };
                GpuBuffer::new(shared, desc)
            })
            .collect::<Result<_, _>>()?;
        let timestamps = (0..config.frames_in_flight)
            .map(|_| super::timestamps::TimestampPool::new(shared, PASS_TIMESTAMPS))
            .collect::<Result<_, _>>()?;
        let as_bytes = |v: &[[f32; 3]]| bytemuck::cast_slice::<_, u8>(v).to_vec();
        let uploads: Vec<(u32, Vec<u8>)> = vec![
            // With the host's geometry `gather_draws` writes the triangles,
            // vertices and normals each frame; otherwise `translate_vertices`
            // writes the vertices before every frame's first reader.
            (
                binding::TRIANGLES,
                match (&world, &one_view) {
                    (Some(w), _) => bytemuck::cast_slice(&w.corners).to_vec(),
                    (None, Some(v)) => bytemuck::cast_slice(&v.corners).to_vec(),
                    (None, None) => Vec::new(),
                },
            ),
            (
                binding::VERTICES,
                one_view
                    .as_ref()
                    .map_or(Vec::new(), |v| bytemuck::cast_slice(&v.vertices).to_vec()),
            ),
            (
                binding::WORLD_VERTICES,
                world.as_ref().map_or(Vec::new(), |w| {
                    bytemuck::cast_slice::<[Vec3; 2], u8>(&w.pairs).to_vec()
                }),
            ),
            (binding::TRIANGLE_NORMALS, as_bytes(&normals)),
        ];
        // A restaged BVH is copied in at each frame's start instead.
        let bvh_uploads = [
            (
                binding::BVH_NODES,
                bytemuck::cast_slice(&bvh.nodes).repeat(node_copies),
            ),
            (
                binding::BVH_PRIMS,
                bytemuck::cast_slice(&bvh.prims).to_vec(),
            ),
        ];
        let uploads: Vec<(u32, Vec<u8>)> = uploads
            .into_iter()
            .chain(bvh_uploads.into_iter().filter(|_| restaged_bvh.is_none()))
            .chain([(binding::EDGE_LUT, bytemuck::cast_slice(&lut.masks).to_vec())])
            .collect();
        upload_into(renderer, &buffers, &uploads)?;
        let max_draws = host.map_or(0, |h| h.max_draws);
        let uploads = slot_uploads::SlotUploads::new(shared, config.frames_in_flight, max_draws)?;
        let slot_commands = slot_commands::SlotCommands::new(shared, config.frames_in_flight)?;
        Ok(ShadowPass {
            renderer,
            config,
            bounds,
            scene,
            triangles: triangles as u32,
            frame_triangles: triangles as u32,
            host_geometry: host.map(host_geometry::HostGeometryState::new),
            loop_budget: loop_budget(&shared.info.name),
            buffers,
            set,
            host_sets,
            slot_edge_slots: vec![0; config.frames_in_flight],
            status,
            uploads,
            slot_commands,
            timestamps,
            readback: Default::default(),
            retired: Vec::new(),
            world,
            sizes,
            overrun_exact: true,
            step_marks: None,
            uploaded_counted: None,
            one_view: one_view.is_some(),
            restaged_bvh,
            bvh_build_seconds: layout.bvh_build_seconds,
        })
    }

    /// Frame slots (`ShadowPassConfig::frames_in_flight`).
    pub fn frames_in_flight(&self) -> usize {
        self.status.len()
    }

    /// The image's size.
    pub fn resolution(&self) -> [u32; 2] {
        self.scene.resolution
    }

    /// Entries of the cell list now.
    pub fn cell_capacity(&self) -> u64 {
        self.sizes.cell_capacity
    }

    /// How many times a frame slot recorded its fixed commands (those
    /// naming only the pass's objects, `slot_commands.rs`): once per slot,
    /// then again only after [`Self::grow`], [`Self::resize`],
    /// [`Self::reserve_host_geometry`] or a frame of another shape (its
    /// size, triangles drawn, draws or edge surfaces); other frames
    /// execute them as recorded.
    pub fn fixed_command_recordings(&self) -> u64 {
        self.slot_commands.recordings()
    }

    /// Bytes of the pass's buffers, its frame slots' status included.
    pub fn memory_bytes(&self) -> u64 {
        let buffers: u64 = self.distinct_buffers().iter().map(|b| b.size()).sum();
        let restaged = self.restaged_bvh.as_ref().map_or(0, |r| r.bytes());
        let status: u64 = self.status.iter().map(|b| b.size()).sum();
        buffers + restaged + status + self.uploads.memory_bytes()
    }
}
