//! The watertight ray/triangle test every ray of the crate's CPU side
//! ends in — the BVH's primary and shadow rays, and a multisampled
//! visibility buffer's candidates (`gbuffer::multisampled`), which have no
//! BVH — kept here, beside the triangles, so the pass alone
//! (`--no-default-features`) has it too.

use super::Triangle;
use glam::DVec3;

/// Watertight ray/triangle intersection (Woop, Benthin, Wald, "Watertight
/// Ray/Triangle Intersection", JCGT 2013) in `f64`: rays through a shared
/// edge or vertex hit exactly one of the adjacent triangles or both, never
/// neither, so no light leaks through the seams of a closed mesh or ground.
#[derive(Clone, Copy, Debug)]
pub struct WatertightRay {
    origin: DVec3,
    /// Axis permutation: kz is the dominant direction axis.
    kx: usize,
    ky: usize,
    kz: usize,
    shear: DVec3,
}

impl WatertightRay {
    pub fn new(origin: DVec3, direction: DVec3) -> Self {
        let abs = direction.abs();
        let kz = if abs.x >= abs.y && abs.x >= abs.z {
            0
        } else if abs.y >= abs.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if direction[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        let dz = direction[kz];
        WatertightRay {
            origin,
            kx,
            ky,
            kz,
            shear: DVec3::new(direction[kx] / dz, direction[ky] / dz, 1.0 / dz),
        }
    }

    /// Ray parameter of the hit, if the ray meets the triangle (either side).
    #[inline]
    pub fn intersect(&self, tri: &Triangle) -> Option<f64> {
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let a = tri[0] - self.origin;
        let b = tri[1] - self.origin;
        let c = tri[2] - self.origin;
        let (sx, sy, sz) = (self.shear.x, self.shear.y, self.shear.z);
        let ax = a[kx] - sx * a[kz];
        let ay = a[ky] - sy * a[kz];
        let bx = b[kx] - sx * b[kz];
        let by = b[ky] - sy * b[kz];
        let cx = c[kx] - sx * c[kz];
        let cy = c[ky] - sy * c[kz];
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None; // ray parallel to the triangle's plane
        }
        let t_scaled = sz * (u * a[kz] + v * b[kz] + w * c[kz]);
        let t = t_scaled / det;
        t.is_finite().then_some(t)
    }
}
