//! What a frame of the shadow pass left in its buffers, copied back — for
//! tests and tools only: each call submits and waits, through one
//! read-back buffer the pass keeps (made, or made larger, when a call
//! needs more than it holds).

use super::ShadowPass;
use crate::gbuffer::{GBuffer, DEPTH_SURFACE, NO_HIT};
use crate::gpu::edge_surfaces::{read_traced_tables, TracedEdges};
use crate::gpu::frame_report::{gbuffer_from_gpu, resolved_images};
use crate::gpu::pass_copies::read_back;
use crate::gpu::shared::{self, binding, counter};
use crate::gpu::GpuError;
use glam::Vec3;

impl ShadowPass<'_> {
    /// The counters and the light state (the light fit, cascades and
    /// grids) of the last frame, copied back — for the batch `render`'s
    /// report: it submits and waits.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub(crate) unsafe fn read_back_counters_and_light(
        &self,
    ) -> Result<(Vec<u32>, shared::LightState), GpuError> {
        let light_words = size_of::<shared::LightState>() / 4;
        let [counters, light] = read_back(
            self.renderer,
            &self.buffers,
            &self.readback,
            [binding::COUNTERS, binding::LIGHT],
            [counter::WORDS, light_words],
        )?;
        Ok((
            counters,
            bytemuck::pod_read_unaligned(bytemuck::cast_slice(&light)),
        ))
    }

    /// The masks, the second mask halves (empty with one) and the shaded
    /// pixels of the last frame, copied back — for tests and tools: it
    /// submits and waits.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back(&self) -> Result<PassImages, GpuError> {
        let halves = self.config.settings.mask_halves(&self.scene);
        let pixels = self.scene.pixel_count();
        let wanted = [
            binding::MASKS,
            binding::MASKS_HIGH,
            binding::SHADED,
            binding::G_ID_FLAGS,
        ];
        let words = [pixels, pixels * (halves - 1), pixels, pixels];
        let [masks, masks_high, shaded, gbuffer_words] =
            read_back(self.renderer, &self.buffers, &self.readback, wanted, words)?;
        Ok(PassImages {
            masks,
            masks_high,
            shaded,
            gbuffer_words,
        })
    }

    /// The eye-relative vertices the last frame read (`B_VERTICES`), copied
    /// back — for tests: it submits and waits.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back_vertices(&self) -> Result<Vec<Vec3>, GpuError> {
        let count = self.buffers[binding::VERTICES as usize].size() as usize / 12;
        // SAFETY: the caller's promise.
        unsafe { self.read_back_vec3s(binding::VERTICES, count) }
    }

    /// The BVH nodes the last frame traversed (`B_BVH_NODES`' first
    /// `world_node_count`, made eye-relative by `translate_vertices`) and
    /// the anchor-space nodes they came from, copied back — for tests: it
    /// submits and waits. Empty without a ray-cast G-buffer.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back_bvh_nodes(&self) -> Result<[Vec<shared::BvhNode>; 2], GpuError> {
        if self.is_one_view() {
            return Err(GpuError::Unsupported(
                "a pass for one view holds no anchor-space BVH, and after a frame its BVH's \
                 memory holds the bin's cell list"
                    .into(),
            ));
        }
        let nodes = self.world.as_ref().map_or(0, |w| w.bvh_nodes as usize);
        let words = nodes * size_of::<shared::BvhNode>() / 4;
        let [all] = read_back(
            self.renderer,
            &self.buffers,
            &self.readback,
            [binding::BVH_NODES],
            [2 * words],
        )?;
        let all: Vec<shared::BvhNode> = bytemuck::pod_collect_to_vec(&all);
        Ok([all[..nodes].to_vec(), all[nodes..].to_vec()])
    }

    /// The last frame's triangle normals (`B_TRIANGLE_NORMALS`: the
    /// scene's, or those `gather_draws` made), copied back — for tests:
    /// it submits and waits.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back_triangle_normals(&self) -> Result<Vec<Vec3>, GpuError> {
        // SAFETY: the caller's promise.
        unsafe { self.read_back_vec3s(binding::TRIANGLE_NORMALS, self.frame_triangles as usize) }
    }

    /// The first `count` `vec3`s of binding `b`'s buffer, copied back.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    unsafe fn read_back_vec3s(&self, b: u32, count: usize) -> Result<Vec<Vec3>, GpuError> {
        let [words] = read_back(
            self.renderer,
            &self.buffers,
            &self.readback,
            [b],
            [count * 3],
        )?;
        Ok(bytemuck::cast_slice::<u32, [f32; 3]>(&words)
            .iter()
            .map(|&v| Vec3::from(v))
            .collect())
    }

    /// The last frame's G-buffer, copied back as the CPU twin's
    /// [`GBuffer`] (normals per entry: the host's where its depth and
    /// normal made the entry, else the triangle's facing the camera;
    /// depth along the view axis; the depth's uncertainty where the host's
    /// depth made the entries) — so the CPU twin's later passes can
    /// run on exactly the entries the GPU's did.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back_gbuffer(&self) -> Result<GBuffer, GpuError> {
        if self.config.gbuffer == super::GBufferInput::Uploaded {
            return Err(GpuError::Unsupported(
                "an uploaded G-buffer is the caller's own: the pass has no other".into(),
            ));
        }
        let pixels = self.scene.pixel_count();
        // With traced edge surfaces the extra surfaces follow the pixels
        // (receiver rows below the image).
        let entries = match self.sizes.edge_surfaces {
            Some(_) => self.sizes.receivers as usize,
            None => pixels,
        };
        let normals = self.sizes.normal_entries as usize;
        let wanted = [
            binding::G_ID_FLAGS,
            binding::G_POSITION,
            binding::G_AXIS_X,
            binding::G_AXIS_Y,
            binding::G_NORMAL,
            binding::TRIANGLE_NORMALS,
            binding::COUNTERS,
        ];
        let triangles = self.frame_triangles as usize;
        let words = [
            entries,
            3 * entries,
            3 * entries,
            3 * entries,
            4 * normals,
            3 * triangles,
            counter::WORDS,
        ];
        let [words, position, axis_x, axis_y, g_normal, triangle_normals, counters] =
            read_back(self.renderer, &self.buffers, &self.readback, wanted, words)?;
        let vectors = |w: &[u32]| -> Vec<Vec3> {
            bytemuck::cast_slice::<u32, [f32; 3]>(w)
                .iter()
                .map(|&v| v.into())
                .collect()
        };
        let g_normal: &[[f32; 4]] = bytemuck::cast_slice(&g_normal);
        let triangle_normals = vectors(&triangle_normals);
        let forward = self
            .scene
            .camera
            .frame(self.scene.resolution)
            .forward
            .as_vec3();
        let mut g = gbuffer_from_gpu(
            self.scene.resolution,
            forward,
            &words,
            [vectors(&position), vectors(&axis_x), vectors(&axis_y)],
            &counters,
            |i, id, gpu_flags| match id {
                NO_HIT => Vec3::ZERO,
                DEPTH_SURFACE => Vec3::from_slice(&g_normal[i][..3]),
                _ if gpu_flags & shared::FLAG_NORMAL_FLIPPED != 0 => -triangle_normals[id as usize],
                _ => triangle_normals[id as usize],
            },
        );
        if normals != 0 {
            g.depth_uncertainty = Some(
                (0..pixels)
                    .map(|i| {
                        if g.triangle_id[i] == DEPTH_SURFACE {
                            g_normal[i][3]
                        } else {
                            0.0
                        }
                    })
                    .collect(),
            );
        }
        if let Some(slots) = self.traced_edge_slots() {
            self.attach_edge_surfaces(&mut g, slots.surfaces, &counters)?;
        }
        g.truncate(pixels);
        Ok(g)
    }

    /// The `edge_surfaces` step's tables read back into `g` (whose
    /// entries past the pixels are the extra surfaces' slots), as the
    /// batch `render` attaches them.
    fn attach_edge_surfaces(
        &self,
        g: &mut GBuffer,
        capacity: u64,
        counters: &[u32],
    ) -> Result<(), GpuError> {
        if let Some((records, coverage)) = self.read_edge_tables(capacity, counters)? {
            let pixels = self.scene.pixel_count();
            let slots: Vec<usize> = (pixels..pixels + coverage.len()).collect();
            let traced = TracedEdges {
                pixels: records,
                coverage,
                surfaces: g.select(&slots),
            };
            g.edges = Some(Box::new(traced.into_edge_surfaces(counters)));
        }
        Ok(())
    }

    /// The `edge_surfaces` step's tables of the last frame: per pixel its
    /// record, per filled slot its coverage.
    #[allow(clippy::type_complexity)]
    fn read_edge_tables(
        &self,
        capacity: u64,
        counters: &[u32],
    ) -> Result<Option<(Vec<[u32; 4]>, Vec<u32>)>, GpuError> {
        let size = |b: u32| self.buffers[b as usize].size() as usize / 4;
        let wanted = [binding::EDGE_PIXELS, binding::EDGE_COVERAGE];
        let [pixel_words, coverage_words] = read_back(
            self.renderer,
            &self.buffers,
            &self.readback,
            wanted,
            wanted.map(size),
        )?;
        let read = |b: u32| -> Result<&[u8], GpuError> {
            Ok(bytemuck::cast_slice(match b {
                binding::EDGE_PIXELS => &pixel_words,
                _ => &coverage_words,
            }))
        };
        let (_, tables) = read_traced_tables(&read, counters, self.scene.resolution, capacity)?;
        Ok(Some(tables))
    }

    /// The last frame's images as the batch `render` returns them —
    /// masks, lit fraction (NaN where not shadow-tested; at edge pixels
    /// over the samples that count) and shaded pixels — copied back, for
    /// tools (the viewer): it submits and waits. The G-buffer
    /// is [`Self::read_back_gbuffer`]'s.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back_frame(&self) -> Result<PassFrame, GpuError> {
        let pixels = self.scene.pixel_count();
        let halves = self.config.settings.mask_halves(&self.scene);
        let wanted = [
            binding::MASKS,
            binding::MASKS_HIGH,
            binding::SHADED,
            binding::COUNTERS,
        ];
        let words = [pixels, pixels * (halves - 1), pixels, counter::WORDS];
        let [masks, masks_high, shaded, counters] =
            read_back(self.renderer, &self.buffers, &self.readback, wanted, words)?;
        // The samples that count at edge pixels: the traced records'
        // second word, on the first mask half only (as
        // `GBuffer::counted_samples` of the CPU twin's G-buffer), or
        // an uploaded G-buffer's own.
        let counted: Option<Vec<u32>> = match self.traced_edge_slots() {
            Some(slots) => self
                .read_edge_tables(slots.surfaces, &counters)?
                .map(|(records, _)| {
                    let extra = 32 * (halves as u32 - 1);
                    records.iter().map(|r| r[1].count_ones() + extra).collect()
                }),
            None => self.uploaded_counted.clone(),
        };
        let counted = counted.map(|samples| move |i: usize| samples[i]);
        let (visibility, shaded) = resolved_images(&shaded, halves, counted);
        Ok(PassFrame {
            masks,
            masks_high,
            visibility,
            shaded,
        })
    }
}

/// A frame as [`ShadowPass::read_back_frame`] copies it: the batch
/// render's images ([`crate::gpu::frame_report::GpuRender`]'s, without
/// the G-buffer).
#[derive(Clone, Debug)]
pub struct PassFrame {
    pub masks: Vec<u32>,
    pub masks_high: Vec<u32>,
    /// Lit fraction, NaN where not shadow-tested.
    pub visibility: Vec<f32>,
    /// Shaded image, RGB8 per pixel.
    pub shaded: Vec<[u8; 3]>,
}

/// A frame's images as [`ShadowPass::read_back`] copies them.
pub struct PassImages {
    pub masks: Vec<u32>,
    pub masks_high: Vec<u32>,
    /// Packed RGBA8 shaded pixels (`resolve.comp`).
    pub shaded: Vec<u32>,
    /// The G-buffer's words: triangle id below `ID_BITS`, flags above
    /// (`ID_MASK` for a miss).
    pub gbuffer_words: Vec<u32>,
}
