//! What a frame of the shadow pass left in its buffers, copied back — for
//! tests and tools only: each call allocates, submits and waits.

use super::ShadowPass;
use crate::gbuffer::{GBuffer, DEPTH_SURFACE, NO_HIT};
use crate::gpu::frame_report::gbuffer_from_gpu;
use crate::gpu::pass_copies::read_back;
use crate::gpu::shared::{self, binding, counter};
use crate::gpu::GpuError;
use glam::Vec3;

impl ShadowPass<'_> {
    /// The masks, the second mask halves (empty with one) and the shaded
    /// pixels of the last frame, copied back — for tests and tools: it
    /// allocates, submits and waits.
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
            read_back(self.renderer, &self.buffers, wanted, words)?;
        Ok(PassImages {
            masks,
            masks_high,
            shaded,
            gbuffer_words,
        })
    }

    /// The eye-relative vertices the last frame read (`B_VERTICES`), copied
    /// back — for tests: it allocates, submits and waits.
    ///
    /// # Safety
    /// No frame of this pass is executing.
    pub unsafe fn read_back_vertices(&self) -> Result<Vec<Vec3>, GpuError> {
        let count = self.buffers[binding::VERTICES as usize].size() as usize / 12;
        // SAFETY: the caller's promise.
        unsafe { self.read_back_vec3s(binding::VERTICES, count) }
    }

    /// The last frame's triangle normals (`B_TRIANGLE_NORMALS`: the
    /// scene's, or those `gather_draws` made), copied back — for tests:
    /// it allocates, submits and waits.
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
        let [words] = read_back(self.renderer, &self.buffers, [b], [count * 3])?;
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
        let pixels = self.scene.pixel_count();
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
            pixels,
            3 * pixels,
            3 * pixels,
            3 * pixels,
            4 * normals,
            3 * triangles,
            counter::WORDS,
        ];
        let [words, position, axis_x, axis_y, g_normal, triangle_normals, counters] =
            read_back(self.renderer, &self.buffers, wanted, words)?;
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
        Ok(g)
    }
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
