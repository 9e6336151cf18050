//! Run-time choice of the AVX2 builds of the warp's kernels and of the AVX-512-enabled builds
//! of the hottest ones (x86-64 only), and the scalar operations that keep them bit-identical to
//! the portable builds (no FMA, same operation order, min / max as compare-selects); the
//! switches exist so tests can prove it and benchmarks can time each build.

use zwarp_core::SimdSwitch;

static AVX2: SimdSwitch = SimdSwitch::avx2();
static AVX512: SimdSwitch = SimdSwitch::avx512();

/// Enables or disables the AVX2 builds of the warp's kernels (tests and benchmarks; on by
/// default where the CPU has AVX2).
pub fn set_simd(enabled: bool) {
    AVX2.set(enabled);
}

/// `true` if the AVX2 builds run: the switch is on and the CPU reports AVX2.
#[inline]
pub fn has_avx2() -> bool {
    AVX2.active()
}

/// Enables or disables the AVX-512 build of the search's walks (tests and benchmarks; on by
/// default where the CPU has AVX-512 F, VL, BW and DQ). That build is the AVX2 code compiled
/// with AVX-512 enabled (32 vector registers, mask registers): the same operations, the same
/// bits, fewer spills.
pub fn set_avx512(enabled: bool) {
    AVX512.set(enabled);
}

/// `true` if the AVX-512 build of the walks runs: the AVX2 builds run, its switch is on and the
/// CPU reports AVX-512 F, VL, BW and DQ.
#[inline]
pub fn has_avx512() -> bool {
    has_avx2() && AVX512.active()
}

/// `min` as a compare-select (`a < b ? a : b`): what `minps` computes, so loops of it vectorize
/// and the AVX2 builds stay bit-identical to the portable ones. No NaN may reach it (the layer
/// preparation rejects NaN input; empty texels are `+inf`).
#[inline(always)]
pub(crate) fn fmin(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// `max` as a compare-select (`a > b ? a : b`), as `maxps` computes it (see [`fmin`]).
#[inline(always)]
pub(crate) fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// AVX2 helpers shared by the kernels' AVX2 builds.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;
    use zwarp_core::Motion;

    /// Deinterleaves eight `Motion`s starting at `m` into (x, y, depth) vectors
    /// (`zwarp_core::simd::avx2::load3x8`).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn load_motion8(m: *const Motion) -> (__m256, __m256, __m256) {
        let [x, y, z] = zwarp_core::simd::avx2::load3x8(m as *const f32);
        (x, y, z)
    }
}
