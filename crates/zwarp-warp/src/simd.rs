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

/// AVX2 helpers shared by the kernels' AVX2 builds.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;
    use zwarp_core::Motion;

    /// Deinterleaves eight `Motion`s starting at `m` into (x, y, depth) vectors.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn load_motion8(m: *const Motion) -> (__m256, __m256, __m256) {
        let p = m as *const f32;
        let (a, b, c) = (_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8)), _mm256_loadu_ps(p.add(16)));
        // a = x0 y0 z0 x1 y1 z1 x2 y2, b = z2 x3 y3 z3 x4 y4 z4 x5, c = y5 z5 x6 y6 z6 x7 y7 z7.
        let i = |v: [i32; 8]| _mm256_setr_epi32(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]);
        let pick = |a: __m256, b: __m256, c: __m256, ia: [i32; 8], ib: [i32; 8], ic: [i32; 8], mb: i32, mc: i32| {
            let pa = _mm256_permutevar8x32_ps(a, i(ia));
            let pb = _mm256_permutevar8x32_ps(b, i(ib));
            let pc = _mm256_permutevar8x32_ps(c, i(ic));
            let mb = _mm256_castsi256_ps(i(std::array::from_fn(|k| if mb >> k & 1 != 0 { -1 } else { 0 })));
            let mc = _mm256_castsi256_ps(i(std::array::from_fn(|k| if mc >> k & 1 != 0 { -1 } else { 0 })));
            _mm256_blendv_ps(_mm256_blendv_ps(pa, pb, mb), pc, mc)
        };
        let x = pick(
            a,
            b,
            c,
            [0, 3, 6, 0, 0, 0, 0, 0],
            [0, 0, 0, 1, 4, 7, 0, 0],
            [0, 0, 0, 0, 0, 0, 2, 5],
            0b0011_1000,
            0b1100_0000,
        );
        let y = pick(
            a,
            b,
            c,
            [1, 4, 7, 0, 0, 0, 0, 0],
            [0, 0, 0, 2, 5, 0, 0, 0],
            [0, 0, 0, 0, 0, 0, 3, 6],
            0b0001_1000,
            0b1110_0000,
        );
        let z = pick(
            a,
            b,
            c,
            [2, 5, 0, 0, 0, 0, 0, 0],
            [0, 0, 0, 3, 6, 0, 0, 0],
            [0, 0, 0, 0, 0, 1, 4, 7],
            0b0001_1100,
            0b1110_0000,
        );
        (x, y, z)
    }
}
