//! Which instruction set the CPU twin's batched tests use: AVX-512 or
//! AVX2 where the processor has them (`is_x86_feature_detected!`, asked
//! once), else plain scalar code. Every path performs the same IEEE
//! operations in the same order, without fused multiply-adds, so masks and
//! counters do not depend on the path (`tests/simd_paths.rs` runs each on
//! every scene and mode). `IZB_SIMD=scalar` (or `avx2`) caps the path, as
//! on a machine without the wider units. Each kernel is a [`Kernel`],
//! and [`SimdPath::dispatch`] is the only way into its AVX2 and AVX-512F
//! copies: it checks the processor, so every caller stays safe code.

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
    /// that it does (the processor is asked once per path).
    pub fn or_supported(self) -> SimdPath {
        static WIDEST_UP_TO: std::sync::OnceLock<[SimdPath; 3]> = std::sync::OnceLock::new();
        let table = WIDEST_UP_TO.get_or_init(|| {
            Self::ALL.map(|cap| {
                Self::ALL
                    .into_iter()
                    .filter(|p| *p <= cap && p.supported())
                    .max()
                    .unwrap_or(SimdPath::Scalar)
            })
        });
        table[self as usize]
    }

    /// Runs `kernel`, writing `out`, compiled for this path's instruction
    /// set or for the widest narrower one the processor runs
    /// ([`Self::or_supported`]): the one place the CPU twin enters code
    /// compiled for AVX2 or AVX-512F, so no path a caller names can reach
    /// instructions the processor lacks.
    #[inline(always)]
    pub fn dispatch<K: Kernel>(self, kernel: K, out: &mut K::Out) -> K::Output {
        match self.or_supported() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `or_supported` returns Avx512 only where the
            // processor has AVX-512F.
            SimdPath::Avx512 => unsafe { run_avx512(kernel, out) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `or_supported` returns Avx2 only where the processor
            // has AVX2.
            SimdPath::Avx2 => unsafe { run_avx2(kernel, out) },
            _ => kernel.run(out),
        }
    }
}

/// A loop to compile once per instruction set ([`SimdPath::dispatch`]):
/// its inputs as `Self`, what it writes as `Out`, its body as
/// [`Kernel::run`].
///
/// Every implementation marks `run` `#[inline(always)]` and calls only
/// `#[inline(always)]` code in its loops, so that the body is compiled
/// inside the AVX2 and AVX-512F copies, with their instructions; the
/// loops meant for the vector units run over a constant number of lanes.
/// Two things measured with rustc 1.95 shape the trait: a closure in its
/// place stays a call into code compiled without those instructions, and
/// an output reached through a field of `self`, rather than a `&mut`
/// parameter of each copy, leaves the compiler unsure that the inputs do
/// not alias it, and the loops scalar.
pub trait Kernel {
    /// What the kernel writes.
    type Out: ?Sized;
    /// What it returns.
    type Output;
    fn run(self, out: &mut Self::Out) -> Self::Output;
}

/// # Safety
/// The processor has AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2<K: Kernel>(kernel: K, out: &mut K::Out) -> K::Output {
    kernel.run(out)
}

/// # Safety
/// The processor has AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn run_avx512<K: Kernel>(kernel: K, out: &mut K::Out) -> K::Output {
    kernel.run(out)
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

#[cfg(test)]
mod tests {
    use super::SimdPath;

    #[test]
    fn every_path_falls_back_to_the_widest_supported_one_at_most_as_wide() {
        for path in SimdPath::ALL {
            let runs = path.or_supported();
            assert!(runs <= path && runs.supported(), "{path:?} → {runs:?}");
            let mut wider = SimdPath::ALL
                .into_iter()
                .filter(|p| *p > runs && *p <= path);
            assert!(wider.all(|p| !p.supported()), "{path:?} → {runs:?}");
        }
        assert_eq!(SimdPath::Scalar.or_supported(), SimdPath::Scalar);
    }
}
