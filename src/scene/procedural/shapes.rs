//! Triangle-mesh building blocks for the procedural scenes.

use crate::scene::Triangle;
use glam::DVec3;
use std::f64::consts::TAU;

/// Axis-aligned rectangle at height `y` spanning `[x0, x1] × [z0, z1]`,
/// two triangles with an upward normal.
pub fn ground(y: f64, x0: f64, x1: f64, z0: f64, z1: f64) -> Vec<Triangle> {
    let a = DVec3::new(x0, y, z0);
    let b = DVec3::new(x1, y, z0);
    let c = DVec3::new(x1, y, z1);
    let d = DVec3::new(x0, y, z1);
    vec![[a, d, c], [a, c, b]]
}

/// Parallelogram `origin + s·u + t·v`, s, t in [0, 1].
pub fn quad(origin: DVec3, u: DVec3, v: DVec3) -> Vec<Triangle> {
    let (a, b, c, d) = (origin, origin + u, origin + u + v, origin + v);
    vec![[a, b, c], [a, c, d]]
}

/// Axis-aligned box, 12 triangles.
pub fn cuboid(min: DVec3, max: DVec3) -> Vec<Triangle> {
    let size = max - min;
    let (x, y, z) = (DVec3::X * size.x, DVec3::Y * size.y, DVec3::Z * size.z);
    let mut t = Vec::with_capacity(12);
    t.extend(quad(min, z, y)); // -x
    t.extend(quad(min + x, y, z)); // +x
    t.extend(quad(min, x, z)); // -y
    t.extend(quad(min + y, z, x)); // +y
    t.extend(quad(min, y, x)); // -z
    t.extend(quad(min + z, x, y)); // +z
    t
}

/// UV sphere with `segments` around and `rings` from pole to pole.
pub fn sphere(center: DVec3, radius: f64, segments: u32, rings: u32) -> Vec<Triangle> {
    let point = |i: u32, j: u32| {
        let phi = TAU * i as f64 / segments as f64;
        let theta = std::f64::consts::PI * j as f64 / rings as f64;
        center
            + radius
                * DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                )
    };
    let mut t = Vec::new();
    for j in 0..rings {
        for i in 0..segments {
            let (a, b) = (point(i, j), point(i + 1, j));
            let (c, d) = (point(i + 1, j + 1), point(i, j + 1));
            if j != 0 {
                t.push([a, b, c]);
            }
            if j != rings - 1 {
                t.push([a, c, d]);
            }
        }
    }
    t
}

/// Open tube of `sides` facets from `a` to `b`: a wire, a post, a branch.
pub fn tube(a: DVec3, b: DVec3, radius: f64, sides: u32) -> Vec<Triangle> {
    let axis = (b - a).normalize();
    let helper = if axis.y.abs() < 0.9 {
        DVec3::Y
    } else {
        DVec3::X
    };
    let e1 = axis.cross(helper).normalize();
    let e2 = axis.cross(e1);
    let ring = |k: u32| {
        let phi = TAU * k as f64 / sides as f64;
        radius * (e1 * phi.cos() + e2 * phi.sin())
    };
    let mut t = Vec::with_capacity(2 * sides as usize);
    for k in 0..sides {
        let (r0, r1) = (ring(k), ring(k + 1));
        t.push([a + r0, b + r0, b + r1]);
        t.push([a + r0, b + r1, a + r1]);
    }
    t
}

/// Height field over `[x0, x1] × [z0, z1]` with `n × n` quads.
pub fn height_field(
    x0: f64,
    x1: f64,
    z0: f64,
    z1: f64,
    n: u32,
    height: impl Fn(f64, f64) -> f64,
) -> Vec<Triangle> {
    let point = |i: u32, j: u32| {
        let x = x0 + (x1 - x0) * i as f64 / n as f64;
        let z = z0 + (z1 - z0) * j as f64 / n as f64;
        DVec3::new(x, height(x, z), z)
    };
    let mut t = Vec::with_capacity(2 * (n * n) as usize);
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            );
            t.push([a, d, c]);
            t.push([a, c, b]);
        }
    }
    t
}

/// Direction a sun light travels, from its elevation above the horizon and
/// its azimuth around +Y (0° = coming from +Z), both in degrees.
pub fn sun_direction(elevation_deg: f64, azimuth_deg: f64) -> DVec3 {
    let (e, a) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
    -DVec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos())
}
