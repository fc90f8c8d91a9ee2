//! What a pass holds, planned from its scene and configuration without a
//! device: the anchor-space vertices (or for a pass of one view the
//! eye-relative ones), the ray cast's BVH and every buffer's size
//! ([`FrameSizes`]). `ShadowPass::make` allocates it, and
//! [`planned_memory`] reports it for machines that cannot run the frame
//! (`izb info --gpu-memory`).
//!
//! A pass of one view (the batch `render`'s: its eye never moves) needs
//! no moving eye's machinery: it holds the scene's eye-relative vertices
//! and a BVH built around that eye, as the CPU twin rounds them, and
//! lets the bin's cell and overflow lists reuse the BVH's memory
//! ([`frame_allocation`]'s shared buffers) — the BVH is copied in again
//! from host memory at each frame's start, after the G-buffer step's
//! last read of the frame before. That keeps courtyard at 1080p within
//! 64 B per pixel + triangle of device memory, which the resident pass's
//! anchor-space vertices and second BVH copy do not.

use super::{GBufferInput, HostGeometryConfig, ShadowPassConfig};
use crate::gpu::frame_inputs::SceneUpload;
use crate::gpu::frame_memory::{
    frame_allocation, frame_buffer_descs, group_by_pass, initial_cell_capacity, receivers,
    EdgeSlots, FrameSizes,
};
use crate::gpu::frame_report::PassMemory;
use crate::gpu::gbuffer::{build_bvh, GpuBvh};
use crate::gpu::translate_vertices::WorldVertices;
use crate::gpu::GpuError;
use crate::scene::Scene;
use crate::settings::IzbSettings;
use glam::DVec3;

/// A pass's resident data and buffer sizes.
pub(super) struct ResidentLayout {
    /// The scene's bounds, or the host geometry's declared ones.
    pub(super) bounds: (DVec3, DVec3),
    /// Without the host's geometry: the vertices a moving eye translates.
    pub(super) world: Option<WorldVertices>,
    /// A pass of one view: the scene's eye-relative triangles, vertices
    /// and normals for that view, as the CPU twin rounds them.
    pub(super) one_view: Option<SceneUpload>,
    /// With a ray-cast G-buffer: its BVH, in anchor space (for one view:
    /// around that eye).
    pub(super) bvh: GpuBvh,
    /// Copies of the BVH's nodes `B_BVH_NODES` holds: the eye-relative
    /// ones, then (a resident pass's) the anchor-space ones they are made
    /// from.
    pub(super) node_copies: usize,
    /// Triangles the buffers hold: the scene's, or with the host's
    /// geometry the most a frame may draw.
    pub(super) triangles: usize,
    /// Every buffer's size (the receivers not yet checked against a
    /// device's workgroup counts).
    pub(super) sizes: FrameSizes,
    /// Host seconds the BVH's build took (0 without one).
    pub(super) bvh_build_seconds: f64,
}

impl ResidentLayout {
    /// The layout of a pass for `scene` under `config`, with the host's
    /// geometry `host` and `edge_slots` slots for edge surfaces; with
    /// `one_view` (the scene's eye-relative upload), for `scene`'s view
    /// only (no host geometry).
    pub(super) fn new(
        scene: &Scene,
        config: &ShadowPassConfig,
        host: Option<HostGeometryConfig>,
        edge_slots: Option<EdgeSlots>,
        one_view: Option<SceneUpload>,
    ) -> Result<Self, GpuError> {
        let settings = config.settings;
        // In a resident pass nothing holds the eye's frame but the vertices
        // (and a ray cast's BVH nodes), which `translate_vertices` makes
        // for each frame's eye from anchor-space ones: the eye moves freely.
        let bounds = host.map_or_else(|| scene.bounds(), |h| h.bounds);
        let one_view = one_view.filter(|_| host.is_none());
        let resident = host.is_none() && one_view.is_none();
        let mut world = resident.then(|| WorldVertices::new(scene, (bounds.0 + bounds.1) * 0.5));
        let triangles = host.map_or(scene.triangles.len(), |h| h.max_triangles as usize);
        // A ray cast reads the scene's triangles (the host's geometry is
        // refused with it: `HostGeometryConfig::check`).
        let start = std::time::Instant::now();
        let bvh = match (config.gbuffer, &mut world, &one_view) {
            (GBufferInput::RayCast, Some(w), _) => {
                let bvh = build_bvh(&w.anchor_triangles())?;
                w.bvh_nodes = bvh.nodes.len() as u32;
                bvh
            }
            (GBufferInput::RayCast, None, Some(upload)) => build_bvh(&upload.triangles)?,
            _ => GpuBvh::EMPTY,
        };
        let bvh_build_seconds = start.elapsed().as_secs_f64();
        let node_copies = 1 + usize::from(world.as_ref().is_some_and(|w| w.bvh_nodes > 0));
        let max_cells = crate::gpu::izb_frame::max_cells(scene.pixel_count(), triangles, settings)?;
        let (lut, _) = crate::lut::tables_for(settings.light_samples(scene));
        let pixels = scene.pixel_count() as u64;
        let sizes = FrameSizes {
            pixels,
            tiles: crate::gpu::edge_surfaces::edge_tiles(scene.resolution),
            receivers: receivers(scene.resolution, edge_slots.map_or(0, |s| s.surfaces)),
            edge_surfaces: edge_slots,
            triangles: triangles as u64,
            vertices: match (&world, &one_view) {
                (Some(w), _) => w.pairs.len() as u64,
                (None, Some(upload)) => upload.vertices.len() as u64,
                (None, None) => 3 * triangles as u64,
            },
            world_vertices: world.as_ref().map_or(0, |w| w.pairs.len()) as u64,
            bvh_nodes: (bvh.nodes.len() * node_copies) as u64,
            bvh_prims: bvh.prims.len() as u64,
            max_cells,
            cell_capacity: config
                .cell_capacity
                .unwrap_or_else(|| initial_cell_capacity(triangles)),
            lut_entries: lut.masks.len() as u64,
            shadow_map_words: 0,
            mask_halves: settings.mask_halves(scene) as u64,
            normal_entries: match config.gbuffer {
                GBufferInput::DepthNormal(_) => pixels,
                _ => 0,
            },
            draws: host.map_or(0, |h| u64::from(h.max_draws)),
        };
        Ok(ResidentLayout {
            bounds,
            world,
            one_view,
            bvh,
            node_copies,
            triangles,
            sizes,
            bvh_build_seconds,
        })
    }

    /// The buffers to make, and per binding the index of its buffer: one
    /// per binding, or for a pass of one view the bin's lists in the
    /// BVH's buffers.
    pub(super) fn allocation(
        &self,
    ) -> (
        Vec<crate::gpu::resources::BufferDesc>,
        [usize; crate::gpu::shared::BINDING_COUNT as usize],
    ) {
        let descs = frame_buffer_descs(&self.sizes);
        match self.one_view {
            Some(_) => frame_allocation(descs),
            None => (descs.to_vec(), std::array::from_fn(|b| b)),
        }
    }
}

/// The device memory a ray-cast pass for `scene` allocates (one frame
/// slot, the cell list at its first guess) per pass, without a device:
/// for budgets on machines that cannot run the frame; with
/// `edge_surfaces` extra surfaces and edge pixels, their G-buffer rows and
/// tables too. With `one_view` the pass of `izb render --backend vulkan`
/// (one view, the bin's lists in the BVH's memory), else a resident pass
/// whose eye moves (the viewer's, a host's).
pub fn planned_memory(
    scene: &Scene,
    settings: IzbSettings,
    edge_surfaces: Option<EdgeSlots>,
    one_view: bool,
) -> Result<Vec<PassMemory>, GpuError> {
    let config = ShadowPassConfig::ray_cast(settings);
    let upload = one_view.then(|| SceneUpload::new(scene));
    let layout = ResidentLayout::new(scene, &config, None, edge_surfaces, upload)?;
    let (descs, _) = layout.allocation();
    Ok(group_by_pass(descs.iter().map(|d| {
        (d.pass, d.name, d.size.max(4).next_multiple_of(4))
    })))
}
