//! One `GpuRenderer` used from two threads at once: its command pool and
//! queue are externally synchronised Vulkan objects, so frames are
//! serialised inside it (`GpuContext::submit_and_wait`). Both threads'
//! masks must equal the same frames rendered one after the other, with
//! the validation layer on (whatever `IZB_VALIDATION` says) and no
//! message. Skips without a device; fails instead with `IZB_REQUIRE_GPU=1`.

mod common;

use common::gpu::{assert_no_validation_messages, own_renderer};
use izb::cpu::IzbSettings;
use izb::gpu::{GBufferSource, GpuOptions};

#[test]
fn two_threads_share_one_renderer() {
    let options = GpuOptions {
        validation: true,
        ..GpuOptions::from_env()
    };
    let Some(renderer) = own_renderer(&options) else {
        return;
    };
    let scenes: Vec<_> = ["default", "wires"]
        .iter()
        .map(|n| {
            izb::scene::load(n)
                .unwrap()
                .with_resolution([96, 54])
                .unwrap()
        })
        .collect();
    let settings = IzbSettings::default();
    let render = |scene| {
        renderer
            .render(scene, settings, GBufferSource::Gpu)
            .unwrap()
            .masks
    };
    let one_after_other: Vec<Vec<u32>> = scenes.iter().map(render).collect();
    // Each thread renders both scenes, in opposite orders, twice.
    let (scenes, render) = (&scenes, &render);
    let at_once: Vec<Vec<Vec<u32>>> = std::thread::scope(|s| {
        let threads: Vec<_> = [[0, 1, 0, 1], [1, 0, 1, 0]]
            .into_iter()
            .map(|order| s.spawn(move || order.map(|k| render(&scenes[k])).to_vec()))
            .collect();
        threads.into_iter().map(|t| t.join().unwrap()).collect()
    });
    let mut compared = 0;
    for (order, masks) in [[0, 1, 0, 1], [1, 0, 1, 0]].iter().zip(&at_once) {
        for (&k, m) in order.iter().zip(masks) {
            assert_eq!(
                m, &one_after_other[k],
                "scene {k} differs when rendered concurrently"
            );
            compared += 1;
        }
    }
    assert_eq!(compared, 8);
    assert_eq!(
        renderer.context.max_concurrent_submissions(),
        1,
        "two frames were recorded or submitted at once"
    );
    assert_no_validation_messages(&renderer, "two threads");
}
