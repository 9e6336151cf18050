//! The run-time choice of the AVX2 builds of the set-up and tile kernels (on by default where
//! the CPU has AVX2). Both builds compute bit-identical results (no FMA, same operation order);
//! the switch exists so tests can prove it and for timing the portable build.

use zwarp_core::SimdSwitch;

static AVX2: SimdSwitch = SimdSwitch::avx2();

/// Enables or disables the AVX2 builds (for tests / benchmarks).
pub(crate) fn set_simd(enabled: bool) {
    AVX2.set(enabled);
}

/// `true` if the AVX2 builds run.
#[inline]
pub(crate) fn has_avx2() -> bool {
    AVX2.active()
}
