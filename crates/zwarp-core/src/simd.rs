//! The run-time choice between a kernel's AVX2 build and its portable build (x86-64), one switch
//! per crate and level. Every AVX2 build in zwarp computes bit-identical results to its portable twin; the
//! switch exists so that tests can prove it and benchmarks can time the portable build.

use std::sync::atomic::{AtomicBool, Ordering};

/// A crate's switch for the builds of one x86-64 SIMD level: on by default, active where it is
/// on and the CPU reports that level. [`SimdSwitch::avx2`] guards the AVX2 builds;
/// [`SimdSwitch::avx512`] guards builds of the same AVX2 code compiled with AVX-512 (F, VL, BW,
/// DQ) enabled, which lets the compiler use 32 vector registers and mask registers for the same
/// operations (the results stay bit-identical: no instruction changes what it computes).
#[derive(Debug)]
pub struct SimdSwitch {
    on: AtomicBool,
    avx512: bool,
}

impl SimdSwitch {
    /// The AVX2 switch (for a `static`), on.
    pub const fn avx2() -> Self {
        SimdSwitch { on: AtomicBool::new(true), avx512: false }
    }

    /// The AVX-512 switch (for a `static`), on; active only where AVX2 is too.
    pub const fn avx512() -> Self {
        SimdSwitch { on: AtomicBool::new(true), avx512: true }
    }

    /// Turns the builds on (default) or off.
    pub fn set(&self, enabled: bool) {
        self.on.store(enabled, Ordering::Relaxed);
    }

    /// `true` if the builds run: the switch is on and the CPU reports the level (never off
    /// x86-64).
    #[inline]
    pub fn active(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            self.on.load(Ordering::Relaxed)
                && has!("avx2")
                && (!self.avx512 || (has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq")))
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }
}

impl Default for SimdSwitch {
    fn default() -> Self {
        Self::avx2()
    }
}

/// Defines `$name`, whose body (AVX2 intrinsics) is compiled twice: for AVX2, and for AVX2 with
/// AVX-512 F, VL, BW and DQ enabled, which runs the same 256-bit operations with 32 vector
/// registers and mask registers to schedule them (bit-identical results). Each call takes the
/// second build where `$wide` holds (a crate's [`SimdSwitch::avx512`]), else the first; the
/// caller must have checked AVX2. The body is stamped into both builds, so closures in it take
/// their features.
///
/// ```ignore
/// zwarp_core::avx2_or_avx512! {
///     /// Docs of `rows`.
///     pub(crate) unsafe fn rows(a: &[f32], out: &mut [f32]) -> usize where wide = has_avx512(); {
///         // AVX2 intrinsics
///     }
/// }
/// ```
#[macro_export]
macro_rules! avx2_or_avx512 {
    ($(#[$meta:meta])* $vis:vis unsafe fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? where wide = $wide:expr; $body:block) => {
        $(#[$meta])*
        #[inline(always)]
        $vis unsafe fn $name($($arg: $ty),*) $(-> $ret)? {
            #[target_feature(enable = "avx2")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn narrow($($arg: $ty),*) $(-> $ret)? $body
            #[target_feature(enable = "avx2,avx512f,avx512vl,avx512bw,avx512dq")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn wide($($arg: $ty),*) $(-> $ret)? $body
            if $wide {
                wide($($arg),*)
            } else {
                narrow($($arg),*)
            }
        }
    };
}

/// AVX2 building blocks shared by the crates' AVX2 builds: glam's matrix-vector product on eight
/// lanes, and the transposes between eight three-float records (`Motion`'s `(x, y, depth)`, an
/// RGB texel) and three lane vectors.
///
/// The functions are `#[inline(always)]` without a `target_feature` of their own, so they take
/// the caller's: call them only from `#[target_feature(enable = "avx2")]` functions (the
/// caller's CPU check covers them).
#[cfg(target_arch = "x86_64")]
pub mod avx2 {
    use std::arch::x86_64::*;

    /// `m * (v0, v1, v2, v3)` per lane, bit for bit as glam's `Mat4 * Vec4` computes it: the
    /// columns scaled and summed in order, `((c0 v0 + c1 v1) + c2 v2) + c3 v3`, no FMA (no
    /// closure inside: one would not take the caller's AVX2 and its intrinsics would not inline).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub unsafe fn mat4_mul8(m: &glam::Mat4, v: [__m256; 4]) -> [__m256; 4] {
        let c = m.to_cols_array_2d();
        let mut r = [_mm256_setzero_ps(); 4];
        for (i, r) in r.iter_mut().enumerate() {
            let t0 = _mm256_mul_ps(_mm256_set1_ps(c[0][i]), v[0]);
            let t1 = _mm256_mul_ps(_mm256_set1_ps(c[1][i]), v[1]);
            let t2 = _mm256_mul_ps(_mm256_set1_ps(c[2][i]), v[2]);
            let t3 = _mm256_mul_ps(_mm256_set1_ps(c[3][i]), v[3]);
            *r = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(t0, t1), t2), t3);
        }
        r
    }

    /// Lanes of `v` picked by the constant indices `i`.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub unsafe fn pick(v: __m256, i: [i32; 8]) -> __m256 {
        _mm256_permutevar8x32_ps(v, _mm256_setr_epi32(i[0], i[1], i[2], i[3], i[4], i[5], i[6], i[7]))
    }

    /// Lanes picked from three vectors by constant indices and merged by the immediate masks
    /// (`MB`: lanes from `b`, `MC`: lanes from `c`, the rest from `a`): one lane shuffle of the
    /// three-float transposes.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub unsafe fn merge3<const MB: i32, const MC: i32>(
        (a, ia): (__m256, [i32; 8]),
        (b, ib): (__m256, [i32; 8]),
        (c, ic): (__m256, [i32; 8]),
    ) -> __m256 {
        _mm256_blend_ps::<MC>(_mm256_blend_ps::<MB>(pick(a, ia), pick(b, ib)), pick(c, ic))
    }

    /// Eight three-float records at `p` (24 floats) as three component vectors: the AoS -> SoA
    /// transpose.
    ///
    /// # Safety
    /// The CPU must support AVX2; `p` must be valid for reading 24 floats.
    #[inline(always)]
    pub unsafe fn load3x8(p: *const f32) -> [__m256; 3] {
        // a = x0 y0 z0 x1 y1 z1 x2 y2 | b = z2 x3 y3 z3 x4 y4 z4 x5 | c = y5 z5 x6 y6 z6 x7 y7 z7
        let (a, b, c) = (_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8)), _mm256_loadu_ps(p.add(16)));
        [
            merge3::<0b0011_1000, 0b1100_0000>(
                (a, [0, 3, 6, 0, 0, 0, 0, 0]),
                (b, [0, 0, 0, 1, 4, 7, 0, 0]),
                (c, [0, 0, 0, 0, 0, 0, 2, 5]),
            ),
            merge3::<0b0001_1000, 0b1110_0000>(
                (a, [1, 4, 7, 0, 0, 0, 0, 0]),
                (b, [0, 0, 0, 2, 5, 0, 0, 0]),
                (c, [0, 0, 0, 0, 0, 0, 3, 6]),
            ),
            merge3::<0b0001_1100, 0b1110_0000>(
                (a, [2, 5, 0, 0, 0, 0, 0, 0]),
                (b, [0, 0, 0, 3, 6, 0, 0, 0]),
                (c, [0, 0, 0, 0, 0, 1, 4, 7]),
            ),
        ]
    }

    /// Three component vectors of eight records as the three vectors of their 24 interleaved
    /// floats: the SoA -> AoS transpose, inverse of [`load3x8`].
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[inline(always)]
    pub unsafe fn interleave3x8([x, y, z]: [__m256; 3]) -> [__m256; 3] {
        [
            merge3::<0b1001_0010, 0b0010_0100>(
                (x, [0, 0, 0, 1, 0, 0, 2, 0]),
                (y, [0, 0, 0, 0, 1, 0, 0, 2]),
                (z, [0, 0, 0, 0, 0, 1, 0, 0]),
            ),
            merge3::<0b0010_0100, 0b0100_1001>(
                (x, [0, 3, 0, 0, 4, 0, 0, 5]),
                (y, [0, 0, 3, 0, 0, 4, 0, 0]),
                (z, [2, 0, 0, 3, 0, 0, 4, 0]),
            ),
            merge3::<0b0100_1001, 0b1001_0010>(
                (x, [0, 0, 6, 0, 0, 7, 0, 0]),
                (y, [5, 0, 0, 6, 0, 0, 7, 0]),
                (z, [0, 5, 0, 0, 6, 0, 0, 7]),
            ),
        ]
    }

    /// Eight records' component vectors stored as 24 interleaved floats at `p`.
    ///
    /// # Safety
    /// The CPU must support AVX2; `p` must be valid for writing 24 floats.
    #[inline(always)]
    pub unsafe fn store3x8(p: *mut f32, v: [__m256; 3]) {
        for (k, v) in interleave3x8(v).into_iter().enumerate() {
            _mm256_storeu_ps(p.add(8 * k), v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The transposes are each other's inverse and put record k's components in lane k.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_three_float_transposes_round_trip() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        #[target_feature(enable = "avx2")]
        unsafe fn run(src: &[f32; 24]) -> ([[f32; 8]; 3], [f32; 24]) {
            let v = avx2::load3x8(src.as_ptr());
            let mut back = [0.0f32; 24];
            avx2::store3x8(back.as_mut_ptr(), v);
            (v.map(|l| std::mem::transmute::<std::arch::x86_64::__m256, [f32; 8]>(l)), back)
        }
        let src: [f32; 24] = std::array::from_fn(|i| i as f32);
        // SAFETY: AVX2 checked above.
        let (lanes, back) = unsafe { run(&src) };
        for (c, lane) in lanes.iter().enumerate() {
            assert_eq!(*lane, std::array::from_fn(|k| (3 * k + c) as f32));
        }
        assert_eq!(back, src);
    }

    /// Eight lanes of `mat4_mul8` are glam's `Mat4 * Vec4` bit for bit.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_lane_matrix_product_is_glams() {
        use glam::{Mat4, Vec3, Vec4};
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        #[target_feature(enable = "avx2")]
        unsafe fn run(m: &Mat4, v: &[[f32; 8]; 4]) -> [[f32; 8]; 4] {
            use std::arch::x86_64::_mm256_loadu_ps;
            let r = avx2::mat4_mul8(m, v.map(|l| _mm256_loadu_ps(l.as_ptr())));
            r.map(|l| std::mem::transmute::<std::arch::x86_64::__m256, [f32; 8]>(l))
        }
        let m = Mat4::perspective_rh(1.1, 1.7, 0.1, 90.0)
            * Mat4::look_at_rh(Vec3::new(0.3, 1.7, 4.1), Vec3::new(-0.2, 0.1, 0.0), Vec3::Y);
        let v: [[f32; 8]; 4] = std::array::from_fn(|c| std::array::from_fn(|k| (c as f32 - 1.3) * (k as f32 + 0.37)));
        // SAFETY: AVX2 checked above.
        let lanes = unsafe { run(&m, &v) };
        for k in 0..8 {
            let want = m * Vec4::new(v[0][k], v[1][k], v[2][k], v[3][k]);
            let got = Vec4::new(lanes[0][k], lanes[1][k], lanes[2][k], lanes[3][k]);
            assert_eq!(got.to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "lane {k}");
        }
    }

    #[test]
    fn a_switch_turned_off_is_never_active() {
        let (s, w) = (SimdSwitch::avx2(), SimdSwitch::avx512());
        s.set(false);
        w.set(false);
        assert!(!s.active() && !w.active());
        s.set(true);
        w.set(true);
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            assert_eq!(s.active(), has!("avx2"));
            let wide = has!("avx2") && has!("avx512f") && has!("avx512vl") && has!("avx512bw") && has!("avx512dq");
            assert_eq!(w.active(), wide);
        }
        #[cfg(not(target_arch = "x86_64"))]
        assert!(!s.active() && !w.active());
    }
}
