//! Run-time choice of the AVX2 builds of the warp's kernels (x86-64 only). Every AVX2 build
//! computes bit-identical results to the portable one (no FMA, same operation order); the
//! switch exists so tests can prove it and benchmarks can time the portable build.

use std::sync::atomic::{AtomicBool, Ordering};

static SIMD_ENABLED: AtomicBool = AtomicBool::new(true);

/// Enables or disables the AVX2 builds of the warp's kernels (tests and benchmarks; on by
/// default where the CPU has AVX2).
pub fn set_simd(enabled: bool) {
    SIMD_ENABLED.store(enabled, Ordering::Relaxed);
}

/// `true` if the AVX2 builds run: the switch is on and the CPU reports AVX2.
#[inline]
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        SIMD_ENABLED.load(Ordering::Relaxed) && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
