//! The host's draws gathered into the pass's eye-relative triangles — the
//! CPU twin of the shadow pass's `gather_draws.comp`.
//!
//! A renderer keeps its meshes in its own vertex and index buffers, in
//! object space, and places them with per-instance transforms. The pass
//! reads those buffers where they lie (positions `R32G32B32_SFLOAT` at
//! any 4-byte offset and stride, `u16` or `u32` indices or none) and
//! writes, per triangle of the frame, its three eye-relative vertices and
//! its unit normal — what every later pass reads.
//!
//! Precision (`paper-notes/precision-envelope.md`): the host folds the eye
//! into each draw's transform in `f64` — p = R·v + (t − eye) — and rounds
//! R and t − eye to `f32` once per draw and frame, so a vertex's error is
//! relative to its distance from the eye (plus R's rounding times the
//! object-space |v|, small), never to its distance from the world's
//! origin. The normal is the object-space edge cross product, relative to
//! the triangle's first vertex (small coordinates), turned by R's cofactor
//! matrix — (Ra)×(Rb) = cof(R)(a×b) for any R, mirrored or scaled — which
//! keeps its error at object scale rather than at the eye's distance
//! (a normal rebuilt from eye-relative `f32` vertices flipped 1–2·10⁻⁴ of
//! the tangent-plane tests).
//!
//! A vertex is `((r.x·v.x + r.y·v.y) + r.z·v.z) + r.w` per row, in that
//! order, without fused multiply-add on either side (the shader's
//! operations are `precise`), so the GPU's vertices equal this twin's bit
//! for bit. The normal's square root and division are correctly rounded
//! here but may not be on a GPU (Vulkan allows a few ulp): tests compare
//! normals within that.

use glam::{DAffine3, DVec3, Vec3};
use izb_contract::{word::NO_INDICES, GpuDraw};

/// A draw's object-to-eye transform as `Draw` holds it: the rows of R
/// with (t − eye) in their w, and the cofactor matrix's rows (the
/// normals' transform).
pub type FoldedTransform = ([[f32; 4]; 3], [[f32; 3]; 3]);

/// Draw `transform` (object to world) with `eye` folded in, rounded once.
/// `None` where a rounded entry is not finite.
pub fn fold_transform(transform: DAffine3, eye: DVec3) -> Option<FoldedTransform> {
    let m = transform.matrix3;
    let t = transform.translation - eye;
    let rows = [0, 1, 2].map(|i| {
        let r = m.row(i);
        [r.x as f32, r.y as f32, r.z as f32, t[i] as f32]
    });
    // cof(M) = [m1×m2 | m2×m0 | m0×m1] (columns).
    let cofactor_columns = [
        m.y_axis.cross(m.z_axis),
        m.z_axis.cross(m.x_axis),
        m.x_axis.cross(m.y_axis),
    ];
    let cofactor = [0, 1, 2].map(|i| cofactor_columns.map(|c| c[i] as f32));
    let finite = rows.iter().flatten().all(|v| v.is_finite())
        && cofactor.iter().flatten().all(|v| v.is_finite());
    finite.then_some((rows, cofactor))
}

/// World bounds relative to `eye`, rounded outward to `f32` and widened
/// by 2⁻²⁰ of their diagonal: a gathered vertex outside them left the
/// bounds the pass was made for, not by rounding.
pub fn eye_relative_bounds(bounds: (DVec3, DVec3), eye: DVec3) -> [Vec3; 2] {
    let slack = (bounds.1 - bounds.0).length() * (-20f64).exp2();
    let down = |v: f64| {
        let f = v as f32;
        if f as f64 > v {
            f.next_down()
        } else {
            f
        }
    };
    let up = |v: f64| {
        let f = v as f32;
        if (f as f64) < v {
            f.next_up()
        } else {
            f
        }
    };
    let lo = bounds.0 - eye - DVec3::splat(slack);
    let hi = bounds.1 - eye + DVec3::splat(slack);
    [
        Vec3::new(down(lo.x), down(lo.y), down(lo.z)),
        Vec3::new(up(hi.x), up(hi.y), up(hi.z)),
    ]
}

/// The frame's triangles as the later passes read them, and what the
/// gather counted.
#[derive(Clone, Debug, Default)]
pub struct GatheredDraws {
    /// Eye-relative vertices, per triangle in draw order.
    pub triangles: Vec<[Vec3; 3]>,
    /// Unit normals (either facing: the G-buffer turns them to the eye).
    pub normals: Vec<Vec3>,
    /// Triangles with an index at or past their draw's vertex count
    /// (collapsed onto the draw's vertex 0: they cast no shadow).
    pub index_out_of_range: u32,
    /// Triangles with a vertex outside `bounds`.
    pub outside_bounds: u32,
}

/// One draw's vertex `v` in object space, from its slot's words.
fn object_vertex(d: &GpuDraw, words: &[u32], v: u32) -> Vec3 {
    let first = (d.vertex_offset + v * d.vertex_stride) as usize;
    Vec3::from_array([0, 1, 2].map(|k| f32::from_bits(words[first + k])))
}

/// Corner `k` (0..3) of a draw's triangle `t`: its index into the draw's
/// vertices.
fn corner_index(d: &GpuDraw, slots: &[&[u32]], t: u32, k: u32) -> u32 {
    let i = 3 * t + k;
    if d.index_slot == NO_INDICES {
        return i;
    }
    let words = slots[d.index_slot as usize];
    let at = d.index_offset + i;
    match d.index_bytes {
        2 => (words[(at / 2) as usize] >> (16 * (at % 2))) & 0xFFFF,
        _ => words[at as usize],
    }
}

/// The object-to-eye transform of one point (the shader's order).
fn transform(rows: &[[f32; 4]; 3], v: Vec3) -> Vec3 {
    let row = |r: [f32; 4]| ((r[0] * v.x + r[1] * v.y) + r[2] * v.z) + r[3];
    Vec3::new(row(rows[0]), row(rows[1]), row(rows[2]))
}

/// Gathers `draws` (their first triangles the running sum of the counts
/// before them) from the host's buffers, `slots[s]` the words of
/// `HOST_GEOMETRY` slot `s`. The draws were checked against the buffers'
/// sizes on the host (`ShadowPass::record_host_geometry`); an index is
/// checked here, against its draw's vertex count.
pub fn gather_draws(draws: &[GpuDraw], slots: &[&[u32]], bounds: [Vec3; 2]) -> GatheredDraws {
    let total: u32 = draws.iter().map(|d| d.triangle_count).sum();
    let mut out = GatheredDraws {
        triangles: Vec::with_capacity(total as usize),
        normals: Vec::with_capacity(total as usize),
        ..Default::default()
    };
    for d in draws {
        let rows = [d.row_x, d.row_y, d.row_z];
        let vertices = slots[d.vertex_slot as usize];
        for t in 0..d.triangle_count {
            let mut corners = [0, 1, 2].map(|k| corner_index(d, slots, t, k));
            if corners.iter().any(|&c| c >= d.vertex_count) {
                out.index_out_of_range += 1;
                corners = [0; 3];
            }
            let [a, b, c] = corners.map(|i| object_vertex(d, vertices, i));
            let m = (b - a).cross(c - a);
            let cofactor = [d.cofactor_x, d.cofactor_y, d.cofactor_z].map(Vec3::from_array);
            let n = Vec3::new(cofactor[0].dot(m), cofactor[1].dot(m), cofactor[2].dot(m));
            let length = n.dot(n).sqrt();
            let tri = [a, b, c].map(|v| transform(&rows, v));
            let inside = |v: &Vec3| v.cmpge(bounds[0]).all() && v.cmple(bounds[1]).all();
            if !tri.iter().all(inside) {
                out.outside_bounds += 1;
            }
            out.triangles.push(tri);
            out.normals
                .push(if length > 0.0 { n / length } else { Vec3::ZERO });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat3, DQuat};

    fn draw(rows: [[f32; 4]; 3], cofactor: [[f32; 3]; 3], vertex_count: u32) -> GpuDraw {
        GpuDraw {
            row_x: rows[0],
            row_y: rows[1],
            row_z: rows[2],
            cofactor_x: cofactor[0],
            first_triangle: 0,
            cofactor_y: cofactor[1],
            triangle_count: 2,
            cofactor_z: cofactor[2],
            vertex_slot: 0,
            vertex_offset: 1,
            vertex_stride: 4,
            vertex_count,
            index_slot: 1,
            index_offset: 1,
            index_bytes: 2,
        }
    }

    /// A mirrored, scaled, turned draw with `u16` indices at an odd
    /// offset and an interleaved stride: the vertices are the transform's
    /// in `f64` within a few `f32` ulps of the eye distance, the normals
    /// the transformed triangle's own (mirroring included), and an index
    /// past the vertex count collapses its triangle and is counted.
    #[test]
    fn a_turned_mirrored_draw_gathers_its_world_triangles() {
        let object = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 2.0, 0.5],
            [0.3, 0.1, 1.0],
        ];
        let mut words = vec![0xDEAD_BEEFu32];
        for p in object {
            words.extend(p.map(|c: f32| c.to_bits()));
            words.push(0xFFFF_FFFF);
        }
        let indices: [u16; 7] = [9, 0, 1, 2, 1, 3, 2];
        let index_words: Vec<u32> = indices
            .chunks(2)
            .map(|c| u32::from(c[0]) | (u32::from(*c.get(1).unwrap_or(&0)) << 16))
            .collect();
        let transform = DAffine3::from_mat3_translation(
            DMat3::from_quat(DQuat::from_rotation_y(0.7))
                * DMat3::from_diagonal(DVec3::new(2.0, -1.0, 3.0)),
            DVec3::new(1e4, -3.0, 2e4),
        );
        let eye = DVec3::new(1e4 + 5.0, 1.0, 2e4 - 7.0);
        let (rows, cofactor) = fold_transform(transform, eye).unwrap();
        let bounds = eye_relative_bounds((DVec3::splat(-1e5), DVec3::splat(1e5)), eye);
        let slots: [&[u32]; 2] = [&words, &index_words];
        let g = gather_draws(&[draw(rows, cofactor, 4)], &slots, bounds);
        assert_eq!(
            (g.index_out_of_range, g.outside_bounds, g.triangles.len()),
            (0, 0, 2)
        );
        for (t, tri) in g.triangles.iter().enumerate() {
            let world = [0, 1, 2].map(|k| {
                let p = object[indices[1 + 3 * t + k] as usize].map(f64::from);
                transform.transform_point3(DVec3::from_array(p)) - eye
            });
            for k in 0..3 {
                let err = (tri[k].as_dvec3() - world[k]).length();
                assert!(err <= 4e-7 * 2e4, "triangle {t} corner {k}: {err}");
            }
            let n = (world[1] - world[0]).cross(world[2] - world[0]).normalize();
            assert!(
                g.normals[t].as_dvec3().dot(n) > 1.0 - 1e-6,
                "{t}: {} {n}",
                g.normals[t]
            );
        }
        let mut bad = draw(rows, cofactor, 3);
        bad.triangle_count = 2;
        let g = gather_draws(&[bad], &slots, bounds);
        assert_eq!(g.index_out_of_range, 1);
        assert_eq!(g.triangles[1], [g.triangles[1][0]; 3]);
        assert_eq!(g.normals[1], Vec3::ZERO);
        let near = eye_relative_bounds((DVec3::splat(-1.0), DVec3::splat(1.0)), eye);
        assert_eq!(
            gather_draws(&[draw(rows, cofactor, 4)], &slots, near).outside_bounds,
            2
        );
    }
}
