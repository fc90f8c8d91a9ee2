//! The cases: a random small scene in the comfortable range (a tilted
//! ground quad, a few occluders around a unit cube, a camera a few radii
//! away, a directional or a nearby point light), then a random set of
//! extremes. The *relative* extremes (a far point light, a far or near
//! camera with or without a field of view that keeps the scene in frame,
//! extreme near/far planes, slivers, coincident and near-coincident copies,
//! many triangles) change what the image shows, so the comfortable twin
//! keeps them; the *similarity* (scale, offset) does not, so the twin
//! undoes it.

use glam::DVec3;
use izb::scene::{Camera, Light, Scene, Triangle};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::{FRAC_PI_2, TAU};

/// Small enough for 10⁵ cases, large enough for several edge pixels.
pub const RESOLUTION: [u32; 2] = [32, 18];

/// The comfortable scene's radius, roughly (ground ±2, occluders to 1.5).
const RADIUS: f64 = 3.0;

/// One generated case: the twin's inputs and the similarity that makes
/// the extreme scene of them.
pub struct Case {
    pub index: u64,
    /// The extremes applied, by name.
    pub classes: Vec<&'static str>,
    pub triangles: Vec<Triangle>,
    pub camera: Camera,
    pub light: Light,
    /// The similarity: p ↦ scale · p + offset.
    pub scale: f64,
    pub offset: DVec3,
    /// The point light's distance from the origin in scene radii.
    pub light_radii: Option<f64>,
    /// The camera's distance from its target in scene radii.
    pub camera_radii: f64,
}

impl Case {
    /// The comfortable twin: the scene the renderer was handed, with the
    /// similarity undone, so the relative extremes are kept.
    ///
    /// It is undone from the extreme inputs as `f64` rounded them, not
    /// built from the generator's values: at an offset of 4·10⁷ each vertex
    /// moves by up to 4·10⁻⁹, and where near-coincident copies lie 10⁻¹⁵
    /// apart that can move a sample ray to another copy (primary
    /// visibility decides exactly, on the rounded scene). Undoing the
    /// offset is exact (Sterbenz); undoing a scale rounds once more, at
    /// 10⁻¹⁶ of the scene. [`Case::generator_twin`] is the other twin.
    pub fn twin(&self) -> Result<Scene, String> {
        let (triangles, camera, light) = self.extreme_inputs();
        let undo = |p: DVec3| (p - self.offset) / self.scale;
        let triangles = triangles.iter().map(|t| t.map(undo)).collect();
        let camera = Camera {
            eye: undo(camera.eye),
            target: undo(camera.target),
            near: camera.near / self.scale,
            far: camera.far / self.scale,
            ..camera
        };
        let light = match light {
            Light::Point { position } => Light::Point {
                position: undo(position),
            },
            directional => directional,
        };
        Scene::new("twin", triangles, camera, light, RESOLUTION).map_err(|e| e.to_string())
    }

    /// The generator's own scene, before the similarity and its rounding:
    /// what the extreme scene would be in exact arithmetic. Its shadows
    /// against the twin's measure what the inputs' `f64` rounding at the
    /// extreme's distance from the origin does (the envelope's
    /// `MAX_ORIGIN_RADII`).
    pub fn generator_twin(&self) -> Result<Scene, String> {
        Scene::new(
            "generator twin",
            self.triangles.clone(),
            self.camera,
            self.light,
            RESOLUTION,
        )
        .map_err(|e| e.to_string())
    }

    /// The extreme scene, built as `izb render` builds a scene (the
    /// envelope is enforced by `Scene::new`).
    pub fn extreme(&self) -> Result<Scene, String> {
        let (triangles, camera, light) = self.extreme_inputs();
        Scene::new("extreme", triangles, camera, light, RESOLUTION).map_err(|e| e.to_string())
    }

    /// The extreme scene's inputs: the similarity applied in `f64`.
    fn extreme_inputs(&self) -> (Vec<Triangle>, Camera, Light) {
        let f = |p: DVec3| p * self.scale + self.offset;
        let triangles = self.triangles.iter().map(|t| t.map(f)).collect();
        let c = &self.camera;
        let camera = Camera {
            eye: f(c.eye),
            target: f(c.target),
            near: c.near * self.scale,
            far: c.far * self.scale,
            ..*c
        };
        let light = match self.light {
            Light::Point { position } => Light::Point {
                position: f(position),
            },
            directional => directional,
        };
        (triangles, camera, light)
    }

    /// Whether the similarity is exact in floating point: a power-of-two
    /// scale and no offset.
    pub fn exact_similarity(&self) -> bool {
        self.offset == DVec3::ZERO && self.scale.log2().fract() == 0.0
    }

    pub fn describe(&self) -> String {
        format!(
            "#{} {} | {} triangles, scale {:e}, offset {:.3e}, camera at {:.3e} radii, fov {:.3e}°, \
             near {:.3e}, far {:.3e}, light {}",
            self.index,
            self.classes.join("+"),
            self.triangles.len(),
            self.scale,
            self.offset.length(),
            self.camera_radii,
            self.camera.fov_y_deg,
            self.camera.near,
            self.camera.far,
            match self.light_radii {
                Some(k) => format!("point at {k:.3e} radii"),
                None => "directional".into(),
            }
        )
    }
}

fn log_uniform(rng: &mut Pcg64, lo: f64, hi: f64) -> f64 {
    (lo.ln() + (hi.ln() - lo.ln()) * rng.random::<f64>()).exp()
}

fn unit_vector(rng: &mut Pcg64) -> DVec3 {
    let z: f64 = rng.random_range(-1.0..1.0);
    let phi: f64 = rng.random_range(0.0..TAU);
    let r = (1.0 - z * z).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A unit vector between two elevations above the horizontal, degrees.
fn above(rng: &mut Pcg64, min_deg: f64, max_deg: f64) -> DVec3 {
    let elevation = rng.random_range(min_deg..max_deg).to_radians();
    let azimuth = rng.random_range(0.0..TAU);
    DVec3::new(
        elevation.cos() * azimuth.cos(),
        elevation.sin(),
        elevation.cos() * azimuth.sin(),
    )
}

fn occluder(rng: &mut Pcg64) -> Triangle {
    let centre = DVec3::new(
        rng.random_range(-1.0..1.0),
        rng.random_range(0.2..1.4),
        rng.random_range(-1.0..1.0),
    );
    let size = log_uniform(rng, 0.05, 1.0);
    [0; 3].map(|_| centre + unit_vector(rng) * size)
}

/// A triangle of height `ratio` × its longest edge (below 4 ε₃₂ it is
/// degenerate and dropped by name).
fn sliver(rng: &mut Pcg64, ratio: f64) -> Triangle {
    let [a, b, _] = occluder(rng);
    let along = rng.random_range(0.0..1.0);
    let across = (b - a).any_orthonormal_vector() * (b - a).length() * ratio;
    [a, b, a.lerp(b, along) + across]
}

/// A bumpy canopy of 2 m² triangles over the ground: many small occluders.
fn canopy(m: usize, rng: &mut Pcg64) -> Vec<Triangle> {
    let height = rng.random_range(0.6..1.2);
    let bumps = rng.random_range(1.0..8.0);
    let at = |i: usize, j: usize| {
        let (u, v) = (
            i as f64 / m as f64 * 1.6 - 0.8,
            j as f64 / m as f64 * 1.6 - 0.8,
        );
        DVec3::new(u, height + 0.05 * (bumps * u).sin() * (bumps * v).cos(), v)
    };
    let mut t = Vec::with_capacity(2 * m * m);
    for i in 0..m {
        for j in 0..m {
            t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    t
}

fn seeded(seed: u64, index: u64) -> Pcg64 {
    // splitmix64 of the pair: neighbouring indices get unrelated streams.
    let mut z = seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    Pcg64::seed_from_u64(z ^ (z >> 31))
}

/// Case `index` of the run with `seed`: the same pair gives the same case.
pub fn case(seed: u64, index: u64) -> Case {
    let mut rng = seeded(seed, index);
    let rng = &mut rng;
    let mut classes = Vec::new();
    let pick = |rng: &mut Pcg64| rng.random_bool(0.3);

    // The ground, tilted up to 20° about a random horizontal axis.
    let tilt = glam::DQuat::from_axis_angle(
        DVec3::new(rng.random_range(-1.0..1.0), 0.0, 1.0).normalize(),
        rng.random_range(-20f64..20.0).to_radians(),
    ) * glam::DQuat::from_rotation_y(rng.random_range(0.0..TAU));
    let [a, b, c, d] = [(-2.0, -2.0), (2.0, -2.0), (2.0, 2.0), (-2.0, 2.0)]
        .map(|(x, z)| tilt * DVec3::new(x, 0.0, z));
    let mut triangles = vec![[a, c, b], [a, d, c]];
    for _ in 0..rng.random_range(1..=6) {
        triangles.push(occluder(rng));
    }
    if pick(rng) {
        classes.push("slivers");
        for _ in 0..rng.random_range(1..=3) {
            let ratio = log_uniform(rng, 1e-8, 1e-2);
            triangles.push(sliver(rng, ratio));
        }
    }
    if pick(rng) {
        classes.push("coincident");
        let copies = [2, 64, 65, 200, 3000][rng.random_range(0..5)];
        let t = occluder(rng);
        triangles.extend((0..copies).map(|k| [t[k % 3], t[(k + 1) % 3], t[(k + 2) % 3]]));
    }
    if pick(rng) {
        classes.push("near-coincident");
        let copies = [2, 50, 500, 2000][rng.random_range(0..4)];
        let t = occluder(rng);
        let size = (t[1] - t[0]).length();
        for _ in 0..copies {
            let delta = log_uniform(rng, 1e-15, 1e-7) * size;
            triangles.push(t.map(|v| v + unit_vector(rng) * delta));
        }
    }
    if rng.random_bool(0.04) {
        classes.push("many triangles");
        triangles.extend(canopy(48, rng));
    }

    // The camera a few radii away, looking near the centre.
    let target = unit_vector(rng) * rng.random_range(0.0..0.5);
    let toward_eye = above(rng, 10.0, 70.0);
    let mut camera_radii = log_uniform(rng, 1.0, 3.5);
    let mut fov_y_deg = rng.random_range(25.0..70.0);
    if pick(rng) {
        classes.push("camera distance");
        camera_radii = 10f64.powf(rng.random_range(-6.0..30.0));
        if rng.random_bool(0.5) {
            // Keep the scene in frame: the field narrows with the distance.
            fov_y_deg = (2.0 * (1.2 / camera_radii).atan())
                .min(FRAC_PI_2)
                .to_degrees();
        }
    }
    let distance = camera_radii * RADIUS;
    let (mut near, mut far) = (
        distance * log_uniform(rng, 1e-3, 0.1),
        (distance + RADIUS) * log_uniform(rng, 1.5, 100.0),
    );
    if pick(rng) {
        classes.push("near/far");
        near = distance * 10f64.powf(rng.random_range(-6.0..0.5));
        far = near * (1.0 + 10f64.powf(rng.random_range(-6.0..30.0)));
    }
    let camera = Camera {
        eye: target + toward_eye * distance,
        target,
        up: DVec3::Y,
        fov_y_deg,
        near,
        far,
    };

    // The light: directional, or a point light above the scene.
    let (light, light_radii) = if pick(rng) {
        classes.push("light distance");
        let k = 10f64.powf(rng.random_range(0.2..30.0));
        let position = above(rng, 15.0, 85.0) * k * RADIUS;
        (Light::Point { position }, Some(k))
    } else if rng.random_bool(0.6) {
        let direction = -above(rng, 15.0, 85.0);
        (Light::Directional { direction }, None)
    } else {
        let k = log_uniform(rng, 1.0, 15.0);
        let position = above(rng, 15.0, 85.0) * k * RADIUS;
        (Light::Point { position }, Some(k))
    };

    // The similarity.
    let mut scale = 1.0;
    let mut offset = DVec3::ZERO;
    if pick(rng) || classes.is_empty() {
        if rng.random_bool(0.5) {
            classes.push("scale 2^k");
            scale = 2f64.powi(rng.random_range(-40..=100));
        } else {
            classes.push("scale");
            scale = 10f64.powf(rng.random_range(-12.0..30.0));
        }
    }
    if pick(rng) {
        classes.push("offset");
        offset = unit_vector(rng) * 10f64.powf(rng.random_range(-6.0..30.0));
    }
    Case {
        index,
        classes,
        triangles,
        camera,
        light,
        scale,
        offset,
        light_radii,
        camera_radii,
    }
}
