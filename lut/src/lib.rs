//! `izb-lut`: the sub-pixel sample pattern and (from the LUT issue on) the
//! edge-visibility lookup table. Pure Rust, no I/O: `build.rs` of the `izb`
//! crate, the CLI and the tests all call the same code.

/// Number of visibility samples per pixel: one bit each in a `u32` mask.
pub const SAMPLES_PER_PIXEL: usize = 32;
