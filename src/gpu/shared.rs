//! What the Rust side of the GPU backend shares with the shaders: the
//! contract (izb-contract: every struct, constant and binding, declared
//! once there and rendered to `contract.glsl` by `build.rs`), re-exported
//! under the names the passes use, and the host-side helpers of its words.

pub use izb_contract::{
    binding, counter, host_image, mode, BvhNode, CascadeGrid, FrameParams, GpuDraw, GpuTriangle,
    GpuTriangleCorners, LightState, VisibilityView,
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

/// The float ↔ ordered-uint map of `common.glsl` (`ordered_bits`), with
/// which the GPU's light setup and bin reduce floats by integer atomics:
/// unsigned order of the words is the order of the floats, so an atomic
/// minimum keeps the smallest. The CPU twins reduce the floats directly;
/// this spelling documents and tests the map.
pub fn ordered_bits(f: f32) -> u32 {
    let u = f.to_bits();
    if u & 0x8000_0000 != 0 {
        !u
    } else {
        u | 0x8000_0000
    }
}

/// Inverse of [`ordered_bits`].
pub fn from_ordered_bits(u: u32) -> f32 {
    f32::from_bits(if u & 0x8000_0000 != 0 {
        u & 0x7FFF_FFFF
    } else {
        !u
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ordered_bits_preserve_order() {
        let values = [
            -1e30f32,
            -2.5,
            -1e-30,
            -0.0,
            0.0,
            1e-30,
            3.0,
            1e30,
            f32::INFINITY,
        ];
        for w in values.windows(2) {
            assert!(
                ordered_bits(w[0]) <= ordered_bits(w[1]),
                "{} vs {}",
                w[0],
                w[1]
            );
            assert_eq!(from_ordered_bits(ordered_bits(w[1])), w[1]);
        }
    }
}
