//! The shadow pass's step for a moving eye, `translate_vertices`
//! (`shaders/translate_vertices.comp`): the scene's eye-relative `f32`
//! vertices made on the GPU each frame from anchor-relative
//! double-singles, and with a ray-cast G-buffer its BVH nodes from
//! anchor-space ones — the twin of [`crate::cpu::translate_vertices`], whose
//! module says why the arithmetic keeps the envelope's exactness.

use super::shared::{GpuTriangle, GpuTriangleCorners};
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
    /// With a ray-cast G-buffer: the BVH's nodes, built in anchor space
    /// over the pairs' high parts ([`Self::anchor_triangles`]) and made
    /// eye-relative each frame; 0 without one.
    pub bvh_nodes: u32,
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
            bvh_nodes: 0,
        }
    }

    /// The triangles with the high parts of their anchor-relative
    /// vertices: what the anchor-space BVH is built over.
    pub fn anchor_triangles(&self) -> Vec<GpuTriangle> {
        let at = |i: u32| self.pairs[i as usize][0].to_array();
        let corners = self.corners.iter();
        corners
            .map(|c| GpuTriangle {
                a: at(c.a),
                b: at(c.b),
                c: at(c.c),
            })
            .collect()
    }

    /// `eye` relative to the anchor, as `FrameParams::eye_hi`/`eye_lo`.
    pub fn eye(&self, eye: DVec3) -> [Vec3; 2] {
        split(eye - self.anchor)
    }
}

/// Records the step: one thread per vertex and per BVH node (`threads`,
/// the larger count), then a barrier before the passes that read
/// `B_VERTICES` and `B_BVH_NODES`.
pub fn translate_vertices(rec: &Recorder, kernels: &Kernels, threads: u32) {
    rec.begin_label("translate_vertices");
    rec.dispatch_linear(&kernels.translate_vertices, threads);
    rec.barrier();
    rec.end_label();
}
