//! The shadow pass's step for a moving eye, `translate_vertices`
//! (`shaders/translate_vertices.comp`): the scene's eye-relative `f32`
//! vertices made on the GPU each frame from anchor-relative
//! double-singles — the twin of [`crate::cpu::translate_vertices`], whose
//! module says why the arithmetic keeps the envelope's exactness.

use super::shared::GpuTriangleCorners;
use super::{Kernels, Recorder};
use crate::cpu::translate_vertices::split;
use crate::scene::Scene;
use glam::{DVec3, Vec3};
use std::collections::HashMap;

/// The scene's distinct vertices (equal `f64` positions once) relative to
/// `anchor` as double-singles, and each triangle's corners into them.
pub struct WorldVertices {
    pub anchor: DVec3,
    pub corners: Vec<GpuTriangleCorners>,
    pub pairs: Vec<[Vec3; 2]>,
}

impl WorldVertices {
    /// Splits `scene`'s vertices relative to `anchor`. Distinct by their
    /// world position, not by a rounded eye-relative one: two vertices one
    /// eye rounds together another may not.
    pub fn new(scene: &Scene, anchor: DVec3) -> Self {
        let mut index: HashMap<[u64; 3], u32> = HashMap::with_capacity(scene.triangles.len());
        let mut pairs = Vec::with_capacity(scene.triangles.len());
        let corners = scene
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| {
                    *index
                        .entry(v.to_array().map(f64::to_bits))
                        .or_insert_with(|| {
                            pairs.push(split(v - anchor));
                            (pairs.len() - 1) as u32
                        })
                });
                GpuTriangleCorners { a, b, c }
            })
            .collect();
        WorldVertices {
            anchor,
            corners,
            pairs,
        }
    }

    /// `eye` relative to the anchor, as `FrameParams::eye_hi`/`eye_lo`.
    pub fn eye(&self, eye: DVec3) -> [Vec3; 2] {
        split(eye - self.anchor)
    }
}

/// Records the step: one thread per vertex, then a barrier before the
/// passes that read `B_VERTICES`.
pub fn translate_vertices(rec: &Recorder, kernels: &Kernels, vertices: u32) {
    rec.begin_label("translate_vertices");
    rec.dispatch_linear(&kernels.translate_vertices, vertices);
    rec.barrier();
    rec.end_label();
}
