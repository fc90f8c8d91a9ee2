//! A ray-cast shadow pass whose eye moves (`izb view`'s orbit and zoom):
//! the pass keeps its vertices and BVH in anchor space and makes both
//! eye-relative on the GPU each frame (`translate_vertices`). Over frames
//! whose eye orbits, zooms and whose light turns: the translated nodes
//! and vertices equal the CPU twin's bit for bit
//! (`izb::cpu::translate_vertices`), every triangle's translated vertices
//! lie inside every box on its path from the root (brute force), and the
//! masks equal `GpuRenderer::render`'s of the same view, whose BVH is
//! built for that eye. No Vulkan device: the test prints that it skipped,
//! unless `IZB_REQUIRE_GPU=1`.

mod common;

use common::gpu::assert_no_validation_messages;
use common::shadow_pass::{pass_renderer, run_frame, scene_at, settings, view_at};
use glam::{DMat3, Vec3};
use izb::cpu::translate_vertices::{translate_nodes, translate_vertices};
use izb::cpu::SampleMode;
use izb::gpu::gbuffer::build_bvh;
use izb::gpu::shadow_pass::{FrameView, GBufferInput, ShadowPass, ShadowPassConfig};
use izb::gpu::shared::BvhNode;
use izb::gpu::translate_vertices::WorldVertices;
use izb::gpu::GBufferSource;
use izb::scene::{self, Scene};

/// Frames per mode; each moves the eye.
const FRAMES: usize = 4;

/// Frame `k`: the light turning and the camera turning about its eye
/// (`view_at`), and the eye orbiting the target by 7° a frame and
/// closing in by 6 % a frame.
fn moving_view(scene: &Scene, k: usize) -> FrameView {
    let mut view = view_at(scene, k);
    let up = scene.camera.up.normalize();
    let orbit = DMat3::from_axis_angle(up, (7.0 * k as f64).to_radians());
    let target = view.camera.target;
    let zoom = 0.94f64.powi(k as i32);
    view.camera.eye = target + orbit * (view.camera.eye - target) * zoom;
    view
}

/// Every triangle under each node has its three vertices inside the
/// node's box: walked from the root, each leaf's triangles checked
/// against every box on the way down. Returns the triangles checked.
fn assert_boxes_hold_their_triangles(
    nodes: &[BvhNode],
    prims: &[u32],
    corners: &[[u32; 3]],
    vertices: &[Vec3],
) -> usize {
    let inside = |n: &BvhNode, v: Vec3| (0..3).all(|k| n.lo[k] <= v[k] && v[k] <= n.hi[k]);
    let mut checked = 0;
    let mut stack = vec![(0usize, Vec::<usize>::new())];
    while let Some((i, mut path)) = stack.pop() {
        path.push(i);
        let n = nodes[i];
        if n.prim_count == 0 {
            let first = n.first as usize;
            stack.push((first, path.clone()));
            stack.push((first + 1, path));
            continue;
        }
        for &t in &prims[n.first as usize..(n.first + n.prim_count) as usize] {
            for c in corners[t as usize] {
                let v = vertices[c as usize];
                for &p in &path {
                    assert!(inside(&nodes[p], v), "node {p} misses {v} of triangle {t}");
                }
            }
            checked += 1;
        }
    }
    checked
}

#[test]
fn a_ray_cast_pass_follows_a_moving_eye_bit_for_bit() {
    let Some(r) = pass_renderer() else { return };
    let scene = scene::load("default")
        .unwrap()
        .with_resolution([96, 54])
        .unwrap();
    let (lo, hi) = scene.bounds();
    let world = WorldVertices::new(&scene, (lo + hi) * 0.5);
    let bvh = build_bvh(&world.anchor_triangles()).unwrap();
    let corners: Vec<[u32; 3]> = world.corners.iter().map(|c| [c.a, c.b, c.c]).collect();
    let bits = |v: &[BvhNode]| bytemuck::cast_slice::<BvhNode, u32>(v).to_vec();
    let mut compared = 0;
    for mode in [SampleMode::Exact32, SampleMode::Lut32] {
        let s = settings(mode);
        let config = ShadowPassConfig {
            settings: s,
            frames_in_flight: 2,
            cell_capacity: None,
            edge_slots: None,
            gbuffer: GBufferInput::RayCast,
        };
        let mut pass = ShadowPass::new(&r, scene.clone(), config).unwrap();
        for k in 0..FRAMES {
            let view = moving_view(&scene, k);
            let before = r.context.shared.allocations();
            run_frame(&r, &mut pass, k, &view);
            assert_eq!(r.context.shared.allocations(), before, "frame {k}");
            // SAFETY: the frame was waited for; nothing is executing.
            let (status, images, [nodes, anchored], vertices) = unsafe {
                (
                    pass.status(k % 2).unwrap(),
                    pass.read_back().unwrap(),
                    pass.read_back_bvh_nodes().unwrap(),
                    pass.read_back_vertices().unwrap(),
                )
            };
            assert!(!status.cell_list_overrun && status.loop_cap_trips == 0);
            let eye = world.eye(view.camera.eye);
            // The anchor-space BVH is the one built here, and the GPU's
            // translation is the twin's, node for node and bit for bit.
            assert_eq!(bits(&anchored), bits(&bvh.nodes), "frame {k}: anchored");
            assert_eq!(bits(&nodes), bits(&translate_nodes(&bvh.nodes, eye)));
            let twin = translate_vertices(&world.pairs, eye);
            let vbits = |v: &[Vec3]| bytemuck::cast_slice::<Vec3, u32>(v).to_vec();
            assert_eq!(vbits(&vertices[..twin.len()]), vbits(&twin), "frame {k}");
            let held = assert_boxes_hold_their_triangles(&nodes, &bvh.prims, &corners, &twin);
            assert_eq!(held, scene.triangles.len());
            // The same view rendered by a batch frame, its BVH built for
            // this eye: the same masks.
            let batch = r
                .render(&scene_at(&scene, &view), s, GBufferSource::Gpu)
                .unwrap();
            assert_eq!(images.masks, batch.masks, "{mode:?}, frame {k}");
            assert_eq!(status.shadow_tested, batch.report.counters.shadow_tested);
            compared += 1;
        }
        assert_no_validation_messages(&r, "moving eye");
    }
    assert_eq!(compared, 2 * FRAMES);
}
