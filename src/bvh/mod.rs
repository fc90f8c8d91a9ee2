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

mod clusters;
mod packet;

pub use packet::PACKET_RAYS;

pub use crate::scene::WatertightRay;
use crate::scene::{Scene, Triangle};
pub(crate) use clusters::{identical_boxes, Clusters};
use glam::{DVec3, Vec3A};
use obvhs::cwbvh::{bvh2_to_cwbvh::bvh2_to_cwbvh, CwBvh};
use obvhs::{aabb::Aabb, bvh2::Bvh2, ray::Ray, BvhBuildParams};

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
    /// Triangle id for each entry of `triangles`.
    ids: Vec<u32>,
    /// Where BVH primitive `p`'s triangles start in `triangles`, when some
    /// primitive stands for a group of identical boxes (`clusters.rs`);
    /// empty when each primitive is one triangle (`triangles[p]`).
    starts: Vec<u32>,
    /// The eye-relative triangles indexed by triangle id.
    by_id: Vec<Triangle>,
    /// The power of two the `f32` tree's coordinates and ray parameters
    /// are scaled by ([`tree_scale`]).
    scale: f64,
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
        let scale = tree_scale(radius);
        let bounds: Vec<Aabb> = by_id.iter().map(|t| padded_bounds(t, pad, scale)).collect();
        let Some(clusters) = identical_boxes(&bounds) else {
            let bvh = build_cwbvh(&bounds);
            let ids = bvh.primitive_indices.clone();
            let triangles = ids.iter().map(|&i| by_id[i as usize]).collect();
            return SceneBvh {
                bvh,
                triangles,
                ids,
                starts: Vec::new(),
                by_id,
                scale,
            };
        };
        let heads: Vec<Aabb> = (0..clusters.len())
            .map(|r| bounds[clusters.members(r)[0] as usize])
            .collect();
        let bvh = build_cwbvh(&heads);
        let mut starts = Vec::with_capacity(heads.len() + 1);
        let mut ids = Vec::with_capacity(by_id.len());
        for &r in &bvh.primitive_indices {
            starts.push(ids.len() as u32);
            ids.extend_from_slice(clusters.members(r as usize));
        }
        starts.push(ids.len() as u32);
        let triangles = ids.iter().map(|&i| by_id[i as usize]).collect();
        SceneBvh {
            bvh,
            triangles,
            ids,
            starts,
            by_id,
            scale,
        }
    }

    /// The entries of `triangles` under BVH primitive `prim`.
    #[inline]
    fn members(&self, prim: usize) -> std::ops::Range<usize> {
        if self.starts.is_empty() {
            prim..prim + 1
        } else {
            self.starts[prim] as usize..self.starts[prim + 1] as usize
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
        let ray = self.f32_ray(origin, direction, t_max);
        let tester = WatertightRay::new(origin, direction);
        let mut best: Option<Hit> = None;
        let mut best_t = t_max;
        let mut hit = obvhs::ray::RayHit::none();
        self.bvh.ray_traverse(ray, &mut hit, |_, prim| {
            let mut nearest = f32::INFINITY;
            for k in self.members(prim) {
                if self.ids[k] == skip {
                    continue;
                }
                match tester.intersect(&self.triangles[k]) {
                    Some(t) if t > t_min && t < best_t => {
                        best_t = t;
                        best = Some(Hit {
                            triangle: self.ids[k],
                            t,
                        });
                        // Round up so the f32 traversal keeps every box that
                        // could hold a nearer f64 hit.
                        nearest = self.f32_t(t);
                    }
                    _ => {}
                }
            }
            nearest
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
        let ray = self.f32_ray(origin, direction, t_max);
        let tester = WatertightRay::new(origin, direction);
        !self.bvh.ray_traverse_miss(ray, |_, prim| {
            let hit = self.members(prim).any(|k| {
                self.ids[k] != skip
                    && tester
                        .intersect(&self.triangles[k])
                        .is_some_and(|t| t > t_min && t < t_max)
            });
            if hit {
                0.0
            } else {
                f32::INFINITY
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
        let ray = self.f32_ray(origin, direction, t_max);
        let tester = WatertightRay::new(origin, direction);
        !self.bvh.ray_traverse_miss(ray, |_, prim| {
            let hit = self.members(prim).any(|k| {
                tester
                    .intersect(&self.triangles[k])
                    .is_some_and(|t| t > t_min && t < t_max && accept(self.ids[k]))
            });
            if hit {
                0.0
            } else {
                f32::INFINITY
            }
        })
    }
}

/// A triangle as the BVH builder sees it: padded eye-relative `f32`
/// bounds, times the tree's scale.
fn padded_bounds(tri: &Triangle, pad: f64, scale: f64) -> Aabb {
    let lo = tri[0].min(tri[1]).min(tri[2]);
    let hi = tri[0].max(tri[1]).max(tri[2]);
    Aabb::new(
        Vec3A::from(((lo - pad) * scale).as_vec3()),
        Vec3A::from(((hi + pad) * scale).as_vec3()),
    )
}

/// The power of two that brings the scene's eye-relative radius into
/// [2²⁰, 2²¹) for the `f32` tree. `obvhs`'s single-ray node test clamps a
/// box's entry distance to at least 10⁻⁴ (`cwbvh::node::EPSILON`, an
/// absolute length), which culled every box of a scene smaller than about
/// 10⁻³ units (primary rays missed; the envelope's lower limit was 10⁻²);
/// scaled, that clamp is 5·10⁻¹¹ of the radius, below `f32` resolution,
/// whatever the scene's size. A power of two scales every `f32` bound and
/// every slab distance exactly (Goldberg 1991), so the tree `obvhs` builds
/// and the boxes a ray visits are otherwise those of the unscaled scene.
fn tree_scale(radius: f64) -> f64 {
    if !(radius.is_finite() && radius > 0.0) {
        return 1.0;
    }
    2f64.powi(20 - radius.log2().floor() as i32)
}

/// `obvhs::cwbvh::builder::build_cwbvh` with `medium_build()`, step by
/// step (the same calls, so the same BVH), so that the BVH2's depth is
/// known before `bvh2_to_cwbvh`, which recurses once per level: a tree
/// deeper than [`DEEP_BVH2`] (hostile geometry that is not one group of
/// identical boxes, e.g. thousands of nested boxes: 6 297 levels) is
/// converted on a thread whose stack grows with the depth, never
/// overflowing the caller's.
fn build_cwbvh(boxes: &[Aabb]) -> CwBvh {
    let params = BvhBuildParams::medium_build();
    let mut bvh2 = obvhs::ploc::PlocBuilder::with_capacity(boxes.len()).build(
        params.ploc_search_distance,
        boxes,
        (0..boxes.len() as u32).collect(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    obvhs::bvh2::reinsertion::ReinsertionOptimizer::default().run(
        &mut bvh2,
        params.reinsertion_batch_ratio,
        None,
    );
    to_cwbvh(&bvh2, params.max_prims_per_leaf.clamp(1, 3))
}

/// `bvh2_to_cwbvh` on a stack deep enough for `bvh2`.
fn to_cwbvh(bvh2: &Bvh2, leaf_prims: u32) -> CwBvh {
    let convert = || bvh2_to_cwbvh(bvh2, leaf_prims, true, false);
    let depth = bvh2_depth(bvh2);
    if depth <= DEEP_BVH2 {
        return convert();
    }
    std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("deep-bvh".into())
            .stack_size((8 << 20) + depth * STACK_PER_LEVEL)
            .spawn_scoped(scope, convert)
            .expect("a thread for the BVH conversion")
            .join()
            .expect("the BVH conversion does not panic")
    })
}

/// Deepest BVH2 converted on the caller's stack: well inside a test
/// thread's 2 MiB at [`STACK_PER_LEVEL`].
const DEEP_BVH2: usize = 256;

/// Stack reserved per BVH2 level for the conversion: `bvh2_to_cwbvh`'s
/// recursive frames measured well below this (it is only reserved address
/// space; pages are touched as the recursion reaches them).
const STACK_PER_LEVEL: usize = 4 << 10;

/// Levels of a BVH2 (a leaf root: 1), by an explicit walk.
fn bvh2_depth(bvh2: &Bvh2) -> usize {
    if bvh2.nodes.is_empty() {
        return 0;
    }
    let mut depth = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        depth = depth.max(d);
        let n = &bvh2.nodes[i];
        if n.prim_count == 0 {
            stack.push((n.first_index as usize, d + 1));
            stack.push((n.first_index as usize + 1, d + 1));
        }
    }
    depth
}

/// The id `closest_hit` skips to skip no triangle.
pub const NO_SKIP: u32 = u32::MAX;

impl SceneBvh {
    /// The ray as the `f32` tree sees it: its origin and end scaled with
    /// the tree ([`tree_scale`]), rounded to `f32` for culling only; the
    /// padding of the bounds absorbs the rounding (module docs).
    fn f32_ray(&self, origin: DVec3, direction: DVec3, t_max: f64) -> Ray {
        Ray::new(
            Vec3A::from((origin * self.scale).as_vec3()),
            f32_direction(direction),
            0.0,
            self.f32_t(t_max),
        )
    }

    /// A ray parameter `t` (an end, or a hit so far) as the `f32` tree
    /// culls with it: scaled, rounded up, so the traversal keeps every box
    /// that could hold a nearer `f64` hit.
    fn f32_t(&self, t: f64) -> f32 {
        f32_t_max(t * self.scale)
    }

    /// The packet's origin as the `f32` tree sees it.
    fn f32_origin(&self, origin: DVec3) -> Vec3A {
        Vec3A::from((origin * self.scale).as_vec3())
    }
}

/// A direction as the `f32` traversal sees it, with no `-0.0` component:
/// obvhs takes a ray's octant from `d < 0.0` (so `-0.0` counts as
/// positive) but its slab inverse from the sign bit (`-0.0` gives
/// `-1/ε`), and a ray whose octant and inverses disagree misses every box
/// it meets along that axis (found by `tests/hostile_geometry.rs`: a
/// ray along `-normal` with `normal.x == 0`; an `f64` component below 1e-45 rounds
/// to `-0.0`). Adding `+0.0` turns `-0.0` into `+0.0` and leaves every
/// other value as it is.
fn f32_direction(direction: DVec3) -> Vec3A {
    Vec3A::from(direction.as_vec3()) + Vec3A::ZERO
}

/// A ray's `f64` end as the `f32` traversal culls with it: rounded up.
fn f32_t_max(t_max: f64) -> f32 {
    if t_max.is_finite() {
        (t_max as f32).next_up()
    } else {
        f32::INFINITY
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

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::bvh2::node::Bvh2Node;

    /// A chain 100 000 levels deep (every inner node: a leaf and the rest)
    /// converts without overflowing this test thread's 2 MiB stack.
    #[test]
    fn a_chain_deeper_than_any_stack_converts() {
        const LEVELS: usize = 100_000;
        let unit = Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        // Node 0 is the root; inner node 2k (k >= 1) and the root have
        // children 2k+1 (a leaf) and 2k+2.
        let mut nodes = vec![Bvh2Node::new(unit, 0, 1)];
        for k in 0..LEVELS {
            nodes.push(Bvh2Node::new(unit, 1, k as u32));
            let last = k + 1 == LEVELS;
            nodes.push(if last {
                Bvh2Node::new(unit, 1, LEVELS as u32)
            } else {
                Bvh2Node::new(unit, 0, nodes.len() as u32 + 1)
            });
        }
        let bvh2 = Bvh2 {
            nodes,
            primitive_indices: (0..=LEVELS as u32).collect(),
            ..Default::default()
        };
        assert_eq!(bvh2_depth(&bvh2), LEVELS + 1);
        let cwbvh = to_cwbvh(&bvh2, 3);
        let mut prims = cwbvh.primitive_indices.clone();
        prims.sort_unstable();
        assert_eq!(prims, (0..=LEVELS as u32).collect::<Vec<_>>());
    }
}
