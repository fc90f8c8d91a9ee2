//! Build script. `izb-lut` is a build-dependency so that the 32-sample
//! edge-visibility LUT is generated here, at compile time, by the same code
//! the `izb lut` command runs (design §2). Until the LUT lands this script
//! only checks that the pattern crate and the renderer agree on the mask
//! width.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    assert_eq!(
        izb_lut::SAMPLES_PER_PIXEL,
        u32::BITS as usize,
        "occlusion masks are one u32 per pixel"
    );
}
