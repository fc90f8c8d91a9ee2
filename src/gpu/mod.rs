//! The Vulkan backend (ash): every pass of the CPU pipeline as a compute
//! shader, checked sample by sample against its CPU twin.
//!
//! | pass | GPU module | shader | CPU twin |
//! |---|---|---|---|
//! | 0 | [`gbuffer`] | `gbuffer.comp` | [`crate::gbuffer::gbuffer`] |
//! | 0, moving eye | [`translate_vertices`] | `translate_vertices.comp` | [`crate::cpu::translate_vertices`] |
//! | 0, host geometry | [`gather_draws`] | `gather_draws.comp` | [`crate::cpu::gather_draws`] |
//! | 0, host input | `gbuffer::gbuffer_from_visibility` | `gbuffer_from_visibility.comp` | [`crate::gbuffer::gbuffer_from_visibility`] |
//! | 0, host input | `gbuffer::gbuffer_from_multisampled_visibility` | `gbuffer_from_visibility.comp` (`MULTISAMPLED`), `edge_surfaces.comp` (`CANDIDATE_HITS`) | [`crate::gbuffer::gbuffer_from_multisampled_visibility`] |
//! | 0, host input | `gbuffer::gbuffer_from_depth` | `gbuffer_from_depth.comp` | [`crate::gbuffer::gbuffer_from_depth`] |
//! | 1 | [`light_setup`] | `light_setup.comp` | [`mod@crate::cpu::light_setup`] |
//! | 2 | [`bin`] | `bin.comp` | [`crate::cpu::bin::bin`] |
//! | 3 | [`evaluate`] | `evaluate.comp` | [`crate::cpu::evaluate::evaluate`] |
//! | 4 | [`resolve`] | `resolve.comp` | [`crate::cpu::resolve`], [`crate::output::shade_pixel`] |
//! | 5, host output | [`export_images`] | `export_images.comp` | [`crate::cpu::export_images`] |
//!
//! The baselines' passes sit beside them: [`shadow_map`] (depth-only
//! passes on the hardware rasteriser, orthographic and perspective,
//! [`shadow_raster`]; the moment maps' blur and the lookup are compute),
//! [`shadow_volumes`] (a depth-fail stencil pass on the rasteriser
//! between two compute passes) and [`shadow_rays`] (compute).
//!
//! [`shadow_pass`] records the IZB's five passes into a caller's command
//! buffer with every resource made once (`paper-notes/embedding.md`);
//! `izb_frame` is its batch host ([`frame::GpuRenderer::render`]: the
//! CLI's, the bench's and the tests' frames), and the baselines run a
//! batch frame of their own (`frame.rs`: one command buffer of uploads,
//! the G-buffer and light setup, their passes with timestamps, the
//! read-backs). Nothing is read back inside a frame (the light view and
//! grid are fitted on the GPU). [`context`] opens the device,
//! [`resources`] and [`pipeline`] own the Vulkan objects, [`shared`]
//! mirrors `shaders/common.glsl`.

pub mod bin;
pub mod context;
mod device_candidates;
mod edge_surfaces;
pub mod evaluate;
pub mod export_images;
pub mod frame;
pub mod frame_inputs;
pub mod frame_memory;
pub mod frame_report;
pub mod gather_draws;
pub mod gbuffer;
pub mod host_device;
pub mod host_images;
mod instance;
mod izb_frame;
pub mod light_setup;
pub mod options;
mod pass_copies;
pub mod pipeline;
pub mod resolve;
pub mod resources;
pub mod shadow_map;
pub mod shadow_pass;
pub mod shadow_raster;
pub mod shadow_rays;
pub mod shadow_volumes;
pub mod shared;
mod timestamps;
pub mod translate_vertices;
mod validation_messages;
pub mod visibility_raster;

pub use context::{list_devices, DeviceInfo, GpuContext, GpuOptions};
pub use frame::{GBufferSource, GpuRenderer};
pub use frame_report::{GpuRender, GpuRenderReport};

use ash::vk;
use pipeline::{BindingLayout, ComputeKernel};
use std::sync::Arc;
use std::time::Duration;

/// Everything that can go wrong on the GPU path, each naming the problem.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No loader, no driver, no suitable device, or a missing layer.
    #[error("no usable Vulkan device: {0}")]
    NoVulkan(String),
    #[error("Vulkan call failed: {0}")]
    Vulkan(vk::Result),
    #[error("the GPU device was lost (driver reset or crash); no result was produced")]
    DeviceLost,
    #[error("the GPU did not finish the frame within {0:?}")]
    Timeout(Duration),
    #[error("GPU memory allocation failed: {0}")]
    Allocation(String),
    #[error(
        "buffer `{name}` needs {size} bytes, above this device's storage-buffer limit of {limit} \
         bytes: lower the resolution or the scene size"
    )]
    BufferTooLarge {
        name: &'static str,
        size: u64,
        limit: u64,
    },
    #[error("buffer `{0}` is not host-visible")]
    NotMapped(&'static str),
    /// The device stops shader loops after a fixed count (lavapipe), and a
    /// subgroup of invocations (pixels testing candidates, triangles
    /// walking their cells) needs more than that.
    #[error(
        "{device} ends a shader's loops after {cap} iterations per subgroup, and a subgroup \
         in this frame needs more ({trips} loop trips in one invocation when it stopped): use a \
         GPU or --backend cpu"
    )]
    LoopCap {
        device: String,
        cap: u32,
        trips: u32,
    },
    #[error("{0}")]
    Unsupported(String),
    /// Settings with edge pixels' per-sample surfaces
    /// (`crate::gbuffer::edge_surfaces`) and an uploaded G-buffer without
    /// them.
    #[error(
        "the settings use edge surfaces (each edge pixel's samples on the surface its own ray \
         sees) but the uploaded G-buffer has none: build it with them (gbuffer_with), let the \
         GPU cast them (GBufferSource::Gpu), or render the pixel centre's µQuad alone \
         (--no-edge-surfaces, or an izb…-flat bench method)"
    )]
    EdgeSurfaces,
}

impl GpuError {
    /// Maps a Vulkan result, singling out a lost device.
    pub fn vk(e: vk::Result) -> Self {
        match e {
            vk::Result::ERROR_DEVICE_LOST => GpuError::DeviceLost,
            e => GpuError::Vulkan(e),
        }
    }
}

macro_rules! spirv {
    ($name:literal) => {
        include_bytes!(concat!(env!("OUT_DIR"), "/", $name, ".spv"))
    };
}

/// Every compiled shader module by name, as `build.rs` wrote them (for
/// tests that read the SPIR-V back, `tests/spirv_layout.rs`).
pub const SPIRV_MODULES: [(&str, &[u8]); 40] = [
    ("gbuffer", spirv!("gbuffer")),
    ("translate_vertices", spirv!("translate_vertices")),
    ("gather_draws", spirv!("gather_draws")),
    ("gbuffer_from_visibility", spirv!("gbuffer_from_visibility")),
    (
        "gbuffer_from_multisampled_visibility",
        spirv!("gbuffer_from_multisampled_visibility"),
    ),
    ("gbuffer_from_depth", spirv!("gbuffer_from_depth")),
    ("edge_surfaces", spirv!("edge_surfaces")),
    (
        "edge_surfaces_from_candidates",
        spirv!("edge_surfaces_from_candidates"),
    ),
    ("light_setup_receivers", spirv!("light_setup_receivers")),
    ("light_setup_frame", spirv!("light_setup_frame")),
    ("light_setup_extent", spirv!("light_setup_extent")),
    ("light_setup_grid", spirv!("light_setup_grid")),
    ("bin_levels", spirv!("bin_levels")),
    ("bin_receivers", spirv!("bin_receivers")),
    ("bin_count", spirv!("bin_count")),
    ("bin_scan_blocks", spirv!("bin_scan_blocks")),
    ("bin_scan_top", spirv!("bin_scan_top")),
    ("bin_scan_apply", spirv!("bin_scan_apply")),
    ("bin_scatter", spirv!("bin_scatter")),
    ("evaluate", spirv!("evaluate")),
    ("evaluate_heavy", spirv!("evaluate_heavy")),
    ("evaluate_high", spirv!("evaluate_high")),
    ("evaluate_heavy_high", spirv!("evaluate_heavy_high")),
    ("resolve", spirv!("resolve")),
    ("export_masks", spirv!("export_masks")),
    ("export_masks_paired", spirv!("export_masks_paired")),
    ("export_lit_r16", spirv!("export_lit_r16")),
    ("export_lit_r8", spirv!("export_lit_r8")),
    ("shadow_map", spirv!("shadow_map")),
    ("shadow_blur_x", spirv!("shadow_blur_x")),
    ("shadow_blur_y", spirv!("shadow_blur_y")),
    ("shadow_lookup", spirv!("shadow_lookup")),
    ("shadow_volume", spirv!("shadow_volume")),
    ("volume_depth", spirv!("volume_depth")),
    ("volume_lookup", spirv!("volume_lookup")),
    ("shadow_rays", spirv!("shadow_rays")),
    ("visibility_raster_vert", spirv!("visibility_raster_vert")),
    ("visibility_raster_frag", spirv!("visibility_raster_frag")),
    (
        "depth_normal_raster_vert",
        spirv!("depth_normal_raster_vert"),
    ),
    (
        "depth_normal_raster_frag",
        spirv!("depth_normal_raster_frag"),
    ),
];

/// The compiled pipelines of every pass.
pub struct Kernels {
    pub gbuffer: ComputeKernel,
    /// The G-buffer from the host's visibility buffer (the shadow pass).
    pub gbuffer_from_visibility: ComputeKernel,
    /// The same from a multisampled visibility buffer, and its edge
    /// surfaces from the samples' candidates (no BVH).
    pub gbuffer_from_multisampled_visibility: ComputeKernel,
    pub edge_surfaces_from_candidates: ComputeKernel,
    pub gbuffer_from_depth: ComputeKernel,
    /// The shadow pass's eye-relative vertices for a moving eye.
    pub translate_vertices: ComputeKernel,
    pub gather_draws: ComputeKernel,
    pub edge_surfaces: ComputeKernel,
    pub light_setup_receivers: ComputeKernel,
    pub light_setup_frame: ComputeKernel,
    pub light_setup_extent: ComputeKernel,
    pub light_setup_grid: ComputeKernel,
    pub bin_levels: ComputeKernel,
    pub bin_receivers: ComputeKernel,
    pub bin_count: ComputeKernel,
    pub bin_scan_blocks: ComputeKernel,
    pub bin_scan_top: ComputeKernel,
    pub bin_scan_apply: ComputeKernel,
    pub bin_scatter: ComputeKernel,
    pub evaluate: ComputeKernel,
    pub evaluate_heavy: ComputeKernel,
    /// Evaluate's steps for `MODE_PAIRED64`'s second mask half.
    pub evaluate_high: ComputeKernel,
    pub evaluate_heavy_high: ComputeKernel,
    pub resolve: ComputeKernel,
    /// The shadow pass's copies into the host's images
    /// ([`export_images`]): masks of one or two halves, the lit fraction
    /// as `R16_UNORM` or `R8_UNORM`.
    pub export_masks: ComputeKernel,
    pub export_masks_paired: ComputeKernel,
    pub export_lit_r16: ComputeKernel,
    pub export_lit_r8: ComputeKernel,
    pub shadow_blur_x: ComputeKernel,
    pub shadow_blur_y: ComputeKernel,
    pub shadow_lookup: ComputeKernel,
    pub volume_depth: ComputeKernel,
    pub volume_lookup: ComputeKernel,
    pub shadow_rays: ComputeKernel,
}

impl Kernels {
    pub fn new(
        shared: &Arc<context::DeviceShared>,
        layout: &BindingLayout,
    ) -> Result<Self, GpuError> {
        let k = |name, spirv| ComputeKernel::new(shared, layout, name, spirv);
        Ok(Kernels {
            gbuffer: k("gbuffer", spirv!("gbuffer"))?,
            gbuffer_from_visibility: k(
                "gbuffer_from_visibility",
                spirv!("gbuffer_from_visibility"),
            )?,
            gbuffer_from_multisampled_visibility: k(
                "gbuffer_from_multisampled_visibility",
                spirv!("gbuffer_from_multisampled_visibility"),
            )?,
            edge_surfaces_from_candidates: k(
                "edge_surfaces_from_candidates",
                spirv!("edge_surfaces_from_candidates"),
            )?,
            gbuffer_from_depth: k("gbuffer_from_depth", spirv!("gbuffer_from_depth"))?,
            translate_vertices: k("translate_vertices", spirv!("translate_vertices"))?,
            gather_draws: k("gather_draws", spirv!("gather_draws"))?,
            edge_surfaces: k("edge_surfaces", spirv!("edge_surfaces"))?,
            light_setup_receivers: k("light_setup_receivers", spirv!("light_setup_receivers"))?,
            light_setup_frame: k("light_setup_frame", spirv!("light_setup_frame"))?,
            light_setup_extent: k("light_setup_extent", spirv!("light_setup_extent"))?,
            light_setup_grid: k("light_setup_grid", spirv!("light_setup_grid"))?,
            bin_levels: k("bin_levels", spirv!("bin_levels"))?,
            bin_receivers: k("bin_receivers", spirv!("bin_receivers"))?,
            bin_count: k("bin_count", spirv!("bin_count"))?,
            bin_scan_blocks: k("bin_scan_blocks", spirv!("bin_scan_blocks"))?,
            bin_scan_top: k("bin_scan_top", spirv!("bin_scan_top"))?,
            bin_scan_apply: k("bin_scan_apply", spirv!("bin_scan_apply"))?,
            bin_scatter: k("bin_scatter", spirv!("bin_scatter"))?,
            evaluate: k("evaluate", spirv!("evaluate"))?,
            evaluate_heavy: k("evaluate_heavy", spirv!("evaluate_heavy"))?,
            evaluate_high: k("evaluate_high", spirv!("evaluate_high"))?,
            evaluate_heavy_high: k("evaluate_heavy_high", spirv!("evaluate_heavy_high"))?,
            resolve: k("resolve", spirv!("resolve"))?,
            export_masks: k("export_masks", spirv!("export_masks"))?,
            export_masks_paired: k("export_masks_paired", spirv!("export_masks_paired"))?,
            export_lit_r16: k("export_lit_r16", spirv!("export_lit_r16"))?,
            export_lit_r8: k("export_lit_r8", spirv!("export_lit_r8"))?,
            shadow_blur_x: k("shadow_blur_x", spirv!("shadow_blur_x"))?,
            shadow_blur_y: k("shadow_blur_y", spirv!("shadow_blur_y"))?,
            shadow_lookup: k("shadow_lookup", spirv!("shadow_lookup"))?,
            volume_depth: k("volume_depth", spirv!("volume_depth"))?,
            volume_lookup: k("volume_lookup", spirv!("volume_lookup"))?,
            shadow_rays: k("shadow_rays", spirv!("shadow_rays"))?,
        })
    }
}

/// Records a barrier that makes every earlier transfer write visible to
/// the host (read-backs and status copies, read after the host's wait).
///
/// # Safety
/// `cmd` is a command buffer of `device` in the recording state.
pub(crate) unsafe fn transfers_visible_to_host(device: &ash::Device, cmd: vk::CommandBuffer) {
    let to_host = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::TRANSFER_WRITE)
        .dst_access_mask(vk::AccessFlags::HOST_READ)];
    // SAFETY: the caller's promise; `to_host` outlives the call.
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
}

/// Records a frame's dispatches: binds the shared descriptor set, labels
/// passes for debuggers, and puts a barrier between dependent dispatches.
/// Its methods are safe because [`Recorder::new`] is not: its caller
/// promises what every recorded command needs.
pub struct Recorder<'a> {
    shared: &'a context::DeviceShared,
    cmd: vk::CommandBuffer,
    layout: &'a BindingLayout,
    set: &'a pipeline::DescriptorSet,
    /// Where to time each dispatch (the timed repetition of a frame).
    steps: Option<&'a timestamps::StepMarks>,
}

impl<'a> Recorder<'a> {
    /// A recorder of `cmd` with `set` bound to every dispatch.
    ///
    /// # Safety
    /// `cmd` is a command buffer of `shared`'s device in the recording
    /// state, recorded by this thread alone while the recorder lives, and
    /// executed only after recording ends. Every kernel dispatched through
    /// the recorder, `layout` and `set` (which holds its buffers) stay
    /// alive until the command buffer has finished executing.
    pub unsafe fn new(
        shared: &'a context::DeviceShared,
        cmd: vk::CommandBuffer,
        layout: &'a BindingLayout,
        set: &'a pipeline::DescriptorSet,
    ) -> Self {
        // Bound once: every compute pipeline has this layout, so the set
        // stays bound across pipeline binds (Vulkan spec, "Pipeline
        // Layout Compatibility"). Each dispatch binding it again cost
        // lavapipe about 1 µs of recording.
        // SAFETY: the caller's promise: `cmd` is recording, `set` and
        // `layout` outlive its execution.
        unsafe {
            shared.device.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                layout.pipeline_layout,
                0,
                &[set.handle()],
                &[],
            );
        }
        Recorder {
            shared,
            cmd,
            layout,
            set,
            steps: None,
        }
    }

    /// Times every later dispatch with `steps`.
    pub fn time_steps(&mut self, steps: &'a timestamps::StepMarks) {
        self.steps = Some(steps);
    }

    fn device(&self) -> &ash::Device {
        &self.shared.device
    }

    /// Binds a host-image set (`HOST_SET`, [`host_images`]) for the
    /// dispatches after it.
    ///
    /// # Safety
    /// `set` is a host-image set of this device, written, whose images and
    /// views stay alive, in the layouts it names, until the command buffer
    /// has finished executing.
    pub(crate) unsafe fn bind_host_images(&self, set: vk::DescriptorSet) {
        // SAFETY: `Recorder::new`'s promise covers the command buffer and
        // the layout; the caller's covers `set`.
        unsafe {
            self.device().cmd_bind_descriptor_sets(
                self.cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.layout.pipeline_layout,
                shared::host_image::SET,
                &[set],
                &[],
            );
        }
    }

    /// The command buffer, for the raster passes' own commands (recording
    /// into it is `unsafe`; [`Recorder::new`]'s promise covers it).
    pub(crate) fn cmd(&self) -> vk::CommandBuffer {
        self.cmd
    }

    /// The device the command buffer belongs to.
    pub(crate) fn shared(&self) -> &context::DeviceShared {
        self.shared
    }

    /// The pipeline layout and set every pass binds.
    pub(crate) fn binding(&self) -> (vk::PipelineLayout, vk::DescriptorSet) {
        (self.layout.pipeline_layout, self.set.handle())
    }

    /// Marks the end of step `name` when the dispatches are timed.
    pub(crate) fn mark(&self, name: &'static str) {
        if let Some(steps) = self.steps {
            steps.mark(self.cmd, name);
        }
    }

    /// Dispatches `kernel` over `groups` workgroups.
    pub fn dispatch(&self, kernel: &ComputeKernel, groups: [u32; 3]) {
        let d = self.device();
        // SAFETY: `self.cmd` is recording and the kernel outlives its
        // execution (`Recorder::new`'s promise); the set is bound there.
        unsafe {
            d.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, kernel.pipeline);
            d.cmd_dispatch(self.cmd, groups[0], groups[1], groups[2]);
        }
        self.mark(kernel.name);
    }

    /// One thread per pixel in 8×8 tiles.
    pub fn dispatch_pixels(&self, kernel: &ComputeKernel, size: [u32; 2]) {
        let [wx, wy] = shared::WORKGROUP_PIXELS;
        self.dispatch(kernel, [size[0].div_ceil(wx), size[1].div_ceil(wy), 1]);
    }

    /// One thread per item, 256 per workgroup (at least one workgroup).
    pub fn dispatch_linear(&self, kernel: &ComputeKernel, items: u32) {
        self.dispatch(
            kernel,
            [items.div_ceil(shared::WORKGROUP_LINEAR).max(1), 1, 1],
        );
    }

    /// Makes every earlier shader or transfer write visible to every later
    /// shader or transfer access.
    pub fn barrier(&self) {
        let barrier = [vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(
                vk::AccessFlags::SHADER_READ
                    | vk::AccessFlags::SHADER_WRITE
                    | vk::AccessFlags::TRANSFER_READ
                    | vk::AccessFlags::TRANSFER_WRITE,
            )];
        let stages = vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER;
        // SAFETY: `self.cmd` is recording (`Recorder::new`); the barrier
        // arrays outlive the call.
        unsafe {
            self.device().cmd_pipeline_barrier(
                self.cmd,
                stages,
                stages,
                vk::DependencyFlags::empty(),
                &barrier,
                &[],
                &[],
            );
        }
    }

    /// Opens a debug label (no-op without debug utils).
    pub fn begin_label(&self, name: &str) {
        if let Some(debug) = &self.shared.debug_device {
            let name = std::ffi::CString::new(name).unwrap_or_default();
            let label = vk::DebugUtilsLabelEXT::default().label_name(&name);
            // SAFETY: `self.cmd` is recording; `label` outlives the call.
            unsafe { debug.cmd_begin_debug_utils_label(self.cmd, &label) };
        }
    }

    /// Closes the label opened by [`Self::begin_label`].
    pub fn end_label(&self) {
        if let Some(debug) = &self.shared.debug_device {
            // SAFETY: `self.cmd` is recording and a label is open (the passes
            // pair every begin with an end).
            unsafe { debug.cmd_end_debug_utils_label(self.cmd) };
        }
    }
}
