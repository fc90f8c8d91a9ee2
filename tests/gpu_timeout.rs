//! A frame that outlives its time limit is reported as a timeout — no hang,
//! no crash — and the abandoned work is never freed under the GPU. Its own
//! test binary: `IZB_GPU_TIMEOUT_S` is read per process, and the device it
//! poisons must not be shared with other tests. The validation layer is
//! on (whatever `IZB_VALIDATION` says) and any message fails the test: the
//! timeout path must not misuse the objects it abandons.

mod common;

use common::gpu::{assert_no_validation_messages, own_renderer};
use izb::cpu::IzbSettings;
use izb::gpu::{GBufferSource, GpuError, GpuOptions};

#[test]
fn a_frame_past_its_time_limit_is_a_timeout_error() {
    // One microsecond: no device finishes a 320×180 frame of the hairball
    // (20 000 triangles) that fast.
    std::env::set_var("IZB_GPU_TIMEOUT_S", "0.000001");
    let options = GpuOptions {
        validation: true,
        ..GpuOptions::from_env()
    };
    let Some(renderer) = own_renderer(&options) else {
        return;
    };
    let scene = izb::scene::load("hairball")
        .unwrap()
        .with_resolution([320, 180])
        .unwrap();
    let start = std::time::Instant::now();
    let err = renderer
        .render(&scene, IzbSettings::default(), GBufferSource::Gpu)
        .err()
        .expect("the frame cannot finish within a microsecond");
    println!("{err} after {:?}", start.elapsed());
    assert!(
        matches!(err, GpuError::Timeout(_)),
        "unexpected error: {err}"
    );
    assert!(renderer.context.shared.is_poisoned());
    assert_no_validation_messages(&renderer, "timed-out frame");
    // Dropping the renderer now must neither block nor free in-flight work.
    drop(renderer);
}
