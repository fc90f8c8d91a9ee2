//! Measures where the exact mode stops agreeing with the same-sample
//! reference (`f64`) as a scene's inputs grow extreme: a point light moved
//! away along a fixed direction, the whole scene scaled, the whole scene
//! moved away from the origin. Prints one line per case: samples
//! compared, mismatches, and how many of them lie within the documented
//! float margin.
//!
//! `cargo run --release --example precision_envelope -- [SCENE] [WxH]`

use glam::DVec3;
use izb::bvh::SceneBvh;
use izb::cpu::{render_cpu, IzbSettings, SampleMode};
use izb::gbuffer::{flags, pixel_surface};
use izb::reference::same_samples::{decision_margin, same_sample_masks, FLOAT_DECISION_TOLERANCE};
use izb::scene::{self, Camera, Light, Scene};

fn masks(scene: &Scene) -> (Vec<u32>, Vec<u32>, Vec<bool>) {
    let bvh = SceneBvh::build(scene);
    let reference = same_sample_masks(scene, &bvh, izb::lut::sample_pattern());
    let exact = render_cpu(
        scene,
        &bvh,
        IzbSettings {
            mode: SampleMode::Exact32,
            ..Default::default()
        },
    );
    let tested = exact
        .gbuffer
        .flags
        .iter()
        .map(|f| f & flags::SHADOW_TESTED != 0)
        .collect();
    (reference, exact.masks, tested)
}

fn bits(a: &[u32], b: &[u32], t: &[bool]) -> u64 {
    (0..a.len())
        .filter(|&i| t[i])
        .map(|i| (a[i] ^ b[i]).count_ones() as u64)
        .sum()
}

/// (differing samples, compared samples, samples the IZB left lit, samples
/// differing with a decision margin above the float tolerance).
fn mismatch(scene: &Scene) -> (u64, u64, u64, u64) {
    let (reference, exact, tested) = masks(scene);
    let tested = |i: usize| tested[i];
    let (diff, total) = izb::metrics::sample_mismatches(&exact, &reference, tested);
    let missed: u64 = (0..reference.len())
        .filter(|&i| tested(i))
        .map(|i| (reference[i] & !exact[i]).count_ones() as u64)
        .sum();
    let bvh = SceneBvh::build(scene);
    let frame = scene.camera.frame(scene.resolution);
    let light = scene.light.relative_to(scene.camera.eye);
    let triangles = scene.eye_relative_triangles();
    let pattern = izb::lut::sample_pattern();
    let w = scene.resolution[0];
    let mut beyond = 0;
    for i in (0..reference.len()).filter(|&i| tested(i) && exact[i] != reference[i]) {
        let px = pixel_surface(&bvh, scene, &frame, i as u32 % w, i as u32 / w).unwrap();
        let differing = exact[i] ^ reference[i];
        beyond += (0..32)
            .filter(|b| differing >> b & 1 == 1)
            .filter(|&b| {
                decision_margin(&triangles, &px, &light, pattern[b]) >= FLOAT_DECISION_TOLERANCE
            })
            .count() as u64;
    }
    (diff, total, missed, beyond)
}

fn transformed(
    base: &Scene,
    f: impl Fn(DVec3) -> DVec3,
    light: Light,
    near_far: f64,
) -> Result<Scene, String> {
    let triangles = base.triangles.iter().map(|t| t.map(&f)).collect();
    let c = &base.camera;
    let camera = Camera {
        eye: f(c.eye),
        target: f(c.target),
        up: c.up,
        fov_y_deg: c.fov_y_deg,
        near: c.near * near_far,
        far: c.far * near_far,
    };
    Scene::new(base.name.clone(), triangles, camera, light, base.resolution)
        .map_err(|e| e.to_string())
}

/// One case's line: the IZB against the reference, or the refusal.
fn report(what: &str, scene: Result<Scene, String>) {
    match scene {
        Err(e) => println!("{what}: refused ({e})"),
        Ok(scene) => {
            let (d, t, missed, beyond) = mismatch(&scene);
            println!(
                "{what}: {d} of {t} samples differ ({:.2e}); {missed} missed (lit in the IZB); \
                 {beyond} beyond float rounding",
                d as f64 / t.max(1) as f64
            );
        }
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("default", String::as_str);
    let resolution = args.get(1).map_or([160, 90], |r| {
        let (w, h) = r.split_once('x').unwrap();
        [w.parse().unwrap(), h.parse().unwrap()]
    });
    let base = scene::load(name)
        .unwrap()
        .with_resolution(resolution)
        .unwrap();
    let (lo, hi) = base.bounds();
    let centre = (lo + hi) * 0.5;
    let radius = (hi - lo).length() * 0.5;
    let eye = base.camera.eye;
    let eye_radius = (lo - eye).abs().max((hi - eye).abs()).length();
    println!("{name} at {resolution:?}: centre {centre}, radius {radius:.3}, eye-relative radius {eye_radius:.3}");
    let toward = match base.light {
        Light::Directional { direction } => -direction,
        Light::Point { position } => (position - centre).normalize(),
    };
    let dir_scene =
        transformed(&base, |p| p, Light::Directional { direction: -toward }, 1.0).unwrap();
    let (dref, dizb, dt) = masks(&dir_scene);
    println!(
        "directional toward the same: IZB vs reference {}",
        bits(&dref, &dizb, &dt)
    );
    for k in [1e2, 0.999e4] {
        let light = Light::Point {
            position: centre + toward * radius * k,
        };
        let (r, z, t) = masks(&transformed(&base, |p| p, light, 1.0).unwrap());
        println!(
            "  {k:e} radii: reference vs directional {}, IZB vs directional {}, IZB vs reference {}",
            bits(&r, &dref, &t),
            bits(&z, &dizb, &t),
            bits(&z, &r, &t)
        );
    }
    for k in [2.0, 10.0, 1e2, 1e3, 0.999e4, 1e5, 1e6] {
        let light = Light::Point {
            position: centre + toward * radius * k,
        };
        report(
            &format!("point light at {k:e} radii"),
            transformed(&base, |p| p, light, 1.0),
        );
    }
    for s in [1e-12, 1e-11, 1e-10, 1e-8, 1e-5, 1e-3, 1e3, 1e6, 1e8, 1e9] {
        let light = match base.light {
            Light::Directional { direction } => Light::Directional { direction },
            Light::Point { position } => Light::Point {
                position: position * s,
            },
        };
        report(
            &format!("scaled by {s:e}"),
            transformed(&base, |p| p * s, light, s),
        );
    }
    for o in [1e2, 1e4, 1e6, 1e8, 1e10, 1e12, 1e14] {
        let offset = DVec3::new(1.0, 0.5, -0.7) * o * radius;
        let light = match base.light {
            Light::Directional { direction } => Light::Directional { direction },
            Light::Point { position } => Light::Point {
                position: position + offset,
            },
        };
        report(
            &format!("moved {o:e} radii from the origin"),
            transformed(&base, |p| p + offset, light, 1.0),
        );
    }
    // The field of view narrowed around the target: the pixel's angle
    // shrinks toward the f32 rounding of eye-relative positions (2⁻²⁴).
    for k in [1.0, 2.0, 3.0, 4.0, 5.0, 6.0] {
        let mut camera = base.camera;
        camera.fov_y_deg /= 10f64.powf(k);
        let pixel = camera.fov_y_deg.to_radians() / resolution[1] as f64;
        let zoomed = Scene::new(
            base.name.clone(),
            base.triangles.to_vec(),
            camera,
            base.light,
            base.resolution,
        )
        .map_err(|e| e.to_string());
        report(
            &format!("field narrowed by 1e{k}: a pixel spans {pixel:.3e} rad"),
            zoomed,
        );
    }
    // The camera moved back along its view with the field narrowed to
    // frame the same view: eye-relative f32 positions round by ~d·2⁻²⁴,
    // which approaches the scene's own size.
    let d0 = (base.camera.target - eye).length();
    for k in [3.0, 1e1, 3e1, 1e2, 3e2, 1e3, 1e4, 1e5, 1e7] {
        let d = k * radius;
        let mut camera = base.camera;
        let back = (eye - camera.target).normalize();
        camera.eye = camera.target + back * d;
        camera.fov_y_deg =
            (2.0 * ((base.camera.fov_y_deg.to_radians() * 0.5).tan() * d0 / d).atan()).to_degrees();
        camera.near = base.camera.near * d / d0;
        camera.far = base.camera.far + d;
        let moved = Scene::new(
            base.name.clone(),
            base.triangles.to_vec(),
            camera,
            base.light,
            base.resolution,
        )
        .map_err(|e| e.to_string());
        report(&format!("camera {k:e} radii away, the same view"), moved);
    }
}
