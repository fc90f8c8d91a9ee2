//! Closest hits of a packet of up to 32 rays from one origin in one walk of
//! the BVH: the sample rays of an edge pixel (`gbuffer/edge_surfaces.rs`),
//! which leave the eye through one pixel and are as coherent as rays get.
//!
//! Walked one by one, the 32 rays visit nearly the same nodes 32 times. The
//! packet walks the tree once and keeps a child when the packet's
//! *interval* of inverse directions may meet its box before the farthest
//! ray's closest hit so far: the interval-arithmetic slab test of Wald,
//! Boulos & Shirley 2007 (BVH packet traversal) and Boulos et al. 2006
//! (culling whole ray packets). The slab distance `x · d⁻¹` of a plane `x`
//! is linear in `d⁻¹`, so over the packet's interval its extremes are at
//! the interval's ends: four products per axis bound every ray's entry and
//! exit, whatever the signs. At the leaves each ray is tested with its own
//! `f64` watertight test against its own closest hit so far.
//!
//! **The same hits as [`SceneBvh::closest_hit`], ray by ray.** The packet
//! keeps every child some ray would keep (a ray's closest hit lies inside
//! the padded box by the padding, 16 `f32` ulps of the scene radius, far
//! beyond the few ulps of the `f32` slab arithmetic, and the intervals are
//! widened on top), and it visits children in the order of the rays'
//! common octant, so each ray meets the triangles it would meet alone, in
//! the same order, among others it rejects; ties go to the same triangle.
//! Rays of different octants (a pixel on an axis plane through the eye)
//! are walked one by one. `tests::packet_hits_equal_single_ray_hits`
//! checks it on every procedural scene.

use super::{Hit, SceneBvh, WatertightRay};
use glam::{DVec3, UVec2, Vec3A};
use obvhs::cwbvh::node::{extract_byte64, CwBvhNode};
use obvhs::ray::safe_inverse;

/// The most rays in one packet (a pixel's samples: one mask word).
pub const PACKET_RAYS: usize = 32;

/// How far each slab interval is widened, relative to its end: the packet
/// only ever keeps more than each ray would, never less.
const WIDEN: f32 = 1.0 / 65536.0;

/// The packet as the node test sees it: its common `f32` origin and the
/// range of its rays' `f32` inverse directions (as `obvhs` computes them).
struct PacketSlabs {
    origin: Vec3A,
    inv_lo: Vec3A,
    inv_hi: Vec3A,
}

impl PacketSlabs {
    /// The children of `node` (as a traversal hit mask) that some ray of
    /// the packet may meet in `[0, t_max]`.
    #[inline(always)]
    fn children(&self, node: &CwBvhNode, oct_inv4: u32, t_max: f32) -> u32 {
        let extent = node.compute_extent();
        let base = Vec3A::from(node.p) - self.origin;
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut mask = 0;
        for c in 0..8 {
            if node.child_meta[c] == 0 {
                continue;
            }
            let q_lo = Vec3A::new(
                node.child_min_x[c] as f32,
                node.child_min_y[c] as f32,
                node.child_min_z[c] as f32,
            );
            let q_hi = Vec3A::new(
                node.child_max_x[c] as f32,
                node.child_max_y[c] as f32,
                node.child_max_z[c] as f32,
            );
            let (lo, hi) = (base + extent * q_lo, base + extent * q_hi);
            let (a, b) = (lo * self.inv_lo, lo * self.inv_hi);
            let (p, q) = (hi * self.inv_lo, hi * self.inv_hi);
            let near = a.min(b).min(p.min(q));
            let far = a.max(b).max(p.max(q));
            let enter = (near - near.abs() * WIDEN).max_element().max(0.0);
            let exit = (far + far.abs() * WIDEN).min_element().min(t_max);
            if enter <= exit {
                mask |= extract_byte64(child_bits8, c) << extract_byte64(bit_index8, c);
            }
        }
        mask
    }
}

/// The packet's directions as the leaf prefilter reads them: `f32`,
/// structure of arrays, with their lengths.
struct EdgeTestRays {
    x: [f32; PACKET_RAYS],
    y: [f32; PACKET_RAYS],
    z: [f32; PACKET_RAYS],
    len: [f32; PACKET_RAYS],
}

/// How close to an edge, relative to `|Vₐ||V_b||D|`, a ray is left to the
/// watertight test: 10⁻⁵, against `f32` rounding of ~10⁻⁶ in the
/// prefilter's products and ~10⁻¹⁵ in the watertight test's.
const EDGE_MARGIN: f64 = 1e-5;

/// How far beyond a ray's closest hit so far, relative, a triangle's plane
/// must lie for the prefilter to drop it (the `f32` quotient's rounding is
/// ~10⁻⁷).
const T_MARGIN: f32 = 1e-5;

impl EdgeTestRays {
    fn new(directions: &[DVec3]) -> EdgeTestRays {
        let mut rays = EdgeTestRays {
            x: [0.0; PACKET_RAYS],
            y: [0.0; PACKET_RAYS],
            z: [0.0; PACKET_RAYS],
            len: [0.0; PACKET_RAYS],
        };
        for (i, d) in directions.iter().enumerate() {
            (rays.x[i], rays.y[i], rays.z[i]) = (d.x as f32, d.y as f32, d.z as f32);
            rays.len[i] = d.length() as f32;
        }
        rays
    }

    /// The rays that may meet triangle `tri` (bit i for ray i): all but
    /// those with one edge function clearly negative and another clearly
    /// positive, which the watertight test rejects too. The edge functions
    /// are `(Vₐ × V_b) · D` with the vertices relative to the origin
    /// (Olano & Greer 1997); a ray meets the triangle's plane inside it
    /// exactly when the three share a sign, the watertight test's rule.
    #[inline(always)]
    fn may_hit(
        &self,
        tri: &crate::scene::Triangle,
        origin: DVec3,
        best_t: &[f32; PACKET_RAYS],
    ) -> u32 {
        let v = tri.map(|p| p - origin);
        let len = v.map(|p| p.length());
        let mut edges = [[0.0f32; 3]; 3];
        let mut margin = [0.0f32; 3];
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            edges[k] = a.cross(b).as_vec3().to_array();
            margin[k] = (EDGE_MARGIN * len[k] * len[(k + 1) % 3]) as f32;
        }
        // The plane, oriented so the origin lies on its negative side:
        // a ray meets it in front where `n · D > 0`, at t = offset / n·D.
        let normal = (v[1] - v[0]).cross(v[2] - v[0]);
        let offset = normal.dot(v[0]);
        let (normal, offset) = if offset < 0.0 {
            (-normal, -offset)
        } else {
            (normal, offset)
        };
        let plane_margin = (EDGE_MARGIN * normal.length()) as f32;
        let [nx, ny, nz] = normal.as_vec3().to_array();
        let offset = offset as f32;
        let [e0, e1, e2] = edges;
        let mut keep = [0u32; PACKET_RAYS];
        for i in 0..PACKET_RAYS {
            let (x, y, z, len) = (self.x[i], self.y[i], self.z[i], self.len[i]);
            let f0 = e0[0] * x + e0[1] * y + e0[2] * z;
            let f1 = e1[0] * x + e1[1] * y + e1[2] * z;
            let f2 = e2[0] * x + e2[1] * y + e2[2] * z;
            let (m0, m1, m2) = (margin[0] * len, margin[1] * len, margin[2] * len);
            let neg = (f0 < -m0) | (f1 < -m1) | (f2 < -m2);
            let pos = (f0 > m0) | (f1 > m1) | (f2 > m2);
            // Behind the origin, or certainly no nearer than the ray's
            // closest hit so far: the watertight test's `t` would not be
            // kept either.
            let den = nx * x + ny * y + nz * z;
            let m = plane_margin * len;
            let behind = den < -m;
            let beyond = offset > (den + m) * best_t[i] * (1.0 + T_MARGIN);
            keep[i] = (!(neg & pos) & !behind & !beyond) as u32;
        }
        let mut maybe = 0u32;
        for (i, k) in keep.iter().enumerate() {
            maybe |= k << i;
        }
        maybe
    }
}

/// The `obvhs` octant code of a direction (its traversal order).
fn octant(d: Vec3A) -> u32 {
    (d.x < 0.0) as u32 | ((d.y < 0.0) as u32) << 1 | ((d.z < 0.0) as u32) << 2
}

impl SceneBvh {
    /// For each ray `origin + t · directions[i]`, its closest hit with `t`
    /// in `(t_min, t_max[i])` into `hits[i]`: what
    /// [`closest_hit`](SceneBvh::closest_hit) returns for it (skipping no
    /// triangle), for up to [`PACKET_RAYS`] rays in one walk of the tree
    /// (module docs). The origin, like every ray's, lies within 3R of the
    /// eye (the bounds' padding, `bvh` module docs).
    pub fn closest_hits(
        &self,
        origin: DVec3,
        directions: &[DVec3],
        t_min: f64,
        t_max: &[f64],
        hits: &mut [Option<Hit>],
    ) {
        let n = directions.len();
        assert!(n <= PACKET_RAYS && t_max.len() == n && hits.len() == n);
        let f32_dir = super::f32_direction;
        let first = directions.first().map(|&d| octant(f32_dir(d)));
        if directions
            .iter()
            .any(|&d| Some(octant(f32_dir(d))) != first)
        {
            for i in 0..n {
                hits[i] = self.closest_hit(origin, directions[i], t_min, t_max[i], super::NO_SKIP);
            }
            return;
        }
        if n == 0 || self.bvh.nodes.is_empty() {
            hits.fill(None);
            return;
        }
        let mut slabs = PacketSlabs {
            origin: self.f32_origin(origin),
            inv_lo: Vec3A::splat(f32::INFINITY),
            inv_hi: Vec3A::splat(f32::NEG_INFINITY),
        };
        let mut testers = [WatertightRay::new(origin, DVec3::Z); PACKET_RAYS];
        let mut best_t = [0.0f64; PACKET_RAYS];
        let mut cull_t = [0.0f32; PACKET_RAYS];
        for i in 0..n {
            let d = f32_dir(directions[i]);
            let inv = Vec3A::new(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
            slabs.inv_lo = slabs.inv_lo.min(inv);
            slabs.inv_hi = slabs.inv_hi.max(inv);
            testers[i] = WatertightRay::new(origin, directions[i]);
            best_t[i] = t_max[i];
            cull_t[i] = self.f32_t(t_max[i]);
            hits[i] = None;
        }
        let rays = EdgeTestRays::new(directions);
        let mut best_t32 = [f32::INFINITY; PACKET_RAYS];
        for i in 0..n {
            best_t32[i] = best_t[i] as f32;
        }
        let live = if n == PACKET_RAYS {
            u32::MAX
        } else {
            (1u32 << n) - 1
        };
        let mut packet_t = cull_t[..n].iter().copied().fold(0.0, f32::max);
        let mut state = self.bvh.new_traversal(f32_dir(directions[0]));
        let mut node;
        obvhs::traverse!(
            self.bvh,
            node,
            state,
            slabs.children(node, state.oct_inv4, packet_t),
            {
                let prim = state.primitive_id as usize;
                let mut hit_any = false;
                for k in self.members(prim) {
                    let tri = &self.triangles[k];
                    let mut maybe = rays.may_hit(tri, origin, &best_t32) & live;
                    while maybe != 0 {
                        let i = maybe.trailing_zeros() as usize;
                        maybe &= maybe - 1;
                        match testers[i].intersect(tri) {
                            Some(t) if t > t_min && t < best_t[i] => {
                                best_t[i] = t;
                                best_t32[i] = t as f32;
                                // Scaled and rounded up as in `closest_hit`.
                                cull_t[i] = self.f32_t(t);
                                hits[i] = Some(Hit {
                                    triangle: self.ids[k],
                                    t,
                                });
                                hit_any = true;
                            }
                            _ => {}
                        }
                    }
                }
                if hit_any {
                    packet_t = cull_t[..n].iter().copied().fold(0.0, f32::max);
                }
            }
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{self, procedural};

    /// Every pixel's 32 pattern rays of every procedural scene (at 64×36):
    /// the packet's hits equal the single rays' hits, triangle and `t`.
    #[test]
    fn packet_hits_equal_single_ray_hits() {
        let pattern = crate::lut::sample_pattern();
        let mut checked = 0usize;
        let mut hit = 0usize;
        for name in procedural::NAMES {
            let scene = scene::load(name)
                .unwrap()
                .with_resolution([64, 36])
                .unwrap();
            let bvh = SceneBvh::build(&scene);
            let frame = scene.camera.frame(scene.resolution);
            let (near, far) = (scene.camera.near, scene.camera.far);
            for y in 0..36 {
                for x in 0..64 {
                    let dirs: Vec<DVec3> = pattern
                        .iter()
                        .map(|s| frame.direction(x as f64 + s[0] as f64, y as f64 + s[1] as f64))
                        .collect();
                    // Half the rays bounded, as the probes bound them.
                    let t_max: Vec<f64> = (0..32)
                        .map(|i| if i % 2 == 0 { far } else { far * 0.01 })
                        .collect();
                    let mut hits = [None; PACKET_RAYS];
                    bvh.closest_hits(DVec3::ZERO, &dirs, near, &t_max, &mut hits);
                    for i in 0..32 {
                        let one = bvh.closest_hit(
                            DVec3::ZERO,
                            dirs[i],
                            near,
                            t_max[i],
                            crate::bvh::NO_SKIP,
                        );
                        assert_eq!(hits[i], one, "{name} pixel ({x}, {y}) sample {i}");
                        checked += 1;
                        hit += one.is_some() as usize;
                    }
                }
            }
        }
        assert_eq!(checked, procedural::NAMES.len() * 64 * 36 * 32);
        assert!(hit > checked / 4, "only {hit} of {checked} rays hit");
    }
}
