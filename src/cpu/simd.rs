//! Which instruction set the CPU twin's batched tests use: AVX-512 or
//! AVX2 where the processor has them (`is_x86_feature_detected!`, asked
//! once), else plain scalar code. Every path performs the same IEEE
//! operations in the same order, without fused multiply-adds, so masks and
//! counters do not depend on the path (`tests/simd_paths.rs` runs each on
//! every scene and mode). `IZB_SIMD=scalar` (or `avx2`) caps the path, as
//! on a machine without the wider units.

/// An instruction set for the batched tests, narrowest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SimdPath {
    /// Plain Rust, one lane at a time (what the compiler makes of it).
    Scalar,
    /// 8 lanes of `f32` (x86-64 AVX2).
    Avx2,
    /// 16 lanes of `f32` (x86-64 AVX-512F).
    Avx512,
}

impl SimdPath {
    /// Every path, narrowest first.
    pub const ALL: [SimdPath; 3] = [SimdPath::Scalar, SimdPath::Avx2, SimdPath::Avx512];

    /// Whether this processor runs the path.
    pub fn supported(self) -> bool {
        match self {
            SimdPath::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            SimdPath::Avx2 => std::arch::is_x86_feature_detected!("avx2"),
            #[cfg(target_arch = "x86_64")]
            SimdPath::Avx512 => std::arch::is_x86_feature_detected!("avx512f"),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The widest supported path, capped by `IZB_SIMD` (`scalar`, `avx2`,
    /// `avx512`); asked once per process.
    pub fn detected() -> SimdPath {
        static PATH: std::sync::OnceLock<SimdPath> = std::sync::OnceLock::new();
        *PATH.get_or_init(|| {
            let cap = match std::env::var("IZB_SIMD").as_deref() {
                Ok("scalar") => SimdPath::Scalar,
                Ok("avx2") => SimdPath::Avx2,
                _ => SimdPath::Avx512,
            };
            Self::ALL
                .into_iter()
                .filter(|p| *p <= cap && p.supported())
                .max()
                .unwrap_or(SimdPath::Scalar)
        })
    }

    /// This path if the processor runs it, else the widest narrower one
    /// that it does.
    pub fn or_supported(self) -> SimdPath {
        Self::ALL
            .into_iter()
            .filter(|p| *p <= self && p.supported())
            .max()
            .unwrap_or(SimdPath::Scalar)
    }
}

impl Default for SimdPath {
    fn default() -> Self {
        Self::detected()
    }
}

/// Asks the processor to bring `item` into its caches ahead of a read
/// that depends on a load not yet done: evaluate's walk reads each cell
/// entry's triangle by id, and the tangent-plane test's unpredictable
/// branch keeps the out-of-order core from starting the next entry's load
/// early. A hint only: no value changes, any address is allowed.
#[inline(always)]
pub fn prefetch<T>(item: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing the program sees and never faults,
    // whatever the address (Intel SDM, PREFETCHh).
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(item.cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = item;
}
