//! Ray casting on the real geometry: an `obvhs` compressed-wide BVH built
//! over eye-relative `f32` bounds, with every ray/triangle test done in
//! `f64` by a watertight intersector.
//!
//! Why this split: `obvhs` traverses in `f32`, which is fine for culling as
//! long as the bounds it sees are conservative; the hit itself decides what
//! is in shadow, so it runs in `f64` on eye-relative coordinates (paper-notes/frustum-test.md:
//! never hand `f32` a large absolute coordinate). Bounds are padded by 16
//! `f32` ulps of the scene's eye-relative radius R: every ray starts within
//! 3R of the eye (the same-sample reference starts lines 2R behind a
//! sample), so rounding its origin and direction to `f32` moves it by at
//! most ~5 ε₃₂ R inside the scene, and the `f32` traversal can never cull a
//! box that the `f64` test would hit.

mod packet;

pub use packet::PACKET_RAYS;

use crate::scene::{Scene, Triangle};
use glam::{DVec3, Vec3A};
use obvhs::{aabb::Aabb, cwbvh::CwBvh, ray::Ray, Boundable, BvhBuildParams};
use std::time::Duration;

/// A triangle as the BVH builder sees it: padded eye-relative `f32` bounds.
struct PaddedBounds(Aabb);

impl Boundable for PaddedBounds {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// Closest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Triangle id (index into `Scene::triangles`).
    pub triangle: u32,
    /// Ray parameter: the hit is `origin + t · direction`.
    pub t: f64,
}

/// BVH over a scene's triangles, in the frame centred on the camera eye.
pub struct SceneBvh {
    bvh: CwBvh,
    /// Eye-relative triangles in BVH primitive order (sequential leaf reads).
    triangles: Vec<Triangle>,
    /// Triangle id for each BVH primitive.
    ids: Vec<u32>,
    /// The eye-relative triangles indexed by triangle id.
    by_id: Vec<Triangle>,
}

impl SceneBvh {
    /// Builds the BVH for `scene`, relative to its camera eye.
    pub fn build(scene: &Scene) -> Self {
        let by_id = scene.eye_relative_triangles();
        let radius = by_id
            .iter()
            .flatten()
            .map(|v| v.abs().max_element())
            .fold(0.0, f64::max);
        let pad = 16.0 * f32::EPSILON as f64 * radius;
        let bounds: Vec<PaddedBounds> = by_id.iter().map(|t| padded_bounds(t, pad)).collect();
        let bvh = obvhs::cwbvh::builder::build_cwbvh(
            &bounds,
            BvhBuildParams::medium_build(),
            &mut Duration::default(),
        );
        let ids = bvh.primitive_indices.clone();
        let triangles = ids.iter().map(|&i| by_id[i as usize]).collect();
        SceneBvh {
            bvh,
            triangles,
            ids,
            by_id,
        }
    }

    /// Eye-relative triangle by id.
    pub fn triangle(&self, id: u32) -> &Triangle {
        &self.by_id[id as usize]
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.by_id.len()
    }

    /// True if the BVH holds no triangle.
    pub fn is_empty(&self) -> bool {
        self.by_id.is_empty()
    }

    /// Closest hit with `t` in `(t_min, t_max)`, ignoring triangle `skip`
    /// ([`NO_SKIP`] to skip none). Eye-relative origin.
    pub fn closest_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        skip: u32,
    ) -> Option<Hit> {
        let ray = f32_ray(origin, direction, t_max);
        let tester = WatertightRay::new(origin, direction);
        let mut best: Option<Hit> = None;
        let mut best_t = t_max;
        let mut hit = obvhs::ray::RayHit::none();
        self.bvh.ray_traverse(ray, &mut hit, |_, prim| {
            if self.ids[prim] == skip {
                return f32::INFINITY;
            }
            match tester.intersect(&self.triangles[prim]) {
                Some(t) if t > t_min && t < best_t => {
                    best_t = t;
                    best = Some(Hit {
                        triangle: self.ids[prim],
                        t,
                    });
                    // Round up so the f32 traversal keeps every box that
                    // could hold a nearer f64 hit.
                    (t as f32).next_up()
                }
                _ => f32::INFINITY,
            }
        });
        best
    }

    /// Whether any triangle other than `skip` is hit with `t` in
    /// `(t_min, t_max)`.
    pub fn occluded(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        skip: u32,
    ) -> bool {
        let ray = f32_ray(origin, direction, t_max);
        let tester = WatertightRay::new(origin, direction);
        !self.bvh.ray_traverse_miss(ray, |_, prim| {
            if self.ids[prim] == skip {
                return f32::INFINITY;
            }
            match tester.intersect(&self.triangles[prim]) {
                Some(t) if t > t_min && t < t_max => 0.0,
                _ => f32::INFINITY,
            }
        })
    }
}

impl SceneBvh {
    /// Whether the ray meets, with `t` in `(t_min, t_max)`, any triangle for
    /// which `accept(id)` holds (a filtered any-hit query).
    pub fn any_hit(
        &self,
        origin: DVec3,
        direction: DVec3,
        t_min: f64,
        t_max: f64,
        accept: impl Fn(u32) -> bool,
    ) -> bool {
        let ray = f32_ray(origin, direction, t_max);
        let tester = WatertightRay::new(origin, direction);
        !self.bvh.ray_traverse_miss(ray, |_, prim| {
            match tester.intersect(&self.triangles[prim]) {
                Some(t) if t > t_min && t < t_max && accept(self.ids[prim]) => 0.0,
                _ => f32::INFINITY,
            }
        })
    }
}

fn padded_bounds(tri: &Triangle, pad: f64) -> PaddedBounds {
    let lo = tri[0].min(tri[1]).min(tri[2]);
    let hi = tri[0].max(tri[1]).max(tri[2]);
    PaddedBounds(Aabb::new(
        Vec3A::from((lo - pad).as_vec3()),
        Vec3A::from((hi + pad).as_vec3()),
    ))
}

/// The id `closest_hit` skips to skip no triangle.
pub const NO_SKIP: u32 = u32::MAX;

fn f32_ray(origin: DVec3, direction: DVec3, t_max: f64) -> Ray {
    // Rounded to f32 for culling only; the padding of the bounds absorbs
    // the rounding (module docs).
    Ray::new(
        Vec3A::from(origin.as_vec3()),
        Vec3A::from(direction.as_vec3()),
        0.0,
        f32_t_max(t_max),
    )
}

/// A ray's `f64` end as the `f32` traversal culls with it: rounded up.
fn f32_t_max(t_max: f64) -> f32 {
    if t_max.is_finite() {
        (t_max as f32).next_up()
    } else {
        f32::INFINITY
    }
}

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

/// Smallest ray parameter a secondary ray leaving the surface point `p` may
/// accept. `p` is eye-relative and computed in `f64`, so its error is a few
/// ulps of its magnitude; 2^-30 of that magnitude is ~10^6 times larger than
/// the error (robust even where the ray leaves at 1e-6 of grazing) and still
/// far below any modelled feature (2^-30 · 100 m ≈ 0.1 µm).
pub fn self_hit_offset(p: DVec3) -> f64 {
    p.abs().max_element().max(f64::MIN_POSITIVE) * (1.0 / (1u64 << 30) as f64)
}
