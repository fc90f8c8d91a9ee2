//! Built-in procedural scenes: each renders with no arguments (geometry,
//! camera, light and resolution included), so every command works on a
//! fresh machine without files.

pub mod shapes;

use super::{Camera, Light, Scene, SceneError, Triangle};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use shapes::{cuboid, ground, height_field, quad, sphere, sun_direction, tube};

/// Names accepted wherever a `SCENE` argument is.
pub const NAMES: &[&str] = &[
    "default", "wires", "hairball", "city", "grazing", "far", "analytic",
];

/// Offset of the `far` scene: the `default` scene moved 1e5 units along every
/// axis, where an `f32` world coordinate has a spacing of 2^-7 ≈ 8 mm.
pub const FAR_OFFSET: DVec3 = DVec3::splat(1e5);

/// Default image size of the procedural scenes.
pub const RESOLUTION: [u32; 2] = [960, 540];

/// The analytic test scene's parameters (see [`analytic`]).
pub mod analytic_params {
    /// Half the side of the square occluder.
    pub const OCCLUDER_HALF_SIDE: f64 = 1.0;
    /// Height of the occluder above the ground plane y = 0.
    pub const OCCLUDER_HEIGHT: f64 = 1.0;
    /// Half the side of the ground square (large enough to fill the view:
    /// "infinite" for the camera below).
    pub const GROUND_HALF_SIDE: f64 = 1000.0;
    /// Direction the light travels (not normalised).
    pub const LIGHT_DIRECTION: [f64; 3] = [2.5, -1.0, 0.8];
}

/// A procedural scene before validation: geometry, camera, light, size.
pub struct Procedural {
    pub triangles: Vec<Triangle>,
    pub camera: Camera,
    pub light: Light,
    pub resolution: [u32; 2],
}

/// The raw procedural scene `name`, or `None` if there is no such scene.
pub fn raw(name: &str) -> Option<Procedural> {
    Some(match name {
        "default" => default_scene(),
        "wires" => wires(),
        "hairball" => hairball(20_000),
        "city" => city(),
        "grazing" => grazing(),
        "far" => far(),
        "analytic" => analytic(),
        _ => return None,
    })
}

/// Geometry of a procedural scene by name (for specs that name one).
pub fn geometry(name: &str) -> Option<Vec<Triangle>> {
    raw(name).map(|p| p.triangles)
}

/// Builds the procedural scene `name`, or `Ok(None)` if no such scene.
pub fn build(name: &str) -> Result<Option<Scene>, SceneError> {
    let Some(p) = raw(name) else {
        return Ok(None);
    };
    Scene::new(name, p.triangles, p.camera, p.light, p.resolution).map(Some)
}

fn camera(eye: [f64; 3], target: [f64; 3], fov_y_deg: f64) -> Camera {
    Camera {
        eye: DVec3::from(eye),
        target: DVec3::from(target),
        up: DVec3::Y,
        fov_y_deg,
        near: 0.05,
        far: 2000.0,
    }
}

/// Ground, boxes, a sphere, a fence of thin wires and a pergola of slats
/// casting stripes; sun 35° above the horizon.
pub fn default_scene() -> Procedural {
    let mut t = ground(0.0, -15.0, 15.0, -15.0, 15.0);
    t.extend(cuboid(
        DVec3::new(-3.5, 0.0, -2.0),
        DVec3::new(-2.0, 1.5, -0.5),
    ));
    t.extend(cuboid(
        DVec3::new(1.0, 0.0, -3.5),
        DVec3::new(2.0, 3.0, -2.5),
    ));
    t.extend(cuboid(DVec3::new(2.5, 0.0, 0.5), DVec3::new(3.3, 0.6, 1.3)));
    t.extend(sphere(DVec3::new(-0.5, 1.0, 0.5), 1.0, 48, 24));
    // Fence: two posts and horizontal wires 5 mm thick.
    let (fx0, fx1, fz) = (-5.0, 1.0, 3.0);
    t.extend(tube(
        DVec3::new(fx0, 0.0, fz),
        DVec3::new(fx0, 1.3, fz),
        0.04,
        8,
    ));
    t.extend(tube(
        DVec3::new(fx1, 0.0, fz),
        DVec3::new(fx1, 1.3, fz),
        0.04,
        8,
    ));
    for k in 0..8 {
        let y = 0.25 + 0.14 * k as f64;
        t.extend(tube(
            DVec3::new(fx0, y, fz),
            DVec3::new(fx1, y, fz),
            0.0025,
            6,
        ));
    }
    // Pergola: four posts and a roof of slats 6 cm wide with 10 cm gaps.
    let (px0, px1, pz0, pz1, top) = (3.0, 6.0, -1.5, 2.5, 2.4);
    for (x, z) in [(px0, pz0), (px1, pz0), (px0, pz1), (px1, pz1)] {
        t.extend(cuboid(
            DVec3::new(x - 0.06, 0.0, z - 0.06),
            DVec3::new(x + 0.06, top, z + 0.06),
        ));
    }
    let mut z = pz0;
    while z + 0.06 <= pz1 {
        t.extend(cuboid(
            DVec3::new(px0 - 0.2, top, z),
            DVec3::new(px1 + 0.2, top + 0.08, z + 0.06),
        ));
        z += 0.16;
    }
    Procedural {
        triangles: t,
        camera: camera([6.5, 4.2, 8.0], [0.8, 0.5, 0.0], 50.0),
        light: Light::directional(sun_direction(35.0, 60.0)),
        resolution: RESOLUTION,
    }
}

/// Power lines: dozens of 3 mm wires strung between poles at several heights
/// and angles over the ground.
pub fn wires() -> Procedural {
    let mut t = ground(0.0, -20.0, 20.0, -20.0, 20.0);
    let mut rng = Pcg32::seed_from_u64(7);
    for pole in 0..4 {
        let x = -6.0 + 4.0 * pole as f64;
        t.extend(tube(
            DVec3::new(x, 0.0, -4.0),
            DVec3::new(x, 4.0, -4.0),
            0.08,
            8,
        ));
        t.extend(tube(
            DVec3::new(x, 0.0, 4.0),
            DVec3::new(x, 4.0, 4.0),
            0.08,
            8,
        ));
    }
    for _ in 0..48 {
        let a = DVec3::new(
            rng.random_range(-6.0..6.0),
            rng.random_range(1.0..4.0),
            -4.0,
        );
        let b = DVec3::new(rng.random_range(-6.0..6.0), rng.random_range(1.0..4.0), 4.0);
        t.extend(tube(a, b, 0.0015, 6));
    }
    Procedural {
        triangles: t,
        camera: camera([9.0, 7.0, 9.0], [0.0, 1.0, 0.0], 50.0),
        light: Light::directional(sun_direction(45.0, 30.0)),
        resolution: RESOLUTION,
    }
}

/// `n` random thin triangles (4 mm wide, 30 cm long) in a ball above the
/// ground: dense sub-pixel occluders.
pub fn hairball(n: usize) -> Procedural {
    let mut t = ground(0.0, -10.0, 10.0, -10.0, 10.0);
    let mut rng = Pcg32::seed_from_u64(42);
    let unit = |rng: &mut Pcg32| loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length_squared() <= 1.0 && v.length_squared() > 1e-6 {
            return v;
        }
    };
    let centre = DVec3::new(0.0, 2.0, 0.0);
    for _ in 0..n {
        let p = centre + 1.5 * unit(&mut rng);
        let along = unit(&mut rng).normalize() * 0.15;
        let side = along.cross(unit(&mut rng)).normalize() * 0.002;
        t.push([p - along - side, p - along + side, p + along]);
    }
    Procedural {
        triangles: t,
        camera: camera([5.0, 3.5, 6.0], [0.0, 1.4, 0.0], 50.0),
        light: Light::directional(sun_direction(50.0, 20.0)),
        resolution: RESOLUTION,
    }
}

/// A 12 × 12 grid of blocks of random height on a large ground: big
/// triangles spanning many light-space cells.
pub fn city() -> Procedural {
    let mut t = ground(0.0, -150.0, 150.0, -150.0, 150.0);
    let mut rng = Pcg32::seed_from_u64(1234);
    for i in 0..12 {
        for j in 0..12 {
            let x = -66.0 + 12.0 * i as f64;
            let z = -66.0 + 12.0 * j as f64;
            let h = rng.random_range(3.0..30.0);
            t.extend(cuboid(
                DVec3::new(x - 4.0, 0.0, z - 4.0),
                DVec3::new(x + 4.0, h, z + 4.0),
            ));
        }
    }
    Procedural {
        triangles: t,
        camera: camera([90.0, 60.0, 110.0], [0.0, 0.0, 0.0], 55.0),
        light: Light::directional(sun_direction(40.0, 35.0)),
        resolution: RESOLUTION,
    }
}

/// Bumpy terrain under a sun 3° above the horizon: long shadows, light
/// nearly tangent to the receivers.
pub fn grazing() -> Procedural {
    let hills = |x: f64, z: f64| {
        0.35 * (0.45 * x).sin() * (0.38 * z).cos()
            + 1.2 * (-((x - 4.0).powi(2) + (z + 3.0).powi(2)) / 6.0).exp()
            + 0.8 * (-((x + 6.0).powi(2) + (z - 2.0).powi(2)) / 3.0).exp()
    };
    let mut t = height_field(-30.0, 30.0, -30.0, 30.0, 96, hills);
    t.extend(cuboid(
        DVec3::new(-1.0, 0.0, -1.0),
        DVec3::new(0.0, 1.5, 0.0),
    ));
    t.extend(tube(
        DVec3::new(2.0, -0.5, 3.0),
        DVec3::new(2.0, 2.5, 3.0),
        0.05,
        8,
    ));
    Procedural {
        triangles: t,
        camera: camera([14.0, 6.0, 16.0], [0.0, 0.0, 0.0], 50.0),
        light: Light::directional(sun_direction(3.0, 250.0)),
        resolution: RESOLUTION,
    }
}

/// The `default` scene translated by [`FAR_OFFSET`].
pub fn far() -> Procedural {
    let mut p = default_scene();
    for v in p.triangles.iter_mut().flatten() {
        *v += FAR_OFFSET;
    }
    p.camera.eye += FAR_OFFSET;
    p.camera.target += FAR_OFFSET;
    p
}

/// An (effectively infinite) ground plane y = 0 and a square occluder
/// parallel to it under a directional light: the lit fraction of every
/// ground pixel has a closed form (see `reference::analytic`).
pub fn analytic() -> Procedural {
    use analytic_params::*;
    let g = GROUND_HALF_SIDE;
    let mut t = ground(0.0, -g, g, -g, g);
    let s = OCCLUDER_HALF_SIDE;
    t.extend(quad(
        DVec3::new(-s, OCCLUDER_HEIGHT, -s),
        DVec3::new(0.0, 0.0, 2.0 * s),
        DVec3::new(2.0 * s, 0.0, 0.0),
    ));
    Procedural {
        triangles: t,
        camera: camera([6.0, 3.5, -2.5], [2.2, 0.0, 0.7], 30.0),
        light: Light::directional(DVec3::from(LIGHT_DIRECTION)),
        resolution: [480, 270],
    }
}
