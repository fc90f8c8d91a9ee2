//! Measures the BVH builds on hostile geometry (issue 28): N distinct
//! triangles whose `f32` bounding boxes coincide, for the CPU
//! `SceneBvh::build` and the GPU `gbuffer::build_bvh`. Each case runs in a
//! child process, so a stack overflow is reported rather than fatal.
//!
//! `cargo run --release --example bvh_hostile -- [CASE N...]`
//!
//! Cases: `same-box` (vertices at random points of one box's faces),
//! `sub-ulp` (one triangle moved by less than an `f32` ulp per copy),
//! `row` (identical triangles evenly spaced along x) and `nested`
//! (triangles with one centre and boxes growing by an ulp), the last two
//! for what identical boxes alone do not cover.

use glam::DVec3;
use izb::bvh::SceneBvh;
use izb::gpu::gbuffer::build_bvh;
use izb::gpu::shared::GpuTriangle;
use izb::scene::{Camera, Light, Scene};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg32;
use std::time::{Duration, Instant};

const CASES: [&str; 4] = ["same-box", "sub-ulp", "row", "nested"];
const SIZES: [usize; 4] = [1_000, 8_000, 30_000, 65_000];
/// A case stops growing once one size took longer than this.
const GIVE_UP: Duration = Duration::from_secs(60);

fn triangles(case: &str, n: usize) -> Vec<[DVec3; 3]> {
    let mut rng = Pcg32::seed_from_u64(28);
    let base = DVec3::new(-0.5, 0.0, -3.0);
    match case {
        "same-box" => (0..n)
            .map(|_| {
                // x, y and z each reach 0 and 1: the box is the unit cube.
                let (za, yb, xc): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
                [
                    DVec3::new(0.0, 0.0, za),
                    DVec3::new(1.0, yb, 0.0),
                    DVec3::new(xc, 1.0, 1.0),
                ]
                .map(|v| base + v)
            })
            .collect(),
        "sub-ulp" => (0..n)
            .map(|i| {
                // Below a quarter of an f32 ulp at 1: every copy rounds to
                // the same f32 box, yet no two are equal in f64.
                let d = i as f64 * (f32::EPSILON as f64 / 4.0) / n as f64;
                [
                    DVec3::new(0.0, 0.0, 0.0),
                    DVec3::new(1.0, d, 0.0),
                    DVec3::new(0.5 + d, 1.0, 0.5),
                ]
                .map(|v| base + v)
            })
            .collect(),
        "row" => (0..n)
            .map(|i| {
                // Powers of two: every box and union is exact in f32.
                let x = i as f64 / 32768.0;
                [
                    DVec3::new(x, 0.0, 0.0),
                    DVec3::new(x + 1.0 / 131072.0, 0.0, 0.0),
                    DVec3::new(x, 1.0, 0.5),
                ]
                .map(|v| base + v)
            })
            .collect(),
        "nested" => (0..n)
            .map(|i| {
                let s = 1.0 + i as f64 * 1e-3 / n as f64;
                [
                    DVec3::new(-s, -s, 0.0),
                    DVec3::new(s, -s, s),
                    DVec3::new(0.0, s, -s),
                ]
                .map(|v| base + 0.5 * v)
            })
            .collect(),
        other => panic!("unknown case {other}"),
    }
}

fn scene(case: &str, n: usize) -> Scene {
    let camera = Camera {
        eye: DVec3::new(0.0, 0.5, 0.0),
        target: DVec3::new(0.0, 0.5, -3.0),
        up: DVec3::Y,
        fov_y_deg: 60.0,
        near: 0.05,
        far: 100.0,
    };
    Scene::new(
        case,
        triangles(case, n),
        camera,
        Light::directional(DVec3::new(-1.0, -2.0, -1.0)),
        [64, 64],
    )
    .expect("a valid scene")
}

/// Runs one case in this process and prints its line.
fn run_case(case: &str, n: usize) {
    let scene = scene(case, n);
    let kept = scene.triangles.len();
    let start = Instant::now();
    let bvh = SceneBvh::build(&scene);
    let cpu = start.elapsed();
    assert_eq!(bvh.len(), kept);
    let gpu_tris: Vec<GpuTriangle> = scene
        .eye_relative_triangles()
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| v.as_vec3().to_array());
            GpuTriangle { a, b, c }
        })
        .collect();
    let start = Instant::now();
    let gpu = build_bvh(&gpu_tris);
    let gpu_time = start.elapsed();
    let gpu = match gpu {
        Ok(b) => format!("{:.3} s, depth {}", gpu_time.as_secs_f64(), b.depth),
        Err(e) => format!("{:.3} s, refused: {e}", gpu_time.as_secs_f64()),
    };
    println!(
        "{case:>9} N={n:>6} kept {kept:>6}: cpu {:.3} s; gpu {gpu}",
        cpu.as_secs_f64()
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [case, n] = args.as_slice() {
        run_case(case, n.parse().expect("N is a number"));
        return;
    }
    let exe = std::env::current_exe().expect("own path");
    for case in CASES {
        for n in SIZES {
            let start = Instant::now();
            let status = std::process::Command::new(&exe)
                .args([case, &n.to_string()])
                .status()
                .expect("child runs");
            if !status.success() {
                println!("{case:>9} N={n:>6}: child failed ({status}): stack overflow or abort");
            }
            if start.elapsed() > GIVE_UP {
                println!("{case:>9}: larger N skipped (over {GIVE_UP:?})");
                break;
            }
        }
    }
}
