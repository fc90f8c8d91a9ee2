//! What the Rust side of the GPU backend shares with the shaders: the
//! contract (izb-contract: every struct, constant and binding, declared
//! once there and rendered to `contract.glsl` by `build.rs`), re-exported
//! under the names the passes use, and the host-side helpers of its words.

pub use izb_contract::{
    binding, counter, mode, BvhNode, CascadeGrid, FrameParams, GpuTriangle, LightState,
};

/// Number of descriptor bindings.
pub use izb_contract::BINDING_COUNT;

/// Local sizes of the pixel passes (8×8 tiles) and the linear passes.
pub const WORKGROUP_PIXELS: [u32; 2] = [
    izb_contract::workgroup::PIXELS_X,
    izb_contract::workgroup::PIXELS_Y,
];
pub const WORKGROUP_LINEAR: u32 = izb_contract::workgroup::LINEAR;

/// Bits of the G-buffer word that hold the triangle id (`ID_BITS`); the
/// four flag bits sit above them.
pub const ID_BITS: u32 = izb_contract::size::ID_BITS;
/// Id field of a miss; also one more than the largest triangle id.
pub const ID_MASK: u32 = izb_contract::word::ID_MASK;

/// GPU-only G-buffer flag (`FLAG_NORMAL_FLIPPED`): the receiver's
/// camera-facing normal is minus its triangle's stored normal. Stored
/// instead of a per-pixel normal (12 bytes per pixel).
pub const FLAG_NORMAL_FLIPPED: u32 = izb_contract::flags::NORMAL_FLIPPED;

/// Alpha of a shaded pixel that is not shadow-tested (`ALPHA_NOT_TESTED`);
/// otherwise alpha is the count of lit samples, 0..=32.
pub const ALPHA_NOT_TESTED: u8 = izb_contract::word::ALPHA_NOT_TESTED as u8;

/// The lit fraction a shaded pixel's alpha encodes with `samples` (32,
/// or 64 for `Paired64`) per pixel: exact (k/samples), NaN where not
/// shadow-tested, as [`crate::cpu::resolve_halves`] gives it.
pub fn lit_fraction_of_alpha(alpha: u8, samples: u32) -> f32 {
    if alpha == ALPHA_NOT_TESTED {
        f32::NAN
    } else {
        f32::from(alpha) / samples as f32
    }
}

/// The G-buffer word of a triangle id ([`crate::gbuffer::NO_HIT`] for a
/// miss) and its flags (`gbuffer_triangle` / `gbuffer_flags` in GLSL).
pub fn pack_id_flags(triangle: u32, flags: u32) -> u32 {
    let id = if triangle == crate::gbuffer::NO_HIT {
        ID_MASK
    } else {
        triangle & ID_MASK
    };
    (flags << ID_BITS) | id
}

/// Inverse of [`pack_id_flags`]: (triangle id, flags).
pub fn unpack_id_flags(word: u32) -> (u32, u32) {
    let id = word & ID_MASK;
    let id = if id == ID_MASK {
        crate::gbuffer::NO_HIT
    } else {
        id
    };
    (id, word >> ID_BITS)
}

/// The GLSL float ↔ ordered-uint map (`ordered_bits` in the shadow-map
/// shaders), declared with its CPU twin.
pub use crate::baseline::shadow_map::{from_ordered_bits, ordered_bits};
