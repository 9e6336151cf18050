//! Run-time choice of the AVX2 builds of the warp's kernels (x86-64 only), and the scalar
//! operations that keep them bit-identical to the portable builds (no FMA, same operation
//! order, min / max as compare-selects); the switch exists so tests can prove it and benchmarks
//! can time the portable build.

use zwarp_core::Avx2Switch;

static AVX2: Avx2Switch = Avx2Switch::new();

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
